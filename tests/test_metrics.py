"""Metrics (hoibench.metrics): the claims.

* The embedding metrics equal text-to-motion's reference implementation on seeded random
  embeddings (tests/data/metrics_reference.npz, produced as tests/data/README.md says).
* Physical metrics give the analytic value on constructed cases: a joint at a known signed
  distance from a box, a body pushed a known depth into a box, a foot sliding at a known speed.
* A synthetic clip with an injected defect scores worse on the metric aimed at it.
* Sharded and merged state equals the whole-data computation; a process pool (and local Dask
  when installed) equals a serial run bit for bit.
"""
from __future__ import annotations

import copy
import importlib.util
from pathlib import Path

import numpy as np
import pytest

from hoibench import metrics as M
from hoibench.metrics import embedding as E
from hoibench.metrics import motion as mo
from hoibench.metrics.state import Metric

REF = Path(__file__).parent / "data" / "metrics_reference.npz"


@pytest.fixture(scope="module")
def ref():
    with np.load(REF, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


# ====================================================================== reference equivalence
def test_fid_equals_reference(ref):
    assert E.fid(ref["fid_real"], ref["fid_gen"], method="sqrtm") == pytest.approx(float(ref["fid_expected"]),
                                                                                  rel=1e-10)
    # the fast exact form (default) agrees with the reference's numbers
    assert E.fid(ref["fid_real"], ref["fid_gen"]) == pytest.approx(float(ref["fid_expected"]), rel=1e-10)
    mu, sigma = E.activation_statistics(ref["fid_real"])
    np.testing.assert_allclose(mu, ref["fid_real_mu"], rtol=1e-14)
    np.testing.assert_allclose(sigma, ref["fid_real_sigma"], rtol=1e-12)


def test_fid_with_rank_deficient_covariances_equals_reference(ref):
    # fewer samples than dimensions: sqrtm returns a complex matrix, its imaginary part is dropped
    got = E.fid(ref["fid_small_real"], ref["fid_small_gen"], method="sqrtm")
    assert got == pytest.approx(float(ref["fid_small_expected"]), rel=1e-8)
    # the eigendecomposition form needs no complex detour and agrees to 1e-6 relative
    assert E.fid(ref["fid_small_real"], ref["fid_small_gen"]) == pytest.approx(float(ref["fid_small_expected"]),
                                                                              rel=1e-6)


@pytest.mark.parametrize("n, d, seed", [(40, 64, 0), (300, 64, 1), (20, 128, 2), (2000, 32, 3)])
def test_trace_of_the_product_square_root_equals_sqrtm(n, d, seed):
    from scipy import linalg
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(n, d)) @ rng.normal(size=(d, d)) * 0.3
    b = rng.normal(size=(n, d)) * 1.2 + 0.1
    s1, s2 = np.cov(a, rowvar=False), np.cov(b, rowvar=False)
    want = np.trace(linalg.sqrtm(s1 @ s2)).real
    assert E.trace_sqrt_product(s1, s2) == pytest.approx(want, rel=1e-6)
    mu1, mu2 = a.mean(0), b.mean(0)
    assert E.frechet_distance(mu1, s1, mu2, s2) == pytest.approx(
        E.frechet_distance(mu1, s1, mu2, s2, method="sqrtm"), rel=1e-6)
    with pytest.raises(ValueError, match="method"):
        E.frechet_distance(mu1, s1, mu2, s2, method="svd")


def test_r_precision_and_mm_dist_equal_reference_pooled_as_final_evaluations(ref):
    pools = list(ref["rp_pools"])
    np.testing.assert_allclose(E.r_precision(ref["rp_text"], ref["rp_motion"], pools), ref["rp_expected"],
                               rtol=0, atol=0)
    for p, hits in zip(pools, ref["rp_pool_hits_expected"]):
        np.testing.assert_array_equal(E.pool_hits(ref["rp_text"][p], ref["rp_motion"][p])[0], hits)
    mm = E.mm_dist(ref["rp_text"], ref["rp_motion"], pools)
    assert mm == pytest.approx(float(ref["mm_dist_expected"]), rel=1e-13)
    first = pools[0]
    np.testing.assert_array_equal(E.pool_hits(ref["rp_text"][first], ref["rp_motion"][first])[0],
                                  ref["rp_calc_first_pool_expected"])
    assert E.mm_dist(ref["rp_text"], ref["rp_motion"]) == pytest.approx(
        float(ref["matching_score_all_expected"]), rel=1e-13)


def test_diversity_and_multimodality_equal_reference_with_the_same_seed(ref):
    for seed, times, want in zip(ref["div_seeds"], ref["div_times"], ref["div_expected"]):
        assert E.diversity(ref["div_act"], int(times), int(seed)) == pytest.approx(float(want), rel=1e-14)
    for seed, want in zip(ref["mm_seeds"], ref["mm_expected"]):
        assert E.multimodality(ref["mm_act"], int(ref["mm_times"]), int(seed)) == pytest.approx(float(want), rel=1e-14)


def test_confidence_interval_equals_reference_get_metric_statistics(ref):
    from hoibench.tracks.protocol import summarize
    s = summarize(ref["ci_values"])
    assert (s["mean"], s["ci95"]) == pytest.approx(tuple(ref["ci_expected"]), rel=1e-14)
    v = summarize(ref["ci_values_vec"])
    np.testing.assert_allclose([v["mean"], v["ci95"]], ref["ci_vec_expected"], rtol=1e-14)


# ====================================================================== FID numerics
def test_fid_retries_with_eps_on_the_diagonal_when_sqrtm_is_not_finite(ref, monkeypatch):
    from scipy import linalg
    calls = []

    def flaky(m):
        calls.append(m.copy())
        return np.full_like(m, np.nan) if len(calls) == 1 else linalg.sqrtm(m)

    monkeypatch.setattr(E, "_sqrtm", flaky)
    mu1, s1 = E.activation_statistics(ref["fid_real"])
    mu2, s2 = E.activation_statistics(ref["fid_gen"])
    got = E.frechet_distance(mu1, s1, mu2, s2, method="sqrtm")
    off = np.eye(len(mu1)) * 1e-6
    np.testing.assert_allclose(calls[1], (s1 + off) @ (s2 + off))
    covmean = linalg.sqrtm((s1 + off) @ (s2 + off)).real
    want = (mu1 - mu2) @ (mu1 - mu2) + np.trace(s1) + np.trace(s2) - 2 * np.trace(covmean)
    assert got == pytest.approx(want, rel=1e-12)


def test_fid_raises_on_a_large_imaginary_component(monkeypatch):
    monkeypatch.setattr(E, "_sqrtm", lambda m: np.eye(len(m)) * (1 + 0.1j))
    with pytest.raises(ValueError, match="imaginary"):
        E.frechet_distance(np.zeros(2), np.eye(2), np.zeros(2), np.eye(2), method="sqrtm")


def test_fid_of_identical_sets_is_zero_and_grows_with_a_mean_shift():
    x = np.random.default_rng(0).normal(size=(500, 8))
    assert abs(E.fid(x, x)) < 1e-8
    assert E.fid(x, x + 1.0) == pytest.approx(8.0, rel=1e-8)      # |mu1 - mu2|^2 = 8


def test_input_validation_names_the_argument():
    with pytest.raises(ValueError, match="text, motion"):
        E.pool_hits(np.zeros((4, 3)), np.zeros((5, 3)))
    with pytest.raises(ValueError, match="times"):
        E.diversity(np.zeros((10, 3)), 10)
    with pytest.raises(ValueError, match="embeddings"):
        E.fid(np.zeros((4, 3, 1)), np.zeros((4, 3)))
    with pytest.raises(ValueError, match="non-finite"):
        E.fid(np.full((4, 3), np.nan), np.zeros((4, 3)))


def test_r_precision_tie_goes_to_the_lower_index():
    text = np.zeros((3, 2))
    motion = np.zeros((3, 2))                        # every distance ties
    hits, _ = E.pool_hits(text, motion, 3)
    np.testing.assert_array_equal(hits, [1, 2, 3])   # text i ranks its motion at position i


# ====================================================================== pools and state
def test_pools_depend_on_ids_and_seed_only():
    ids = [f"clip{i:03d}" for i in range(100)]
    a = E.make_pools(ids, 32, seed=7)
    b = E.make_pools(list(reversed(ids)), 32, seed=7)
    assert a == b and len(a) == 3 and all(len(p) == 32 for p in a)         # incomplete pool dropped
    assert len(E.make_pools(ids, 32, seed=7, drop_last=False)[-1]) == 4
    assert E.make_pools(ids, 32, seed=8) != a
    with pytest.raises(ValueError, match="duplicates"):
        E.make_pools(["a", "a"], 2)


def test_sharded_fid_equals_whole_data(ref):
    real, gen = ref["fid_real"], ref["fid_gen"]
    whole = E.fid(real, gen)
    shards = []
    for part in (slice(0, 17), slice(17, 150), slice(150, None)):
        m = M.FID(num_features=16)
        m.update(real[part], real=True)
        m.update(gen[part], real=False)
        shards.append(m)
    for order in ([0, 1, 2], [2, 0, 1]):
        merged = Metric.merged([shards[i] for i in order])
        assert merged.compute() == pytest.approx(whole, rel=1e-9)
    assert shards[0].real_n == 17 and merged.real_n == len(real)


def test_sharded_r_precision_diversity_multimodality_equal_whole_data_exactly(ref):
    text, motion = ref["rp_text"], ref["rp_motion"]
    ids = [f"id{i:02d}" for i in range(len(text))]
    pools = E.make_pools(ids, 32, seed=3)
    index = {k: i for i, k in enumerate(ids)}
    whole_rp = E.r_precision(text, motion, [[index[k] for k in p] for p in pools])
    whole_mm = E.mm_dist(text, motion, [[index[k] for k in p] for p in pools])
    shards = [M.RPrecision(), M.RPrecision()]
    for n, pool in enumerate(pools):                  # pools land on shards in any order
        rows = [index[k] for k in pool]
        shards[n % 2].update(text[rows], motion[rows], key=n)
    out = Metric.merged(reversed(shards)).compute()
    assert [out["r_precision_top1"], out["r_precision_top2"], out["r_precision_top3"]] == whole_rp.tolist()
    assert out["mm_dist"] == pytest.approx(whole_mm, rel=1e-15)

    act = ref["div_act"]
    keys = [f"m{i:03d}" for i in range(len(act))]
    d1, d2 = M.Diversity(300), M.Diversity(300)
    d2.update(act[200:], keys[200:])
    d1.update(act[:200], keys[:200])
    assert Metric.merged([d2, d1]).compute(seed=1) == E.diversity(act, 300, 1)

    mm = ref["mm_act"]
    a, b = M.MultiModality(10), M.MultiModality(10)
    for i in range(len(mm)):
        (a if i % 3 else b).update(f"t{i:02d}", mm[i])
    assert Metric.merged([a, b]).compute(seed=5) == E.multimodality(mm, 10, 5)


def test_merging_the_same_unit_twice_or_different_configs_fails():
    a, b = M.RPrecision(), M.RPrecision()
    x = np.random.default_rng(0).normal(size=(4, 3))
    a.update(x, x, key="pool0")
    b.update(x, x, key="pool0")
    with pytest.raises(ValueError, match="two shards"):
        Metric.merged([a, b])
    with pytest.raises(ValueError, match="configurations differ"):
        M.FID(4).merge(M.FID(8))
    c = copy.deepcopy(a)
    c.reset()
    assert c.pools == {} and a.pools


def test_registry_metadata_is_complete_and_loadable():
    names = set(M.METRICS)
    for name in ("r_precision_top1", "r_precision_top2", "r_precision_top3", "fid", "mm_dist", "diversity",
                 "multimodality", "cd", "ocd", "ps", "fsr", "fsr_gmd", "penetration_depth_max_m",
                 "penetration_depth_mean_m", "contact_iou", "hand_contact_ratio", "object_floating_ratio",
                 "jitter_mps3"):
        assert name in names
        info = M.get_metric_info(name)
        assert info.higher_is_better in (True, False, None) and info.units and info.thresholds
        assert callable(info.load())
    assert M.get_metric_info("fid").higher_is_better is False
    assert M.get_metric_info("diversity").higher_is_better is None
    assert M.get_metric_info("r_precision_top3").paper_column == "R Precision Top 3"
    with pytest.raises(KeyError, match="unknown metric"):
        M.get_metric_info("nope")


# ====================================================================== motion metrics, analytic
def _feet_clip(T=21, left=(0.0, 0.0), right=(0.0, 0.0), height=0.03, fps=20.0):
    """Joints (T, 22, 3): feet 10/11 at ``height``, moving at ``left``/``right`` (vx, vz) m/s."""
    J = np.zeros((T, 22, 3))
    J[:, :, 1] = 1.0                                  # everything else well above the floor
    t = np.arange(T) / fps
    for j, (vx, vz) in ((10, left), (11, right)):
        J[:, j] = np.stack([vx * t, np.full(T, height), vz * t], -1)
    return J


def test_a_foot_sliding_at_1_mps_is_counted_as_skating():
    J = _feet_clip(left=(1.0, 0.0))                   # 0.05 m per frame > 0.025 m
    assert mo.foot_skating_counts(J, 20.0, "legacy") == (20, 40)
    assert mo.foot_skating_ratio(J, 20.0, "clean") == 0.5
    assert mo.gmd_skating_counts(J, 20.0) == (20, 20)


def test_legacy_fsr_misses_sliding_along_z_and_clean_does_not():
    J = _feet_clip(left=(0.0, 1.0))
    assert mo.foot_skating_counts(J, 20.0, "legacy") == (0, 40)
    assert mo.foot_skating_counts(J, 20.0, "clean") == (20, 40)


def test_slow_or_lifted_feet_are_not_skating():
    assert mo.foot_skating_counts(_feet_clip(left=(0.3, 0.0)), 20.0, "clean") == (0, 40)
    lifted = _feet_clip(left=(1.0, 0.0), height=0.2)
    assert mo.foot_skating_counts(lifted, 20.0, "legacy") == (0, 0)
    assert np.isnan(mo.foot_skating_ratio(lifted, 20.0))


def test_clean_fsr_threshold_is_a_speed():
    # at 40 fps a 1 m/s slide moves 0.025 m per frame: legacy (per frame) misses it, clean does not
    J = _feet_clip(T=41, left=(0.9, 0.0), fps=40.0)
    assert mo.foot_skating_counts(J, 40.0, "legacy")[0] == 0
    assert mo.foot_skating_counts(J, 40.0, "clean") == (40, 80)


def test_gmd_moving_average_drops_the_edges_of_a_slow_slide():
    # 0.6 m/s: the 5-frame zero-padded average is 0.36 and 0.48 m/s on the two edge frames
    J = _feet_clip(left=(0.6, 0.0))
    assert mo.gmd_skating_counts(J, 20.0) == (16, 20)


def test_jitter_of_a_cubic_trajectory_is_its_constant_jerk():
    fps, c = 30.0, 0.7
    t = np.arange(40) / fps
    J = np.zeros((40, 22, 3))
    J[..., 0] = (c * t ** 3)[:, None]
    assert mo.jitter(J, fps) == pytest.approx(6 * c, rel=1e-6)   # d^3/dt^3 (c t^3) = 6c m/s^3
    assert mo.jitter_sums(J[:3], fps) == (0.0, 0)


# ====================================================================== contact metrics, analytic
from hoibench.core import geometry as geo  # noqa: E402
from hoibench.metrics import contact_metrics as cm  # noqa: E402
from hoibench.metrics import physical as ph  # noqa: E402

needs_open3d = pytest.mark.skipif(importlib.util.find_spec("open3d") is None, reason="open3d not installed")


def same(a: dict, b: dict) -> bool:
    """Dicts equal value for value, NaN equal to NaN (bit-identical floats otherwise)."""
    if a.keys() != b.keys():
        return False
    return all(a[k] == b[k] or (isinstance(a[k], float) and np.isnan(a[k]) and np.isnan(b[k])) for k in a)

BOX_V = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) * 0.5
BOX_F = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])


def _posed(local, R, t):
    return np.einsum("tij,tnj->tni", R, local) + t[:, None]


@needs_open3d
def test_joints_at_known_signed_distances_give_the_known_cd():
    T = 5
    rng = np.random.default_rng(0)
    R, t = geo.axis_angle_to_matrix(rng.normal(size=(T, 3))), rng.normal(size=(T, 3))
    local = np.full((T, 22, 3), 3.0)                       # far from the unit box
    local[:, 20] = (0.6, 0.0, 0.0)                          # 0.1 m outside the x = 0.5 face
    local[:, 21] = (0.0, 0.45, 0.1)                         # 0.05 m inside, below the y = 0.5 face
    joints = _posed(local, R, t)
    d = cm.joint_object_distances(joints, BOX_V, BOX_F, R, t)
    np.testing.assert_allclose(d[:, 20], 0.1, atol=2e-6)
    np.testing.assert_allclose(d[:, 21], -0.05, atol=2e-6)
    gt = np.zeros((T, 22), bool)
    gt[:3, [20, 21]] = True                                 # contact on the first 3 frames
    assert cm.contact_distance(d, gt) == pytest.approx((0.1 ** 2 + 0.05 ** 2) / 2, abs=1e-6)
    assert cm.contact_distance(d[:2], gt) == pytest.approx((0.1 ** 2 + 0.05 ** 2) / 2, abs=1e-6)  # min(T, T')
    assert np.isnan(cm.contact_distance(d, np.zeros((T, 22), bool)))


def test_ocd_takes_the_best_group_map_within_8_frames():
    T = 20
    d = np.full((T, 22), 1.0)
    d[:, 20], d[:, 21] = 0.1, -0.05
    own = np.zeros((T, 22), bool)
    own[:, 20] = True                                       # CD 0.01
    other = np.zeros((T + 8, 22), bool)
    other[:, 21] = True                                     # CD 0.0025, 8 frames longer: allowed
    too_long = np.zeros((T + 9, 22), bool)
    too_long[:, 0] = True                                   # CD 1.0 -- but 9 frames longer: ignored
    assert cm.optimal_contact_distance(d, own, []) == pytest.approx(0.01)
    assert cm.optimal_contact_distance(d, own, [other, too_long]) == pytest.approx(0.0025)
    best = np.zeros((T + 9, 22), bool)
    best[:, 5] = True
    d[:, 5] = 0.0
    assert cm.optimal_contact_distance(d, own, [best]) == pytest.approx(0.01)


@needs_open3d
def test_a_body_pushed_a_known_depth_into_a_box_gives_the_known_ps():
    from hoibench.bodies import ProxyBody
    from hoibench.core.skeleton import SMPL_REST_JOINTS
    from hoibench.metrics.body_surface import proxy_vertices_from_joints

    v_rest = ProxyBody().v_template
    sole = v_rest[:, 1].min()
    depth = 0.3                                             # the body's lowest 0.3 m are inside the box
    gaps = np.sort(v_rest[:, 1] - sole)
    assert np.abs(gaps - depth).min() > 1e-4                # no vertex sits on the box's top face
    offset = np.array([0.2, -sole - depth, -0.1])           # box top face at y = 0
    joints = (SMPL_REST_JOINTS + offset)[None].repeat(3, 0)
    verts = proxy_vertices_from_joints(joints)
    np.testing.assert_allclose(verts[0], v_rest + offset, atol=1e-12)
    big = BOX_V * 20.0 - (0.0, 10.0, 0.0)                   # 20 m box, top face at y = 0
    R, t = np.broadcast_to(np.eye(3), (3, 3, 3)), np.zeros((3, 3))
    dv = cm.body_object_distances(verts, big, BOX_F, R, t)
    neg, total = cm.penetration_counts(dv)
    expected = int((v_rest[:, 1] - sole < depth).sum())
    assert (neg, total) == (3 * expected, 3 * len(v_rest))
    mx, sm, n = cm.penetration_depth_stats(dv)
    assert mx == pytest.approx(depth, abs=1e-5) and n == 3 and sm == pytest.approx(3 * depth, abs=3e-5)
    from hoibench.bodies.contact import signed_distance_field
    sf = cm.surface_frames(signed_distance_field(big, BOX_F), verts)     # the fast path
    np.testing.assert_array_equal(sf.penetrating, [expected] * 3)
    np.testing.assert_allclose(sf.depth, depth, atol=1e-5)
    assert sf.touching.all()


def test_penetration_depth_is_the_deepest_vertex_of_each_frame():
    d = np.array([[-0.1, -0.3, 0.5], [0.2, 0.1, 0.0], [-0.05, 1.0, 1.0]])
    mx, sm, n = cm.penetration_depth_stats(d)
    assert (mx, n) == (0.3, 2) and sm == pytest.approx(0.35)
    assert cm.penetration_counts(d) == (3, 9)


def _posed_bodies(obj, rng, frames=24):
    """Proxy rest bodies (frames, 6890, 3) in the object's frame, each rigidly placed with a
    random vertex at a random point within 8 cm of the object's box: some frames penetrate,
    some touch, some are clear."""
    from hoibench.bodies import ProxyBody
    v = ProxyBody().v_template
    out = []
    for _ in range(frames):
        a = rng.uniform(0, 2 * np.pi)
        R = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
        anchor = v[rng.integers(len(v))]
        target = rng.uniform(obj.vertices.min(0) - 0.08, obj.vertices.max(0) + 0.08)
        out.append((v - anchor) @ R.T + target)
    return np.stack(out)


def _exact_frames(d, contact_m=cm.VERTEX_CONTACT_M):
    return (d < 0).sum(1), np.where(d < 0, -d, 0.0).max(1), (d < contact_m).any(1)


@needs_open3d
@pytest.mark.parametrize("name", ["boxlarge", "yogaball", "stool", "chairwood"])
def test_surface_frames_equal_exact_distances_of_every_vertex(name):
    """The bounded fast path (few exact queries) equals querying all 6,890 x T vertices."""
    from hoibench.bodies.contact import signed_distance_field
    from hoibench.datasets.synthetic import build_object
    obj = build_object(name)
    field = signed_distance_field(obj.vertices, obj.faces)
    local = _posed_bodies(obj, np.random.default_rng(5))
    pen, depth, touch = _exact_frames(field(local))
    assert pen.any() and (pen == 0).any() and touch.any() and (~touch).any()
    sf = cm.surface_frames(field, local)
    np.testing.assert_array_equal(sf.penetrating, pen)
    np.testing.assert_array_equal(sf.depth, depth)
    np.testing.assert_array_equal(sf.touching, touch)
    only = cm.surface_frames(field, local, touching=False)
    assert only.touching is None and np.array_equal(only.depth, depth)


@needs_open3d
@pytest.mark.parametrize("clip", [11, 5, 13])
def test_culled_proxy_points_give_the_exact_surface_frames(clip):
    """proxy_template_points skips clusters that cannot come within the margin; the frames it
    yields equal the exact per-vertex computation on the whole posed proxy body."""
    from hoibench.bodies.contact import signed_distance_field, to_template_frame
    from hoibench.datasets.synthetic import Defect, generate_clip, plan_clips
    from hoibench.metrics.body_surface import (PROXY_VERTICES, proxy_template_points,
                                               proxy_vertices_from_joints)
    c = generate_clip(plan_clips(16, 0)[clip], (0, clip), Defect("penetration", 0.01))
    field = signed_distance_field(c.object.vertices, c.object.faces)
    T = len(c.joints)
    index, pts = proxy_template_points(c.joints, slice(0, T), field, c.obj_rot, c.obj_trans, 0.025)
    local = to_template_frame(proxy_vertices_from_joints(c.joints), c.obj_rot, c.obj_trans)
    np.testing.assert_allclose(pts, local.reshape(-1, 3)[index], atol=1e-12)
    d = field(local)
    skipped = np.ones(T * PROXY_VERTICES, bool)
    skipped[index] = False
    assert skipped.any() and np.all(d.reshape(-1)[skipped] > 0.025)
    pen, depth, touch = _exact_frames(d)
    assert pen.sum() > 0
    sf = cm.surface_frames(field, pts, index, (T, PROXY_VERTICES))
    np.testing.assert_array_equal(sf.penetrating, pen)
    np.testing.assert_array_equal(sf.depth, depth)
    np.testing.assert_array_equal(sf.touching, touch)


def test_floating_and_hand_contact_counts():
    assert cm.floating_frames(np.array([0.0, 0.5, 0.5, 0.01]), np.array([False, True, False, False])) == (1, 4)
    pred = np.zeros((4, 22), bool)
    pred[1, 20] = pred[2, 21] = pred[3, 0] = True
    assert cm.hand_contact_frames(pred) == (2, 4)
    gt = np.zeros((3, 22), bool)
    gt[1, 20] = gt[0, 5] = True
    assert cm.contact_iou_counts(pred, gt) == (1, 3)        # first min(4, 3) frames


def test_cd_aggregation_legacy_divides_by_every_clip():
    stats = {"a": {"frames": 10, "fsr_skating": 0, "fsr_ground": 0, "gmd_skating": 0, "gmd_frames": 9,
                   "jerk_sum": 0.0, "jerk_count": 0, "has_object": True, "cd_sum": 0.05, "cd_count": 5,
                   "ocd": 0.004, "iou_inter": 1, "iou_union": 2, "hand_frames": 5, "ps_neg": 1, "ps_total": 10,
                   "depth_max": 0.01, "depth_sum": 0.01, "depth_count": 1, "float_frames": 0}}
    stats["b"] = dict(stats["a"], cd_sum=0.0, cd_count=0, ocd=float("nan"))   # no GT contact
    out = {}
    for mode in ("legacy", "clean"):
        m = ph.PhysicalMetrics(mode)
        for k, s in stats.items():
            m.update(k, s)
        out[mode] = m.compute()
    assert out["clean"]["cd"] == pytest.approx(0.01) and out["legacy"]["cd"] == pytest.approx(0.005)
    assert out["clean"]["ocd"] == pytest.approx(0.004) and out["legacy"]["ocd"] == pytest.approx(0.002)
    assert out["clean"]["ps"] == out["legacy"]["ps"] == pytest.approx(0.1)


# ====================================================================== injected defects
@pytest.fixture(scope="module")
def defect_stats():
    """Per-clip physical statistics of one synthetic clip (boxlarge lift, both hands) clean and
    with each defect of hoibench.datasets.synthetic injected (generate_clip: the generator
    write_behave_layout(defects=...) runs, kept in memory)."""
    from hoibench.datasets.synthetic import Defect, generate_clip, plan_clips
    spec = plan_clips(16, 0)[11]
    assert spec.object == "boxlarge" and spec.action == "lift"
    out = {}
    for name, d in (("clean", None), ("skating", Defect("foot_skating", 1.5)),
                    ("penetration", Defect("penetration", 0.03)), ("lost", Defect("lost_contact", 0.05))):
        c = generate_clip(spec, (0, 11), d)
        inp = ph.ClipInput(name, c.joints, c.fps, c.obj_rot, c.obj_trans, c.spec.object, c.object.vertices,
                           c.object.faces, c.contacts)
        m = ph.PhysicalMetrics("clean")
        m.update(name, ph.clip_physical_stats(inp, ph.PhysicalConfig("clean")))
        out[name] = m.compute()
    return out


@needs_open3d
def test_foot_skating_defect_worsens_fsr_only(defect_stats):
    clean, bad = defect_stats["clean"], defect_stats["skating"]
    assert bad["fsr"] > clean["fsr"] + 0.1 and bad["fsr_gmd"] > clean["fsr_gmd"] + 0.1
    for k in ("cd", "ocd", "ps", "penetration_depth_max_m"):
        assert bad[k] == pytest.approx(clean[k], abs=1e-9), k


@needs_open3d
def test_penetration_defect_worsens_ps_and_depth(defect_stats):
    clean, bad = defect_stats["clean"], defect_stats["penetration"]
    assert bad["ps"] > clean["ps"] * 1.1
    assert bad["penetration_depth_max_m"] > clean["penetration_depth_max_m"] + 0.02
    assert bad["penetration_depth_mean_m"] > clean["penetration_depth_mean_m"]
    assert bad["fsr"] == clean["fsr"] and bad["fsr_gmd"] == clean["fsr_gmd"]


@needs_open3d
def test_lost_contact_defect_worsens_cd_not_penetration(defect_stats):
    clean, bad = defect_stats["clean"], defect_stats["lost"]
    assert clean["cd"] < 1e-8 and bad["cd"] > 1e-4          # wrists 5 cm off the surface on contact frames
    assert bad["ocd"] > 1e-4
    assert bad["ps"] <= clean["ps"] and bad["penetration_depth_max_m"] <= clean["penetration_depth_max_m"] + 1e-9
    assert bad["fsr"] == clean["fsr"]


# ====================================================================== executors
@pytest.fixture(scope="module")
def clip_inputs_synthetic():
    from hoibench.datasets.synthetic import generate_clip, plan_clips
    specs = plan_clips(8, 3)[:4]
    out = []
    for i, s in enumerate(specs):
        c = generate_clip(s, (3, i))
        out.append(ph.ClipInput(s.name, c.joints[::3], c.fps / 3, c.obj_rot[::3], c.obj_trans[::3], s.object,
                                c.object.vertices, c.object.faces, c.contacts[::3]))
    return out


@needs_open3d
def test_sharded_physical_metrics_equal_serial_exactly(clip_inputs_synthetic):
    cfg = ph.PhysicalConfig("legacy")
    serial = ph.evaluate_physical(clip_inputs_synthetic, cfg)
    shards = [ph.PhysicalMetrics("legacy"), ph.PhysicalMetrics("legacy")]
    for i, inp in enumerate(reversed(clip_inputs_synthetic)):
        shards[i % 2].update(inp.key, ph.clip_physical_stats(inp, cfg))
    assert same(Metric.merged(shards).compute(), serial.compute())


@needs_open3d
def test_process_pool_equals_serial(clip_inputs_synthetic):
    cfg = ph.PhysicalConfig("clean")
    serial = ph.evaluate_physical(clip_inputs_synthetic, cfg).compute()
    pooled = ph.evaluate_physical(clip_inputs_synthetic, cfg, executor="processes:2").compute()
    assert same(pooled, serial)


@needs_open3d
@pytest.mark.skipif(importlib.util.find_spec("distributed") is None, reason="dask.distributed not installed")
def test_local_dask_equals_serial(clip_inputs_synthetic):
    cfg = ph.PhysicalConfig("clean")
    serial = ph.evaluate_physical(clip_inputs_synthetic[:2], cfg).compute()
    assert same(ph.evaluate_physical(clip_inputs_synthetic[:2], cfg, executor="dask://local:2").compute(), serial)


@needs_open3d
def test_user_body_surface_path_agrees_with_the_proxy_path_and_bad_output_is_named():
    """``body_surface="module:function"`` (all vertices, no culling) gives the proxy path's
    counts; a callable returning the wrong shape fails naming the clip and the setting."""
    from hoibench.datasets.synthetic import Defect, generate_clip, plan_clips
    c = generate_clip(plan_clips(16, 0)[11], (0, 11), Defect("penetration", 0.01))
    inp = ph.ClipInput("clip-11", c.joints, c.fps, c.obj_rot, c.obj_trans, c.spec.object, c.object.vertices,
                       c.object.faces, c.contacts)
    proxy = ph.clip_physical_stats(inp, ph.PhysicalConfig("clean"))
    user = ph.clip_physical_stats(inp, ph.PhysicalConfig(
        "clean", body_surface="hoibench.metrics.body_surface:proxy_vertices_from_joints"))
    assert proxy["ps_neg"] > 0
    for k in ("ps_neg", "ps_total", "depth_count", "float_frames"):
        assert user[k] == proxy[k], k
    assert user["depth_max"] == pytest.approx(proxy["depth_max"], abs=1e-6)
    with pytest.raises(ValueError, match=r"clip-11: body_surface numpy:transpose: expected finite vertices"):
        ph.clip_physical_stats(inp, ph.PhysicalConfig("clean", body_surface="numpy:transpose"))
