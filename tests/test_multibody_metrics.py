"""Multi-body metrics (hoibench.metrics.multibody): the claims.

* Contact (CSR, CRR, CSIoU) follows the geometry: a hand box at a known gap from an object
  flips contact exactly across the threshold; CRR needs both roots; CSIoU of known frame sets
  is the exact fraction.
* Penetration (IV, ID) equals the analytic value: two boxes overlapping by a known box have
  that IV within the voxel rounding bound (the bound and the error shrink with the voxel); a
  cube's corner pushed a known depth into a box gives that ID.
* SD and OD equal the hand-computed mean of known pairwise distances, in both modes.
* Merged shards equal one metric fed everything, bit for bit, in any shard order.
* Every invalid input raises ValueError naming the argument.
"""
from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from hoibench.metrics.state import Metric
from hoibench.metrics import multibody as mb

pytest.importorskip("open3d")

MM = 1e-3


# ====================================================================== helpers
def box(lo, hi):
    """Closed, outward-oriented triangle mesh of an axis-aligned box: (8, 3), (12, 3)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    v = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return v, f


def posed(frames_vertices, faces):
    """PosedMesh from a list of (V, 3) vertex arrays, one per frame."""
    return mb.PosedMesh(np.stack(frames_vertices), faces)


def still(v, f, T):
    return posed([v] * T, f)


def corner_cube(half, depth, face_x, centre_yz):
    """A cube of half-size ``half`` turned so that a corner points along -x, placed with that
    corner ``depth`` beyond the plane ``x = face_x`` (inside a box whose +x face it is)."""
    u = np.ones(3) / np.sqrt(3)
    r1 = -u
    r2 = np.array([0.0, 1.0, 0.0]) - u[1] * u
    r2 /= np.linalg.norm(r2)
    R = np.stack([r1, r2, np.cross(r1, r2)])              # right-handed, R u = -x
    v, f = box([-half] * 3, [half] * 3)
    centre = np.array([face_x + np.sqrt(3) * half - depth, *centre_yz])
    return v @ R.T + centre, f


OBJ_V, OBJ_F = box([0, 0, 0], [0.05, 0.05, 0.05])          # a 5 cm object box


def hand_at_gap(gap_m):
    """A 2 x 1 x 1 cm 'hand' box whose -x face is ``gap_m`` from the object's +x face."""
    return box([0.05 + gap_m, 0.02, 0.02], [0.07 + gap_m, 0.03, 0.03])[0]


# ====================================================================== geometry sanity
def test_box_helper_is_closed_and_outward():
    v, f = box([0, 0, 0], [0.01, 0.02, 0.03])
    mb.check_closed(f)
    signed_volume = np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])).sum() / 6
    assert signed_volume == pytest.approx(0.01 * 0.02 * 0.03)


# ====================================================================== CSR
def test_hand_distance_is_the_gap_and_contact_flips_at_the_threshold():
    gaps = [4.9 * MM, 5.1 * MM, 20 * MM, -1 * MM]         # last: the hand 1 mm inside the object
    hand = np.stack([hand_at_gap(g) for g in gaps])
    obj = still(OBJ_V, OBJ_F, len(gaps))
    d = mb.hand_object_distance(hand, [obj])
    np.testing.assert_allclose(d, [4.9 * MM, 5.1 * MM, 20 * MM, 1 * MM], atol=1e-7)
    assert mb.CSR_THRESHOLD_M == 0.005
    assert mb.contact_frames_hand(hand, [obj]).tolist() == [True, False, False, True]
    assert mb.contact_frames_hand(hand, [obj], threshold_m=0.006).tolist() == [True, True, False, True]


def test_distance_is_to_the_surface_not_to_the_vertices():
    # a hand vertex 3 mm above the middle of a face is 3 mm away although every object
    # vertex is > 3.5 cm away
    hand = np.array([[[0.025, 0.025, 0.053], [0.025, 0.025, 0.08], [0.03, 0.025, 0.08]]])
    obj = [still(OBJ_V, OBJ_F, 1)]
    assert mb.hand_object_distance(hand, obj)[0] == pytest.approx(3 * MM, abs=1e-7)
    # the vertex-only reading of the pseudocode: to the nearest object vertex (0.025, 0.025, 0.003 away)
    assert mb.hand_object_distance(hand, obj, distance="vertex")[0] == pytest.approx(
        np.sqrt(2 * 0.025 ** 2 + 0.003 ** 2))
    assert mb.contact_frames_hand(hand, obj).tolist() == [True]
    assert mb.contact_frames_hand(hand, obj, distance="vertex").tolist() == [False]


def test_contact_is_with_the_nearest_of_several_objects():
    far_v, far_f = box([1.0, 0, 0], [1.05, 0.05, 0.05])
    hand = np.stack([hand_at_gap(2 * MM)])
    assert mb.contact_frames_hand(hand, [still(far_v, far_f, 1)]).tolist() == [False]
    assert mb.contact_frames_hand(hand, [still(far_v, far_f, 1), still(OBJ_V, OBJ_F, 1)]).tolist() == [True]
    # objects move: contact follows the posed vertices of each frame
    moving = posed([OBJ_V, OBJ_V - [0.1, 0, 0]], OBJ_F)
    assert mb.contact_frames_hand(np.stack([hand_at_gap(2 * MM)] * 2), [moving]).tolist() == [True, False]


def test_csr_is_the_contact_ratio_averaged_over_hands():
    assert mb.contact_surface_ratio([[1, 1, 0, 0], [True, False, False, False]]) == 0.375
    T = 2
    obj = still(OBJ_V, OBJ_F, T)
    hand_a = np.stack([hand_at_gap(1 * MM)] * T)                         # contact in both frames
    hand_b = np.stack([hand_at_gap(1 * MM), hand_at_gap(30 * MM)])       # in frame 0 only
    csr = mb.CSR()
    csr.update("clip0", [hand_a, hand_b], [obj])
    csr.update_frames("clip1", [[False, False]])
    assert csr.per_clip() == {"clip0": 0.75, "clip1": 0.0}
    assert csr.compute() == 0.375


# ====================================================================== CRR
def test_crr_needs_both_roots_near_one_object():
    # roots on the +x side of the object box, at the centre of the face: distance = x - 0.05
    near, far = 0.05 + 0.04, 0.05 + 0.06                                  # 4 cm and 6 cm
    xl = np.array([near, near, far, far])
    xr = np.array([near, far, near, far])
    left = np.stack([xl, np.full(4, 0.025), np.full(4, 0.025)], axis=1)
    right = np.stack([xr, np.full(4, 0.025), np.full(4, 0.025)], axis=1)
    obj = still(OBJ_V, OBJ_F, 4)
    d = mb.root_object_distances(np.stack([left, right], axis=1), [obj])
    np.testing.assert_allclose(d[:, :, 0], np.stack([xl, xr], axis=1) - 0.05, atol=1e-7)
    dv = mb.root_object_distances(left[:, None], [obj], distance="vertex")    # nearest corner
    assert dv[0, 0, 0] == pytest.approx(np.sqrt(0.04 ** 2 + 2 * 0.025 ** 2))
    assert mb.CRR_THRESHOLD_M == 0.05
    frames = mb.contact_frames_human_roots(left, right, [obj])
    assert frames.tolist() == [True, False, False, False]
    assert mb.contact_ratio(frames) == 0.25


def test_crr_same_object_rule():
    other_v, other_f = box([0.5, 0, 0], [0.55, 0.05, 0.05])
    objs = [still(OBJ_V, OBJ_F, 1), still(other_v, other_f, 1)]
    left = np.array([[-0.02, 0.025, 0.025]])             # 2 cm from the first box only
    right = np.array([[0.57, 0.025, 0.025]])             # 2 cm from the second box only
    assert mb.contact_frames_human_roots(left, right, objs).tolist() == [False]
    assert mb.contact_frames_human_roots(left, right, objs, same_object=False).tolist() == [True]


def test_crr_metric_averages_humans_then_clips():
    obj = still(OBJ_V, OBJ_F, 2)
    p_near = np.array([[0.07, 0.025, 0.025]] * 2)        # 2 cm from the object
    p_mixed = np.array([[0.07, 0.025, 0.025], [0.2, 0.025, 0.025]])
    crr = mb.CRR()
    crr.update("a", [(p_near, p_near), (p_near, p_mixed)], [obj])      # humans: 1.0 and 0.5
    crr.update_frames("b", [[0, 0, 0, 1]])
    assert crr.per_clip() == {"a": 0.75, "b": 0.25}
    assert crr.compute() == 0.5


# ====================================================================== CSIoU
def test_frame_iou_exact_fractions():
    assert mb.frame_iou([1, 0, 1, 1], [1, 0, 1, 1]) == 1.0
    assert mb.frame_iou([1, 1, 0, 0], [0, 0, 1, 1]) == 0.0
    assert mb.frame_iou([1, 1, 1, 1, 0, 0], [0, 0, 1, 1, 1, 0]) == 2 / 5
    assert mb.frame_iou([0, 0, 0], [0, 0, 0]) == 1.0                      # empty union: agree
    assert math.isnan(mb.frame_iou([0, 0, 0], [0, 0, 0], empty_union=None))


def test_csiou_averages_hands_and_handles_the_empty_union():
    gen = [[1, 1, 1, 1, 0, 0], [0] * 6]
    gt = [[0, 0, 1, 1, 1, 0], [0] * 6]
    assert mb.contact_surface_iou(gen, gt) == pytest.approx((0.4 + 1.0) / 2)
    assert mb.contact_surface_iou(gen, gt, empty_union=None) == 0.4       # hand left out
    assert math.isnan(mb.contact_surface_iou([[0, 0]], [[0, 0]], empty_union=None))
    m = mb.CSIoU(empty_union=None)
    m.update_frames("undefined", [[0, 0]], [[0, 0]])
    m.update_frames("defined", gen, gt)
    assert m.compute() == 0.4                                             # nan clip left out


def test_csiou_from_meshes():
    T = 5
    obj = still(OBJ_V, OBJ_F, T)
    gen_gaps = [1, 1, 1, 30, 30]        # mm: contact frames {0, 1, 2}
    gt_gaps = [30, 1, 1, 1, 30]         # {1, 2, 3}
    gen = np.stack([hand_at_gap(g * MM) for g in gen_gaps])
    gt = np.stack([hand_at_gap(g * MM) for g in gt_gaps])
    m = mb.CSIoU()
    m.update("c", [gen], [obj], [gt])                                     # GT objects = generated
    assert m.compute() == 2 / 4


# ====================================================================== IV
def test_iv_of_overlapping_boxes_within_the_voxel_bound_and_converging():
    a_v, a_f = box([0, 0, 0], [0.05, 0.05, 0.05])
    L = np.array([13.3, 21.7, 7.4]) * MM                  # the overlap is an L0 x L1 x L2 box
    b_v, b_f = box(np.array([0.05] * 3) - L, [0.09, 0.09, 0.09])
    true = L.prod()
    errors = {}
    for h in (4 * MM, 2 * MM, 0.5 * MM, 0.25 * MM):
        iv = mb.interpenetration_volume(a_v, a_f, b_v, b_f, voxel_m=h)
        # each side counts round(L / h) voxels: off by at most h / 2
        assert np.prod(L - h / 2) <= iv <= np.prod(L + h / 2)
        assert iv == mb.interpenetration_volume(b_v, b_f, a_v, a_f, voxel_m=h)   # symmetric
        errors[h] = abs(iv - true) / true
    assert max(errors[0.5 * MM], errors[0.25 * MM]) < min(errors[4 * MM], errors[2 * MM])
    assert errors[0.25 * MM] < 0.02


def test_iv_exact_when_the_overlap_is_voxel_aligned_and_zero_when_apart():
    a_v, a_f = box([0, 0, 0], [0.05, 0.05, 0.05])
    b_v, b_f = box([0.04, 0.03, 0.045], [0.09, 0.09, 0.09])  # overlap 10 x 20 x 5 mm
    assert mb.interpenetration_volume(a_v, a_f, b_v, b_f) == pytest.approx(1e-6, rel=1e-12)
    c_v, c_f = box([0.06, 0, 0], [0.08, 0.05, 0.05])
    assert mb.interpenetration_volume(a_v, a_f, c_v, c_f) == 0.0
    inner_v, inner_f = box([0.01, 0.01, 0.01], [0.03, 0.02, 0.035])      # inside a: its own volume
    assert mb.interpenetration_volume(a_v, a_f, inner_v, inner_f, voxel_m=1 * MM) == pytest.approx(
        0.02 * 0.01 * 0.025, rel=1e-12)


def test_corner_iv_is_the_cut_tetrahedron():
    # a cube corner pushed d along the body diagonal cuts a tetrahedron of volume sqrt(3)/2 d^3
    d = 3 * MM
    c_v, c_f = corner_cube(0.01, d, 0.05, (0.025, 0.025))
    iv = mb.interpenetration_volume(c_v, c_f, OBJ_V, OBJ_F, voxel_m=0.2 * MM)
    assert iv == pytest.approx(np.sqrt(3) / 2 * d ** 3, rel=0.03)


def test_clip_iv_reduces_pairs_then_averages_frames():
    # bodies: a, b overlapping by 10x10x5 mm (0.5 cm^3), a, c by 20x10x5 mm (1 cm^3), b, c apart;
    # frame 1 has everything apart
    a_v, a_f = box([0, 0, 0], [0.05, 0.05, 0.05])
    b_v, b_f = box([0.04, 0.04, 0.045], [0.09, 0.09, 0.09])
    c_v, c_f = box([-0.04, -0.04, 0.045], [0.02, 0.01, 0.09])
    away = np.array([1.0, 0, 0])
    bodies = [posed([a_v, a_v], a_f), posed([b_v, b_v + away], b_f), posed([c_v, c_v - away], c_f)]
    p = mb.pairwise_penetration(bodies, depth=False)
    assert p.pairs == ((0, 1), (0, 2), (1, 2))
    np.testing.assert_allclose(p.volume_m3 * 1e6, [[0.5, 1.0, 0.0], [0, 0, 0]], rtol=1e-12)
    assert mb.clip_interpenetration_volume(bodies) == pytest.approx((0.5 + 1.0) / 2)
    assert mb.clip_interpenetration_volume(bodies, pair_reduction="max") == pytest.approx(1.0 / 2)
    assert mb.clip_interpenetration_volume(bodies, pair_reduction="mean") == pytest.approx(1.5 / 3 / 2)
    assert mb.clip_interpenetration_volume(bodies, pairs=[(1, 2)]) == 0.0
    iv = mb.InterpenetrationVolume()
    iv.update("clip", bodies)
    assert iv.compute() == pytest.approx(0.75)


# ====================================================================== ID
def test_id_of_a_corner_pushed_a_known_depth():
    for d in (1 * MM, 3 * MM):
        c_v, c_f = corner_cube(0.01, d, 0.05, (0.025, 0.025))
        assert mb.interpenetration_depth(c_v, c_f, OBJ_V, OBJ_F) == pytest.approx(d, abs=1e-6)
        assert mb.interpenetration_depth(OBJ_V, OBJ_F, c_v, c_f) == pytest.approx(d, abs=1e-6)
    c_v, c_f = corner_cube(0.01, -1 * MM, 0.05, (0.025, 0.025))           # 1 mm short: no contact
    assert mb.interpenetration_depth(c_v, c_f, OBJ_V, OBJ_F) == 0.0


def test_id_of_a_box_inside_another_is_its_deepest_vertex():
    inner_v, inner_f = box([0.01, 0.01, 0.01], [0.02, 0.02, 0.02])
    # deepest inner vertex (0.02, 0.02, 0.02): 2 cm from the faces x = y = z = 0
    assert mb.interpenetration_depth(inner_v, inner_f, OBJ_V, OBJ_F) == pytest.approx(0.02, abs=1e-6)


def test_clip_id_sums_pairs_and_averages_frames():
    c1_v, c1_f = corner_cube(0.01, 2 * MM, 0.05, (0.025, 0.025))
    c2_v, c2_f = corner_cube(0.01, 4 * MM, 0.05, (0.025, 0.025))
    c2_v = c2_v + [0.0, 0.0, 1.0]                                   # a second object box, far up
    o2_v = OBJ_V + [0.0, 0.0, 1.0]
    bodies = [still(OBJ_V, OBJ_F, 2), posed([c1_v, c1_v + [0.1, 0, 0]], c1_f), still(o2_v, OBJ_F, 2),
              still(c2_v, c2_f, 2)]
    pairs = [(0, 1), (2, 3), (0, 3)]
    p = mb.pairwise_penetration(bodies, pairs, volume=False)
    np.testing.assert_allclose(p.depth_m, [[2 * MM, 4 * MM, 0], [0, 4 * MM, 0]], atol=1e-6)
    assert mb.clip_interpenetration_depth(bodies, pairs) == pytest.approx((6 + 4) / 2, abs=1e-3)
    assert mb.clip_interpenetration_depth(bodies, pairs, pair_reduction="max") == pytest.approx(4, abs=1e-3)
    m = mb.InterpenetrationDepth()
    m.update("clip", bodies, pairs)
    assert m.compute() == pytest.approx(5.0, abs=1e-3)


def test_open_meshes_are_refused_for_penetration():
    v, f = box([0, 0, 0], [0.01, 0.01, 0.01])
    bodies = [still(OBJ_V, OBJ_F, 1), still(v, f[:-1], 1)]              # one face missing
    with pytest.raises(ValueError, match=r"bodies\[1\]\.faces.*not closed"):
        mb.pairwise_penetration(bodies)
    with pytest.raises(ValueError, match=r"faces_b.*not closed"):
        mb.interpenetration_depth(OBJ_V, OBJ_F, v, f[:-1])
    flipped = f.copy()
    flipped[0] = flipped[0, ::-1]
    with pytest.raises(ValueError, match=r"faces_a.*twice"):
        mb.interpenetration_volume(v, flipped, OBJ_V, OBJ_F)
    mb.pairwise_penetration(bodies, check_closed_meshes=False)           # allowed when asked


# ====================================================================== SD / OD
def _traj(offset, T=4):
    return np.tile(np.asarray(offset, float), (T, 1))


A, B, C = _traj([0, 0, 0]), _traj([3, 0, 0]), _traj([0, 4, 0])     # per-frame distances 3, 4, 5


def test_mean_pairwise_distance_both_modes():
    x = np.stack([A, B, C])[:, :, None, :]
    assert mb.mean_pairwise_distance(x, "per_frame") == pytest.approx(4.0)
    # diffh2o: |flattened difference| / T = sqrt(T) d / T = d / 2 for T = 4
    assert mb.mean_pairwise_distance(x, "diffh2o") == pytest.approx(2.0)


def test_sd_and_od_on_known_trajectories():
    prompts = [[A, B], [A, B, C]]
    assert mb.sample_diversity(prompts, num_frames=None, mode="per_frame") == pytest.approx((3 + 4) / 2)
    # all five: pairs A-B x4 (3), A-A and B-B (0), A-C x2 (4), B-C x2 (5): 30 / 10
    everything = [A, B, A, B, C]
    assert mb.overall_diversity(everything, num_frames=None, mode="per_frame") == pytest.approx(3.0)
    assert mb.overall_diversity(everything, num_frames=None) == pytest.approx(1.5)
    sd = mb.SampleDiversity(num_frames=None, mode="per_frame")
    sd.update("p0", [A, B])
    sd.update("p1", np.stack([A, B, C]))
    assert sd.compute() == pytest.approx(3.5)
    od = mb.OverallDiversity(num_frames=None, mode="per_frame")
    for k, t in enumerate(everything):
        od.update(("split", k), t)
    assert od.compute() == pytest.approx(3.0)


def test_diffh2o_frame_subset_and_two_wrists():
    assert mb.downsample_indices(31, 15).tolist() == list(range(0, 30, 2))
    assert mb.downsample_indices(45, 15).tolist() == list(range(0, 45, 3))
    t = np.arange(31, dtype=float)[:, None] * np.ones(3)
    np.testing.assert_array_equal(mb.wrist_trajectory(t)[:, 0, 0], np.arange(0, 30, 2))
    # two wrists, each offset by 3 m from the other sample: per-frame distance 3
    two = np.stack([A, A], axis=1)
    assert mb.mean_pairwise_distance(np.stack([two, two + [3, 0, 0]]), "per_frame") == pytest.approx(3.0)
    # (T, 3) is one wrist
    np.testing.assert_array_equal(mb.wrist_trajectory(A, None), A[:, None, :])


# ====================================================================== merging
def _clip_ids(n):
    return [f"clip{i:02d}" for i in range(n)]


def _feed(make, items, update):
    m = make()
    for key, args in items:
        update(m, key, *args)
    return m


MERGE_CASES = {
    "csr": (lambda: mb.CSR(), lambda m, k, f: m.update_frames(k, f),
            lambda rs: (list(rs.random((2, 7)) < 0.5),)),
    "crr": (lambda: mb.CRR(), lambda m, k, f: m.update_frames(k, f),
            lambda rs: (list(rs.random((3, 5)) < 0.3),)),
    "csiou": (lambda: mb.CSIoU(), lambda m, k, f, g: m.update_frames(k, f, g),
              lambda rs: (list(rs.random((2, 9)) < 0.5), list(rs.random((2, 9)) < 0.5))),
    "iv": (lambda: mb.InterpenetrationVolume(), lambda m, k, v: m.update_pairs(k, v),
           lambda rs: (rs.random((6, 3)) * 1e-6,)),
    "id": (lambda: mb.InterpenetrationDepth(pair_reduction="max"), lambda m, k, v: m.update_pairs(k, v),
           lambda rs: (rs.random((6, 3)) * 1e-2,)),
    "sd": (lambda: mb.SampleDiversity(), lambda m, k, s: m.update(k, s),
           lambda rs: (rs.normal(size=(3, 40, 2, 3)),)),
    "od": (lambda: mb.OverallDiversity(mode="per_frame"), lambda m, k, t: m.update(k, t),
           lambda rs: (rs.normal(size=(33, 2, 3)),)),
}


@pytest.mark.parametrize("name", sorted(MERGE_CASES))
def test_merged_shards_equal_serial_bit_for_bit(name):
    make, update, draw = MERGE_CASES[name]
    rs = np.random.RandomState(7)
    items = [(k, draw(rs)) for k in _clip_ids(10)]
    serial = _feed(make, items, update).compute()
    shuffled = [items[i] for i in np.random.RandomState(1).permutation(len(items))]
    assert _feed(make, shuffled, update).compute() == serial                # feed order is irrelevant
    shards = [_feed(make, shuffled[s::3], update) for s in range(3)]
    for order in itertools.permutations(range(3)):
        assert Metric.merged([shards[i] for i in order]).compute() == serial
    with pytest.raises(ValueError, match="two shards"):
        Metric.merged([shards[0], shards[0]])


def test_merge_from_meshes_and_config_mismatch():
    a_v, a_f = box([0, 0, 0], [0.05, 0.05, 0.05])
    clips = {f"c{i}": [still(a_v, a_f, 1), still(*box([0.05 - 0.005 * (i + 1), 0, 0], [0.09, 0.01, 0.01]), 1)]
             for i in range(3)}
    serial = mb.InterpenetrationVolume()
    for k, bodies in clips.items():
        serial.update(k, bodies)
    shards = []
    for k, bodies in reversed(list(clips.items())):
        s = mb.InterpenetrationVolume()
        s.update(k, bodies)
        shards.append(s)
    assert Metric.merged(shards).compute() == serial.compute() == pytest.approx((0.5 + 1.0 + 1.5) / 3)
    with pytest.raises(ValueError, match="configurations differ"):
        Metric.merged([mb.CSR(), mb.CSR(threshold_m=0.002)])


# ====================================================================== invalid input
_HAND = np.stack([hand_at_gap(0.001)] * 2)
_OBJ = still(OBJ_V, OBJ_F, 2)
_NAN_HAND = _HAND.copy()
_NAN_HAND[1, 3, 0] = np.nan
_BAD_FACES = OBJ_F.copy()
_BAD_FACES[0, 0] = 8
_ROOT = np.array([[0.07, 0.025, 0.025]] * 2)


def _od_one():
    m = mb.OverallDiversity(num_frames=None)
    m.update("x", A)
    return m.compute()


def _duplicate_clip():
    m = mb.CSR()
    m.update_frames("x", [[1, 0]])
    m.update("x", [_NAN_HAND], [_OBJ])          # refused for the id before the geometry is read


INVALID = [
    (lambda: mb.contact_frames_hand(_NAN_HAND, [_OBJ]), r"hand_vertices: 1 non-finite"),
    (lambda: mb.contact_frames_hand(_HAND[..., :2], [_OBJ]), r"hand_vertices: expected shape"),
    (lambda: mb.contact_frames_hand(np.zeros((2, 0, 3)), [_OBJ]), r"hand_vertices: empty"),
    (lambda: mb.contact_frames_hand(_HAND, []), r"object_meshes: empty"),
    (lambda: mb.contact_frames_hand(_HAND, [(_OBJ.vertices, _BAD_FACES)]), r"object_meshes\[0\]\.faces: indices"),
    (lambda: mb.contact_frames_hand(_HAND, [(_OBJ.vertices, OBJ_F.astype(float))]),
     r"object_meshes\[0\]\.faces: expected integer"),
    (lambda: mb.contact_frames_hand(_HAND, [still(OBJ_V, OBJ_F, 3)]), r"object_meshes\[0\]\.vertices: expected 2"),
    (lambda: mb.contact_frames_hand(_HAND, [OBJ_V]), r"object_meshes\[0\]"),
    (lambda: mb.contact_frames_hand(_HAND, [_OBJ], threshold_m=-0.001), r"threshold_m"),
    (lambda: mb.contact_frames_hand(_HAND, [_OBJ], threshold_m=float("nan")), r"threshold_m"),
    (lambda: mb.contact_frames_human_roots(_ROOT + [np.inf, 0, 0], _ROOT, [_OBJ]), r"left_root: 2 non-finite"),
    (lambda: mb.contact_frames_human_roots(_ROOT, _ROOT[:1], [_OBJ]), r"right_root: expected 2 frames"),
    (lambda: mb.CRR().update("c", [(_ROOT,)], [_OBJ]), r"roots\[0\]: expected a \(left_root, right_root\)"),
    (lambda: mb.CRR().update("c", [(_ROOT, _ROOT[:, :2])], [_OBJ]), r"roots\[0\]: right_root"),
    (lambda: mb.frame_iou([1, 0, 1], [1, 0]), r"gt_frames: expected 3 frames"),
    (lambda: mb.frame_iou([1, 2, 0], [1, 0, 0]), r"frames: expected booleans"),
    (lambda: mb.contact_surface_iou([[1, 0]], [[1, 0], [0, 0]]), r"gt_frames_per_hand: expected 1 hands"),
    (lambda: mb.contact_surface_ratio([[1, 0], [1, 0, 0]]), r"frames_per_hand: bodies have different"),
    (lambda: mb.contact_surface_ratio([]), r"frames_per_hand: empty"),
    (lambda: mb.CSIoU(empty_union=2.0), r"empty_union"),
    (lambda: mb.CSR(distance="chamfer"), r"distance: expected one of"),
    (lambda: mb.root_object_distances(_ROOT[:, None], [_OBJ], distance="mesh"), r"distance: expected one of"),
    (lambda: mb.interpenetration_volume(OBJ_V, OBJ_F, OBJ_V, OBJ_F, voxel_m=0), r"voxel_m"),
    (lambda: mb.interpenetration_volume(OBJ_V, OBJ_F, OBJ_V * np.nan, OBJ_F), r"vertices_b: 24 non-finite"),
    (lambda: mb.interpenetration_depth(OBJ_V, OBJ_F[:, :2], OBJ_V, OBJ_F), r"faces_a: expected shape"),
    (lambda: mb.interpenetration_depth(OBJ_V, OBJ_F, OBJ_V, OBJ_F, nsamples=2), r"nsamples"),
    (lambda: mb.pairwise_penetration([_OBJ]), r"bodies: need at least two"),
    (lambda: mb.pairwise_penetration([_OBJ, _OBJ], pairs=[(0, 0)]), r"pairs\[0\]"),
    (lambda: mb.pairwise_penetration([_OBJ, still(OBJ_V, OBJ_F, 3)]), r"bodies: bodies have different frame"),
    (lambda: mb.InterpenetrationVolume(pair_reduction="median"), r"pair_reduction"),
    (lambda: mb.InterpenetrationDepth().update_pairs("c", np.full((2, 1), np.nan)), r"depth_m: 2 non-finite"),
    (lambda: mb.InterpenetrationVolume().update_pairs("c", -np.ones((2, 1))), r"volume_m3: penetration"),
    (lambda: mb.mean_pairwise_distance(np.zeros((1, 4, 1, 3))), r"trajectories: need at least 2"),
    (lambda: mb.mean_pairwise_distance(np.zeros((2, 4, 1, 3)), mode="l1"), r"mode"),
    (lambda: mb.wrist_trajectory(np.full((20, 3), np.inf)), r"trajectory: 60 non-finite"),
    (lambda: mb.wrist_trajectory(np.zeros((14, 3))), r"trajectory: 14 frames, fewer than num_frames=15"),
    (lambda: mb.wrist_trajectory(np.zeros((20, 2))), r"trajectory: expected shape"),
    (lambda: mb.sample_diversity([[A, A[:3]]], num_frames=None), r"samples_per_prompt\[0\]: trajectories differ"),
    (lambda: mb.SampleDiversity(num_frames=0), r"num_frames"),
    (lambda: mb.downsample_indices(10, 15), r"frames: 10, fewer than num_frames=15"),
    (lambda: mb.SampleDiversity().update("p", [np.zeros((20, 3))]), r"trajectories: need at least 2"),
    (lambda: mb.SampleDiversity().update("p", [A, np.zeros((20, 3))]), r"trajectories\[0\]: 4 frames"),
    (_od_one, r"need at least 2 trajectories"),
    (lambda: mb.CSR().update_frames(["unhashable"], [[1, 0]]), r"clip_id: expected a hashable"),
    (_duplicate_clip, r"clip_id: clip 'x' was already added"),
    (lambda: mb.CSR().compute(), r"no clips"),
]


@pytest.mark.parametrize("call, match", INVALID, ids=[m for _, m in INVALID])
def test_invalid_input_raises_naming_the_field(call, match):
    with pytest.raises(ValueError, match=match):
        call()
