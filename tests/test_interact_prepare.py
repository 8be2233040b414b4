"""``hoibench prepare interact`` on fixtures in InterAct's processed layout.

Expected values are computed here, independently of the loader: bodies with ``smplx`` called
as InterAct's ``process/canonicalize_human.py`` calls it (BEHAVE: SMPL-H, 10 betas, axis-angle
hands; GRAB: SMPL-X with ``v_template=vtemp`` and 24 PCA hand components; OMOMO: SMPL-X,
16 betas), objects as ``R(angles) @ mesh vertex + trans`` with the mesh read by ``trimesh``.
(On the proxy body the hand mean is zero, so ``flat_hand_mean`` cannot be told apart here.)
"""
from __future__ import annotations

import json

import numpy as np
import pytest


@pytest.fixture(scope="module")
def interact_raw(tmp_path_factory):
    pytest.importorskip("smplx")
    from hoibench.datasets.interact_layout import write_interact_layout
    root = tmp_path_factory.mktemp("interact") / "raw"
    info = write_interact_layout(root, 3, seed=0)
    return root, info


def _prepare(raw, out, split="object", sources=None, fps=30.0):
    from hoibench.datasets import interact
    from hoibench.datasets.store import PrepareConfig, Store, prepare
    cfg = PrepareConfig("interact", fps=fps, body_model_type="smplx")
    manifest = prepare(interact.prepare_jobs(raw, raw / "body_models", out, cfg, sources=sources, split=split),
                       out, cfg)
    interact.write_texts(out, manifest)
    return manifest, Store(out)


@pytest.fixture(scope="module")
def interact_store(interact_raw, tmp_path_factory):
    raw, info = interact_raw
    return _prepare(raw, tmp_path_factory.mktemp("interact_data"))


def _expected(raw, source, name):
    import contextlib
    import io
    import smplx
    import torch
    import trimesh
    from scipy.spatial.transform import Rotation
    seq = raw / source / "sequences_canonical" / name
    h, o = np.load(seq / "human.npz"), np.load(seq / "object.npz")
    poses, trans = h["poses"], h["trans"]
    T = len(poses)
    f = lambda a: torch.from_numpy(np.asarray(a, np.float32))       # noqa: E731
    models = str(raw / "body_models")
    quiet = contextlib.redirect_stdout(io.StringIO())
    if source == "grab":
        m = smplx.create(models, model_type="smplx", gender="male", num_pca_comps=24, v_template=f(h["vtemp"]),
                         batch_size=T, ext="npz")
        out = m(body_pose=f(poses[:, 3:66]), global_orient=f(poses[:, :3]), left_hand_pose=f(poses[:, 66:90]),
                right_hand_pose=f(poses[:, 90:114]), transl=f(trans))
    else:
        mt, nb = ("smplh", 10) if source == "behave" else ("smplx", 16)
        with quiet:
            m = smplx.create(models, model_type=mt, gender="male", use_pca=False, num_betas=nb, ext="npz",
                             flat_hand_mean=source == "omomo")
        face = {} if mt == "smplh" else {k: f(np.zeros((T, 10 if k == "expression" else 3)))
                                         for k in ("jaw_pose", "leye_pose", "reye_pose", "expression")}
        out = m(body_pose=f(poses[:, 3:66]), global_orient=f(poses[:, :3]), left_hand_pose=f(poses[:, 66:111]),
                right_hand_pose=f(poses[:, 111:156]), betas=f(np.repeat(h["betas"][None], T, 0)), transl=f(trans),
                **face)
    mesh = trimesh.load(raw / source / "objects" / str(o["name"]) / f"{o['name']}.obj", force="mesh")
    R = Rotation.from_rotvec(o["angles"]).as_matrix()
    obj = np.einsum("tij,vj->tvi", R, np.asarray(mesh.vertices)) + o["trans"][:, None]
    return out.joints.detach().numpy()[:, :22], out.vertices.detach().numpy(), obj


def test_joints_objects_texts_markers_match(interact_raw, interact_store):
    from hoibench.bodies.markers import MARKERS_SMPLH, MARKERS_SMPLX
    raw, info = interact_raw
    manifest, store = interact_store
    assert manifest["counts"]["clips"] == 3 and manifest["counts"]["failed"] == 0
    seen = set()
    for source, name, obj in info["sequences"]:
        clip = store.load(f"{source}-{name}")
        joints, verts, obj_verts = _expected(raw, source, name)
        assert np.abs(clip["joints"] - joints).max() <= 1e-4
        v, _ = store.object_template(f"{source}-{obj}")
        got = np.einsum("tij,vj->tvi", clip["obj_rot"], v) + clip["obj_trans"][:, None]
        assert np.abs(got - obj_verts).max() <= 1e-4
        texts = [json.loads(t) for t in clip["texts"]]
        assert [t["text"] for t in texts] == [f"A person lifts the {obj} with both hands.",
                                              f"the person carries the {obj}  "]   # as InterAct reads it
        assert texts[0]["tokens"] == f"a/DET person/NOUN lift/VERB the/DET {obj}/NOUN"
        # the scorer's caption file: InterAct's captions, whole-clip (its loader ignores time tags)
        lines = (store.root / "texts" / f"{source}-{name}.txt").read_text().splitlines()
        assert lines[0] == f"A person lifts the {obj} with both hands.#a/DET person/NOUN lift/VERB the/DET {obj}/NOUN#0.0#0.0"
        prov = json.loads(str(clip["provenance"]))
        assert prov["source_dataset"] == source
        mfile = raw / source / "sequences_canonical" / name / "markers.npy"
        if mfile.exists():
            np.testing.assert_array_equal(clip["markers"], np.load(mfile))
            assert prov["markers"] == "markers.npy"
        else:
            ids = list(MARKERS_SMPLX if source != "behave" else MARKERS_SMPLH)
            assert np.abs(clip["markers"] - verts[:, ids]).max() <= 1e-4
        # the evaluator's object points: sample_points.npy moved into the centred template frame
        pts = np.load(raw / source / "objects" / obj / "sample_points.npy")
        import trimesh
        mean = np.asarray(trimesh.load(raw / source / "objects" / obj / f"{obj}.obj", force="mesh").vertices).mean(0)
        np.testing.assert_allclose(clip["object_sample_points"], pts - mean, atol=1e-6)
        seen.add(source)
        if source == "grab":
            assert "poses" not in clip          # subject template: no betas can rebuild the body
        else:
            assert str(clip["body_model_type"]) == ("smplh" if source == "behave" else "smplx")
    assert seen == {"behave", "grab", "omomo"}


def test_object_and_sequence_splits(interact_raw, interact_store, tmp_path):
    from hoibench.datasets import interact
    from hoibench.datasets.store import PrepareConfig
    raw, info = interact_raw
    _, store = interact_store
    want_obj = {f"{s}-{n}" for s, n, o in info["sequences"] if o in info["test_objects"]}
    assert set(store.clip_ids("test")) == want_obj == {f"grab-{info['sequences'][1][1]}"}
    cfg = PrepareConfig("interact", fps=30.0)
    jobs = interact.prepare_jobs(raw, raw / "body_models", tmp_path, cfg, split="sequence")
    want_seq = {f"{s}-{n}" for s, n, _ in info["sequences"] if n in info["test_sequences"]}
    assert {j[0] for j in jobs if j[1] == "test"} == want_seq == {f"omomo-{info['sequences'][2][1]}"}
    only = interact.prepare_jobs(raw, raw / "body_models", tmp_path, cfg, sources="grab,behave")
    assert {j[0].split("-")[0] for j in only} == {"grab", "behave"}


def test_bad_input_is_one_line(interact_raw, tmp_path):
    from hoibench.datasets import interact
    from hoibench.datasets.store import PrepareConfig
    raw, _ = interact_raw
    cfg = PrepareConfig("interact", fps=30.0)
    with pytest.raises(ValueError, match="'arctic' is not an InterAct source hoibench reads"):
        interact.prepare_jobs(raw, raw / "body_models", tmp_path, cfg, sources="arctic")
    (tmp_path / "behave").mkdir()
    with pytest.raises(FileNotFoundError, match="no test_seq.txt"):
        interact.prepare_jobs(tmp_path, raw / "body_models", tmp_path / "o", cfg, sources=None, split="sequence")
    seq = tmp_path / "s" / "x_box_0"
    seq.mkdir(parents=True)
    np.savez(seq / "human.npz", poses=np.zeros((5, 100)), trans=np.zeros((5, 3)), betas=np.zeros(10),
             gender=np.array("male"))
    np.savez(seq / "object.npz", angles=np.zeros((5, 3)), trans=np.zeros((5, 3)), name=np.array("box"))
    with pytest.raises(ValueError, match=r"x_box_0: human.npz: poses: 100 columns, at least 156 expected"):
        interact.load_sequence(str(seq), str(tmp_path), str(raw / "body_models"), "behave")


def test_rows_from_the_store_equal_rows_from_interact_files(interact_raw, interact_store):
    """The evaluator's input built from a stored clip (centred template, hoibench's object
    translation) equals the one built from InterAct's own files (its mesh frame and
    translation): the BPS basis sits at InterAct's object origin either way."""
    from scipy.spatial.transform import Rotation
    from hoibench.evaluator.interact_features import clip_rows, interact_rows
    raw, info = interact_raw
    _, store = interact_store
    basis = np.random.default_rng(5).uniform(-0.5, 0.5, (128, 3))
    for source, name, obj in info["sequences"]:
        seq = raw / source / "sequences_canonical" / name
        o = np.load(seq / "object.npz")
        clip = store.load(f"{source}-{name}")
        markers = np.load(seq / "markers.npy") if (seq / "markers.npy").exists() else clip["markers"]
        want = interact_rows(markers, np.load(raw / source / "objects" / obj / "sample_points.npy"),
                             Rotation.from_rotvec(o["angles"]).as_matrix(), o["trans"], basis)
        assert np.abs(clip_rows(clip, basis) - want).max() <= 1e-5
        # a submission's sample (hoibench's conventions, rotation vectors) gives the same rows
        sample = {"markers": clip["markers"][None], "obj_trans": clip["obj_trans"][None],
                  "obj_rotvec": Rotation.from_matrix(clip["obj_rot"]).as_rotvec()[None],
                  "object_sample_points": clip["object_sample_points"], "object_origin": clip["object_origin"]}
        assert np.abs(clip_rows(sample, basis, 0) - want).max() <= 1e-5


def test_submission_markers_are_validated(interact_store, tmp_path):
    from hoibench.scoring.submission import from_store, validation_report, write_submission
    _, store = interact_store
    gt = from_store(store.root, tmp_path / "gt")
    report = validation_report(gt, store.root, protocol="interact-clean")
    assert not report.errors, report.errors
    sid = store.clip_ids("test")[0]
    arrays = dict(np.load(gt / "samples" / f"{sid}.npz"))
    meta = json.loads((gt / "submission.json").read_text())
    no_markers = {k: v for k, v in arrays.items() if k != "markers"}
    write_submission(tmp_path / "a", meta, {sid: no_markers})
    errs = validation_report(tmp_path / "a", store.root, protocol="interact-clean").errors
    assert any(p.field == "markers" and "missing: this track's evaluator reads markers" in p.message for p in errs)
    moved = dict(arrays, markers=arrays["markers"] + np.array([0, 0, 1.0], np.float32))
    write_submission(tmp_path / "b", meta, {sid: moved})
    errs = validation_report(tmp_path / "b", store.root, protocol="interact-clean").errors
    assert any(p.field == "markers" and "from every joint" in p.message for p in errs)
    bad_shape = dict(arrays, markers=arrays["markers"][:, :, :70])
    write_submission(tmp_path / "c", meta, {sid: bad_shape})
    errs = validation_report(tmp_path / "c", store.root, protocol="interact-clean").errors
    assert any(p.field == "markers" and "expected shape (K, T, 77, 3)" in p.message for p in errs)


def test_pose_layouts_of_the_other_sources():
    """InterCap's 12 PCA components per hand and CHAIRS' jaw/eyes after the hands become
    hoibench's axis-angle layouts (root, body, [jaw, eyes,] left hand, right hand)."""
    from hoibench.datasets.interact import SOURCES, hoibench_poses
    rng = np.random.default_rng(0)
    comps = (rng.normal(size=(12, 45)), rng.normal(size=(12, 45)))
    p = rng.normal(size=(4, 90))
    out = hoibench_poses(p, SOURCES["intercap"], comps, "s")
    np.testing.assert_allclose(out[:, :66], p[:, :66])
    np.testing.assert_allclose(out[:, 66:111], p[:, 66:78] @ comps[0])
    np.testing.assert_allclose(out[:, 111:156], p[:, 78:90] @ comps[1])
    q = rng.normal(size=(4, 165))
    out = hoibench_poses(q, SOURCES["chairs"], None, "s")
    np.testing.assert_array_equal(out[:, 66:75], q[:, 156:165])       # jaw, left eye, right eye
    np.testing.assert_array_equal(out[:, 75:165], q[:, 66:156])       # hands
    np.testing.assert_array_equal(hoibench_poses(q, SOURCES["omomo"], None, "s"), q[:, :156])
    with pytest.raises(ValueError, match="s: human.npz: poses: 80 columns, 90 expected"):
        hoibench_poses(p[:, :80], SOURCES["intercap"], comps, "s")
