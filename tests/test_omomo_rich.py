"""OMOMO and RICH loaders on hoibench's synthetic raw layouts (proxy SMPL-X body), checked
against the generator's ground truth; the SMPL-X proxy; bad input through the store."""
from __future__ import annotations

import json
import pickle
import shutil

import numpy as np
import pytest

pytest.importorskip("smplx")
pytest.importorskip("trimesh")

from hoibench.bodies.proxy import ProxyBody, build_proxy_arrays, write_proxy_model  # noqa: E402
from hoibench.datasets import omomo, rich  # noqa: E402
from hoibench.datasets import synthetic_layouts as sl  # noqa: E402
from hoibench.core.skeleton import SMPL_REST_JOINTS, forward_kinematics  # noqa: E402
from hoibench.core import geometry as geo  # noqa: E402
from hoibench.datasets.store import PrepareConfig, Store, prepare  # noqa: E402

TOL_M = 1e-4
N_OMOMO, N_RICH = 6, 6


@pytest.fixture(scope="module")
def omomo_raw(tmp_path_factory):
    pytest.importorskip("joblib")            # OMOMO's pickles are joblib files
    root = tmp_path_factory.mktemp("omomo") / "raw"
    manifest = sl.write_omomo_layout(root, N_OMOMO, seed=1)
    return root, manifest


@pytest.fixture(scope="module")
def rich_raw(tmp_path_factory):
    root = tmp_path_factory.mktemp("rich") / "raw"
    manifest = sl.write_rich_layout(root, N_RICH, seed=1)
    return root, manifest


@pytest.fixture(scope="module")
def omomo_loaded(omomo_raw):
    root, _ = omomo_raw
    cfg = PrepareConfig("omomo", fps=30.0, body_model_type="smplx")
    jobs = omomo.prepare_jobs(root, root / "body_models", root.parent / "out", cfg)
    return {j[0]: (j, j[4](*j[5])) for j in jobs}


@pytest.fixture(scope="module")
def rich_loaded(rich_raw):
    root, _ = rich_raw
    cfg = PrepareConfig("rich-cat", fps=30.0, body_model_type="smplx")
    jobs = rich.prepare_jobs(root, root / "body_models", root.parent / "out", cfg)
    return {j[0]: (j, j[4](*j[5]) if j[4] is rich.load_clip else None) for j in jobs}


def _proxy_vertices(seq):
    """The proxy SMPL-X surface of a clip's stored body parameters (y-up world)."""
    T = seq.num_frames
    poses = seq.body.poses.reshape(T, -1, 3).astype(np.float64)
    return ProxyBody("smplx").forward(poses, seq.body.trans.astype(np.float64),
                                      np.asarray(seq.body.betas, dtype=np.float64))


# --------------------------------------------------------------------------- SMPL-X proxy
def test_smplx_proxy_has_the_released_structure_and_poses_like_smplx(tmp_path):
    import smplx
    import torch

    a = build_proxy_arrays("smplx")
    V = len(a["v_template"])
    assert V == 10475 and a["J"].shape == (55, 3) and a["weights"].shape == (V, 55)
    assert a["shapedirs"].shape == (V, 3, 400) and a["posedirs"].shape == (V, 3, 486)
    assert a["lmk_faces_idx"].shape == (51,) and a["dynamic_lmk_faces_idx"].shape == (79, 17)
    np.testing.assert_array_equal(a["J"][:22], SMPL_REST_JOINTS)
    np.testing.assert_allclose(a["J_regressor"] @ a["v_template"], a["J"], atol=1e-12)
    parents = a["kintree_table"][0].copy()
    parents[0] = -1
    assert parents[22:25].tolist() == [15, 15, 15] and parents[25] == 20 and parents[40] == 21
    paths = write_proxy_model(tmp_path, "smplx")
    assert [p.name for p in paths] == ["SMPLX_MALE.npz", "SMPLX_FEMALE.npz", "SMPLX_NEUTRAL.npz"]
    model = smplx.create(str(tmp_path), model_type="smplx", gender="female", ext="npz", num_betas=16,
                         use_pca=True, num_pca_comps=12, flat_hand_mean=False, use_face_contour=True)
    assert model.num_betas == 16
    rng = np.random.default_rng(3)
    T = 5
    pose = rng.normal(0.0, 0.5, (T, 55, 3))
    pose[:, 25:] = 0.0
    trans, betas = rng.normal(0.0, 1.0, (T, 3)), rng.normal(0.0, 1.0, (T, 16))
    t = lambda x: torch.tensor(np.asarray(x, dtype=np.float32))  # noqa: E731
    with torch.no_grad():
        out = model(global_orient=t(pose[:, 0]), body_pose=t(pose[:, 1:22].reshape(T, 63)), jaw_pose=t(pose[:, 22]),
                    leye_pose=t(pose[:, 23]), reye_pose=t(pose[:, 24]), left_hand_pose=t(np.zeros((T, 12))),
                    right_hand_pose=t(np.zeros((T, 12))), transl=t(trans), betas=t(betas),
                    expression=t(rng.normal(0.0, 1.0, (T, 10))))
    fk, _ = forward_kinematics(geo.axis_angle_to_matrix(pose[:, :22]),
                               SMPL_REST_JOINTS * (1 + 0.05 * betas[:, :1, None]), trans)
    np.testing.assert_allclose(out.joints[:, :22].numpy(), fk, atol=1e-5)
    v, j = ProxyBody("smplx").forward(pose, trans, betas)
    np.testing.assert_allclose(v, out.vertices.numpy(), atol=1e-5)
    np.testing.assert_allclose(j, fk, atol=1e-9)
    with torch.no_grad():
        rest = model(betas=torch.zeros(1, 16)).joints[0].numpy()
    nose = rest[55]
    assert np.linalg.norm(nose - SMPL_REST_JOINTS[15]) < 0.25 and nose[2] > SMPL_REST_JOINTS[15, 2]
    assert (rest[60:66, 1] < -1.1).all()                        # toes and heels at the sole
    assert (rest[66:71, 0] > SMPL_REST_JOINTS[20, 0] + 0.05).all()  # left finger tips
    # the body is the SMPL-H proxy's
    vh, jh = ProxyBody("smplh").forward(pose[:, :22], trans, betas)
    np.testing.assert_allclose(jh, j, atol=1e-12)
    with pytest.raises(NotImplementedError, match="smplx"):
        build_proxy_arrays("smpl")


# --------------------------------------------------------------------------- OMOMO
def test_omomo_joints_and_object_vertices_match_the_ground_truth(omomo_raw, omomo_loaded):
    root, manifest = omomo_raw
    assert len(omomo_loaded) == N_OMOMO
    for name, (job, seq) in omomo_loaded.items():
        gt = np.load(root / "hoibench_gt" / f"{name}.npz", allow_pickle=False)
        floor = seq.provenance["floor_shift_m"]
        joints = seq.joints.astype(np.float64) + [0.0, floor, 0.0]
        assert seq.num_frames == len(gt["joints"]) and seq.fps == 30.0
        np.testing.assert_allclose(joints, gt["joints"], atol=TOL_M, err_msg=name)
        obj = seq.object_vertices_at() + [0.0, floor, 0.0]
        want = np.einsum("tij,vj->tvi", gt["obj_rot"], gt["object_vertices"]) + gt["obj_trans"][:, None]
        np.testing.assert_allclose(obj, want, atol=TOL_M, err_msg=name)
        np.testing.assert_allclose(seq.contacts, gt["contacts"])
        assert seq.dataset == "omomo" and seq.body.model_type == "smplx" and len(seq.body.betas) == 16
        assert job[1] == ("test" if seq.subject in ("sub16", "sub17") else "train")
        assert seq.provenance["rest_offsets_fk_max_dev_m"] < 1e-5   # OMOMO's own FK agrees
    assert {j[1] for j, _ in omomo_loaded.values()} == {"train", "test"}


def test_omomo_z_up_becomes_y_up_with_the_floor_at_zero(omomo_loaded):
    for name, (_, seq) in omomo_loaded.items():
        verts, joints = _proxy_vertices(seq)            # the stored parameters rebuild the body
        np.testing.assert_allclose(joints, seq.joints, atol=1e-5, err_msg=name)
        assert abs(verts[..., 1].min()) < 1e-5, name     # floor at y = 0
        assert (seq.joints[:, 15, 1] > seq.joints[:, 0, 1]).all(), name   # head above pelvis
        assert np.all(geo.is_rotation_matrix(seq.obj_rot, atol=1e-5)), name


def test_omomo_object_scale_is_applied_to_the_uncentred_template(omomo_raw, omomo_loaded):
    import trimesh

    root, _ = omomo_raw
    scales = set()
    for name, (_, seq) in omomo_loaded.items():
        obj = seq.object_name
        s = sl.OMOMO_OBJECT_SCALE[obj]
        raw = np.asarray(trimesh.load(root / "captured_objects" / f"{obj}_cleaned_simplified.obj",
                                      process=False, force="mesh").vertices)
        assert np.linalg.norm(raw.mean(0)) > 0.01                  # the file is not centred
        np.testing.assert_allclose(seq.object_vertices, s * (raw - raw.mean(0)), atol=1e-12)
        np.testing.assert_allclose(seq.object_vertices.mean(0), 0.0, atol=1e-12)
        assert seq.provenance["object_scale"] == pytest.approx(s, rel=1e-6)
        scales.add(s)
    assert len(scales) > 1 and any(abs(s - 1.0) > 0.05 for s in scales)


def test_omomo_texts_come_from_the_annotation_files(omomo_raw, omomo_loaded):
    root, manifest = omomo_raw
    for entry in manifest["clips"]:
        seq = omomo_loaded[entry["name"]][1]
        path = root / "omomo_text_anno_json_data" / f"{entry['name']}.json"
        if entry["text"]:
            want = json.loads(path.read_text())[entry["name"]]
            assert seq.texts == [{"text": want, "start": None, "end": None, "source": "omomo"}]
        else:
            assert not path.exists() and seq.texts == []
    assert any(not e["text"] for e in manifest["clips"])


def test_omomo_resamples_by_time(omomo_raw):
    root, _ = omomo_raw
    jobs = omomo.prepare_jobs(root, root / "body_models", root.parent / "out20", PrepareConfig("omomo", fps=20.0))
    job = jobs[0]
    seq = job[4](*job[5])
    gt = np.load(root / "hoibench_gt" / f"{job[0]}.npz", allow_pickle=False)["joints"]
    assert seq.fps == 20.0 and seq.num_frames == int((len(gt) - 1) / 1.5) + 1
    k = np.arange(0, seq.num_frames, 2)                      # t = k / 20 s = source frame 1.5 k
    joints = seq.joints[k].astype(np.float64) + [0.0, seq.provenance["floor_shift_m"], 0.0]
    np.testing.assert_allclose(joints, gt[(3 * k) // 2], atol=TOL_M)


def test_omomo_writer_is_deterministic(omomo_raw, tmp_path):
    root, _ = omomo_raw
    sl.write_omomo_layout(tmp_path, N_OMOMO, seed=1, body_model=False)
    for f in ("train_diffusion_manip_seq_joints24.p", "test_diffusion_manip_seq_joints24.p"):
        assert (tmp_path / f).read_bytes() == (root / f).read_bytes()


def _read_pickle(path):
    import joblib
    return joblib.load(path)


def _write_pickle(path, data):
    import joblib
    joblib.dump(data, path)


def _editable_omomo_copy(omomo_raw, tmp_path):
    """A copy of the generated OMOMO download to damage: ``(root, train pickle path, its data)``."""
    root = tmp_path / "raw"
    shutil.copytree(omomo_raw[0], root)
    pkl = root / "train_diffusion_manip_seq_joints24.p"
    return root, pkl, _read_pickle(pkl)


def test_omomo_bad_input_fails_the_sequence_and_the_rest_are_prepared(omomo_raw, tmp_path):
    root, pkl, data = _editable_omomo_copy(omomo_raw, tmp_path)
    names = [d["seq_name"] for d in data.values()]
    keyless, two_part, no_template = names[0], names[1], names[2]
    del data[0]["obj_rot"]
    data[1]["obj_bottom_trans"] = data[1]["obj_trans"]
    _write_pickle(pkl, data)
    obj = no_template.split("_")[1]
    (root / "captured_objects" / f"{obj}_cleaned_simplified.obj").unlink()
    cfg = PrepareConfig("omomo", fps=20.0, body_model_type="smplx")
    out = tmp_path / "store"
    manifest = prepare(omomo.prepare_jobs(root, root / "body_models", out, cfg), out, cfg)
    errors = {e["sequence"]: e["error"] for e in map(json.loads, (out / "errors.jsonl").read_text().splitlines())}
    everything = names + [d["seq_name"] for d in _read_pickle(root / "test_diffusion_manip_seq_joints24.p").values()]
    uses_obj = {n for n in everything if n.split("_")[1] == obj}
    assert set(errors) == {keyless, two_part} | uses_obj
    assert errors[keyless].startswith(keyless) and "missing key 'obj_rot'" in errors[keyless]
    assert "missing key 'obj_bottom_rot'" in errors[two_part]      # a two-part object needs both poses
    assert errors[no_template].startswith(no_template) and f"{obj}_cleaned_simplified.obj" in errors[no_template]
    assert manifest["counts"]["clips"] == N_OMOMO - len(errors) > 0
    assert set(Store(out).clip_ids()) == set(everything) - set(errors)


def test_omomo_one_template_name_per_object_scale(omomo_raw, tmp_path):
    root, pkl, data = _editable_omomo_copy(omomo_raw, tmp_path)
    twin = dict(data[0])
    sub, obj, take = omomo.parse_name(twin["seq_name"])
    twin["seq_name"] = f"sub{sub}_{obj}_999"
    twin["obj_scale"] = twin["obj_scale"] * 1.25
    data[len(data)] = twin
    _write_pickle(pkl, data)
    jobs = {j[0]: j for j in omomo.prepare_jobs(root, root / "body_models", tmp_path / "o", PrepareConfig("omomo"))}
    a, b = jobs[data[0]["seq_name"]][5][5], jobs[twin["seq_name"]][5][5]
    assert a != b and a.startswith(f"{obj}_s") and b.startswith(f"{obj}_s")
    others = [j[5][5] for n, j in jobs.items() if omomo.parse_name(n)[1] != obj]
    assert all("_s" not in o for o in others)


# --------------------------------------------------------------------------- RICH
def test_rich_joints_and_contacts_match_the_ground_truth(rich_raw, rich_loaded):
    root, manifest = rich_raw
    clips = [(j, s) for j, s in rich_loaded.values() if s is not None]
    assert len(clips) >= N_RICH
    for job, seq in clips:
        _, split, seqname, sub, fids = job[5][:5]
        gt = np.load(root / "hoibench_gt" / f"{seqname}_{sub}.npz", allow_pickle=False)
        idx = np.searchsorted(gt["frame_ids"], fids[:seq.num_frames])
        joints = seq.joints.astype(np.float64) + [0.0, seq.provenance["floor_shift_m"], 0.0]
        np.testing.assert_allclose(joints, gt["joints"][idx], atol=TOL_M, err_msg=job[0])
        np.testing.assert_array_equal(seq.contacts, gt["contacts"][idx])
        assert seq.num_frames in rich.CLIP_LENGTHS and seq.object_name is None
        assert seq.provenance["label"] == "RICH-CAT (hoibench rebuild)" and job[1] == split
        assert (seq.joints[:, 15, 1] > seq.joints[:, 0, 1]).all(), job[0]       # y up
        verts, pj = _proxy_vertices(seq)
        if seq.provenance["world_scale_c"] == 1.0:           # parameters exact: mesh floor at 0
            np.testing.assert_allclose(pj, seq.joints, atol=1e-5)
            assert abs(verts[..., 1].min()) < 1e-5
        else:                                                # c != 1: joints exact, mesh rigid
            np.testing.assert_allclose(pj[:, 0], seq.joints[:, 0], atol=1e-5)
    assert any(s.provenance["world_scale_c"] != 1.0 for _, s in clips)
    assert {j[1] for j, _ in clips} >= {"train", "test"}


def test_rich_frame_gaps_split_clips(rich_raw, rich_loaded):
    root, manifest = rich_raw
    gapped = [e for e in manifest["sequences"] if len(e["runs"]) > 1]
    assert gapped
    for e in gapped:
        starts = sorted(j[5][4][0] for j, _ in rich_loaded.values()
                        if j[4] is rich.load_clip and j[5][2] == e["sequence"])
        assert starts == [r[0] for r in e["runs"]]            # one clip per run, at its start
        (a0, a1), (b0, b1) = e["runs"]
        assert b0 > a1 + 1                                    # ids skip: never interpolated across
    for j, _ in rich_loaded.values():
        if j[4] is rich.load_clip:
            assert np.all(np.diff(j[5][4]) == 1)
    assert rich.split_runs([12, 3, 4, 5, 9, 10]) == [[3, 4, 5], [9, 10], [12]]
    assert rich.cut_lengths(400) == [(0, 192), (192, 192)]
    assert rich.cut_lengths(330) == [(0, 192), (192, 128)]
    assert rich.cut_lengths(127) == [(0, 64)] and rich.cut_lengths(63) == []


def test_rich_clip_lengths_at_20_fps(rich_raw):
    root, manifest = rich_raw
    cfg = PrepareConfig("rich-cat", fps=20.0)
    jobs = rich.prepare_jobs(root, root / "body_models", root.parent / "out20", cfg)
    want = 0
    for e in manifest["sequences"]:
        n = [len(rich.cut_lengths(int(np.floor((b - a) / 1.5 + 1e-9)) + 1)) for a, b in e["runs"]]
        want += max(sum(n), 1)                   # a subject with no long-enough run: one failed unit
        if not sum(n):
            fail = [j for j in jobs if j[0] == f"{e['sequence']}_{e['subject']}"]
            assert fail and fail[0][4] is not rich.load_clip
    assert len(jobs) == want
    job = next(j for j in jobs if j[4] is rich.load_clip)
    seq = job[4](*job[5])
    assert seq.fps == 20.0 and seq.num_frames == job[5][7] == 64


def test_vertex_to_joint_contact_mapping_by_hand():
    w = np.zeros((6, 24))
    w[0, [3, 6]] = [0.7, 0.3]        # spine1
    w[1, [3, 6]] = [0.4, 0.6]        # spine2
    w[2, 22] = 1.0                   # SMPL's left hand -> left wrist
    w[3, [23, 21]] = [0.9, 0.1]      # right hand -> right wrist
    w[4, [10, 7]] = [0.5, 0.5]       # tie: the lower index (ankle 7)
    w[5, 15] = 1.0                   # head
    vmap = rich.vertex_joint_map(w)
    assert vmap.tolist() == [3, 6, 20, 21, 7, 15]
    labels = np.array([[1, 0, 0, 0, 0, 0],
                       [0, 1, 1, 1, 0, 0],
                       [0, 0, 0, 0, 0, 0]])
    got = rich.joint_contacts(labels, vmap)
    want = np.zeros((3, 22), bool)
    want[0, 3] = True
    want[1, [6, 20, 21]] = True
    np.testing.assert_array_equal(got, want)
    # OR: one of a joint's several vertices suffices; SMPL-H / SMPL-X fingers fold to wrists
    vmap2 = np.array([5, 5, 5])
    np.testing.assert_array_equal(rich.joint_contacts([[0, 0, 1]], vmap2)[0], np.arange(22) == 5)
    wh = np.eye(52)[[37, 22, 51, 12]]
    assert rich.vertex_joint_map(wh).tolist() == [21, 20, 21, 12]
    wx = np.eye(55)[[22, 24, 25, 54]]
    assert rich.vertex_joint_map(wx).tolist() == [15, 15, 20, 21]
    with pytest.raises(ValueError, match="weights"):
        rich.vertex_joint_map(np.zeros((4, 30)))


def test_rich_bad_frame_pickles_fail_their_clip_and_the_rest_are_prepared(rich_raw, rich_loaded, tmp_path):
    src, manifest = rich_raw
    root = tmp_path / "raw"
    shutil.copytree(src, root, ignore=shutil.ignore_patterns("body_models"))
    models = src / "body_models"
    gapped = next(e for e in manifest["sequences"] if len(e["runs"]) > 1)
    seqname, sub, split = gapped["sequence"], gapped["subject"], gapped["split"]
    bad_frame = gapped["runs"][1][0] + 5
    (root / "bodies" / split / seqname / f"{bad_frame:05d}" / f"{sub}.pkl").write_bytes(b"\x80\x04 not a pickle")
    other = next(e for e in manifest["sequences"] if len(e["runs"]) == 1 and e["split"] == "train")
    f0 = other["runs"][0][0] + 2
    path = root / "bodies" / other["split"] / other["sequence"] / f"{f0:05d}" / f"{other['subject']}.pkl"
    d = pickle.loads(path.read_bytes())
    del d["transl"]
    path.write_bytes(pickle.dumps(d))
    cfg = PrepareConfig("rich-cat", fps=30.0, body_model_type="smplx")
    out = tmp_path / "store"
    jobs = rich.prepare_jobs(root, models, out, cfg)
    manifest_out = prepare(jobs, out, cfg)
    errors = {e["sequence"]: e["error"] for e in map(json.loads, (out / "errors.jsonl").read_text().splitlines())}
    broken = f"{seqname}_{sub}_{gapped['runs'][1][0]:05d}"
    keyless = f"{other['sequence']}_{other['subject']}_{other['runs'][0][0]:05d}"
    assert set(errors) == {broken, keyless}
    assert errors[broken].startswith(broken) and seqname in errors[broken]
    assert "unreadable pickle" in errors[broken] and f"{bad_frame:05d}/{sub}.pkl" in errors[broken]
    assert "missing key 'transl'" in errors[keyless]
    ok = set(Store(out).clip_ids())
    assert f"{seqname}_{sub}_{gapped['runs'][0][0]:05d}" in ok        # the other run still prepared
    assert manifest_out["counts"]["clips"] == len(jobs) - 2 == len(ok)


def test_omomo_split_file_with_unknown_and_unlisted_sequences_is_reported(omomo_raw, tmp_path):
    import json
    root, manifest = omomo_raw
    names = sorted(c["name"] if "name" in c else c["seq_name"] for c in manifest["clips"])
    split = tmp_path / "split.json"
    split.write_text(json.dumps({"train": names[1:] + ["sub99_ghost_000"], "test": []}))
    cfg = PrepareConfig("omomo", fps=20.0, body_model_type="smplx")
    jobs = omomo.prepare_jobs(root, root / "body_models", tmp_path / "out", cfg, split_file=split)
    by_id = {j[0]: j for j in jobs}
    with pytest.raises(ValueError, match="sub99_ghost_000: listed in split file"):
        by_id["sub99_ghost_000"][4](*by_id["sub99_ghost_000"][5])
    with pytest.raises(ValueError, match=f"{names[0]}: not listed in split file"):
        by_id[names[0]][4](*by_id[names[0]][5])
