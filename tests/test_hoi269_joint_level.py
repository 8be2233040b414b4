"""hoi269 (HOI-Diff reference, object frame handling) and joint_level (exact round trips)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hoibench.core import geometry as geo
from hoibench.core import skeleton as sk
from hoibench.datasets.random_motion import random_motion
from hoibench.representations import hml263, hoi269, joint_level, normalization

REFERENCE = np.load(Path(__file__).parent / "data" / "hoi269_reference.npz")


def _object_track(joints, seed=0):
    rng = np.random.default_rng(seed)
    T = len(joints)
    t = np.arange(T) / 20.0
    aa = np.stack([0.3 * np.sin(t), 0.5 + 0.4 * t, 0.2 * np.cos(2 * t)], -1)
    trans = joints[:, 0] + np.array([0.1, 0.2, 0.4]) + 0.01 * rng.standard_normal((T, 3))
    return aa, trans


@pytest.mark.parametrize("clip", str(REFERENCE["clips"]).split(","))
def test_legacy_equals_hoidiff_reference(clip):
    f = hoi269.encode(REFERENCE[f"{clip}__input"], REFERENCE[f"{clip}__obj_rotvec"],
                      REFERENCE[f"{clip}__obj_trans"], mode="legacy")
    ref = REFERENCE[f"{clip}__features"]
    assert f.shape == ref.shape
    np.testing.assert_allclose(f[:, :259], ref[:, :259], rtol=0, atol=3e-5)
    np.testing.assert_array_equal(f[:, 259:263], ref[:, 259:263])
    np.testing.assert_allclose(f[:, 263:], ref[:, 263:], rtol=0, atol=1e-6)


def test_clean_object_is_rigidly_attached_to_the_canonical_body():
    # object vertices relative to the body must be the same before and after canonicalising
    x = random_motion(60, seed=4)
    aa, trans = _object_track(x)
    f = hoi269.encode(x, aa, trans, mode="clean")
    joints, rot, t = hoi269.decode(f)
    verts = np.array([[0.2, 0.0, 0.0], [0.0, 0.3, -0.1], [0.05, -0.1, 0.25]])
    world = geo.apply_rigid(geo.axis_angle_to_matrix(aa[:-1]), trans[:-1], verts[None])
    canon = geo.apply_rigid(rot, t, verts[None])
    # distances from each vertex to each joint are frame-invariant under a rigid change
    d_world = np.linalg.norm(world[:, :, None] - x[:-1, None], axis=-1)
    d_canon = np.linalg.norm(canon[:, :, None] - joints[:, None], axis=-1)
    np.testing.assert_allclose(d_canon, d_world, atol=2e-5)


def test_legacy_leaves_object_rotation_in_world_frame():
    x = random_motion(30, seed=9)  # does not face +Z initially
    aa, trans = _object_track(x)
    legacy = hoi269.encode(x, aa, trans, mode="legacy")
    np.testing.assert_allclose(legacy[:, hoi269.OBJ_ROTVEC], aa[:-1], atol=1e-6)
    clean = hoi269.encode(x, aa, trans, mode="clean")
    assert np.abs(clean[:, hoi269.OBJ_ROTVEC] - aa[:-1]).max() > 0.1


def test_matrix_and_axis_angle_object_input_agree_in_clean_mode():
    x = random_motion(20, seed=1)
    aa, trans = _object_track(x)
    a = hoi269.encode(x, aa, trans)
    b = hoi269.encode(x, geo.axis_angle_to_matrix(aa), trans)
    np.testing.assert_allclose(a, b, atol=1e-6)


def test_hoi269_rejects_bad_object_input():
    x = random_motion(10, seed=0)
    aa, trans = _object_track(x)
    with pytest.raises(ValueError, match="obj_trans: non-finite"):
        bad = trans.copy(); bad[3, 1] = np.nan
        hoi269.encode(x, aa, bad)
    with pytest.raises(ValueError, match="obj_rot: expected rotation matrices"):
        hoi269.encode(x, np.tile(np.eye(3) * 2.0, (10, 1, 1)), trans)
    with pytest.raises(ValueError, match="leading dims"):
        hoi269.encode(x, aa[:5], trans[:5])


def test_joint_level_roundtrips_are_exact():
    xs = random_motion(40, seed=6, batch=2)
    aa, trans = zip(*(_object_track(x, i) for i, x in enumerate(xs)))
    f = hoi269.encode(xs, np.stack(aa), np.stack(trans))
    jl = joint_level.from_hoi269(f)
    assert jl.shape == (2, 39, 24, 12) and jl.dtype == np.float32
    np.testing.assert_array_equal(joint_level.to_hoi269(jl), f)
    back, glob = joint_level.to_hoi269(jl, return_global_root=True)
    np.testing.assert_array_equal(joint_level.from_hoi269(back, global_root=glob), jl)
    h = f[..., :263]
    np.testing.assert_array_equal(joint_level.to_hoi269(joint_level.from_hoi269(h), with_object=False), h)


def test_joint_level_layout_matches_chainhoi():
    x = random_motion(30, seed=2)
    aa, trans = _object_track(x)
    f = hoi269.encode(x, aa, trans)
    jl = joint_level.from_hoi269(f)
    np.testing.assert_array_equal(jl[:, 0, :4], f[:, :4])
    np.testing.assert_array_equal(jl[:, 0, 4:7], f[:, 193:196])
    np.testing.assert_array_equal(jl[:, 5, 0:3], f[:, 4 + 4 * 3: 4 + 5 * 3])      # joint 5 ric
    np.testing.assert_array_equal(jl[:, 5, 3:9], f[:, 67 + 4 * 6: 67 + 5 * 6])    # joint 5 rot6d
    np.testing.assert_array_equal(jl[:, 5, 9:12], f[:, 193 + 5 * 3: 193 + 6 * 3])  # joint 5 vel
    np.testing.assert_array_equal(jl[:, 22, :4], f[:, 259:263])
    assert not jl[:, 22, 4:].any() and not jl[:, 23, 6:].any() and not jl[:, 0, 11].any()
    np.testing.assert_array_equal(jl[:, 23, :6], f[:, 263:269])
    # global root = decoded root; yaw rotates world into the heading frame
    joints = hml263.decode(f[:, :263])
    np.testing.assert_allclose(jl[:, 0, 8:11], joints[:, 0], atol=1e-5)
    yaw = jl[:, 0, 7].astype(np.float64)
    local = f[:, 4:67].reshape(-1, 21, 3).astype(np.float64)
    world_rel = joints[:, 1:] - joints[:, :1] * np.array([1, 0, 1])
    rotated = np.einsum("tij,tkj->tki", geo.rotation_about_y(yaw), world_rel)
    np.testing.assert_allclose(rotated, local, atol=1e-5)


def test_normalisation_grouped_std_and_chunking():
    xs = random_motion(30, seed=1, batch=4)
    feats = list(hml263.encode(xs))
    stats = normalization.compute_stats(feats, mode="legacy")
    cat = np.concatenate(feats).astype(np.float64)
    np.testing.assert_allclose(stats.mean, cat.mean(0), atol=1e-6)
    for sl in hml263.GROUPS.values():
        np.testing.assert_allclose(stats.std[sl], cat.std(0)[sl].mean(), rtol=1e-5)
    again = normalization.compute_stats([np.concatenate(feats[:2]), *feats[2:]], mode="legacy")
    np.testing.assert_allclose(again.std, stats.std, rtol=1e-6)
    assert stats.count == len(cat)


def test_normalisation_clean_guards_zero_std_groups():
    still = np.repeat(random_motion(2, seed=0)[:1], 10, axis=0)
    feats = [hml263.encode(still)]
    legacy = normalization.compute_stats(feats, mode="legacy")
    clean = normalization.compute_stats(feats, mode="clean")
    assert legacy.std[259] == 0.0 and clean.std[259] == 1.0
    assert np.isfinite(clean.normalize(feats[0])).all()
    np.testing.assert_allclose(clean.denormalize(clean.normalize(feats[0])), feats[0], atol=1e-6)
    assert len(clean.sha256()) == 64 and clean.sha256() != legacy.sha256()


def test_hoi_graph_edges():
    edges = sk.hoi_graph_edges()
    assert len(edges) == 21 + 4 + 8
    adj = sk.hoi_graph_adjacency(self_loops=False)
    assert (adj == adj.T).all() and adj[22].sum() == 4 and adj[23].sum() == 8
    assert set(np.flatnonzero(adj[23])) == {0, 10, 11, 12, 16, 17, 20, 21}


def test_reference_offsets_are_consistent_with_chains_and_raw_directions():
    # every reference offset is its length times the raw unit direction
    lengths = np.linalg.norm(sk.REFERENCE_TARGET_OFFSETS, axis=1)
    np.testing.assert_allclose(sk.RAW_OFFSETS * lengths[:, None], sk.REFERENCE_TARGET_OFFSETS, atol=1e-7)
    for chain in sk.KINEMATIC_CHAINS:
        for p, c in zip(chain[:-1], chain[1:]):
            assert sk.PARENTS[c] == p
    rest = sk.joints_from_offsets(sk.offsets_from_joints(sk.SMPL_REST_JOINTS), sk.SMPL_REST_JOINTS[0])
    np.testing.assert_allclose(rest, sk.SMPL_REST_JOINTS, atol=1e-12)
