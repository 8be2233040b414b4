"""CHOIS's metrics against numbers computed by CHOIS's own released code.

Source of every recorded value: GitHub lijiaman/chois_release @ 9cd4cf6, run outside this
repository (a throwaway directory; CPU, torch 2.13.0+cpu, numpy 2.4.6, scikit-learn 1.9.1)
on the inputs built by :func:`make_clip` and :func:`make_penetration` below, which the
driver script imported from this file so the inputs are the same arrays:

* ``evaluation_metrics.py`` ``compute_metrics`` (the file unchanged, imported as a module;
  its 22 return values by name) on :func:`make_clip` as float64 torch tensors, the human
  rotations as (T, 22, 3, 3), ``use_joints24`` True for 24 joints and False for 22,
  ``actual_len`` T, ``human_faces`` / ``obj_faces`` None (the function does not read them).
  Device: on CUDA ``.cpu().numpy()`` is a copy, on CPU a view, so ``compute_foot_sliding_for_smpl``
  (which lowers the joints by the floor in place) would also lower the hand joints that the
  contact scores read after it. The driver replaced the module's
  ``compute_foot_sliding_for_smpl`` by a wrapper that calls the original on a copy of its
  argument: the CUDA behaviour, which hoibench keeps. (Without it the hand joints are lowered
  by the floor estimate before the contact test, and every clip's contact scores change.)
* ``evaluation_metrics.py`` ``compute_collision`` (same module; the only edit: its hard-coded
  ``object_sdf_folder`` path pointed at the directory holding the grids below as
  ``<name>_cleaned_simplified.obj.npy`` / ``.obj.json``), ``actual_len`` = T, float64 tensors;
  once with the ``centroid``/``extents`` json and once with the SIREN ``coord_center`` json.
* ``trainer_chois.py`` ``compute_signed_distances`` (L63-87) and the methods
  ``load_object_sdf_data`` (L314-334) and ``compute_hand_penetration_metric`` (L909-938),
  copied out of the file into a stand-alone script, ``self`` a small object holding
  ``data_root_folder``, ``test_unseen_objects=False`` and ``hand_vertex_idxs``; the only
  edit: ``.cuda()`` dropped (CPU). Inputs as float32 tensors (the grid is float32 there),
  the grid written as ``<name>.ply.npy`` / ``.ply.json``; once with the hand vertex ids and
  once with ``eval_fullbody=True``.

Tolerances: compute_metrics ran in float64, so rtol 1e-9 (contact counts exactly; the
largest difference seen was 5e-16). The penetration references sample the grid in float32
(``.float()`` in CHOIS) while hoibench works in float64, so those compare at rtol 1e-6 (seen:
1.3e-7 at most); the inputs are float32-representable so both sides read the same numbers.
"""
from __future__ import annotations

import numpy as np
import pytest

from hoibench.metrics import chois as ch
from hoibench.metrics.chois_sdf import SdfGrid, collision_penetration, hand_penetration

T = 120
#: the clips of the compute_metrics references: seed, joint count, whether the GT holds the object
CLIPS = {"joints24": (11, 24, True), "joints24_no_gt_contact": (12, 24, False), "joints22": (13, 22, True)}
PEN_SEED = 21


# ------------------------------------------------------------------------------ input generators
def _smooth(rs: np.random.RandomState, shape, scale: float, a: float = 0.85) -> np.ndarray:
    """AR(1)-filtered Gaussian noise along axis 0 (bounded and smooth), times ``scale``."""
    shape = (shape,) if np.isscalar(shape) else tuple(shape)
    e = rs.standard_normal(shape)
    out = np.zeros(shape)
    out[0] = e[0] * np.sqrt(1 - a * a)
    for t in range(1, shape[0]):
        out[t] = a * out[t - 1] + np.sqrt(1 - a * a) * e[t]
    return out * scale


def _rotvec_to_mat(rv) -> np.ndarray:
    rv = np.asarray(rv, np.float64)
    th = np.linalg.norm(rv, axis=-1)[..., None, None]
    k = rv / np.where(th[..., 0] > 0, th[..., 0], 1.0)
    kx = np.zeros(rv.shape[:-1] + (3, 3))
    kx[..., 0, 1], kx[..., 0, 2], kx[..., 1, 2] = -k[..., 2], k[..., 1], -k[..., 0]
    kx[..., 1, 0], kx[..., 2, 0], kx[..., 2, 1] = k[..., 2], -k[..., 1], k[..., 0]
    return np.eye(3) + np.sin(th) * kx + (1 - np.cos(th)) * (kx @ kx)


def _rot_z(theta) -> np.ndarray:
    theta = np.asarray(theta, np.float64)
    return _rotvec_to_mat(np.stack([np.zeros_like(theta), np.zeros_like(theta), theta], -1))


def _feet(rs, floor: float, start, fwd, lat, drift: float):
    """Toes and ankles (left, right) of a walk on the floor ``floor``: 30-frame cycles of 18
    stance frames (xy drifting ``drift`` m/frame per axis, z within ~1 mm of the floor: the
    static frames of CHOIS's floor estimate and the sliding of its foot score) and 12 swing
    frames (0.5 m step, 12 cm lift); the right foot half a cycle behind."""
    toes, ankles = [], []
    for sign, lag in ((1.0, 0), (-1.0, 15)):
        cur = start + sign * 0.1 * lat
        lift = np.zeros(T)
        xy = np.zeros((T, 3))
        swing_from = cur.copy()
        for t in range(T):
            ph = (t + lag) % 30
            if ph < 18:
                cur = cur + np.append(rs.standard_normal(2) * drift, 0.0)
                lift[t] = rs.standard_normal() * 0.0008
            else:
                if ph == 18:
                    swing_from = cur.copy()
                s = (ph - 17) / 12.0
                cur = swing_from + fwd * 0.5 * s
                lift[t] = 0.12 * np.sin(np.pi * s)
            xy[t] = cur
        toe = xy.copy()
        toe[:, 2] = floor + lift
        ankle = toe - 0.13 * fwd
        ankle[:, 2] = floor + 0.065 + 0.8 * lift + rs.standard_normal(T) * 0.002
        toes.append(toe)
        ankles.append(ankle)
    return toes, ankles


def _ramp(a, b) -> np.ndarray:
    """0 before frame a, up to 1 over 10 frames, 1 until b, down to 0 over 10 frames."""
    t = np.arange(T, dtype=np.float64)
    if a is None:
        return np.zeros(T)
    return np.clip(np.minimum((t - a) / 10.0, (b + 10 - t) / 10.0), 0.0, 1.0)


BOX_REST_HALF = np.array([0.2, 0.15, 0.25])


def box_rest_vertices() -> np.ndarray:
    """(98, 3): the surface points of a 5x5x5 lattice on a 0.4 x 0.3 x 0.5 m box, centred on 0."""
    ax = np.linspace(-1.0, 1.0, 5)
    g = np.stack(np.meshgrid(ax, ax, ax, indexing="ij"), -1).reshape(-1, 3)
    g = g[(np.abs(g) == 1.0).any(axis=1)]
    return g * BOX_REST_HALF


def make_clip(seed: int, joints: int = 24, gt_contact: bool = True) -> dict:
    """One 120-frame window, ground truth and prediction (z up, metres), deterministic from
    ``seed``: a walk (feet on floors 0.012 m (GT) and -0.018 m (prediction), toe drift 1 and
    2.2 mm/frame; the GT's right foot on a 10 cm step from frame 100, the prediction's left
    toe 2.5 cm lower over frames 63-65), the body following, 150 body "vertices", root
    rotations (T, 22, 3, 3), a box of 98 vertices carried in front; both hands (joints
    22/23, or 20/21 for 22 joints) move onto the middles of its side faces (GT frames
    ~25-90, prediction ~30-98, stand-off 2 / 3 cm for joints24, 5 / 7 cm for joints22).
    ``gt_contact=False``: the GT hands never leave the body's sides (no GT contact frame)."""
    rs = np.random.RandomState(seed)
    heading = rs.uniform(-np.pi, np.pi)
    fwd = np.array([np.cos(heading), np.sin(heading), 0.0])
    lat = np.array([-np.sin(heading), np.cos(heading), 0.0])
    start = np.append(rs.uniform(-1.0, 1.0, 2), 0.0)
    tmpl_j = np.stack([rs.uniform(-0.15, 0.15, joints), rs.uniform(-0.25, 0.25, joints),
                       rs.uniform(-0.55, 0.6, joints)], -1)
    tmpl_v = np.stack([rs.uniform(-0.2, 0.2, 150), rs.uniform(-0.3, 0.3, 150), rs.uniform(-0.9, 0.8, 150)], -1)
    rest = box_rest_vertices()
    hands = (22, 23) if joints == 24 else (20, 21)
    off = (0.02, 0.03) if joints == 24 else (0.05, 0.07)
    pred_windows = ((32, 88), (30, 85))                     # (left, right) ramp starts and ends
    windows = {True: (((25, 80), (28, 78)), pred_windows), False: (((None, None),) * 2, pred_windows)}
    out = {}
    for side, floor, drift, jit in (("gt", 0.012, 0.0010, 0.0), ("pred", -0.018, 0.0022, 1.0)):
        toes, ankles = _feet(rs, floor, start, fwd, lat, drift)
        if side == "gt":                      # right foot onto a 10 cm step: a second, higher cluster
            toes[1][100:, 2] += 0.10
            ankles[1][100:, 2] += 0.10
        else:                                 # left toe dips 2.5 cm for 3 frames: one or two lone static
            toes[0][63:66, 2] -= 0.025        # heights, DBSCAN noise (-1), whose median CHOIS takes as the floor
        root = (toes[0] + toes[1]) / 2 + 0.05 * fwd + _smooth(rs, (T, 3), 0.01)
        root[:, 2] = floor + 0.92 + _smooth(rs, T, 0.015)
        yaw = heading + _smooth(rs, T, 0.08)
        tilt = _smooth(rs, (T, 3), 0.04) * [1, 1, 0]
        body_rot = _rot_z(yaw) @ _rotvec_to_mat(tilt)                                   # (T, 3, 3)
        tj = tmpl_j + jit * rs.standard_normal(tmpl_j.shape) * 0.02
        j = root[:, None] + np.einsum("tij,kj->tki", body_rot, tj) + _smooth(rs, (T, joints, 3), 0.008)
        j[:, 0] = root
        j[:, 7], j[:, 8], j[:, 10], j[:, 11] = ankles[0], ankles[1], toes[0], toes[1]
        verts = root[:, None] + np.einsum("tij,kj->tki", body_rot, tmpl_v) + _smooth(rs, (T, 150, 3), 0.005)
        rots = _rotvec_to_mat(rs.standard_normal((T, 22, 3)) * 0.5)
        rots[:, 0] = body_rot
        trans = root + np.array([0.002, -0.001, -0.35])
        obj_yaw = heading + _smooth(rs, T, 0.1)
        obj_rot = _rot_z(obj_yaw) @ _rotvec_to_mat(_smooth(rs, (T, 3), 0.05) * [1, 1, 0])
        com = root + 0.5 * fwd + _smooth(rs, (T, 3), 0.02 * (1 + jit))
        com[:, 2] = floor + 0.95 + _smooth(rs, T, 0.01)
        obj_verts = np.einsum("tij,vj->tvi", obj_rot, rest) + com[:, None]
        win = windows[gt_contact][0 if side == "gt" else 1]
        for k, (h, sign) in enumerate(zip(hands, (1.0, -1.0))):
            idle = root + sign * 0.35 * lat + _smooth(rs, (T, 3), 0.01)
            reach = BOX_REST_HALF[1] + off[0 if side == "gt" else 1]
            grasp = np.einsum("tij,j->ti", obj_rot, [0.0, sign * reach, 0.0]) + com + _smooth(rs, (T, 3), 0.004)
            w = _ramp(*win[k])[:, None]
            j[:, h] = (1 - w) * idle + w * grasp
        out[side] = {"joints": j, "verts": verts, "trans": trans, "rot": rots, "obj_com": com, "obj_rot": obj_rot,
                     "obj_verts": obj_verts}
    out["obj_rest"] = rest
    return out


# The rest-pose object of the penetration references: a box, its signed distance known in closed form.
PEN_BOX_CENTRE = np.array([0.03, -0.02, 0.05])
PEN_BOX_HALF = np.array([0.25, 0.15, 0.10])
PEN_GRID_N = 41
#: the SIREN-style normalisation of the second grid (compute_collision L268-277)
PEN_SIREN = {"coord_center": [0.01, -0.03, 0.02], "coord_min": -0.3, "coord_max": 0.35}


def box_sdf(q) -> np.ndarray:
    """Exact signed distance (m) to the box ``PEN_BOX_CENTRE`` +- ``PEN_BOX_HALF``; negative
    inside. (Checked, outside the suite, against trimesh's ``proximity.signed_distance`` of
    ``trimesh.creation.box`` on the ``rest`` points of :func:`make_penetration`: equal to
    1e-16, sign flipped.)"""
    d = np.abs(np.asarray(q, np.float64) - PEN_BOX_CENTRE) - PEN_BOX_HALF
    return np.linalg.norm(np.maximum(d, 0.0), axis=-1) + np.minimum(d.max(axis=-1), 0.0)


def _f32(x) -> np.ndarray:
    return np.asarray(x, np.float32).astype(np.float64)


def make_penetration(seed: int = PEN_SEED) -> dict:
    """Grids and posed vertices for the penetration measures, float32-representable.

    ``grid``: (41, 41, 41) in CHOIS's layout, ``grid[i, j, k]`` = the box's signed distance
    at ``centroid + (u_i, u_j, u_k) * max(extents) / 2`` (``u`` = linspace(-1, 1, 41); x
    along the first axis) divided by ``max(extents) / 2`` (the normalised units that
    trainer_chois rescales to metres); centroid/extents those of the box. ``grid_siren``: the
    box's distance in metres at ``coord_center + coord_min + (u + 1) / 2 * (coord_max -
    coord_min)``. ``rest``: (24, 60, 3) rest-frame vertices: frames 0-3 1 m away, 4-9 within
    4 mm of the box's surface (shallower than compute_collision's 0.04), 10-23 clouds of
    growing spread around the box (some deep, some outside the grid). ``hand_verts`` =
    ``R^T rest + com`` (so CHOIS's ``R (v - com)`` gives ``rest``); ``coll_verts`` = ``s R
    rest + t`` (so ``R^T (v - t) / s`` gives ``rest``)."""
    rs = np.random.RandomState(seed)
    n_t, n_v = 24, 60
    hw = PEN_BOX_HALF.max()
    u = np.linspace(-1.0, 1.0, PEN_GRID_N)
    lattice = np.stack(np.meshgrid(u, u, u, indexing="ij"), -1)
    grid = _f32(box_sdf(PEN_BOX_CENTRE + lattice * hw) / hw)
    s = PEN_SIREN
    grid_siren = _f32(box_sdf(np.asarray(s["coord_center"]) + s["coord_min"]
                              + (lattice + 1.0) / 2.0 * (s["coord_max"] - s["coord_min"])))
    rest = np.zeros((n_t, n_v, 3))
    for t in range(n_t):
        if t < 4:
            rest[t] = PEN_BOX_CENTRE + [1.0, 0.3, -0.2] + rs.uniform(-0.1, 0.1, (n_v, 3))
        elif t < 10:
            axis = rs.randint(0, 3, n_v)
            sign = rs.choice([-1.0, 1.0], n_v)
            p = rs.uniform(-0.9, 0.9, (n_v, 3)) * PEN_BOX_HALF
            p[np.arange(n_v), axis] = sign * (PEN_BOX_HALF[axis] + rs.uniform(-0.004, 0.004, n_v))
            rest[t] = PEN_BOX_CENTRE + p
        else:
            spread = 0.5 + (t - 10) * 0.12
            rest[t] = PEN_BOX_CENTRE + rs.uniform(-1.0, 1.0, (n_v, 3)) * PEN_BOX_HALF * spread
    rot = _f32(_rotvec_to_mat(rs.standard_normal((n_t, 3)) * 0.8))
    com = _f32(rs.uniform(-1.0, 1.0, (n_t, 3)))
    trans = _f32(rs.uniform(-1.0, 1.0, (n_t, 3)))
    scale = _f32(rs.uniform(0.8, 1.25, n_t))
    return {"grid": grid, "centroid": _f32(PEN_BOX_CENTRE), "extents": _f32(2 * PEN_BOX_HALF),
            "grid_siren": grid_siren, "siren": dict(PEN_SIREN), "rest": rest,
            "hand_ids": np.arange(0, n_v, 3), "rot": rot, "com": com, "trans": trans, "scale": scale,
            "hand_verts": _f32(np.einsum("tji,tvj->tvi", rot, rest) + com[:, None]),
            "coll_verts": _f32(scale[:, None, None] * np.einsum("tij,tvj->tvi", rot, rest) + trans[:, None])}


# ------------------------------------------------------------------------------ recorded values
# lijiaman/chois_release @ 9cd4cf6, evaluation_metrics.py compute_metrics (L354-553), run
# outside this repository on make_clip(*CLIPS[name]) as described in the module docstring.
REFERENCE_METRICS = {
    'joints24': {
        'lhand_jpe': 107.03929212178176,
        'rhand_jpe': 79.64945389768954,
        'hand_jpe': 93.34437300973565,
        'mpvpe': 39.7703842875287,
        'mpjpe': 47.823296339641765,
        'rot_dist': 0.1799286829352088,
        'trans_err': 42.848155996360376,
        'gt_contact_percent': 0.38333333333333336,
        'pred_contact_percent': 0.4083333333333333,
        'gt_foot_sliding': 1.6636573096426925,
        'foot_sliding': 0.677338960503248,
        'contact_precision': 0.8367346938775511,
        'contact_recall': 0.8913043478260869,
        'contact_acc': 0.8916666666666667,
        'contact_f1': 0.8631578947368421,
        'obj_rot_dist': 0.2669016103272559,
        'obj_com_pos_err': 72.2313100726529,
        'start_obj_com_pos_err': 48.073132695138895,
        'end_obj_com_pos_err': 62.132738486768545,
        'waypoints_xy_pos_err': 46.82673749363649,
        'gt_floor_height': 0.012029303029893702,
        'floor_height': -0.043861104707958676,
    },
    'joints24_no_gt_contact': {
        'lhand_jpe': 255.66359879808542,
        'rhand_jpe': 253.0538002473161,
        'hand_jpe': 254.35869952270076,
        'mpvpe': 40.91164362567549,
        'mpjpe': 57.97786355152189,
        'rot_dist': 0.17156328488426517,
        'trans_err': 37.60664338198796,
        'gt_contact_percent': 0.0,
        'pred_contact_percent': 0.4083333333333333,
        'gt_foot_sliding': 1.6634351941874033,
        'foot_sliding': 0.6774585188687093,
        'contact_precision': 0.0,
        'contact_recall': 0.0,
        'contact_acc': 0.5916666666666667,
        'contact_f1': 0.0,
        'obj_rot_dist': 0.19586723894490898,
        'obj_com_pos_err': 67.09818525350114,
        'start_obj_com_pos_err': 41.013258872228434,
        'end_obj_com_pos_err': 93.98720535410222,
        'waypoints_xy_pos_err': 19.455274190582678,
        'gt_floor_height': 0.012013867336378036,
        'floor_height': -0.0435593534469193,
    },
    'joints22': {
        'lhand_jpe': 105.31516438057778,
        'rhand_jpe': 70.20781036837654,
        'hand_jpe': 87.76148737447716,
        'mpvpe': 41.54884832406488,
        'mpjpe': 46.60456718283762,
        'rot_dist': 0.1593211375657567,
        'trans_err': 39.01849403605781,
        'gt_contact_percent': 0.4166666666666667,
        'pred_contact_percent': 0.4583333333333333,
        'gt_foot_sliding': 1.6740649305198492,
        'foot_sliding': 0.6752460365104336,
        'contact_precision': 0.8181818181818182,
        'contact_recall': 0.9,
        'contact_acc': 0.875,
        'contact_f1': 0.8571428571428572,
        'obj_rot_dist': 0.21229736584376738,
        'obj_com_pos_err': 69.5282028048385,
        'start_obj_com_pos_err': 45.46922873172103,
        'end_obj_com_pos_err': 105.94173693969066,
        'waypoints_xy_pos_err': 56.82993598504483,
        'gt_floor_height': 0.011950913115098123,
        'floor_height': -0.04321387385306,
    },
}

# lijiaman/chois_release @ 9cd4cf6: "hand_penetration"/"penetration" from trainer_chois.py
# compute_hand_penetration_metric (L909-938, hand ids / eval_fullbody=True); "collision*" from
# evaluation_metrics.py compute_collision (L235-352) as (pen_percent, pen_loss); run outside this
# repository on make_penetration() as described in the module docstring.
REFERENCE_PENETRATION = {
    'hand_penetration': 0.01560129877179861,
    'penetration': 0.015759801492094994,
    'collision': (0.5833333333333334, 0.17779375612735748),
    'collision_siren': (0.5833333333333334, 0.06137485057115555),
}


# ------------------------------------------------------------------------------ tests
RTOL_METRICS = 1e-9          # CHOIS ran in float64 here (seen: <= 5.3e-16, most bit-equal)
RTOL_PENETRATION = 1e-6      # CHOIS samples its float32 grid at float32 coordinates (seen: <= 1.3e-7)


def _hoibench_metrics(c: dict) -> dict:
    g, p = c["gt"], c["pred"]
    return ch.compute_metrics(p["joints"], g["joints"], p["obj_verts"], g["obj_verts"], p["obj_com"], g["obj_com"],
                              p["obj_rot"], g["obj_rot"], pred_verts=p["verts"], gt_verts=g["verts"],
                              pred_trans=p["trans"], gt_trans=g["trans"], pred_root_rot=p["rot"],
                              gt_root_rot=g["rot"])


@pytest.fixture(scope="module")
def clips() -> dict:
    return {name: make_clip(*args) for name, args in CLIPS.items()}


@pytest.mark.parametrize("name", list(CLIPS))
def test_compute_metrics_gives_chois_numbers(clips, name):
    """Every number of CHOIS's compute_metrics, by name, on joints24, joints24 without GT
    contact, and joints22 (wrists, 0.10 m)."""
    ref = REFERENCE_METRICS[name]
    out = _hoibench_metrics(clips[name])
    assert set(out) == set(ref)
    for k, v in ref.items():
        assert out[k] == pytest.approx(v, rel=RTOL_METRICS, abs=1e-12), k


@pytest.mark.parametrize("name", list(CLIPS))
def test_each_helper_gives_chois_numbers(clips, name):
    """The helpers one by one against the same recorded numbers."""
    ref, c = REFERENCE_METRICS[name], clips[name]
    g, p = c["gt"], c["pred"]
    approx = lambda v: pytest.approx(v, rel=RTOL_METRICS, abs=1e-12)   # noqa: E731
    assert ch.hand_jpe(p["joints"], g["joints"]) == approx((ref["lhand_jpe"], ref["rhand_jpe"], ref["hand_jpe"]))
    assert ch.mpjpe(p["joints"], g["joints"]) == approx(ref["mpjpe"])
    assert ch.mpvpe(p["verts"], g["verts"], p["joints"], g["joints"]) == approx(ref["mpvpe"])
    assert ch.trans_err(p["trans"], g["trans"]) == approx(ref["trans_err"])
    assert ch.rot_dist(p["rot"], g["rot"]) == approx(ref["rot_dist"])
    assert ch.rot_dist(p["rot"][:, 0], g["rot"][:, 0]) == approx(ref["rot_dist"])
    assert ch.floor_height(p["joints"]) == approx(ref["floor_height"])
    assert ch.floor_height(g["joints"]) == approx(ref["gt_floor_height"])
    assert ch.foot_sliding(p["joints"], ref["floor_height"]) == approx(ref["foot_sliding"])
    assert ch.foot_sliding(g["joints"], ref["gt_floor_height"]) == approx(ref["gt_foot_sliding"])
    scores = ch.contact_scores(ch.contact_labels(g["joints"], g["obj_verts"]),
                               ch.contact_labels(p["joints"], p["obj_verts"]))
    assert scores == {k: approx(ref[k]) for k in scores}
    errs = ch.object_errors(p["obj_com"], g["obj_com"], p["obj_rot"], g["obj_rot"])
    assert errs == {k: approx(ref[k]) for k in errs}
    assert np.allclose(ch.object_vertices(c["obj_rest"], p["obj_rot"], p["obj_com"]), p["obj_verts"])


def test_the_clips_exercise_what_they_are_meant_to():
    """The recorded numbers show the cases: contact in both and partly overlapping (0 < P, R
    < 1); no GT contact (recall, precision and F1 0 while the prediction has contact); the
    GT floor from the lower of two DBSCAN clusters; the prediction's floor the median of
    the noise label (the dip, 2.5 cm under its -0.018 m floor); feet sliding on both sides."""
    for name in ("joints24", "joints22"):
        r = REFERENCE_METRICS[name]
        assert 0 < r["contact_precision"] < 1 and 0 < r["contact_recall"] < 1 and 0 < r["gt_contact_percent"]
    r = REFERENCE_METRICS["joints24_no_gt_contact"]
    assert r["gt_contact_percent"] == 0 and r["pred_contact_percent"] > 0
    assert r["contact_recall"] == r["contact_precision"] == r["contact_f1"] == 0
    assert r["contact_acc"] == pytest.approx(1 - r["pred_contact_percent"])
    for r in REFERENCE_METRICS.values():
        assert 0.0115 < r["gt_floor_height"] < 0.0125 and -0.045 < r["floor_height"] < -0.040
        assert r["foot_sliding"] > 0.1 and r["gt_foot_sliding"] > 0.1


def test_penetration_grid_is_the_box_in_chois_layout():
    """The constructed grid holds the box's exact signed distance with x along the first axis:
    the centre is 0.10 m deep (the half height), and the far x face sits on the grid's ends."""
    d = make_penetration()
    n = PEN_GRID_N
    hw = PEN_BOX_HALF.max()
    assert d["grid"][n // 2, n // 2, n // 2] * hw == pytest.approx(-0.10, abs=1e-7)
    assert d["grid"][0, n // 2, n // 2] == pytest.approx(0.0, abs=1e-7)
    assert d["grid"][n // 2, 0, n // 2] * hw == pytest.approx(0.25 - 0.15, abs=1e-7)   # y: outside by 0.10


def test_hand_penetration_gives_chois_numbers_and_the_known_depth():
    """trainer_chois compute_hand_penetration_metric with the hand ids and with the whole body,
    and both close to the box's exact depth (the grid's trilinear reading, 1.25 cm cells)."""
    d = make_penetration()
    sdf = SdfGrid(d["grid"], centroid=d["centroid"], extents=d["extents"])
    hand = hand_penetration(d["hand_verts"], d["com"], d["rot"], sdf, vertex_ids=d["hand_ids"])
    full = hand_penetration(d["hand_verts"], d["com"], d["rot"], sdf)
    assert hand == pytest.approx(REFERENCE_PENETRATION["hand_penetration"], rel=RTOL_PENETRATION)
    assert full == pytest.approx(REFERENCE_PENETRATION["penetration"], rel=RTOL_PENETRATION)
    exact = box_sdf(d["rest"])
    assert hand == pytest.approx(np.abs(np.minimum(exact[:, d["hand_ids"]], 0)).mean(), abs=2e-4)
    assert full == pytest.approx(np.abs(np.minimum(exact, 0)).mean(), abs=2e-4)


@pytest.mark.parametrize("key", ["collision", "collision_siren"])
def test_collision_penetration_gives_chois_numbers(key):
    """evaluation_metrics compute_collision, (pen_percent, pen_loss), with the centroid/extents
    grid and with the SIREN coord_center grid; the counted frames match the exact box."""
    d = make_penetration()
    if key == "collision":
        sdf = SdfGrid(d["grid"], centroid=d["centroid"], extents=d["extents"])
        unit = PEN_BOX_HALF.max()
    else:
        s = d["siren"]
        sdf = SdfGrid(d["grid_siren"], coord_center=np.asarray(s["coord_center"]), coord_min=s["coord_min"],
                      coord_max=s["coord_max"])
        unit = 1.0
    pct, depth = collision_penetration(d["coll_verts"], d["rot"], d["trans"], d["scale"], sdf)
    ref_pct, ref_depth = REFERENCE_PENETRATION[key]
    assert pct == ref_pct
    assert depth == pytest.approx(ref_depth, rel=RTOL_PENETRATION)
    exact = box_sdf(d["rest"]) / unit * d["scale"][:, None]
    counted = ((exact < 0) & (-exact > 0.04)).any(axis=1)
    assert pct == counted.mean() and 0 < pct < 1
