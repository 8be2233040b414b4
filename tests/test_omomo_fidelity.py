"""OMOMO as its release is: object templates with duplicate vertices (loaded as OMOMO and
CHOIS load them, ``trimesh.load_mesh``), a per-frame ``obj_scale`` that varies, two-part
objects (``obj_bottom_*`` with ``_top`` / ``_bottom`` templates) and SMPL-X files older than
v1.1. Expected object vertices are computed here the way OMOMO's own loader poses them,
``s_t R_t v + t_t`` on the trimesh-loaded template, then rotated to y-up and shifted by the
clip's recorded floor, independently of hoibench's loader."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

pytest.importorskip("smplx")
trimesh = pytest.importorskip("trimesh")
joblib = pytest.importorskip("joblib")

from hoibench.bodies import build_proxy_arrays  # noqa: E402
from hoibench.datasets import omomo  # noqa: E402
from hoibench.datasets import synthetic_layouts as sl  # noqa: E402
from hoibench.datasets.omomo import ZUP_TO_YUP  # noqa: E402
from hoibench.datasets.store import PrepareConfig, Store, prepare  # noqa: E402

TRAIN = "train_diffusion_manip_seq_joints24.p"


def _soup(path):
    """Rewrite an OBJ so every other face has its own three vertices (duplicates at equal
    positions, as exported scans often have, unevenly spread so the file's vertex mean moves);
    returns (vertices in file, merged count)."""
    m = trimesh.load(str(path), process=False, force="mesh")
    copies = m.faces[::2].reshape(-1)
    v = np.concatenate([m.vertices, m.vertices[copies]])
    f = m.faces.copy()
    f[::2] = len(m.vertices) + np.arange(len(copies)).reshape(-1, 3)
    lines = [f"v {a:.9f} {b:.9f} {c:.9f}" for a, b, c in v] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f]
    path.write_text("\n".join(lines) + "\n")
    as_read = len(trimesh.load(str(path), process=False, force="mesh").vertices)   # unreferenced ones dropped
    return as_read, len(m.vertices)


def _box_obj(path, extents, centre):
    m = trimesh.creation.box(extents=extents)
    v = m.vertices + np.asarray(centre)
    lines = [f"v {a:.9f} {b:.9f} {c:.9f}" for a, b, c in v] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in m.faces]
    path.write_text("\n".join(lines) + "\n")


def _omomo_vertices(template_path, R, t, s, floor):
    """OMOMO's posed object (``s_t R_t v + t_t`` on ``trimesh.load_mesh``), in hoibench's y-up."""
    v = trimesh.load_mesh(str(template_path)).vertices
    z = s[:, None, None] * np.einsum("tij,vj->tvi", R, v) + t.reshape(-1, 1, 3)
    y = z @ ZUP_TO_YUP.T
    y[..., 1] -= floor
    return y


@pytest.fixture(scope="module")
def release(tmp_path_factory):
    """A synthetic OMOMO download edited the ways the real release differs."""
    root = tmp_path_factory.mktemp("omomo_real") / "raw"
    sl.write_omomo_layout(root, 10, seed=2)
    data = joblib.load(root / TRAIN)
    keys = sorted(data)
    info = {}
    # 1. a template whose faces do not share vertices
    obj0 = data[keys[0]]["seq_name"].split("_")[1]
    info["soup"] = (obj0, *_soup(root / "captured_objects" / f"{obj0}_cleaned_simplified.obj"))
    # 2. obj_scale varying a little (accepted) and a lot (refused)
    small, large = data[keys[1]], data[keys[2]]
    T = len(small["obj_scale"])
    wave = np.sin(np.linspace(0, 3 * np.pi, T))
    small["obj_scale"] = (small["obj_scale"] * (1 + 2e-3 * wave)).astype(np.float32)
    large["obj_scale"] = (large["obj_scale"] * (1 + 0.1 * np.sin(np.linspace(0, 3 * np.pi, len(large["obj_scale"]))))
                          ).astype(np.float32)
    info["small"], info["large"] = small["seq_name"], large["seq_name"]
    # 3. a two-part vacuum: the top follows the first sequence's object, the bottom swings
    vac = {k: np.array(v, copy=True) if isinstance(v, np.ndarray) else v for k, v in data[keys[3]].items()}
    sub = vac["seq_name"].split("_")[0]
    vac["seq_name"] = f"{sub}_vacuum_000"
    T = len(vac["obj_rot"])
    ang = 0.4 * np.sin(np.linspace(0, 2 * np.pi, T))
    swing = np.stack([np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]]) for a in ang])
    vac["obj_rot"] = np.repeat(np.eye(3)[None], T, 0).astype(np.float32)
    vac["obj_scale"] = np.full(T, 1.0, np.float32)
    vac["obj_bottom_rot"] = swing.astype(np.float32)
    vac["obj_bottom_trans"] = (vac["obj_trans"].reshape(T, 3) - np.array([0.0, 0.0, 0.6])).astype(np.float32)[:, :, None]
    vac["obj_bottom_scale"] = np.full(T, 1.0, np.float32)
    data[max(keys) + 1] = vac
    info["vacuum"] = vac["seq_name"]
    # 3b. a second vacuum sequence: the same top scale, another bottom scale
    vac2 = {k: np.array(v, copy=True) if isinstance(v, np.ndarray) else v for k, v in vac.items()}
    vac2["seq_name"] = f"{sub}_vacuum_001"
    vac2["obj_bottom_scale"] = np.full(T, 1.25, np.float32)
    data[max(keys) + 2] = vac2
    info["vacuum2"] = vac2["seq_name"]
    _box_obj(root / "captured_objects" / "vacuum_cleaned_simplified_top.obj", (0.04, 0.04, 1.0), (0.3, 0.1, 0.5))
    _box_obj(root / "captured_objects" / "vacuum_cleaned_simplified_bottom.obj", (0.3, 0.25, 0.08), (0.3, 0.1, 0.04))
    # 4. betas past the tenth (OMOMO has 16)
    data[keys[4]]["betas"] = np.asarray(data[keys[4]]["betas"]).copy()
    data[keys[4]]["betas"][0, 12] = 0.5
    info["betas16"] = data[keys[4]]["seq_name"]
    joblib.dump(data, root / TRAIN)
    info["data"] = data
    return root, info


@pytest.fixture(scope="module")
def prepared(release, tmp_path_factory):
    root, info = release
    out = tmp_path_factory.mktemp("omomo_real_out") / "store"
    cfg = PrepareConfig("omomo", fps=30.0, body_model_type="smplx")
    manifest = prepare(omomo.prepare_jobs(root, root / "body_models", out, cfg), out, cfg)
    errors = {e["sequence"]: e["error"] for e in map(json.loads, (out / "errors.jsonl").read_text().splitlines())}
    return Store(out), manifest, errors


def _seq(info, name):
    return next(s for s in info["data"].values() if s["seq_name"] == name)


def _posed(store, clip, part=None):
    name = str(clip["object_name"]) if part is None else str(clip["object_parts"][part])
    v, _ = store.object_template(name)
    R = clip["obj_rot"] if part is None else clip["parts_rot"][part]
    t = clip["obj_trans"] if part is None else clip["parts_trans"][part]
    return np.einsum("tij,vj->tvi", R.astype(np.float64), v.astype(np.float64)) + t[:, None]


def test_templates_are_loaded_as_omomo_loads_them_duplicates_merged(release, prepared):
    root, info = release
    store, _, _ = prepared
    obj, n_file, n_merged = info["soup"]
    assert n_file > n_merged
    path = root / "captured_objects" / f"{obj}_cleaned_simplified.obj"
    assert len(trimesh.load_mesh(str(path)).vertices) == n_merged
    v, _ = store.object_template(obj)
    assert len(v) == n_merged
    cid = next(c for c in store.clip_ids() if c.split("_")[1] == obj)
    clip = store.load(cid)
    prov = json.loads(str(clip["provenance"]))
    assert (prov["template_vertices_in_file"], prov["template_vertices_merged"]) == (n_file, n_merged)
    seq = _seq(info, cid)
    want = _omomo_vertices(path, seq["obj_rot"], seq["obj_trans"], seq["obj_scale"], prov["floor_shift_m"])
    np.testing.assert_allclose(_posed(store, clip), want, atol=2e-5)
    # the stored centre is the merged mesh's mean (OMOMO's), not the file's vertex mean
    file_mean = trimesh.load(str(path), process=False, force="mesh").vertices.mean(0)
    merged_mean = trimesh.load_mesh(str(path)).vertices.mean(0)
    assert np.linalg.norm(file_mean - merged_mean) > 1e-3
    np.testing.assert_allclose(prov["template_mean_subtracted"], merged_mean, atol=1e-9)


def test_a_slightly_varying_scale_is_kept_with_its_measured_error_and_a_large_one_is_refused(release, prepared):
    root, info = release
    store, manifest, errors = prepared
    clip = store.load(info["small"])
    prov = json.loads(str(clip["provenance"]))
    seq = _seq(info, info["small"])
    obj = info["small"].split("_")[1]
    path = root / "captured_objects" / f"{obj}_cleaned_simplified.obj"
    want = _omomo_vertices(path, seq["obj_rot"], seq["obj_trans"], seq["obj_scale"], prov["floor_shift_m"])
    err = float(np.linalg.norm(_posed(store, clip) - want, axis=-1).max())
    assert 1e-5 < err <= prov["object_scale_max_dev_m"] + 2e-5
    v = trimesh.load_mesh(str(path)).vertices
    s = np.asarray(seq["obj_scale"], np.float64)
    bound = np.abs(s - s.mean()).max() * np.linalg.norm(v - v.mean(0), axis=1).max()
    assert prov["object_scale_max_dev_m"] == pytest.approx(bound, rel=1e-6)
    assert prov["object_scale_max_dev_m"] <= omomo.OBJECT_SCALE_TOL_M
    msg = errors[info["large"]]
    assert msg.startswith(info["large"]) and "obj_scale varies" in msg and "mm" in msg
    assert info["large"] not in store.clip_ids()


def test_two_part_objects_store_every_part_with_its_own_pose(release, prepared):
    root, info = release
    store, _, errors = prepared
    name = info["vacuum"]
    assert name not in errors
    clip = store.load(name)
    prov = json.loads(str(clip["provenance"]))
    # one top scale in the release: "vacuum"; two bottom scales: each bottom named by its own
    assert [str(x) for x in clip["object_parts"]] == ["vacuum", "vacuum_bottom_s1.000000"]
    assert str(clip["object_name"]) == "vacuum"
    np.testing.assert_array_equal(clip["parts_rot"][0], clip["obj_rot"])
    np.testing.assert_array_equal(clip["parts_trans"][0], clip["obj_trans"])
    seq = _seq(info, name)
    for k, (part, R, t, s) in enumerate((("top", seq["obj_rot"], seq["obj_trans"], seq["obj_scale"]),
                                         ("bottom", seq["obj_bottom_rot"], seq["obj_bottom_trans"],
                                          seq["obj_bottom_scale"]))):
        path = root / "captured_objects" / f"vacuum_cleaned_simplified_{part}.obj"
        want = _omomo_vertices(path, R, t, s, prov["floor_shift_m"])
        np.testing.assert_allclose(_posed(store, clip, k), want, atol=2e-5)
        assert prov["object_parts"][k]["template"] == path.name
    # the bottom swings relative to the top: the parts move differently
    rel = np.einsum("tji,tjk->tik", clip["parts_rot"][0], clip["parts_rot"][1])
    assert np.ptp(np.arccos(np.clip(rel[:, 1, 1], -1, 1))) > 0.35      # the swing is 0.4 rad
    # its hoi269 object channels follow the primary (top) part
    from hoibench.representations import hoi269
    enc = hoi269.encode(clip["joints"], clip["parts_rot"][0], clip["parts_trans"][0], mode="clean", fps=30.0)
    np.testing.assert_allclose(clip["hoi269"], enc, atol=1e-5)


def test_two_part_templates_are_named_by_each_parts_own_scale(release, prepared):
    root, info = release
    store, _, errors = prepared
    a, b = store.load(info["vacuum"]), store.load(info["vacuum2"])
    assert [str(x) for x in b["object_parts"]] == ["vacuum", "vacuum_bottom_s1.250000"]
    assert str(a["object_parts"][0]) == str(b["object_parts"][0])           # one top template
    va, _ = store.object_template(str(a["object_parts"][1]))
    vb, _ = store.object_template(str(b["object_parts"][1]))
    np.testing.assert_allclose(vb, 1.25 * va, atol=1e-5)                  # each bottom at its own scale
    seq = _seq(info, info["vacuum2"])
    prov = json.loads(str(b["provenance"]))
    path = root / "captured_objects" / "vacuum_cleaned_simplified_bottom.obj"
    want = _omomo_vertices(path, seq["obj_bottom_rot"], seq["obj_bottom_trans"], seq["obj_bottom_scale"],
                           prov["floor_shift_m"])
    np.testing.assert_allclose(_posed(store, b, 1), want, atol=2e-5)


def test_a_missing_part_template_fails_that_sequence_naming_the_file(release, tmp_path):
    root, info = release
    copy = tmp_path / "raw"
    shutil.copytree(root, copy)
    (copy / "captured_objects" / "vacuum_cleaned_simplified_bottom.obj").unlink()
    with pytest.raises(omomo.SequenceError, match="vacuum_cleaned_simplified_bottom.obj"):
        omomo.load_sequence(_seq(info, info["vacuum"]), copy / "captured_objects", copy / "body_models")


def test_smplx_files_older_than_v11_are_named_when_betas_past_the_tenth_are_used(release, prepared, tmp_path):
    root, info = release
    store, _, errors = prepared
    assert info["betas16"] not in errors               # v1.1 layout (the proxy): 16 betas are fine
    old = tmp_path / "models"
    (old / "smplx").mkdir(parents=True)
    a = build_proxy_arrays("smplx")
    a["shapedirs"] = np.asarray(a["shapedirs"])[:, :, :20]        # SMPL-X v1.0: 10 shape + 10 expression
    for g in ("MALE", "FEMALE", "NEUTRAL"):
        np.savez(old / "smplx" / f"SMPLX_{g}.npz", **a)
    omomo._body_model.cache_clear()
    with pytest.raises(omomo.SequenceError) as exc:
        omomo.load_sequence(_seq(info, info["betas16"]), root / "captured_objects", old)
    msg = str(exc.value)
    assert msg.startswith(info["betas16"]) and "v1.0" in msg and "SMPLX_" in msg and "v1.1" in msg
    # a sequence whose betas past the tenth are zero loads with the old files
    seq = _seq(info, info["small"])
    assert not np.any(np.asarray(seq["betas"])[0, 10:])
    omomo.load_sequence(seq, root / "captured_objects", old)
