"""BEHAVE loader on hand-built raw sequences (proxy body), the store, resume and errors."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("smplx")
trimesh = pytest.importorskip("trimesh")

from hoibench.core import geometry as geo  # noqa: E402
from hoibench.bodies import ProxyBody, write_proxy_model  # noqa: E402
from hoibench.datasets import behave  # noqa: E402
from hoibench.datasets.store import PrepareConfig, Store, prepare  # noqa: E402

F = np.diag([1.0, -1.0, -1.0])
CAM_OFFSET = np.array([0.3, 1.1, 2.5])    # camera-frame translation added after the flip


def _world_sequence(T: int, seed: int):
    """Random SMPL-H params in a y-up world, their proxy joints/vertices and a box pose."""
    rng = np.random.default_rng(seed)
    t = np.arange(T) / 30.0
    pose = np.zeros((T, 52, 3))
    pose[:, 1:22] = 0.25 * np.sin(2 * np.pi * rng.uniform(0.2, 1.0, (21, 3)) * t[:, None, None]
                                  + rng.uniform(0, 6, (21, 3)))
    pose[:, 0] = np.stack([np.zeros(T), 0.5 * t, np.zeros(T)], -1)
    trans = np.stack([0.3 * t, 0.95 + 0.02 * np.sin(t), 0.2 * t], -1)
    betas = np.zeros(10)
    betas[0] = rng.uniform(-1, 1)
    obj_aa = np.stack([0.1 * t, 0.3 * t, np.zeros(T)], -1)
    obj_t = trans + np.array([0.0, 0.1, 0.4])
    return pose.reshape(T, 156), trans, betas, obj_aa, obj_t


def _write_raw(root: Path, name: str, T: int = 40, seed: int = 0, gender: str = "male"):
    pose, trans, betas, obj_aa, obj_t = _world_sequence(T, seed)
    body = ProxyBody()
    j0 = body.forward(np.zeros((1, 22, 3)), np.zeros((1, 3)), betas)[1][0, 0]
    cam_pose = pose.copy()
    cam_pose[:, :3] = geo.matrix_to_axis_angle(F @ geo.axis_angle_to_matrix(pose[:, :3]))
    cam_trans = (j0 + trans) @ F.T - j0 + CAM_OFFSET
    seq = root / "sequences" / name
    seq.mkdir(parents=True)
    times = np.array([f"t{(i / 30.0):09.3f}" for i in range(T)])
    np.savez(seq / "smpl_fit_all.npz", poses=cam_pose.astype(np.float32), betas=np.tile(betas, (T, 1)).astype(np.float32),
             trans=cam_trans.astype(np.float32), save_name=np.array(name), frame_times=times)
    R = F @ geo.axis_angle_to_matrix(obj_aa)
    np.savez(seq / "object_fit_all.npz", angles=geo.matrix_to_axis_angle(R), trans=obj_t @ F.T + CAM_OFFSET,
             save_name=np.array(name), frame_times=times)
    (seq / "info.json").write_text(json.dumps({"gender": gender, "cat": "boxsmall"}))
    obj_dir = root / "objects" / "boxsmall"
    if not obj_dir.exists():
        obj_dir.mkdir(parents=True)
        box = trimesh.creation.box(extents=(0.3, 0.2, 0.25))
        box.vertices += np.array([0.05, 0.02, -0.01])   # not centred on purpose
        box.export(obj_dir / "boxsmall_f1000.ply")
    world_joints = body.forward(pose.reshape(T, 52, 3)[:, :22], trans, betas)[1]
    return world_joints, geo.axis_angle_to_matrix(obj_aa), obj_t


@pytest.fixture()
def raw(tmp_path):
    root = tmp_path / "raw"
    truth = {name: _write_raw(root, name, seed=i) for i, name in enumerate(
        ["Date01_Sub01_boxsmall_lift", "Date02_Sub06_boxsmall_carry", "Date03_Sub03_boxsmall_push"])}
    models = tmp_path / "models"
    write_proxy_model(models)
    return root, models, truth



def test_loader_recovers_world_joints_and_object_pose(raw):
    root, models, truth = raw
    name = "Date01_Sub01_boxsmall_lift"
    seq = behave.load_sequence(root / "sequences" / name, root / "objects", models, fps=30.0)
    joints, obj_rot, obj_t = truth[name]
    # y-up world up to the constant camera offset (flipped) and the floor shift
    shift = seq.joints.astype(np.float64) - joints
    expected = F @ CAM_OFFSET - np.array([0.0, seq.provenance["floor_shift_m"], 0.0])
    np.testing.assert_allclose(shift, np.broadcast_to(expected, shift.shape), atol=1e-4)
    np.testing.assert_allclose(seq.obj_rot, obj_rot, atol=1e-6)
    # template is centred on its vertex mean; a corner of the (offset) box lands where the truth puts it
    np.testing.assert_allclose(seq.object_vertices.mean(0), 0.0, atol=1e-12)
    assert abs(seq.joints[..., 1].min()) < 0.2 and seq.joints[:, 15, 1].mean() > seq.joints[:, 0, 1].mean()
    assert seq.subject == "Sub01" and seq.body.gender == "male"


def test_resampling_is_by_time(raw):
    root, models, truth = raw
    name = "Date01_Sub01_boxsmall_lift"
    s30 = behave.load_sequence(root / "sequences" / name, root / "objects", models, fps=30.0)
    s20 = behave.load_sequence(root / "sequences" / name, root / "objects", models, fps=20.0)
    assert s20.num_frames == int(np.floor((39 / 30) * 20 + 1e-9)) + 1
    # frame k at 20 fps is time k/20 = frame 1.5k at 30 fps: even k coincide exactly
    np.testing.assert_allclose(s20.joints[::2], s30.joints[::3][: len(s20.joints[::2])], atol=1e-4)


def test_prepare_store_resume_and_errors(raw, tmp_path):
    root, models, truth = raw
    # defects: truncated npz, mismatched frames, unknown object, non-finite parameter, missing file
    bad = {}
    for i, kind in enumerate(["truncated", "frames", "object", "nan", "missing"]):
        name = f"Date02_Sub0{i + 1}_boxsmall_bad{kind}"
        _write_raw(root, name, T=10, seed=10 + i)
        seq = root / "sequences" / name
        if kind == "truncated":
            data = (seq / "smpl_fit_all.npz").read_bytes()
            (seq / "smpl_fit_all.npz").write_bytes(data[: len(data) // 2])
        elif kind == "frames":
            z = dict(np.load(seq / "object_fit_all.npz"))
            np.savez(seq / "object_fit_all.npz", **{k: (v[:-2] if v.ndim and len(v) == 10 else v) for k, v in z.items()})
        elif kind == "object":
            (seq / "info.json").write_text(json.dumps({"gender": "male", "cat": "spaceship"}))
        elif kind == "nan":
            z = dict(np.load(seq / "smpl_fit_all.npz"))
            z["trans"][4, 1] = np.nan
            np.savez(seq / "smpl_fit_all.npz", **z)
        else:
            (seq / "info.json").unlink()
        bad[name] = kind
    out = tmp_path / "store"
    cfg = PrepareConfig("behave", fps=20.0)
    manifest = prepare(behave.prepare_jobs(root, models, out, cfg), out, cfg)
    assert manifest["counts"]["clips"] == 3 and manifest["counts"]["failed"] == 5
    errors = [json.loads(l) for l in (out / "errors.jsonl").read_text().splitlines()]
    assert {e["sequence"] for e in errors} == set(bad)
    reasons = {e["sequence"]: e["error"] for e in errors}
    for name, kind in bad.items():
        assert reasons[name].startswith(name)
    assert "unreadable" in reasons["Date02_Sub01_boxsmall_badtruncated"]
    assert "frames" in reasons["Date02_Sub02_boxsmall_badframes"]
    assert "spaceship" in reasons["Date02_Sub03_boxsmall_badobject"]
    assert "non-finite" in reasons["Date02_Sub04_boxsmall_badnan"] and "trans" in reasons["Date02_Sub04_boxsmall_badnan"]
    assert "info.json" in reasons["Date02_Sub05_boxsmall_badmissing"]
    store = Store(out)
    assert store.clip_ids("test") == ["Date03_Sub03_boxsmall_push"]
    clip = store.load("Date01_Sub01_boxsmall_lift")
    assert clip["hml263"].shape == (len(clip["joints"]) - 1, 263)
    assert clip["hoi269"].shape[1] == 269 and clip["joint_level"].shape[1:] == (24, 12)
    assert (out / "stats" / "hml263.npz").exists() and manifest["stats"]["hml263"]["split"] == "train"
    # interrupted run: delete one clip and corrupt another's checksum -> rerun redoes just those
    before = {p.name: p.read_bytes() for p in (out / "clips").iterdir()}
    (out / "clips" / "Date01_Sub01_boxsmall_lift.npz").unlink()
    again = prepare(behave.prepare_jobs(root, models, out, cfg), out, cfg)
    after = {p.name: p.read_bytes() for p in (out / "clips").iterdir()}
    assert after == before and again["clips"] == manifest["clips"]
    with pytest.raises(RuntimeError, match="--strict"):
        prepare(behave.prepare_jobs(root, models, tmp_path / "strict", cfg), tmp_path / "strict", cfg, strict=True)


def test_split_file_with_unknown_sequence_is_reported(raw, tmp_path):
    root, models, _ = raw
    split = tmp_path / "split.json"
    split.write_text(json.dumps({"train": ["Date01_Sub01_boxsmall_lift", "Date09_Sub01_ghost_x"],
                                 "test": ["Date03_Sub03_boxsmall_push"]}))
    out = tmp_path / "s"
    cfg = PrepareConfig("behave", fps=20.0)
    m = prepare(behave.prepare_jobs(root, models, out, cfg, split_file=split), out, cfg)
    errs = (out / "errors.jsonl").read_text()
    assert "Date09_Sub01_ghost_x" in errs and "Date02_Sub06_boxsmall_carry: not listed" in errs
    assert m["counts"]["clips"] == 2


@pytest.mark.slow
def test_serial_processes_and_dask_give_identical_stores(raw, tmp_path):
    root, models, _ = raw
    cfg = PrepareConfig("behave", fps=20.0)
    outputs = {}
    executors = ["serial", "processes:2"]
    try:
        import dask.distributed  # noqa: F401
        executors.append("dask://local:2")
    except ImportError:
        pass
    for ex in executors:
        out = tmp_path / ex.replace(":", "_").replace("/", "")
        prepare(behave.prepare_jobs(root, models, out, cfg), out, cfg, executor=ex)
        outputs[ex] = {p.relative_to(out).as_posix(): p.read_bytes()
                       for p in sorted(out.rglob("*")) if p.is_file()}
    ref = outputs["serial"]
    assert len(ref) >= 6
    for ex, files in outputs.items():
        assert files == ref, ex


def test_parse_executor_errors():
    from hoibench.core.parallel import parse_executor
    assert str(parse_executor("processes:3")) == "processes:3"
    assert parse_executor("dask://127.0.0.1:8786").address == "127.0.0.1:8786"
    for bad in ["threads", "processes:0", "processes:x", "dask://"]:
        with pytest.raises(ValueError, match="--executor"):
            parse_executor(bad)


def test_worker_processes_start_with_one_library_thread(monkeypatch):
    """Workers get OMP/BLAS = 1 thread from their first import on; the parent's setting
    comes back afterwards (open3d reads OMP_NUM_THREADS through hoibench.bodies.contact)."""
    import os

    from hoibench.core.parallel import map_units
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "7")
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    got = list(map_units(os.getenv, ["OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"], "processes:1"))
    assert got == ["1", "1", "1"]
    assert os.environ["OPENBLAS_NUM_THREADS"] == "7" and "OMP_NUM_THREADS" not in os.environ
