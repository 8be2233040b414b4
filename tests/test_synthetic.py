"""The synthetic HOI dataset: BEHAVE layout, determinism, camera frame, physical claims and
injected defects, each checked with numbers recomputed from the generated arrays."""
from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path

import numpy as np
import pytest

from synthetic_points import points_around_objects

from hoibench.core import geometry as geo
from hoibench.bodies import proxy_rest_joints
from hoibench.datasets import synthetic as syn
from hoibench.core.skeleton import forward_kinematics

N_CLIPS = 8
WRISTS = (20, 21)
HAND_TOL_M = 0.005          # wrist-to-surface distance allowed while labelled in contact
DRIFT_TOL_M = 0.001         # planted-foot horizontal drift per frame
SEAT_CONTACT_MAX_M = 0.12   # labelled sitting hips: within this of the seat, never inside


def _all_combos():
    return [(o, a, h) for o in syn.OBJECTS for a, hs in syn.CATALOGUE[o].items() for h in hs]


@pytest.fixture(scope="module")
def clips():
    """One clip of every (object, action, hands) combination, subjects in turn."""
    out = []
    for i, (obj, action, hands) in enumerate(_all_combos()):
        spec = syn.ClipSpec("Date01", syn.SUBJECTS[i % 8], obj, action, hands)
        out.append(syn.generate_clip(spec, (11, i)))
    return out


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("synthetic") / "a"
    defects = {1: syn.Defect("foot_skating", 1.0)}
    manifest = syn.write_behave_layout(root, N_CLIPS, seed=3, defects=defects, progress=False)
    return root, manifest, defects


def _mesh_distance(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unsigned distance (N,) from points (N, 3) to a triangle mesh: closest point on each
    triangle by its Voronoi regions (Ericson, Real-Time Collision Detection 5.1.5)."""
    a, b, c = (vertices[faces[:, i]][None] for i in range(3))
    p = points[:, None]
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(-1), (ac * ap).sum(-1)
    bp = p - b
    d3, d4 = (ab * bp).sum(-1), (ac * bp).sum(-1)
    cp = p - c
    d5, d6 = (ab * cp).sum(-1), (ac * cp).sum(-1)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    denom = np.where(va + vb + vc == 0, 1.0, va + vb + vc)
    v, w = vb / denom, vc / denom
    q = a + ab * v[..., None] + ac * w[..., None]                        # face interior
    div = lambda x, y: x / np.where(y == 0, 1.0, y)  # noqa: E731
    t = div(d1, d1 - d3)
    q = np.where(((vc <= 0) & (d1 >= 0) & (d3 <= 0))[..., None], a + t[..., None] * ab, q)
    t = div(d2, d2 - d6)
    q = np.where(((vb <= 0) & (d2 >= 0) & (d6 <= 0))[..., None], a + t[..., None] * ac, q)
    t = div(d4 - d3, (d4 - d3) + (d5 - d6))
    q = np.where(((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0))[..., None], b + t[..., None] * (c - b), q)
    q = np.where(((d1 <= 0) & (d2 <= 0))[..., None], a, q)
    q = np.where(((d3 >= 0) & (d4 <= d3))[..., None], b, q)
    q = np.where(((d6 >= 0) & (d5 <= d6))[..., None], c, q)
    return np.linalg.norm(p - q, axis=-1).min(1)


def _digest(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


# --------------------------------------------------------------------------- layout
def test_same_arguments_give_byte_identical_files(dataset, tmp_path):
    root, _, defects = dataset
    syn.write_behave_layout(tmp_path / "b", N_CLIPS, seed=3, defects=defects, progress=False)
    a, b = _digest(root), _digest(tmp_path / "b")
    assert len(a) > 5 * N_CLIPS and a == b


def test_clips_depend_on_seed_and_index_only():
    spec = syn.ClipSpec("Date02", "Sub06", "boxlarge", "carry", "both")
    c1, c2, c3 = (syn.generate_clip(spec, s) for s in ((5, 2), (5, 2), (5, 3)))
    np.testing.assert_array_equal(c1.joints, c2.joints)
    np.testing.assert_array_equal(c1.obj_trans, c2.obj_trans)
    assert not np.array_equal(c1.joints[:10], c3.joints[:10])


def test_behave_files_have_the_release_keys_dtypes_and_shapes(dataset):
    root, manifest, _ = dataset
    seqs = sorted((root / "sequences").iterdir())
    assert len(seqs) == N_CLIPS
    for seq in seqs:
        assert re.fullmatch(r"Date0[1-3]_Sub0[1-8]_[a-z]+_[a-z]+(_\d+)?", seq.name)
        body = np.load(seq / "smpl_fit_all.npz", allow_pickle=False)
        T = body["poses"].shape[0]
        assert set(body.files) == {"poses", "betas", "trans", "save_name", "frame_times"}
        assert body["poses"].dtype == np.float32 and body["poses"].shape == (T, 156)
        assert np.all(body["poses"][:, 66:] == 0)                       # flat hands
        assert body["betas"].dtype == np.float32 and body["betas"].shape == (T, 10)
        assert body["trans"].dtype == np.float32 and body["trans"].shape == (T, 3)
        assert body["frame_times"].dtype.kind == "U" and body["save_name"].dtype.kind == "U"
        assert all(re.fullmatch(r"t\d{4}\.\d{3}", t) for t in body["frame_times"])
        secs = np.array([float(t[1:]) for t in body["frame_times"]])
        np.testing.assert_allclose(np.diff(secs), 1 / 30, atol=1.1e-3)
        obj = np.load(seq / "object_fit_all.npz", allow_pickle=False)
        assert set(obj.files) == {"angles", "trans", "save_name", "frame_times"}
        assert obj["angles"].dtype == np.float64 and obj["angles"].shape == (T, 3)
        assert obj["trans"].dtype == np.float64 and obj["trans"].shape == (T, 3)
        np.testing.assert_array_equal(obj["frame_times"], body["frame_times"])
        info = json.loads((seq / "info.json").read_text())
        assert {"config", "intrinsic", "cat", "gender", "empty", "kinects", "beta"} <= set(info)
        sub = int(seq.name.split("_")[1][3:])
        assert info["gender"] == ("male" if sub <= 5 else "female")
        assert info["cat"] == seq.name.split("_")[2]
        assert (root / "objects" / info["cat"] / f"{info['cat']}_f1000.ply").exists()
        gt = np.load(seq / "hoibench_gt.npz", allow_pickle=False)
        assert gt["joints"].shape == (T, 22, 3) and gt["contacts"].shape == (T, 22)
        assert gt["contacts"].dtype == bool and gt["foot_planted"].shape == (T, 2)
        meta = json.loads((seq / "hoibench_gt.json").read_text())
        for key in ("segments", "hands", "defects", "stats", "spec", "cam_R", "cam_c"):
            assert key in meta
        for action, start, end, hands in meta["segments"]:
            assert action in syn.ACTIONS and 0 <= start < end <= T / 30 + 1e-6
            assert hands in syn.HANDS
    split = json.loads((root / "split.json").read_text())
    assert split["test"] and split["test"] == sorted(s.name for s in seqs if s.name.startswith("Date03"))
    assert sorted(split["train"] + split["test"]) == [s.name for s in seqs]
    for g in ("MALE", "FEMALE", "NEUTRAL"):
        assert (root / "body_models" / "smplh" / f"SMPLH_{g}.npz").exists()
    assert manifest["n_clips"] == N_CLIPS and len(manifest["clips"]) == N_CLIPS


def test_object_templates_are_centred_closed_and_real_sized(dataset):
    trimesh = pytest.importorskip("trimesh")
    root, _, _ = dataset
    size_range = {  # plausible bounding boxes (min, max extent, metres)
        "boxsmall": (0.25, 0.40), "boxlarge": (0.40, 0.60), "chairwood": (0.40, 0.90),
        "tablesmall": (0.50, 0.62), "stool": (0.33, 0.47), "yogaball": (0.55, 0.70),
        "yogamat": (0.14, 0.65), "backpack": (0.18, 0.44)}
    for name in syn.OBJECTS:
        m = syn.build_object(name)
        mesh = trimesh.Trimesh(m.vertices, m.faces, process=False)
        assert np.abs(m.vertices.mean(0)).max() < 1e-6
        lo, hi = size_range[name]
        assert lo <= m.size.min() and m.size.max() <= hi, (name, m.size)
        assert mesh.volume > 0                        # outward-facing triangles
    for ply in root.glob("objects/*/*_f1000.ply"):
        mesh = trimesh.load(ply, process=False, force="mesh")
        ref = syn.build_object(ply.parent.name)
        np.testing.assert_allclose(mesh.vertices, ref.vertices, atol=1e-7)
        np.testing.assert_array_equal(mesh.faces, ref.faces)


def test_mesh_distance_helper_on_a_unit_square():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    f = np.array([[0, 1, 2], [0, 2, 3]])
    p = np.array([[0.5, 0.5, 2.0], [2.0, 0.5, 0.0], [-1.0, -1.0, 0.0], [0.2, 0.7, -0.3]])
    np.testing.assert_allclose(_mesh_distance(p, v, f), [2.0, 1.0, np.sqrt(2), 0.3], atol=1e-12)


def test_analytic_signed_distance_matches_the_written_mesh():
    for name, m, p, sd in points_around_objects(seed=0, margin=0.1, n=300):
        p = p[sd > 0.002]
        dist = _mesh_distance(p, m.vertices, m.faces)
        # boxes exactly; curved parts differ by at most the tessellation sagitta
        assert np.abs(dist - m.sdf_local(p)).max() < 1.5e-3, name


# --------------------------------------------------------------------------- camera frame
def test_pelvis_offset_rule_moves_the_body_rigidly():
    rng = np.random.default_rng(1)
    T = 5
    aa = rng.normal(0, 0.4, (T, 22, 3))
    trans = rng.normal(0, 1, (T, 3))
    rest = proxy_rest_joints(np.array([0.7] + [0.0] * 9))
    R, c = syn.CAMERA_R, syn.CAMERA_C
    J, _ = forward_kinematics(geo.axis_angle_to_matrix(aa), rest, trans)
    root, t2 = syn.rigid_transform_smpl(aa[:, 0], trans, rest[0], R, c)
    aa2 = aa.copy()
    aa2[:, 0] = root
    J2, _ = forward_kinematics(geo.axis_angle_to_matrix(aa2), rest, t2)
    np.testing.assert_allclose(J2, J @ R.T + c, atol=1e-12)
    naive, _ = forward_kinematics(geo.axis_angle_to_matrix(aa2), rest, trans @ R.T + c)
    np.testing.assert_allclose(naive - J2, np.broadcast_to((np.eye(3) - R) @ rest[0], J2.shape),
                               atol=1e-12)      # rotating trans alone is off by (I - R) J0


def test_camera_parameters_map_back_to_the_generator_joints(dataset):
    root, _, _ = dataset
    for seq in sorted((root / "sequences").iterdir()):
        body = np.load(seq / "smpl_fit_all.npz", allow_pickle=False)
        obj = np.load(seq / "object_fit_all.npz", allow_pickle=False)
        gt = np.load(seq / "hoibench_gt.npz", allow_pickle=False)
        poses = body["poses"].astype(np.float64).reshape(-1, 52, 3)[:, :22]
        betas = body["betas"].astype(np.float64)[0]
        rest = proxy_rest_joints(betas)
        Rc, cc = gt["cam_R"], gt["cam_c"]
        # y-down camera -> y-up world: p = Rc^T (p_cam - cc), about the rest pelvis J0
        R0 = Rc.T @ geo.axis_angle_to_matrix(poses[:, 0])
        trans = (rest[0] + body["trans"].astype(np.float64) - cc) @ Rc - rest[0]
        local = geo.axis_angle_to_matrix(poses)
        local[:, 0] = R0
        J, _ = forward_kinematics(local, rest, trans)
        assert np.abs(J - gt["joints"]).max() < 1e-5
        assert Rc[1, 1] < -0.9                                       # camera y points down
        obj_R = Rc.T @ geo.axis_angle_to_matrix(obj["angles"])
        obj_t = (obj["trans"] - cc) @ Rc
        np.testing.assert_allclose(obj_R, gt["obj_rot"], atol=1e-9)
        np.testing.assert_allclose(obj_t, gt["obj_trans"], atol=1e-9)


def test_behave_loader_reads_the_synthetic_layout(dataset):
    """The loader recovers the generator's joints (1e-4 m) and object poses (1e-6) in the
    generator's world seen through the loader's own transform (camera -> flip -> floor)."""
    pytest.importorskip("smplx")
    pytest.importorskip("trimesh")
    from hoibench.datasets import behave
    root, _, _ = dataset
    flip = np.diag([1.0, -1.0, -1.0])
    for seq in sorted((root / "sequences").iterdir()):
        s = behave.load_sequence(seq, root / "objects", root / "body_models", fps=30.0)
        gt = np.load(seq / "hoibench_gt.npz", allow_pickle=False)
        R = flip @ gt["cam_R"]
        lift = np.array([0.0, s.provenance["floor_shift_m"], 0.0])
        want = gt["joints"] @ R.T + flip @ gt["cam_c"] - lift
        assert np.abs(s.joints - want).max() < 1e-4, seq.name
        np.testing.assert_allclose(s.obj_rot, R @ gt["obj_rot"], atol=1e-6, err_msg=seq.name)
        np.testing.assert_allclose(s.obj_trans, gt["obj_trans"] @ R.T + flip @ gt["cam_c"] - lift,
                                   atol=1e-6, err_msg=seq.name)
        np.testing.assert_array_equal(s.contacts, gt["contacts"].astype(bool))


# --------------------------------------------------------------------------- physical claims
def _sdf(clip, points):
    return clip.object.sdf(points, clip.obj_rot, clip.obj_trans)


def test_planted_feet_do_not_slide(clips):
    worst = 0.0
    for c in clips:
        for k, joints in ((0, (7, 10)), (1, (8, 11))):
            still = c.foot_planted[1:, k] & c.foot_planted[:-1, k]
            step = np.linalg.norm(np.diff(c.joints[:, joints][..., [0, 2]], axis=0), axis=-1)
            worst = max(worst, step[still].max(initial=0.0))
        assert c.foot_planted.any(0).all(), c.name
    assert worst < DRIFT_TOL_M
    assert worst < 1e-9                                  # exact up to rounding (~1e-15 m)


def test_hands_stay_on_the_surface_and_carry_the_object_rigidly(clips):
    worst_sdf, worst_mesh, worst_local = 0.0, 0.0, 0.0
    for c in clips:
        sd = _sdf(c, c.joints)
        for k, w in enumerate(WRISTS):
            on = c.contacts[:, w]
            if not on.any():
                continue
            worst_sdf = max(worst_sdf, np.abs(sd[on, w]).max())
            local = np.einsum("tji,tj->ti", c.obj_rot[on], c.joints[on, w] - c.obj_trans[on])
            d = _mesh_distance(local[::7], c.object.vertices, c.object.faces)
            worst_mesh = max(worst_mesh, d.max())
            runs = np.flatnonzero(np.diff(np.concatenate([[0], on.astype(int), [0]])))
            for a, b in zip(runs[::2], runs[1::2]):          # same local point during a run
                seg = np.einsum("tji,tj->ti", c.obj_rot[a:b], c.joints[a:b, w] - c.obj_trans[a:b])
                worst_local = max(worst_local, np.linalg.norm(seg - seg[0], axis=-1).max())
    assert worst_sdf < 1e-9 and worst_mesh < HAND_TOL_M and worst_local < 1e-9


def test_carried_objects_really_move(clips):
    moved = [np.linalg.norm(c.obj_trans - c.obj_trans[0], axis=-1).max() for c in clips
             if c.spec.action in ("lift", "carry", "putdown", "push", "pull", "kick")]
    assert min(moved) > 0.15


def test_objects_never_go_below_the_floor_and_rest_on_it(clips):
    for c in clips:
        y = c.object_vertices()[..., 1].min(-1)
        assert y.min() >= -1e-9, c.name
        if c.spec.action in ("lift", "push", "pull", "sit", "kick"):
            assert abs(y[0]) < 1e-9, c.name                 # starts on the floor
        assert c.joints[..., 1].min() > 0.0


def test_no_joint_is_inside_the_object(clips):
    worst = max(-_sdf(c, c.joints).min() for c in clips)
    assert worst <= syn.JOINT_PENETRATION_TOL_M


def test_contact_labels_agree_with_the_geometry(clips):
    for c in clips:
        sd = _sdf(c, c.joints)
        lab = c.contacts
        assert lab.any(), c.name
        hands = lab[:, list(WRISTS)]
        assert np.abs(sd[:, list(WRISTS)][hands]).max(initial=0) < HAND_TOL_M
        feet = lab[:, [10, 11]]
        assert np.abs(sd[:, [10, 11]][feet]).max(initial=0) < HAND_TOL_M
        hips = lab[:, [1, 2]]
        if hips.any():
            assert 0.0 < sd[:, [1, 2]][hips].min() and sd[:, [1, 2]][hips].max() < SEAT_CONTACT_MAX_M
        used = {("left", "right")[k] for k in range(2) if hands[:, k].any()}
        assert used == set(c.hands), c.name
        others = np.delete(np.arange(22), [1, 2, 10, 11, 20, 21])
        assert not lab[:, others].any()


def test_sitting_puts_the_pelvis_over_the_seat_and_kicking_rolls_the_ball(clips):
    for c in clips:
        if c.spec.action == "sit":
            seat_y = c.object.seat[0] + c.obj_trans[-1, 1]           # objects keep yaw-only
            pelvis = c.joints[-1, 0]
            assert 0.10 < pelvis[1] - seat_y < 0.22, c.name
            local = c.obj_rot[-1].T @ (pelvis - c.obj_trans[-1])
            lo, hi = c.object.vertices.min(0), c.object.vertices.max(0)
            assert np.all((lo[[0, 2]] < local[[0, 2]]) & (local[[0, 2]] < hi[[0, 2]])), c.name
            assert np.linalg.norm(c.obj_trans[-1] - c.obj_trans[0]) < 1e-12
        if c.spec.action == "kick":
            k = 10 if c.feet == ("left",) else 11
            touch = np.flatnonzero(c.contacts[:, k])
            assert len(touch) >= 2
            after = c.obj_trans[touch[-1]:]
            assert np.linalg.norm(after[-1] - after[0]) > 0.5            # rolled away
            np.testing.assert_allclose(c.obj_trans[:, 1], c.obj_trans[0, 1])


# --------------------------------------------------------------------------- defects
def _defect_clip(obj, action, hands, defect, subject="Sub02"):
    return syn.generate_clip(syn.ClipSpec("Date01", subject, obj, action, hands), 4, [defect])


@pytest.mark.parametrize("obj,action", [("boxlarge", "carry"), ("boxsmall", "hold"), ("yogaball", "kick")])
def test_a_skating_foot_moves_speed_over_fps_per_frame_while_labelled_planted(obj, action):
    hands = "none" if action == "kick" else "both"
    c = _defect_clip(obj, action, hands, syn.Defect("foot_skating", 1.0))
    rec, = c.defects
    a, b = rec["frames"]
    k = ("left", "right").index(rec["side"])
    assert b - a >= 10 and c.foot_planted[a:b, k].all()
    step = np.linalg.norm(np.diff(c.joints[a:b, 10 + k][:, [0, 2]], axis=0), axis=-1)
    np.testing.assert_allclose(step, 1.0 / 30.0, atol=1e-9)
    assert abs(rec["measured_speed_mps"] - 1.0) < 1e-6
    other = 1 - k
    still = c.foot_planted[1:, other] & c.foot_planted[:-1, other]
    assert np.abs(np.diff(c.joints[:, 10 + other], axis=0)[still]).max(initial=0) < 1e-9


@pytest.mark.parametrize("obj,action,hands,depth", [("boxlarge", "lift", "both", 0.03),
                                                    ("chairwood", "push", "left", 0.01),
                                                    ("yogaball", "hold", "both", 0.05)])
def test_a_penetrating_hand_is_depth_inside_the_object(obj, action, hands, depth):
    c = _defect_clip(obj, action, hands, syn.Defect("penetration", depth))
    rec, = c.defects
    a, b = rec["frames"]
    w = rec["joints"][0]
    assert c.contacts[a:b, w].all() and b - a >= 10
    np.testing.assert_allclose(_sdf(c, c.joints)[a:b, w], -depth, atol=1e-9)
    assert abs(rec["measured_depth_m"] - depth) < 1e-6


def test_sitting_and_kicking_penetration():
    depth = 0.04
    spec = syn.ClipSpec("Date01", "Sub05", "stool", "sit", "none")
    clean, bad = syn.generate_clip(spec, 4), syn.generate_clip(spec, 4, syn.Defect("penetration", depth))
    a, b = bad.defects[0]["frames"]
    drop = _sdf(clean, clean.joints)[a:b, 1:3] - _sdf(bad, bad.joints)[a:b, 1:3]
    np.testing.assert_allclose(drop, depth, atol=1e-6)
    kick = _defect_clip("yogaball", "kick", "none", syn.Defect("penetration", 0.03))
    rec, = kick.defects
    a, b = rec["frames"]
    np.testing.assert_allclose(_sdf(kick, kick.joints)[a:b, rec["joints"][0]], -0.03, atol=1e-6)
    with pytest.raises(ValueError, match="thick"):
        _defect_clip("chairwood", "push", "both", syn.Defect("penetration", 0.05))


@pytest.mark.parametrize("obj,action,hands", [("boxlarge", "carry", "both"), ("tablesmall", "pull", "right"),
                                              ("backpack", "putdown", "left")])
def test_a_lost_contact_hand_is_gap_away_while_the_object_moves(obj, action, hands):
    gap = 0.05
    c = _defect_clip(obj, action, hands, syn.Defect("lost_contact", gap))
    rec, = c.defects
    a, b = rec["frames"]
    w = rec["joints"][0]
    assert c.contacts[a:b, w].all()
    np.testing.assert_allclose(_sdf(c, c.joints)[a:b, w], gap, atol=1e-9)
    assert np.linalg.norm(c.obj_trans[b - 1] - c.obj_trans[a]) > 0.01
    with pytest.raises(ValueError, match="hand action"):
        _defect_clip("stool", "sit", "none", syn.Defect("lost_contact", gap))


def test_defects_are_recorded_in_the_ground_truth(dataset):
    root, manifest, defects = dataset
    name = manifest["clips"][1]["name"]
    meta = json.loads((root / "sequences" / name / "hoibench_gt.json").read_text())
    rec, = meta["defects"]
    assert rec["kind"] == "foot_skating" and rec["magnitude"] == 1.0 and rec["units"] == "m/s"
    assert all(not c["defects"] for i, c in enumerate(manifest["clips"]) if i != 1)


# --------------------------------------------------------------------------- planning
def test_plan_spreads_dates_subjects_objects_and_actions():
    small = syn.plan_clips(8, seed=0)
    assert {s.action for s in small} == set(syn.ACTIONS)
    assert 1 <= sum(s.date == "Date03" for s in small) <= 3
    assert {s.subject for s in small} == set(syn.SUBJECTS)
    big = syn.plan_clips(200, seed=5)
    share = np.mean([s.date == "Date03" for s in big])
    assert 0.25 <= share <= 0.30
    assert {s.object for s in big} == set(syn.OBJECTS)
    assert {s.date for s in big} == {"Date01", "Date02", "Date03"}
    assert len({s.name for s in big}) == len(big)
    assert syn.plan_clips(12, seed=5) == big[:12]


def test_clip_spec_rejects_what_the_catalogue_does_not_offer():
    with pytest.raises(ValueError, match="action"):
        syn.ClipSpec("Date01", "Sub01", "backpack", "sit", "none")
    with pytest.raises(ValueError, match="hands"):
        syn.ClipSpec("Date01", "Sub01", "boxsmall", "lift", "left")
    with pytest.raises(ValueError, match="subject"):
        syn.ClipSpec("Date01", "Sub09", "boxsmall", "lift", "both")
    with pytest.raises(ValueError, match="kind"):
        syn.Defect("floating", 1.0)
