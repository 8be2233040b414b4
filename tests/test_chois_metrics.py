"""CHOIS's metrics (hoibench.metrics.chois, chois_sdf, chois_clip) on constructed inputs with
known answers. Each expected value is worked out from the formula in GitHub
lijiaman/chois_release (commit 9cd4cf6) at the lines named in the test:
``evaluation_metrics.py`` (EM) and ``trainer_chois.py`` (TC)."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from hoibench.metrics import chois as ch
from hoibench.metrics.chois_sdf import SdfGrid, collision_penetration, hand_penetration

T = 120


def _motion(seed: int = 0, joints: int = 24) -> np.ndarray:
    rs = np.random.RandomState(seed)
    j = rs.standard_normal((T, joints, 3)) * 0.3
    j[:, :, 2] += 1.0
    return j


def _rot_z(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def _object(far: bool = True):
    rest = np.array([[0.0, 0, 0], [0.1, 0, 0], [0, 0.1, 0]])
    rot = np.repeat(np.eye(3)[None], T, 0)
    com = np.tile([5.0, 5.0, 1.0] if far else [0.0, 0, 1.0], (T, 1))
    return rest, rot, com


def test_translated_copy_gives_the_offset_and_identical_motions_give_zero():
    """EM L393-416: hand errors and trans_err are global (the offset, in mm); mpjpe and mpvpe
    subtract each frame's root joint (0 for a translated copy)."""
    g = _motion()
    off = np.array([0.03, -0.04, 0.0])                      # 50 mm
    p = g + off
    verts = np.random.RandomState(1).standard_normal((T, 30, 3))
    lh, rh, h = ch.hand_jpe(p, g)
    assert lh == pytest.approx(50.0) and rh == pytest.approx(50.0) and h == pytest.approx(50.0)
    assert ch.trans_err(p[:, 0], g[:, 0]) == pytest.approx(50.0)
    assert ch.mpjpe(p, g) == pytest.approx(0.0, abs=1e-9)
    assert ch.mpvpe(verts + off, verts, p, g) == pytest.approx(0.0, abs=1e-9)
    rest, rot, com = _object()
    ov = ch.object_vertices(rest, rot, com)
    out = ch.compute_metrics(g, g, ov, ov, com, com, rot, rot, pred_verts=verts, gt_verts=verts,
                             pred_root_rot=rot, gt_root_rot=rot)
    for k in ("lhand_jpe", "rhand_jpe", "hand_jpe", "mpvpe", "mpjpe", "trans_err", "rot_dist", "obj_rot_dist",
              "obj_com_pos_err", "start_obj_com_pos_err", "end_obj_com_pos_err", "waypoints_xy_pos_err"):
        assert out[k] == pytest.approx(0.0, abs=1e-9), k
    assert out["foot_sliding"] == pytest.approx(out["gt_foot_sliding"])


def test_joints22_use_the_wrists_and_a_tenth_of_a_metre():
    """EM L387-392, L435-439: joints22 -> joints 20/21 and 0.10 m; joints24 -> 22/23 and 0.05 m."""
    g = _motion(joints=22)
    p = g.copy()
    p[:, 20] += [0.0, 0.0, 0.01]                            # left wrist 10 mm off
    assert ch.hand_jpe(p, g) == pytest.approx((10.0, 0.0, 5.0))
    rest, rot, com = np.zeros((1, 3)), np.repeat(np.eye(3)[None], T, 0), np.zeros((T, 3))
    for n, (near, far) in ((22, (0.09, 0.11)), (24, (0.04, 0.06))):
        j = np.zeros((T, n, 3)) + 9.0
        hand = 20 if n == 22 else 22
        j[:60, hand] = [near, 0, 0]
        j[60:, hand] = [far, 0, 0]
        lab = ch.contact_labels(j, ch.object_vertices(rest, rot, com))
        assert lab[:60].all() and not lab[60:].any()


def test_planted_contact_frames_give_known_precision_recall_and_the_zero_rules():
    """EM L490-532: TP/FP/TN/FN over frames; precision 0 when nothing is predicted, recall 0
    when the GT has no contact, F1 0 when both are 0; percents are fractions of frames."""
    g = np.zeros(20, bool)
    p = np.zeros(20, bool)
    g[0:10] = True                                          # GT contact 0-9
    p[5:15] = True                                          # predicted 5-14: TP 5, FP 5, FN 5, TN 5
    s = ch.contact_scores(g, p)
    assert s == pytest.approx({"gt_contact_percent": 0.5, "pred_contact_percent": 0.5, "contact_precision": 0.5,
                               "contact_recall": 0.5, "contact_acc": 0.5, "contact_f1": 0.5})
    p2 = np.zeros(20, bool)
    p2[0:4] = True                                          # TP 4, FN 6, FP 0: precision 1, recall 0.4
    s = ch.contact_scores(g, p2)
    assert s["contact_precision"] == 1.0 and s["contact_recall"] == pytest.approx(0.4)
    assert s["contact_f1"] == pytest.approx(2 * 0.4 / 1.4) and s["contact_acc"] == pytest.approx(0.7)
    none = ch.contact_scores(g, np.zeros(20, bool))
    assert none["contact_precision"] == 0 and none["contact_recall"] == 0 and none["contact_f1"] == 0
    no_gt = ch.contact_scores(np.zeros(20, bool), p)
    assert no_gt["contact_recall"] == 0 and no_gt["contact_precision"] == 0 and no_gt["contact_acc"] == 0.5
    both_empty = ch.contact_scores(np.zeros(20, bool), np.zeros(20, bool))
    assert both_empty["contact_acc"] == 1.0 and both_empty["contact_f1"] == 0


def test_rotation_distance_is_frobenius_of_the_relative_rotation():
    """EM L16-25: ||I - R_p R_g^-1||_F = 2 sqrt(1 - cos theta) for a rotation by theta; the
    root (joint 0 of a (T, J, 3, 3) array) only (L419-421)."""
    theta = 0.3
    g = np.repeat(_rot_z(1.1)[None], T, 0)
    p = np.einsum("ij,tjk->tik", _rot_z(theta), g)
    assert ch.frobenius_rot_dist(p, g) == pytest.approx(2 * np.sqrt(1 - np.cos(theta)))
    stack_p = np.stack([p, g, g], axis=1)
    stack_g = np.stack([g, p, p], axis=1)
    assert ch.rot_dist(stack_p, stack_g) == pytest.approx(2 * np.sqrt(1 - np.cos(theta)))


def test_object_errors_at_start_end_and_waypoints():
    """EM L541-549: com error mean (mm), first and last frame, xy error at frames 29, 59, 89."""
    rest, rot, gcom = _object()
    pcom = gcom.copy()
    pcom[[29, 59, 89]] += [0.03, 0.04, 0.5]                 # xy 50 mm; z ignored by the waypoint error
    e = ch.object_errors(pcom, gcom, rot, rot)
    assert e["waypoints_xy_pos_err"] == pytest.approx(50.0)
    assert e["start_obj_com_pos_err"] == 0 and e["end_obj_com_pos_err"] == 0
    assert e["obj_com_pos_err"] == pytest.approx(3 * np.sqrt(0.03 ** 2 + 0.04 ** 2 + 0.25) * 1000 / T)
    assert np.isnan(ch.object_errors(pcom[:60], gcom[:60], rot[:60], rot[:60])["waypoints_xy_pos_err"])


def _feet(height_ankle: float, height_toe: float, step: float = 0.01) -> np.ndarray:
    j = np.zeros((T, 24, 3)) + [0, 0, 1.0]
    x = np.arange(T) * step
    for idx, h in ((7, height_ankle), (8, height_ankle), (10, height_toe), (11, height_toe)):
        j[:, idx, 0], j[:, idx, 2] = x + idx, h
    return j


def test_foot_sliding_weights_heights_and_divides_by_all_frames():
    """EM L115-155: sum of |d_xy| (2 - 2^(z/H)) over frames with z < H (0.08 ankles, 0.04
    toes), divided by T (not T-1), x1000, mean of four joints. Moving toes: no static frame,
    floor 0 (L110-111)."""
    j = _feet(0.0, 0.0)
    assert ch.floor_height(j) == 0.0
    one = (T - 1) * 0.01 / T * 1000
    assert ch.foot_sliding(j, 0.0) == pytest.approx(one)
    j = _feet(0.1, 0.02)                                   # ankles above 0.08: only toes count
    w = 2 - 2 ** (0.02 / 0.04)
    assert ch.foot_sliding(j, 0.0) == pytest.approx(2 * one * w / 4)
    assert ch.foot_sliding(j, -1.0) == 0.0                 # floor far below: every joint above its H


def test_floor_is_the_lowest_dbscan_cluster_median_noise_included():
    """EM L44-113: static toe heights (speed < 0.005 m/frame) clustered by DBSCAN(eps 0.005,
    min_samples 3); the noise label -1 counts as a cluster, so two lone static frames at
    0.02 m set the floor below a 30-frame cluster at 0.10 m."""
    j = np.zeros((30, 24, 3))
    j[:, 10] = [0, 0, 0.10]                                # left toe static: 30 heights of 0.10
    j[:, 11, 0] = np.arange(30) * 0.1                      # right toe moving fast ...
    j[:, 11, 2] = 0.5
    j[10:13, 11] = [1.0, 0, 0.02]                          # ... but still over frames 10-12: speeds 0, 0, >0
    assert ch.floor_height(j) == pytest.approx(0.02)
    j[10:14, 11] = [1.0, 0, 0.02]                          # three static frames: a cluster, same floor
    assert ch.floor_height(j) == pytest.approx(0.02)
    j[10:14, 11] = [1.0, 0, 0.5]
    assert ch.floor_height(j) == pytest.approx(0.10)


def _sphere_grid(centre, radius, n=129) -> SdfGrid:
    ax = np.linspace(-1, 1, n)
    x, y, z = np.meshgrid(ax, ax, ax, indexing="ij")
    d = np.sqrt((x - centre[0]) ** 2 + (y - centre[1]) ** 2 + (z - centre[2]) ** 2) - radius
    return SdfGrid(d, centroid=np.zeros(3), extents=np.array([2.0, 1.0, 1.0]))   # max extent 2: metres = grid units


def test_hand_penetration_rest_frame_quirk_and_its_fix():
    """TC L909-938 with L63-87: vertices moved as R (v - com) (CHOIS) versus R^T (v - com);
    mean |min(d, 0)| over vertices and frames, metres (x max(extents) / 2). A sphere of radius
    0.2 at (0.3, 0, 0) of the rest frame, the object turned 90 degrees about z: a vertex at the
    posed centre line is 0.1 m deep, but CHOIS's product sends it near (-0.3, 0, 0.1), outside."""
    sdf = _sphere_grid((0.3, 0, 0), 0.2)
    rot = np.repeat(_rot_z(np.pi / 2)[None], 4, 0)
    com = np.zeros((4, 3))
    verts = np.tile([[0.0, 0.3, 0.1], [0.0, 0.3, 0.15], [2.0, 2.0, 2.0]], (4, 1, 1))   # 0.1 deep, 0.05 deep, outside
    clean = hand_penetration(verts, com, rot, sdf, legacy=False)
    assert clean == pytest.approx((0.1 + 0.05) / 3, abs=2e-3)
    assert hand_penetration(verts, com, rot, sdf, legacy=True) == 0.0
    assert hand_penetration(verts, com, rot, sdf, vertex_ids=[0], legacy=False) == pytest.approx(0.1, abs=2e-3)
    same = np.repeat(np.eye(3)[None], 4, 0)                # no rotation: both forms agree
    v0 = np.tile([[0.3, 0.0, 0.0]], (4, 1, 1))
    assert hand_penetration(v0, com, same, sdf) == pytest.approx(hand_penetration(v0, com, same, sdf, legacy=False))


def test_collision_penetration_counts_frames_beyond_its_threshold_in_grid_units():
    """EM L235-352: R^T (v - t) / s, grid value x s; a frame counts when some depth > 0.04
    (grid units x s, not metres) and adds the mean of those depths; depth = sum / counted
    frames, percent = counted / all frames."""
    sdf = _sphere_grid((0.0, 0, 0), 0.5)
    rot = np.repeat(np.eye(3)[None], 4, 0)
    trans = np.zeros((4, 3))
    verts = np.zeros((4, 2, 3)) + 3.0                      # outside in every frame ...
    verts[0, 0] = [0.0, 0, 0.2]                             # frame 0: 0.3 deep
    verts[0, 1] = [0.0, 0, 0.49]                            # 0.01 deep: below the threshold, left out
    verts[1, 0] = [0.0, 0, 0.0]                             # frame 1: 0.5 deep
    pct, depth = collision_penetration(verts, rot, trans, 1.0, sdf)
    assert pct == 0.5 and depth == pytest.approx((0.3 + 0.5) / 2, abs=2e-3)
    pct2, depth2 = collision_penetration(verts * 2.0, rot, trans, 2.0, sdf)   # scale 2: depths x 2
    assert pct2 == 0.5 and depth2 == pytest.approx(0.8, abs=4e-3)


def test_clip_function_reads_gt_fields_and_converts_y_up():
    """The catalogue's per-clip function: ground truth from optional ClipInput fields; y-up
    joints converted to z-up; no GT -> nothing (the scorer reads NaN)."""
    from hoibench.metrics.catalog import METRICS
    from hoibench.metrics.chois_clip import check_settings, chois_clip_metrics
    g_z = _motion(joints=22)
    g_y = g_z[..., [0, 2, 1]] * [1, 1, -1]                  # z-up (x, y, z) -> y-up (x, z, -y)
    off = np.array([0.03, 0.0, -0.04])
    tmpl = np.array([[0.0, 0, 0], [0.1, 0, 0]])
    rot = np.repeat(np.eye(3)[None], T, 0)
    trans = np.tile([0.0, 1.0, 0.5], (T, 1))
    inp = SimpleNamespace(joints=g_y + off, fps=30.0, obj_rot=rot, obj_trans=trans + off, template_vertices=tmpl,
                          gt_joints=g_y, gt_obj_rot=rot, gt_obj_trans=trans)
    out = chois_clip_metrics(inp, {})
    assert out["trans_err"] == pytest.approx(50.0) and out["hand_jpe"] == pytest.approx(50.0)
    assert out["obj_com_pos_err"] == pytest.approx(50.0) and out["waypoints_xy_pos_err"] == pytest.approx(50.0)
    # a translated copy: root-relative errors and rotations vanish; no template faces, no penetration
    assert out["mpjpe"] == pytest.approx(0.0, abs=1e-9) and out["mpvpe"] == pytest.approx(0.0, abs=1e-9)
    assert out["rot_dist"] == pytest.approx(0.0, abs=1e-9) and "hand_penetration" not in out
    assert set(out) <= set(METRICS) and METRICS["hand_jpe"].clip_fn.endswith("chois_clip_metrics")
    assert chois_clip_metrics(SimpleNamespace(joints=g_y), {}) == {}
    check_settings({"up": "z", "rest_frame": "transpose"}, "p.yaml: chois")
    with pytest.raises(ValueError, match="p.yaml: chois: field 'rest_frame' must be one of"):
        check_settings({"rest_frame": "R"}, "p.yaml: chois")
