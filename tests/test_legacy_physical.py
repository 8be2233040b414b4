"""ChainHOI's released metric rules in the legacy protocols (hoibench.metrics.legacy_rules): the claims.

Per rule, a constructed case where ChainHOI's rule and hoibench's clean rule differ: the
legacy setting gives the hand-computed value of the reference's rule, the default (clean)
setting hoibench's, so neither can drift.

1. OCD group members: cropped to the generated length (reference) vs dropped beyond +-8 frames.
4. OMOMO: CD/OCD on the wrists only, feet lowered to their lowest point before FSR, GT labels
   ``|d| <= 0.5``.
5. FSR on the canonical (hml263-decoded) joints vs the world joints.
6. GT labels ``|d| <= tau`` vs ``d < tau``.
7. Evaluated lengths: multiples of 4 (one unit shorter with probability 1/3), offset random
   (BEHAVE) or 0 (OMOMO), seeded per clip and replication.

Also: the protocols carry the settings, bad values are refused naming file and field, and
the clean protocols' content hashes are those of before the settings existed.
"""
from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from hoibench.core import skeleton as sk
from hoibench.metrics import contact_metrics as cm
from hoibench.metrics import legacy_rules as lr
from hoibench.metrics import physical as ph
from hoibench.tracks import protocol as P

needs_open3d = pytest.mark.skipif(importlib.util.find_spec("open3d") is None, reason="open3d not installed")

#: sha256 of the clean protocols before the legacy settings were added (must never change)
CLEAN_SHA256 = {
    "behave-clean": "3d9bb579152fb66826fe300d8bce23bc2f87bfd034d48ff3c53b2a94b2561036",
    "omomo-clean": "4465b4d470fc1febec277d71905a6241494b5b93362fbcc0fbeb91c6d586e8c4",
    "rich-cat-clean": "0392868ea393481257bde4cf03d56379051344932ee634faf9319de070a9f5bd",
    "synthetic-clean": "60ab40d0520112bd7c35c966b8e434a37b45f8aaf0b8684a769b5fdd34dae45a",
}
CLEAN = ph.PhysicalConfig("clean")


def _walker(T: int, axis: int, step: float = 0.05, facing_x: bool = True) -> np.ndarray:
    """The rest skeleton (lowest joint 1 cm above the floor), facing +x (or +z), translated by
    ``step`` metres per frame along world ``axis``: (T, 22, 3)."""
    J0 = sk.SMPL_REST_JOINTS.copy()
    if facing_x:                                   # rotate +90 deg about y: +z -> +x
        J0 = J0 @ np.array([[0, 0, 1.0], [0, 1, 0], [-1, 0, 0]]).T
    J0[:, 1] -= J0[:, 1].min() - 0.01
    J = np.repeat(J0[None], T, axis=0)
    J[:, :, axis] += step * np.arange(T)[:, None]
    return J


def _fsr(joints, config) -> tuple[int, int]:
    st = ph.clip_physical_stats(ph.ClipInput("c", joints, 20.0), config)
    return st["fsr_skating"], st["fsr_ground"]


# ====================================================================== 1. OCD group members
def test_1_ocd_members_longer_than_the_clip_are_cropped_and_kept():
    """Generated T = 20; own map: joint 0 at d = 0.2; member A (32 frames, 12 longer) joint 1
    at 0.05; member B (11 frames, 9 shorter) joint 2 at 0.01; member C (12 frames, 8 shorter)
    joint 3 at 0.1. Reference (compute.py:625-626): A is cut to 20 frames and kept, B dropped
    (20 - 11 > 8), C kept -> min(0.04, 0.0025, 0.01) = 0.0025. Clean: A dropped (|32 - 20| >
    8) -> min(0.04, 0.01) = 0.01."""
    T = 20
    d = np.full((T, 22), 1.0)
    d[:, 0], d[:, 1], d[:, 2], d[:, 3] = 0.2, 0.05, 0.01, 0.1
    own = np.zeros((T, 22), bool)
    own[:, 0] = True

    def member(frames, joint):
        m = np.zeros((frames, 22), bool)
        m[:, joint] = True
        return m

    group = (member(32, 1), member(11, 2), member(12, 3))
    assert cm.optimal_contact_distance(d, own, group, 8, "crop") == pytest.approx(0.05 ** 2)
    assert cm.optimal_contact_distance(d, own, group, 8, "tolerance") == pytest.approx(0.1 ** 2)
    assert cm.optimal_contact_distance(d, own, group) == pytest.approx(0.1 ** 2)       # default: clean
    # the cropped member masks exactly the generated frames: a member whose only contact is
    # beyond frame 20 has no contact after cropping and cannot win
    late = np.zeros((40, 22), bool)
    late[25:, 2] = True
    assert cm.optimal_contact_distance(d, own, (late,), 8, "crop") == pytest.approx(0.2 ** 2)
    with pytest.raises(ValueError, match="members"):
        cm.optimal_contact_distance(d, own, group, 8, "both")


def test_1_members_are_read_from_the_window_offset():
    """With a length window (start 3, length 12) a member's map is read from frame 3, as the
    reference's ``label[idx:idx + L]`` (compute.py:625)."""
    m = np.zeros((30, 22), bool)
    m[3, 1] = True
    inp = ph.ClipInput("c", np.zeros((20, 22, 3)), 20.0, gt_contacts=np.zeros((20, 22), bool), group_contacts=(m,))
    w = ph.window_input(inp, 3, 12)
    assert w.joints.shape == (12, 22, 3) and w.gt_contacts.shape == (12, 22)
    assert w.group_contacts[0].shape == (27, 22) and w.group_contacts[0][0, 1] and w.windows == ()


# ====================================================================== 4. OMOMO
def test_4_omomo_cd_and_ocd_count_only_the_wrists():
    """GT contact on joint 0 (d = 0.3) and the left wrist 20 (d = 0.1) on 10 frames. Reference
    (compute.py:1029, 1089: ``contact_mask[:, 0:20] = 0``): CD = 0.1^2; clean: (0.3^2 +
    0.1^2) / 2 = 0.05."""
    T = 10
    d = np.full((T, 22), 1.0)
    d[:, 0], d[:, 20] = 0.3, 0.1
    gt = np.zeros((T, 22), bool)
    gt[:, [0, 20]] = True
    wrists = lr.select_joints(gt, "wrists")
    assert wrists.sum() == T and wrists[:, 20].all()
    assert cm.contact_distance(d, wrists) == pytest.approx(0.01)
    assert cm.contact_distance(d, lr.select_joints(gt, "all")) == pytest.approx(0.05)
    # OCD: a member with contact on joint 0 only has no wrist contact: not a candidate
    other = np.zeros((T, 22), bool)
    other[:, 0] = True
    d2 = d.copy()
    d2[:, 0] = 0.01
    assert cm.optimal_contact_distance(d2, wrists, (lr.select_joints(other, "wrists"),), 8, "crop") == \
        pytest.approx(0.01)
    assert cm.optimal_contact_distance(d2, gt, (other,), 8, "tolerance") == pytest.approx(0.01 ** 2)


def test_4_omomo_feet_are_lowered_to_their_lowest_point_before_fsr():
    """Left foot at y = 0.10, right at 0.20, both sliding 0.05 m/frame along x for 12 frames.
    World: no foot below 0.05 m -> FSR counts (0, 0). Reference (compute.py:955-967): lowered
    by 0.10 -> the left foot is on the ground at every step and skates: (11, 11)."""
    T = 12
    J = _walker(T, 0, facing_x=False)
    J[:, 10, 1], J[:, 11, 1] = 0.10, 0.20
    legacy = ph.PhysicalConfig("legacy", fsr_feet_to_floor=True)
    assert _fsr(J, legacy) == (T - 1, T - 1)
    assert _fsr(J, ph.PhysicalConfig("legacy")) == (0, 0)
    assert _fsr(J, CLEAN) == (0, 0)


def test_4_omomo_gt_labels_are_unsigned_distances_within_half_a_metre():
    """``contact <= 0.5`` (hoidataset.py:471) on |d|: d = -0.6 (deep inside) is not in
    contact, 0.5 is; clean (d < 0.12, the chainhoi default for an unknown object) differs."""
    d = np.zeros((6, 22))
    d[:, 20] = [-0.6, -0.3, 0.0, 0.4, 0.5, 0.6]
    ref = lr.gt_labels(d, 0.5, "unsigned")[:, 20]
    assert ref.tolist() == [False, True, True, True, True, False]
    assert lr.gt_labels(d, 0.12, "signed")[:, 20].tolist() == [True, True, True, False, False, False]


# ====================================================================== 5. FSR frame
@pytest.mark.parametrize("axis, canonical, world_x, clean", [
    (2, (20, 20), (0, 22), (22, 22)),      # slides along world z = canonical x: only the reference counts it
    (0, (0, 20), (22, 22), (22, 22)),      # slides along world x = canonical z: only the reference misses it
])
def test_5_fsr_runs_on_the_canonical_joints(axis, canonical, world_x, clean):
    """A body facing +x slides 0.05 m/frame (12 frames). The reference's FSR reads the joints
    recovered from the features (chainhoi_omomo.py:422, chainhoi_behave.py:386; HumanML3D's
    canonical frame: frame 0 faces +z, so world z becomes canonical -x), 11 frames, 10 steps
    x 2 feet, every foot on the ground; x-only test (compute.py:553-555). World x-only and
    clean (x, z) counts are 11 steps x 2 feet."""
    J = _walker(12, axis)
    assert _fsr(J, ph.PhysicalConfig("legacy", fsr_frame="canonical")) == canonical
    assert _fsr(J, ph.PhysicalConfig("legacy")) == world_x
    assert _fsr(J, CLEAN) == clean
    C = lr.fsr_joints(J, 20.0, "canonical")
    assert C.shape == (11, 22, 3) and C[..., 1].min() == pytest.approx(0.0, abs=1e-6)   # floor: lowest joint


# ====================================================================== 6. GT labels
@needs_open3d
def test_6_gt_labels_unsigned_vs_signed_from_a_box():
    """A 1 m box (boxlarge: tau 0.17). Joint 0 at d = +0.1, joint 1 at the centre (d = -0.5),
    joint 2 at -0.05, the rest 3 m away. Reference (hoidataset.py:224, ``contact <=
    dis[object]`` on |d|): joints 0, 2; clean (``d < tau``): joints 0, 1, 2. The store's own
    labels are used by the clean rule only."""
    import trimesh
    box = trimesh.creation.box((1.0, 1.0, 1.0))
    T = 3
    J = np.full((T, 22, 3), 3.0)
    J[:, 0], J[:, 1], J[:, 2] = (0.6, 0, 0), (0, 0, 0), (0.45, 0, 0)
    clip = {"joints": J, "obj_rot": np.repeat(np.eye(3)[None], T, 0), "obj_trans": np.zeros((T, 3)),
            "object_name": np.array("boxlarge")}

    class Store:
        def object_template(self, name):
            return np.asarray(box.vertices), np.asarray(box.faces)

    on = lambda lab: sorted(np.flatnonzero(lab.all(axis=0)).tolist())  # noqa: E731
    assert on(ph.gt_contact_labels(Store(), clip, "chainhoi", "unsigned")) == [0, 2]
    assert on(ph.gt_contact_labels(Store(), clip, "chainhoi")) == [0, 1, 2]
    assert on(ph.gt_contact_labels(Store(), clip, "chainhoi", "unsigned", 0.5)) == [0, 1, 2]    # |-0.5| <= 0.5
    stored = dict(clip, contacts=np.ones((T, 22), bool))
    assert ph.gt_contact_labels(Store(), stored, "chainhoi").all()                      # clean: stored labels
    assert on(ph.gt_contact_labels(Store(), stored, "chainhoi", "unsigned")) == [0, 2]  # reference: distances


# ====================================================================== 7. evaluated lengths
def _reference_window(frames, rule, seed):
    """hoidataset.py:299-316 / 543-561 by hand, on the documented draws."""
    rng = np.random.default_rng(seed)
    T0 = min(frames, 199)
    L = (T0 // 4 - 1) * 4 if rng.integers(3) == 2 else (T0 // 4) * 4
    return (int(rng.integers(0, T0 - L + 1)) if rule == "unit4_random" else 0), L


@pytest.mark.parametrize("frames", [50, 61, 199, 250])
def test_7_length_windows_follow_the_reference_rule(frames):
    seen_double = seen_single = 0
    for seed in range(300):
        for rule in ("unit4_random", "unit4_start"):
            start, L = lr.length_window(frames, rule, seed)
            assert (start, L) == _reference_window(frames, rule, seed)
            T0 = min(frames, 199)
            assert L % 4 == 0 and L in ((T0 // 4) * 4, (T0 // 4 - 1) * 4) and 0 <= start <= T0 - L
            if rule == "unit4_start":
                assert start == 0
                seen_double += L < (T0 // 4) * 4
                seen_single += L == (T0 // 4) * 4
        assert lr.length_window(frames, "none", seed) == (0, frames)
    assert abs(seen_double / 300 - 1 / 3) < 0.08 and seen_double + seen_single == 300


def test_7_windows_are_seeded_per_clip_and_replication():
    proto = P.get_protocol("behave-legacy")
    a = lr.replication_windows("clipA", 120, "unit4_random", range(20), proto.seed_for)
    assert a == lr.replication_windows("clipA", 120, "unit4_random", range(20), proto.seed_for)
    assert [w[0] for w in a] == list(range(20))
    assert a[0][1:] == lr.length_window(120, "unit4_random", proto.seed_for("length_crop/clipA", 0))
    b = lr.replication_windows("clipB", 120, "unit4_random", range(20), proto.seed_for)
    assert a != b and len({w[1:] for w in a}) > 1


def test_7_metrics_see_only_the_window():
    """A clip of 50 frames whose feet skate only on the last 2 steps (frames 47 -> 49).
    Reference, offset 0 (OMOMO): the window is 48 or 44 frames, no skating: (0, 2 (L - 1));
    clean: every frame, (4, 98)."""
    T = 50
    J = _walker(T, 0, step=0.0, facing_x=False)
    J[48:, :, 0] += 0.05 * np.arange(1, 3)[:, None]
    windows = tuple((r, *lr.length_window(T, "unit4_start", seed)) for r, seed in enumerate(range(6)))
    assert {w[2] for w in windows} == {44, 48}                  # both lengths drawn
    legacy = ph.PhysicalConfig("legacy", length_crop="unit4_start")
    by_rep = ph.clip_window_stats(ph.ClipInput("c", J, 20.0, windows=windows), legacy)
    for r, start, L in windows:
        assert start == 0 and by_rep[r]["frames"] == L
        assert (by_rep[r]["fsr_skating"], by_rep[r]["fsr_ground"]) == (0, 2 * (L - 1))
    key, out = ph._unit(ph.ClipInput("c", J, 20.0, windows=windows), legacy)
    assert key == "c" and set(out["replications"]) == set(range(6))
    assert _fsr(J, ph.PhysicalConfig("legacy")) == (4, 2 * (T - 1))
    assert _fsr(J, CLEAN) == (4, 2 * (T - 1))


@needs_open3d
def test_7_window_stats_equal_the_stats_of_the_cut_clip():
    """Every metric of a window equals the same metric of the clip cut by hand (object, GT)."""
    import trimesh
    box = trimesh.creation.box((1.0, 1.0, 1.0))
    T = 30
    J = _walker(T, 0, step=0.01, facing_x=False)
    J[..., 2] -= 0.7
    R, t = np.repeat(np.eye(3)[None], T, 0), np.tile([0.0, 0.5, 0.0], (T, 1))
    gt = np.zeros((T, 22), bool)
    gt[5:20, [20, 21]] = True
    inp = ph.ClipInput("c", J, 20.0, R, t, "boxlarge", np.asarray(box.vertices), np.asarray(box.faces), gt,
                       windows=((0, 3, 24),))
    got = ph.clip_window_stats(inp, CLEAN)[0]
    cut = ph.ClipInput("c", J[3:27], 20.0, R[3:27], t[3:27], "boxlarge", np.asarray(box.vertices),
                       np.asarray(box.faces), gt[3:27])
    assert got == ph.clip_physical_stats(cut, CLEAN)


# ====================================================================== protocols
def test_clean_protocols_are_unchanged():
    for pid, sha in CLEAN_SHA256.items():
        p = P.get_protocol(pid)
        assert p.sha256 == sha, pid
        c = p.physical_config()
        assert (c.ocd_members, c.contact_joints, c.contact_gt_rule, c.contact_gt_threshold_m, c.fsr_frame,
                c.fsr_feet_to_floor, c.length_crop) == ("tolerance", "all", "signed", None, "world", False, "none")


def test_legacy_protocols_carry_the_reference_rules():
    b, o, s = (P.get_protocol(x) for x in ("behave-legacy", "omomo-legacy", "synthetic-legacy"))
    assert b.version == o.version == s.version == "1.3" and b.crop_embeddings and o.crop_embeddings
    assert all(p.changelog[-2].startswith("1.2: ") and p.changelog[-1].startswith("1.3: ") for p in (b, o, s))
    cb, co, cs = b.physical_config(), o.physical_config(), s.physical_config()
    assert (cb.ocd_members, cb.contact_joints, cb.contact_gt_rule, cb.contact_gt_threshold_m, cb.fsr_frame,
            cb.fsr_feet_to_floor, cb.length_crop, cb.fsr_canonical_mode) == \
        ("crop", "all", "unsigned", None, "canonical", False, "unit4_random", "legacy-hoidiff")
    assert (co.ocd_members, co.contact_joints, co.contact_gt_rule, co.contact_gt_threshold_m, co.fsr_frame,
            co.fsr_feet_to_floor, co.length_crop) == \
        ("crop", "wrists", "unsigned", 0.5, "canonical", True, "unit4_start")
    assert (cs.length_crop, cs.fsr_canonical_mode) == ("unit4_random", "legacy-hoidiff")


@pytest.mark.parametrize("key, value", [("ocd_members", "drop"), ("contact_joints", "hands"),
                                        ("contact_gt_rule", "abs"), ("fsr_frame", "local"),
                                        ("fsr_feet_to_floor", "yes"), ("fsr_feet_to_floor", 1),
                                        ("length_crop", "unit8"), ("contact_gt_threshold_m", -0.5),
                                        ("contact_gt_threshold_m", "half")])
def test_bad_reference_rule_values_are_refused_naming_file_and_field(tmp_path, key, value):
    import yaml
    d = P.read_protocol_yaml(P.PROTOCOLS_DIR / "omomo-legacy.yaml")
    d["physical"][key] = value
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(d))
    with pytest.raises(ValueError, match=rf"bad\.yaml: physical: field '{key}'"):
        P.load_protocol(path)


def test_physical_config_refuses_bad_values():
    with pytest.raises(ValueError, match="length_crop"):
        ph.PhysicalConfig("legacy", length_crop="random")
    with pytest.raises(ValueError, match="contact_gt_threshold_m"):
        ph.PhysicalConfig("legacy", contact_gt_threshold_m=0.0)
    with pytest.raises(ValueError, match="fsr_canonical_mode"):
        ph.PhysicalConfig("legacy", fsr_canonical_mode="hml")
