"""Tests for hoibench.publish.render: off-screen pyvista rendering to .png / .gif / .mp4.

The rendering tests skip when pyvista or imageio is not installed (they are optional
dependencies: ``pip install pyvista imageio``).
"""
import json
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from hoibench.core.io import atomic_save_npz
from hoibench.publish.render import MAX_GIF_FRAMES, camera_pose, select_frames

T = 12
SIZE = (160, 120)


@pytest.fixture(scope="module")
def deps():
    pytest.importorskip("pyvista")
    iio = pytest.importorskip("imageio.v2")
    return iio


def _box(sx=0.4, sy=0.3, sz=0.3):
    v = np.array([[x, y, z] for x in (-sx / 2, sx / 2) for y in (-sy / 2, sy / 2)
                  for z in (-sz / 2, sz / 2)], np.float32)
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]], np.int32)
    return v, f


def _clip(n=T):
    """A proxy body walking forward and swinging its arms, a box at its left hand,
    contacts at the left wrist (all frames) and the left foot (second half)."""
    from hoibench.bodies import ProxyBody

    t = np.arange(n) / 20.0
    poses = np.zeros((n, 52, 3))
    poses[:, 16, 2], poses[:, 17, 2] = -1.2, 1.2
    poses[:, 18, 1] = 0.8 * np.sin(4 * t)
    poses[:, 1, 0], poses[:, 2, 0] = 0.4 * np.sin(6 * t), -0.4 * np.sin(6 * t)
    trans = np.stack([0.1 * t, np.full(n, 1.15), 0.8 * t], 1)
    _, joints = ProxyBody().forward(poses, trans, np.zeros(10))
    a = 2.0 * t
    rot = np.stack([[[np.cos(x), 0, np.sin(x)], [0, 1, 0], [-np.sin(x), 0, np.cos(x)]] for x in a])
    otrans = joints[:, 20] + np.array([0.15, 0.0, 0.2])
    contacts = np.zeros((n, 22), bool)
    contacts[:, 20] = True
    contacts[n // 2:, 10] = True
    return dict(joints=joints.astype(np.float32), fps=np.float64(20.0), object_name=np.array("box"),
                obj_rot=rot.astype(np.float32), obj_trans=otrans.astype(np.float32), contacts=contacts,
                poses=poses.reshape(n, 156).astype(np.float32), betas=np.zeros(10, np.float32),
                trans=trans.astype(np.float32), gender=np.array("neutral"))


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    root = tmp_path_factory.mktemp("store")
    clip = _clip()
    atomic_save_npz(root / "clips" / "c0.npz", **clip)
    bare = {k: v for k, v in clip.items() if k not in ("poses", "betas", "trans", "gender")}
    atomic_save_npz(root / "clips" / "bare.npz", **bare)
    shifted = dict(clip, trans=clip["trans"] + np.float32(1.0))  # parameters in another frame
    atomic_save_npz(root / "clips" / "shifted.npz", **shifted)
    v, f = _box()
    atomic_save_npz(root / "objects" / "box.npz", vertices=v, faces=f)
    (root / "manifest.json").write_text(json.dumps(
        {"clips": [{"id": c, "split": "test", "frames": T} for c in ("c0", "bare", "shifted")]}))
    return root


def _gif_frames(path):
    from PIL import Image

    with Image.open(path) as im:
        return im.n_frames, im.size, im.info.get("duration")


def _no_temp_files(folder: Path):
    assert not [p.name for p in folder.iterdir() if p.name.startswith(".")]


# --------------------------------------------------------------------------- no pyvista needed
def test_import_is_cheap():
    code = "import sys, hoibench.publish.render; assert 'pyvista' not in sys.modules and 'vtk' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True, cwd=Path(__file__).resolve().parents[1])


def test_select_frames():
    idx, k = select_frames(200, None, ".gif")
    assert k == 4 and len(idx) == 50 and len(idx) <= MAX_GIF_FRAMES and idx[0] == 0
    idx, k = select_frames(60, None, ".gif")
    assert k == 1 and len(idx) == 60
    assert len(select_frames(200, None, ".mp4")[0]) == 200
    assert select_frames(200, None, ".png")[0].tolist() == [100]
    assert select_frames(10, [3], ".png")[0].tolist() == [3]
    assert select_frames(10, 3, ".gif")[0].tolist() == [0, 3, 6, 9]
    assert select_frames(10, slice(2, 8, 2), ".gif")[0].tolist() == [2, 4, 6]
    assert select_frames(10, [-1, 0], ".gif")[0].tolist() == [9, 0]
    with pytest.raises(ValueError):
        select_frames(10, [10], ".gif")
    with pytest.raises(ValueError):
        select_frames(10, [], ".gif")


def test_camera_sees_box_from_front_left():
    cam = camera_pose(np.array([-0.5, 0, -0.5]), np.array([0.5, 1.8, 0.5]), np.array([0.0, 0, 1.0]), (480, 360))
    d = cam["position"] - cam["focal_point"]
    assert d[2] > 0 and d[1] > 0 and d[0] > 0  # in front (+z facing), above, to the body's left (+x)
    assert np.linalg.norm(d) > 2.0


# --------------------------------------------------------------------------- rendering
def test_png_size_and_object_changes_pixels(deps, tmp_path):
    from hoibench.publish.render import render_sequence

    clip = _clip()
    v, f = _box()
    with_obj = render_sequence(clip["joints"], (v, clip["obj_rot"], clip["obj_trans"]), f, clip["contacts"],
                               tmp_path / "with.png", size=SIZE)
    without = render_sequence(clip["joints"], None, None, clip["contacts"], tmp_path / "without.png", size=SIZE)
    a, b = deps.imread(with_obj), deps.imread(without)
    assert a.shape[:2] == (SIZE[1], SIZE[0]) and b.shape == a.shape
    differ = np.any(a[..., :3] != b[..., :3], axis=-1).mean()
    assert differ > 0.005, differ  # the box covers part of the image
    # the same input renders the same picture (posed vertices give the same object as R, t)
    posed = np.einsum("tij,vj->tvi", clip["obj_rot"], v) + clip["obj_trans"][:, None]
    again = render_sequence(clip["joints"], posed, f, clip["contacts"], tmp_path / "again.png", size=SIZE)
    diff = np.abs(deps.imread(again).astype(int) - a.astype(int))
    assert (diff.max(-1) > 8).mean() < 0.002
    _no_temp_files(tmp_path)


def test_gif_frame_count(deps, tmp_path):
    from hoibench.publish.render import render_sequence

    clip = _clip()
    out = render_sequence(clip["joints"], None, None, None, tmp_path / "skel.gif", frames=2, size=SIZE,
                          clip_fps=20.0)
    n, size, duration = _gif_frames(out)
    assert n == T // 2 and size == SIZE and duration == 100  # every 2nd frame of 20 fps, real time
    _no_temp_files(tmp_path)


def test_render_clip_png_and_gif(deps, store, tmp_path):
    from hoibench.publish.render import render_clip

    png = render_clip(store, "c0", tmp_path / "c0.png", size=SIZE)
    assert png.stat().st_size > 0 and deps.imread(png).shape[:2] == (SIZE[1], SIZE[0])
    skel = render_clip(store, "c0", tmp_path / "c0_skel.png", body="skeleton", size=SIZE)
    assert np.any(deps.imread(png) != deps.imread(skel))  # the proxy surface is not the skeleton
    gif = render_clip(store, "c0", tmp_path / "c0.gif", size=SIZE, fps=10)
    n, size, duration = _gif_frames(gif)
    assert n == T and size == SIZE and duration == 100
    _no_temp_files(tmp_path)


def test_render_clip_falls_back_to_skeleton(deps, store, tmp_path):
    from hoibench.publish.render import render_clip

    skel = deps.imread(render_clip(store, "c0", tmp_path / "skel.png", body="skeleton", size=SIZE))
    for cid in ("bare", "shifted"):
        with pytest.warns(UserWarning, match="rendering the skeleton"):
            out = render_clip(store, cid, tmp_path / f"{cid}.png", size=SIZE)
        img = deps.imread(out)
        # same scene as the skeleton render, apart from the title in the label
        assert img.shape == skel.shape
        assert (np.abs(img.astype(int) - skel.astype(int)).max(-1) > 8).mean() < 0.05


def test_mp4_needs_imageio_ffmpeg(deps, store, tmp_path, monkeypatch):
    from hoibench.publish.render import render_clip

    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # makes `import imageio_ffmpeg` fail
    with pytest.raises(ImportError, match="pip install imageio-ffmpeg"):
        render_clip(store, "c0", tmp_path / "c0.mp4", size=SIZE)
    assert list(tmp_path.iterdir()) == []


def test_mp4(deps, store, tmp_path):
    pytest.importorskip("imageio_ffmpeg")
    from hoibench.publish.render import render_clip

    out = render_clip(store, "c0", tmp_path / "c0.mp4", size=SIZE, frames=slice(0, 8))
    reader = deps.get_reader(str(out))
    try:
        assert reader.count_frames() == 8
        assert tuple(reader.get_meta_data()["size"]) == SIZE
    finally:
        reader.close()
    _no_temp_files(tmp_path)


def test_bad_suffix(deps, tmp_path):
    from hoibench.publish.render import render_sequence

    with pytest.raises(ValueError, match="unsupported output format"):
        render_sequence(_clip()["joints"], out_path=tmp_path / "x.jpg")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match="joints"):
            render_sequence(np.zeros((3, 21, 3)), out_path=tmp_path / "x.png")
