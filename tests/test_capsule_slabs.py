"""The multi-body IV counts an overlap too large for one grid part pair by part pair (bounded
memory, time proportional to where the parts meet) with the same result as one grid."""
from __future__ import annotations

import numpy as np
import pytest

from hoibench.bodies import capsules as C
from hoibench.bodies.multibody import Body, MultiBodyClip


def _hand(name, J):
    return Body(name, "hand", J[:, 0].copy(), None, J, None, name)


def _both_ways(clip, fields, monkeypatch):
    """(volumes on one grid, volumes part pair by part pair) of bodies 0 and 1."""
    monkeypatch.setattr(C, "GRID_BLOCK_VOXELS", 10 ** 9)
    one = C.pair_penetration(clip, 0, 1, fields)
    monkeypatch.setattr(C, "GRID_BLOCK_VOXELS", 50)             # every overlap goes by parts, in tiny blocks
    return one, C.pair_penetration(clip, 0, 1, fields)


def test_part_pairs_count_the_same_voxels_as_one_grid_for_two_hands(monkeypatch):
    rng = np.random.default_rng(3)
    J = rng.normal(0, 0.03, (2, 21, 3))                         # two frames of a crumpled hand
    clip = MultiBodyClip("c", "t", "s", 20.0, [_hand("left", J), _hand("right", J + 0.004)])
    (vol, dep), (vol2, dep2) = _both_ways(clip, {}, monkeypatch)
    assert (vol > 0).all() and (dep > 0).all()
    assert np.array_equal(vol, vol2) and np.array_equal(dep, dep2)


def test_part_pairs_count_the_same_voxels_as_one_grid_for_a_hand_in_an_object(monkeypatch):
    trimesh = pytest.importorskip("trimesh")
    m = trimesh.creation.box(extents=(0.08, 0.06, 0.1))
    tmpl = {"box": (np.asarray(m.vertices), np.asarray(m.faces))}
    fields = {"box": C.ObjectField(*tmpl["box"])}
    box = Body("box", "object", np.zeros((2, 3)), np.repeat(np.eye(3)[None], 2, 0), None, "box")
    J = np.random.default_rng(5).normal(0, 0.03, (2, 21, 3)) + np.array([0.03, 0.0, 0.0])
    clip = MultiBodyClip("c", "t", "s", 20.0, [_hand("right", J), box], tmpl)
    (vol, dep), (vol2, dep2) = _both_ways(clip, fields, monkeypatch)
    assert (vol > 0).all() and np.array_equal(vol, vol2) and np.array_equal(dep, dep2)


def test_far_flung_hands_count_the_same_by_parts_as_on_one_grid(monkeypatch):
    """Two untrained-looking hands, joints scattered over a 1 m cube: their boxes overlap over
    about 10^6 voxels of 1 cm, where only a few capsules meet."""
    rng = np.random.default_rng(11)
    J, K = rng.uniform(-0.5, 0.5, (1, 21, 3)), rng.uniform(-0.5, 0.5, (1, 21, 3))
    clip = MultiBodyClip("c", "t", "s", 20.0, [_hand("left", J), _hand("right", K)])
    monkeypatch.setattr(C, "GRID_BLOCK_VOXELS", 10 ** 9)
    (vol, dep) = C.pair_penetration(clip, 0, 1, {}, voxel_m=0.01)
    monkeypatch.setattr(C, "GRID_BLOCK_VOXELS", 20_000)
    (vol2, dep2) = C.pair_penetration(clip, 0, 1, {}, voxel_m=0.01)
    assert dep[0] > 0 and vol[0] > 0 and np.array_equal(vol, vol2) and np.array_equal(dep, dep2)
    # denser: many capsules of one hand meet several of the other's
    J, K = J * 0.2, K * 0.2
    clip = MultiBodyClip("c", "t", "s", 20.0, [_hand("left", J), _hand("right", K)])
    a, b, r = C.segments(J, "hand")
    a2, b2, r2 = C.segments(K, "hand")
    meeting = C.segment_segment_distance(a[0][:, None], b[0][:, None], a2[0][None], b2[0][None]) < r[:, None] + r2
    assert meeting.sum() >= 4 and (meeting.sum(1) >= 2).any()
    monkeypatch.setattr(C, "GRID_BLOCK_VOXELS", 10 ** 9)
    vol, _ = C.pair_penetration(clip, 0, 1, {}, voxel_m=0.002)
    monkeypatch.setattr(C, "GRID_BLOCK_VOXELS", 1000)
    vol2, _ = C.pair_penetration(clip, 0, 1, {}, voxel_m=0.002)
    assert vol[0] > 0 and vol2[0] == vol[0]


def test_segment_segment_distance_matches_known_cases_and_dense_sampling():
    d = C.segment_segment_distance
    o, x, y = np.zeros(3), np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    z = np.array([0, 0, 0.3])
    assert d(-x, x, -y + z, y + z) == pytest.approx(0.3)                 # crossing, 0.3 apart
    assert d(o, x, o + 2 * x + z, 3 * x + z) == pytest.approx(np.hypot(1.0, 0.3))   # collinear-ish: endpoints
    assert d(o, x, y, x + y) == pytest.approx(1.0)                       # parallel
    assert d(o, o, y, y) == pytest.approx(1.0)                           # two points
    rng = np.random.default_rng(2)
    p1, q1, p2, q2 = rng.normal(size=(4, 50, 3))
    s = np.linspace(0, 1, 401)
    A = p1[:, None] + (q1 - p1)[:, None] * s[None, :, None]
    B = p2[:, None] + (q2 - p2)[:, None] * s[None, :, None]
    brute = np.linalg.norm(A[:, :, None] - B[:, None], axis=-1).min((1, 2))
    got = d(p1, q1, p2, q2)
    assert (got <= brute + 1e-12).all() and np.allclose(got, brute, atol=0.01)
