"""RICH as its toolkit documents it: a tree with only ``body_models/smplx`` (no SMPL-H),
hands as 12 PCA coefficients with ``flat_hand_mean=False``, expressions, scenes with two
scans. The fixture's SMPL-X model is the proxy with a non-zero mean hand, rotated hand PCA
components and expression directions that move the face, so each convention changes the
mesh; the expected meshes are computed here with ``smplx`` the way rich_toolkit's
``smplx2images.py`` builds them (``SMPLX(num_pca_comps=12, flat_hand_mean=False)`` on the
pickled parameters), independently of the loader."""
from __future__ import annotations

import json
import pickle
import shutil

import numpy as np
import pytest

smplx = pytest.importorskip("smplx")
trimesh = pytest.importorskip("trimesh")

from hoibench.bodies import build_proxy_arrays, clip_body_forward  # noqa: E402
from hoibench.bodies.proxy import ProxyBody  # noqa: E402
from hoibench.datasets import rich  # noqa: E402
from hoibench.datasets import synthetic_layouts as sl  # noqa: E402
from hoibench.datasets.omomo import ZUP_TO_YUP  # noqa: E402
from hoibench.datasets.store import PrepareConfig, Store, prepare  # noqa: E402


def _toolkit_like_smplx(folder):
    """The proxy SMPL-X with a mean hand, rotated PCA components and a moving face."""
    a = build_proxy_arrays("smplx")
    rng = np.random.default_rng(5)
    for side in "lr":
        q, _ = np.linalg.qr(rng.normal(size=(45, 45)))
        a[f"hands_components{side}"] = q
        a[f"hands_mean{side}"] = rng.normal(0.0, 0.2, 45)
    sd = np.array(a["shapedirs"], dtype=np.float64)
    head = np.asarray(a["weights"]).argmax(1) == 15
    sd[head, :, 300:310] = rng.normal(0.0, 0.004, (int(head.sum()), 3, 10))
    a["shapedirs"] = sd.astype(np.float32)
    (folder / "smplx").mkdir(parents=True, exist_ok=True)
    for g in ("MALE", "FEMALE", "NEUTRAL"):
        np.savez(folder / "smplx" / f"SMPLX_{g}.npz", **a)


def _proxy_deftrafo(folder):
    """SMPL-X -> SMPL deformation transfer for the proxies in the released file's layout:
    each SMPL-topology proxy vertex as barycentric weights of the closest point on the
    SMPL-X proxy surface; a pickled dict with 'mtx' (sparse, vertex then normal columns)."""
    import scipy.sparse as sp
    x = build_proxy_arrays("smplx")
    h = ProxyBody("smplh")
    mesh = trimesh.Trimesh(x["v_template"], x["f"], process=False)
    pts = np.asarray(build_proxy_arrays("smplh")["v_template"])
    closest, _, tri = trimesh.proximity.closest_point(mesh, pts)
    bary = trimesh.triangles.points_to_barycentric(mesh.triangles[tri], closest)
    rows = np.repeat(np.arange(len(pts)), 3)
    cols = np.asarray(x["f"])[tri].reshape(-1)
    M = sp.csr_matrix((bary.reshape(-1), (rows, cols)), shape=(h.num_vertices, 2 * len(x["v_template"])))
    (folder / "transfer_data").mkdir(parents=True, exist_ok=True)
    with open(folder / "transfer_data" / "smplx2smpl_deftrafo_setup.pkl", "wb") as fh:
        pickle.dump({"mtx": M, "indices_to_keep": np.arange(len(pts))}, fh)


@pytest.fixture(scope="module")
def toolkit_tree(tmp_path_factory):
    """A synthetic RICH download with the toolkit's layout: data/ + body_models/smplx only."""
    root = tmp_path_factory.mktemp("richtk") / "rich_toolkit"
    sl.write_rich_layout(root / "data", 6, seed=3, body_model=False)
    _toolkit_like_smplx(root / "body_models")
    return root


@pytest.fixture(scope="module")
def toolkit_store(toolkit_tree, tmp_path_factory):
    out = tmp_path_factory.mktemp("richtk_out") / "store"
    cfg = PrepareConfig("rich-cat", fps=30.0, body_model_type="smplx")
    body_models = toolkit_tree / "body_models"
    jobs = rich.prepare_jobs(toolkit_tree, body_models, out, cfg)
    manifest = prepare(jobs, out, cfg, warnings=rich.prepare_warnings(toolkit_tree, body_models))
    return Store(out), manifest


def _toolkit_mesh(tree, seq, sub, frame_ids, split):
    """rich_toolkit's SMPL-X mesh of the given frames, mapped to hoibench's y-up world with
    the scene's multicam2world and the clip's floor."""
    import torch
    data = tree / "data"
    frames = [pickle.load(open(data / "bodies" / split / seq / f"{i:05d}" / f"{sub}.pkl", "rb"))
              for i in frame_ids]
    gender = json.loads((data / "resource" / "gender.json").read_text())[str(int(sub))]
    model = smplx.create(str(tree / "body_models"), model_type="smplx", gender=gender, ext="npz",
                         num_pca_comps=12, flat_hand_mean=False, use_pca=True, num_betas=10,
                         num_expression_coeffs=10, batch_size=len(frames))
    cat = {k: torch.from_numpy(np.concatenate([f[k] for f in frames]).astype(np.float32)) for k in frames[0]}
    with torch.no_grad():
        v = model(return_verts=True, **cat).vertices.numpy().astype(np.float64)
    scan = rich.read_meta(data / "resource").get((seq, sub), {}).get("scan")
    tf = json.loads(rich.transform_path(data, seq, scan).read_text())
    c, R, t = float(tf["c"]), np.asarray(tf["R"]), np.asarray(tf["t"])
    v = (c * v @ R + t) @ ZUP_TO_YUP.T
    v[..., 1] -= v[..., 1].min()
    return v


def test_a_smplx_only_tree_prepares_every_clip_without_contacts_and_says_what_to_add(toolkit_store):
    store, manifest = toolkit_store
    assert manifest["counts"]["failed"] == 0 and manifest["counts"]["clips"] >= 6
    [warning] = manifest["warnings"]
    assert "WITHOUT contact labels" in warning and "smplh/SMPLH_" in warning
    assert "smplx2smpl_deftrafo_setup.pkl" in warning
    for cid in store.clip_ids():
        clip = store.load(cid)
        assert "contacts" not in clip
        assert json.loads(str(clip["provenance"]))["contacts"] is None


def test_stored_parameters_rebuild_the_toolkit_mesh_and_the_deviation_is_what_was_measured(toolkit_tree,
                                                                                            toolkit_store):
    store, _ = toolkit_store
    seen_scaled = seen_exact = False
    for cid in store.clip_ids():
        clip = store.load(cid)
        prov = json.loads(str(clip["provenance"]))
        assert clip["expression"].shape == (len(clip["joints"]), 10)
        assert not bool(clip["flat_hand_mean"])
        first, last = prov["source_frames"]
        expected = _toolkit_mesh(toolkit_tree, prov["sequence"], prov["subject"], range(first, last + 1),
                                 prov["split_folder"])
        _, verts = clip_body_forward(clip, toolkit_tree / "body_models")
        dev = float(np.linalg.norm(verts - expected, axis=-1).max())
        assert prov["body_params_max_dev_m"] == pytest.approx(dev, abs=2e-5)
        if prov["world_scale_c"] == 1.0:
            seen_exact = True
            assert dev < 2e-5
            assert "scaled by 1/c" not in prov["body_params_note"]
        else:
            seen_scaled = True
            assert dev > 1e-3 and "scaled by 1/c" in prov["body_params_note"]
    assert seen_exact and seen_scaled


def test_hand_convention_and_expression_are_data_every_consumer_reads(toolkit_tree, toolkit_store):
    store, _ = toolkit_store
    clip = next(store.load(c) for c in store.clip_ids()
                if json.loads(str(store.load(c)["provenance"]))["world_scale_c"] == 1.0)
    _, base = clip_body_forward(clip, toolkit_tree / "body_models")
    flipped = dict(clip, flat_hand_mean=np.array(True))
    _, v_flat = clip_body_forward(flipped, toolkit_tree / "body_models")
    no_expr = {k: v for k, v in clip.items() if k != "expression"}
    _, v_neutral = clip_body_forward(no_expr, toolkit_tree / "body_models")
    assert np.linalg.norm(v_flat - base, axis=-1).max() > 5e-3        # the mean hand is 0.2 rad per dof
    assert np.linalg.norm(v_neutral - base, axis=-1).max() > 1e-3     # the face moves with expression
    # a store written before the convention was recorded: RICH clips read as flat_hand_mean=False
    legacy = {k: v for k, v in clip.items() if k != "flat_hand_mean"}
    _, v_legacy = clip_body_forward(legacy, toolkit_tree / "body_models")
    np.testing.assert_allclose(v_legacy, base, atol=1e-6)


def test_smplx_deformation_transfer_gives_rich_contacts_a_joint(toolkit_tree, tmp_path):
    tree = tmp_path / "tree"
    shutil.copytree(toolkit_tree, tree)
    _proxy_deftrafo(tree / "body_models")
    rich.contact_joint_map.cache_clear()
    vmap, src = rich.contact_joint_map(str(tree / "body_models"))
    assert "smplx2smpl_deftrafo_setup.pkl" in src
    own = rich.vertex_joint_map(ProxyBody("smplh").weights)
    agree = float((vmap == own).mean())
    assert agree > 0.9, agree
    assert rich.prepare_warnings(tree, tree / "body_models") == []
    cfg = PrepareConfig("rich-cat", fps=30.0, body_model_type="smplx")
    out = tmp_path / "store"
    manifest = prepare(rich.prepare_jobs(tree, tree / "body_models", out, cfg), out, cfg)
    assert manifest["counts"]["failed"] == 0 and "warnings" not in manifest
    store = Store(out)
    hits = total = 0
    for cid in store.clip_ids():
        clip = store.load(cid)
        prov = json.loads(str(clip["provenance"]))
        gt = np.load(tree / "data" / "hoibench_gt" / f"{prov['sequence']}_{prov['subject']}.npz")
        ids = list(gt["frame_ids"])
        first, last = prov["source_frames"]
        want = gt["contacts"][ids.index(first):ids.index(last) + 1]
        # every joint in contact is found (its labelled vertices keep their joint); a few
        # boundary vertices may add a neighbouring joint
        assert not np.any(want & ~clip["contacts"])
        hits += int((want == clip["contacts"]).sum())
        total += want.size
    assert hits / total > 0.97


def test_multi_scan_scenes_use_the_meta_scan_or_the_shipped_mapping_never_a_guess(tmp_path):
    data = tmp_path / "data"
    (data / "multicam2world").mkdir(parents=True)
    for name in ("LectureHall_chair", "LectureHall_yoga", "Gym", "Gym_table", "BBQ"):
        (data / "multicam2world" / f"{name}_multicam2world.json").write_text("{}")
    seq = "LectureHall_009_021_reparingprojector1"
    assert rich.shipped_scans()[seq] == "scan_yoga_scene_camcoord"
    assert rich.transform_path(data, seq).name == "LectureHall_yoga_multicam2world.json"
    assert rich.transform_path(data, "LectureHall_018_wipingchairs1").name == "LectureHall_chair_multicam2world.json"
    assert rich.transform_path(data, "Gym_011_cooking2").name == "Gym_table_multicam2world.json"
    assert rich.transform_path(data, "Gym_011_pushup1").name == "Gym_multicam2world.json"
    # the user's meta file wins over the shipped mapping
    assert rich.transform_path(data, seq, "scan_chair_scene_camcoord").name == "LectureHall_chair_multicam2world.json"
    # an unknown LectureHall sequence is not guessed: the scene file does not exist, the clip fails naming it
    assert rich.transform_path(data, "LectureHall_099_newaction1").name == "LectureHall_multicam2world.json"
    # a missing variant in a one-scan-file scene falls back to the scene's file: Gym's table
    # sequences use Gym_multicam2world.json when Gym_table_multicam2world.json is absent ...
    (data / "multicam2world" / "Gym_table_multicam2world.json").unlink()
    assert rich.transform_path(data, "Gym_011_cooking2").name == "Gym_multicam2world.json"
    # ... but LectureHall, which ships both variants, never falls back
    (data / "multicam2world" / "LectureHall_multicam2world.json").write_text("{}")
    (data / "multicam2world" / "LectureHall_yoga_multicam2world.json").unlink()
    assert rich.transform_path(data, seq).name == "LectureHall_yoga_multicam2world.json"
    assert rich.transform_path(data, "BBQ_001_guitar", "scan_other_camcoord").name == "BBQ_multicam2world.json"


def test_gym_table_fallback_is_named_in_the_prepare_warnings(tmp_path):
    data = tmp_path / "data"
    (data / "multicam2world").mkdir(parents=True)
    (data / "multicam2world" / "Gym_multicam2world.json").write_text("{}")
    for seq in ("Gym_010_cooking1", "Gym_012_cooking2", "Gym_011_pushup1"):
        (data / "bodies" / "test" / seq).mkdir(parents=True)
    assert rich.scene_fallbacks(tmp_path) == {"Gym_table": ["Gym_010_cooking1", "Gym_012_cooking2"]}
    lines = [w for w in rich.prepare_warnings(tmp_path, tmp_path / "no-models") if "multicam2world" in w]
    assert len(lines) == 1 and "Gym_010_cooking1, Gym_012_cooking2" in lines[0]
    assert "Gym_multicam2world.json" in lines[0] and "pushup" not in lines[0]
    # with the variant present there is nothing to warn about
    (data / "multicam2world" / "Gym_table_multicam2world.json").write_text("{}")
    assert rich.scene_fallbacks(tmp_path) == {}
