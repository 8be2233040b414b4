"""CHOIS's single-window metrics (Li et al., ECCV 2024) as its released code computes them.

Source: GitHub ``lijiaman/chois_release`` (commit 9cd4cf6), ``evaluation_metrics.py``
``compute_metrics`` (L354-553) and its helpers, and ``trainer_chois.py``
``compute_hand_penetration_metric`` (L909-938) with ``compute_signed_distances`` (L63-87).
Pure numpy functions of predicted and ground-truth arrays of one 120-frame window (30 fps,
z up, metres). docs/metrics.md ("CHOIS") lists every rule and quirk with its line.

Conventions (CHOIS's): ``joints`` (T, 24, 3) joints24 (SMPL-X body joints 0-21, then the
left and right hand joints 22, 23) or (T, 22, 3); ``verts`` (T, V, 3) SMPL-X vertices;
``root_rot`` (T, 3, 3) the root's global rotation; object pose ``obj_rot`` (T, 3, 3) and
``obj_com`` (T, 3) with ``v = R v_rest + com`` (``v_rest`` centred on the vertex mean), so
the object's centre of mass is the mean of its vertices.
Penetration (signed-distance sampling) is in :mod:`hoibench.metrics.chois_sdf`.
"""
from __future__ import annotations

import numpy as np

#: joints24 hand joints (evaluation_metrics.py L387-392); joints22: the wrists
HANDS_24 = (22, 23)
HANDS_22 = (20, 21)
#: contact threshold, metres (L435-439)
CONTACT_M_24 = 0.05
CONTACT_M_22 = 0.10
#: waypoint frames of the xy error (L547)
WAYPOINT_FRAMES = (29, 59, 89)
#: floor estimate (L44-113): toe speed below this (m/frame) is static; DBSCAN eps, min_samples
FLOOR_VEL_M = 0.005
DBSCAN_EPS = 0.005
DBSCAN_MIN_SAMPLES = 3
#: foot sliding heights (L128-129), metres; ankles 7, 8 and toes 10, 11
H_ANKLE, H_TOE = 0.08, 0.04
ANKLES, TOES = (7, 8), (10, 11)


def _arr(x, name: str, ndim: int) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != ndim or a.shape[-1] != 3:
        raise ValueError(f"{name}: expected {ndim} dims ending in 3, got shape {a.shape}")
    return a


def hand_indices(joints: np.ndarray) -> tuple[tuple[int, int], float]:
    """((left, right) hand joint, contact threshold m): joints24 -> 22/23 and 0.05, joints22
    -> 20/21 and 0.10 (``use_joints24``, L387-392, L435-439)."""
    n = np.asarray(joints).shape[1]
    if n == 24:
        return HANDS_24, CONTACT_M_24
    if n == 22:
        return HANDS_22, CONTACT_M_22
    raise ValueError(f"joints: expected 24 (joints24) or 22 joints, got {n}")


def hand_jpe(pred_joints, gt_joints) -> tuple[float, float, float]:
    """(lhand_jpe, rhand_jpe, hand_jpe) mm: mean over frames of the global hand-joint
    distance, and the mean of the two (L393-399)."""
    p, g = _arr(pred_joints, "pred_joints", 3), _arr(gt_joints, "gt_joints", 3)
    (lh, rh), _ = hand_indices(p)
    left = float(np.linalg.norm(p[:, lh] - g[:, lh], axis=1).mean() * 1000)
    right = float(np.linalg.norm(p[:, rh] - g[:, rh], axis=1).mean() * 1000)
    return left, right, (left + right) / 2.0


def mpjpe(pred_joints, gt_joints) -> float:
    """mm: mean joint distance after subtracting each frame's root joint (L409-413); all
    joints, the root's zero distance included."""
    p, g = _arr(pred_joints, "pred_joints", 3), _arr(gt_joints, "gt_joints", 3)
    return float(np.linalg.norm((p - p[:, :1]) - (g - g[:, :1]), axis=2).mean() * 1000)


def mpvpe(pred_verts, gt_verts, pred_joints, gt_joints) -> float:
    """mm: mean vertex distance, vertices relative to each frame's root joint (L402-406)."""
    pv, gv = _arr(pred_verts, "pred_verts", 3), _arr(gt_verts, "gt_verts", 3)
    p, g = _arr(pred_joints, "pred_joints", 3), _arr(gt_joints, "gt_joints", 3)
    return float(np.linalg.norm((pv - p[:, :1]) - (gv - g[:, :1]), axis=2).mean() * 1000)


def trans_err(pred_trans, gt_trans) -> float:
    """mm: mean distance of the root translations (L416). CHOIS's translation is the root
    joint plus the subject's ``trans2joint``, the same for both, so root joints give it too."""
    p, g = _arr(pred_trans, "pred_trans", 2), _arr(gt_trans, "gt_trans", 2)
    return float(np.linalg.norm(p - g, axis=1).mean() * 1000)


def frobenius_rot_dist(pred_rot, gt_rot) -> float:
    """Mean over frames of ``||I - R_pred R_gt^-1||_F`` (``get_frobenious_norm_rot_only``,
    L16-25; the inverse is a matrix inverse, equal to the transpose for rotations)."""
    p = np.asarray(pred_rot, np.float64).reshape(-1, 3, 3)
    g = np.asarray(gt_rot, np.float64).reshape(-1, 3, 3)
    if len(p) != len(g) or not len(p):
        raise ValueError(f"rotations: {len(p)} predicted and {len(g)} ground-truth frames")
    err = np.eye(3) - p @ np.linalg.inv(g)
    return float(np.sqrt((err ** 2).sum(axis=(1, 2))).mean())


def rot_dist(pred_root_rot, gt_root_rot) -> float:
    """The root's global rotation distance (L419-421): ``(T, 3, 3)``, or ``(T, J, 3, 3)`` of
    which joint 0 is taken."""
    p, g = np.asarray(pred_root_rot), np.asarray(gt_root_rot)
    if p.ndim == 4:
        p, g = p[:, 0], g[:, 0]
    return frobenius_rot_dist(p, g)


# ------------------------------------------------------------------------ floor, foot sliding
def dbscan_labels_1d(values, eps: float = DBSCAN_EPS, min_samples: int = DBSCAN_MIN_SAMPLES) -> np.ndarray:
    """scikit-learn's DBSCAN labels (``DBSCAN(eps, min_samples).fit``, Euclidean) of 1-D
    values; noise is -1 (L83)."""
    from sklearn.cluster import DBSCAN
    x = np.asarray(values, np.float64).reshape(-1, 1)
    return DBSCAN(eps=eps, min_samples=min_samples).fit(x).labels_


def floor_height(joints) -> float:
    """CHOIS's floor estimate (``determine_floor_height_and_contacts``, L44-113), metres.

    Toe (joints 10, 11) speeds ``|x[t+1] - x[t]|`` with the last repeated; the heights (z) of
    frames below 0.005 m/frame, left then right, are clustered by 1-D DBSCAN (eps 0.005,
    min_samples 3); the floor is the smallest cluster median. Quirk kept: the noise label -1
    is one more "cluster" (``np.unique`` of the labels), so a lone low toe height can be the
    floor. No static frame: 0. (The returned value is the median itself; the 0.01 m
    ``offset_floor_height`` is computed and unused.)"""
    j = _arr(joints, "joints", 3)
    heights = []
    for toe in TOES:
        seq = j[:, toe]
        vel = np.linalg.norm(seq[1:] - seq[:-1], axis=1)
        vel = np.append(vel, vel[-1])
        heights.append(seq[vel < FLOOR_VEL_M, 2])
    h = np.concatenate(heights)
    if not len(h):
        return 0.0
    labels = dbscan_labels_1d(h)
    return float(min(np.median(h[labels == lab]) for lab in np.unique(labels)))


def foot_sliding(joints, floor: float) -> float:
    """CHOIS's weighted foot sliding (``compute_foot_sliding_for_smpl``, L115-155): heights
    relative to ``floor``; for each of left ankle (7, H 0.08 m), left toe (10, H 0.04 m),
    right ankle (8), right toe (11): ``sum over t < T-1 with z_t < H of |d_xy(t)| * (2 -
    2^(z_t / H))`` divided by T (not T-1) times 1000; the mean of the four. Units: metres
    per 1,000 frames. (CHOIS subtracts the floor in place; its tensors live on the GPU so
    the copy changes nothing else, which is the behaviour kept here.)"""
    j = _arr(joints, "joints", 3).copy()
    j[:, :, 2] -= floor
    total = 0.0
    for idx, height in ((ANKLES[0], H_ANKLE), (TOES[0], H_TOE), (ANKLES[1], H_ANKLE), (TOES[1], H_TOE)):
        pos = j[:, idx]
        disp = np.linalg.norm(pos[1:, :2] - pos[:-1, :2], axis=1)
        z = pos[:-1, 2]
        stats = np.abs(disp * (2 - 2 ** (z / height)))[z < height]
        total += stats.sum() / len(j) * 1000
    return total / 4.0


# ------------------------------------------------------------------------------- contact
def hand_object_min_dist(joints, obj_verts) -> np.ndarray:
    """(T, 2): per frame, the smallest distance from the left and right hand joint to the
    object's vertices (L441-449)."""
    j, v = _arr(joints, "joints", 3), _arr(obj_verts, "obj_verts", 3)
    (lh, rh), _ = hand_indices(j)
    hands = j[:, [lh, rh]]                                      # (T, 2, 3)
    d = np.linalg.norm(hands[:, :, None, :] - v[:, None, :, :], axis=-1)
    return d.min(axis=2)


def contact_labels(joints, obj_verts, threshold: float | None = None) -> np.ndarray:
    """(T,) bool: either hand joint closer than the threshold (strict ``<``; 0.05 m
    joints24, 0.10 m joints22) to an object vertex (L451-464, L495-496)."""
    thr = hand_indices(joints)[1] if threshold is None else threshold
    return (hand_object_min_dist(joints, obj_verts) < thr).any(axis=1)


def contact_scores(gt_contact, pred_contact) -> dict[str, float]:
    """CHOIS's contact counts (L466-532) from per-frame labels: ``gt_contact_percent``,
    ``pred_contact_percent`` (fractions of frames, not percent), ``contact_precision``
    (0 when the prediction has no contact frame), ``contact_recall`` (0 when the GT has
    none), ``contact_acc`` ((TP + TN) / T), ``contact_f1`` (0 when precision and recall are
    both 0). No frame is "undefined": a clip without GT contact scores recall 0."""
    g, p = np.asarray(gt_contact, bool), np.asarray(pred_contact, bool)
    tp, fp = int((g & p).sum()), int((~g & p).sum())
    tn, fn = int((~g & ~p).sum()), int((g & ~p).sum())
    n = len(g)
    precision = 0.0 if tp + fp == 0 else tp / (tp + fp)
    recall = 0.0 if tp + fn == 0 else tp / (tp + fn)
    f1 = 0.0 if precision == 0 and recall == 0 else 2 * precision * recall / (precision + recall)
    return {"gt_contact_percent": int(g.sum()) / n, "pred_contact_percent": int(p.sum()) / n,
            "contact_precision": precision, "contact_recall": recall, "contact_acc": (tp + tn) / n,
            "contact_f1": f1}


# -------------------------------------------------------------------------------- object
def object_errors(pred_com, gt_com, pred_obj_rot, gt_obj_rot) -> dict[str, float]:
    """``obj_rot_dist`` (Frobenius, L535-537), ``obj_com_pos_err`` (mm, mean over frames,
    L541), ``start_obj_com_pos_err`` / ``end_obj_com_pos_err`` (mm, first / last frame of the
    arrays, L544-545: the whole window, padding included) and ``waypoints_xy_pos_err`` (mm,
    mean xy distance at frames 29, 59, 89, L547-549; NaN for fewer than 90 frames, where
    CHOIS's indexing fails)."""
    p, g = _arr(pred_com, "pred_obj_com", 2), _arr(gt_com, "gt_obj_com", 2)
    dist = np.linalg.norm(p - g, axis=1)
    wp = list(WAYPOINT_FRAMES)
    way = float(np.linalg.norm(p[wp, :2] - g[wp, :2], axis=1).mean() * 1000) if len(p) > wp[-1] else float("nan")
    return {"obj_rot_dist": frobenius_rot_dist(pred_obj_rot, gt_obj_rot),
            "obj_com_pos_err": float(dist.mean() * 1000), "start_obj_com_pos_err": float(dist[0] * 1000),
            "end_obj_com_pos_err": float(dist[-1] * 1000), "waypoints_xy_pos_err": way}


def object_vertices(rest_verts, obj_rot, obj_com) -> np.ndarray:
    """(T, V, 3) ``R v_rest + com`` (``load_object_geometry_w_rest_geo``)."""
    r = np.asarray(obj_rot, np.float64)
    return np.einsum("tij,vj->tvi", r, np.asarray(rest_verts, np.float64)) + np.asarray(obj_com)[:, None, :]


def compute_metrics(pred_joints, gt_joints, pred_obj_verts, gt_obj_verts, pred_obj_com, gt_obj_com,
                    pred_obj_rot, gt_obj_rot, *, pred_verts=None, gt_verts=None, pred_trans=None, gt_trans=None,
                    pred_root_rot=None, gt_root_rot=None) -> dict[str, float]:
    """Every number of ``compute_metrics`` (L354-553) for one window, by name. Optional
    inputs: ``*_verts`` (mpvpe; NaN without), ``*_trans`` (trans_err; the root joints
    otherwise), ``*_root_rot`` (rot_dist; NaN without). All frames of the arrays count
    (CHOIS's ``actual_len`` cropping is commented out, L371-384)."""
    p, g = _arr(pred_joints, "pred_joints", 3), _arr(gt_joints, "gt_joints", 3)
    if p.shape != g.shape:
        raise ValueError(f"pred_joints {p.shape} and gt_joints {g.shape} differ")
    out: dict[str, float] = {}
    out["lhand_jpe"], out["rhand_jpe"], out["hand_jpe"] = hand_jpe(p, g)
    out["mpvpe"] = mpvpe(pred_verts, gt_verts, p, g) if pred_verts is not None and gt_verts is not None \
        else float("nan")
    out["mpjpe"] = mpjpe(p, g)
    out["trans_err"] = trans_err(p[:, 0] if pred_trans is None else pred_trans,
                                 g[:, 0] if gt_trans is None else gt_trans)
    out["rot_dist"] = rot_dist(pred_root_rot, gt_root_rot) if pred_root_rot is not None and gt_root_rot is not None \
        else float("nan")
    pf, gf = floor_height(p), floor_height(g)
    out["floor_height"], out["gt_floor_height"] = pf, gf
    out["foot_sliding"], out["gt_foot_sliding"] = foot_sliding(p, pf), foot_sliding(g, gf)
    out.update(contact_scores(contact_labels(g, gt_obj_verts), contact_labels(p, pred_obj_verts)))
    out.update(object_errors(pred_obj_com, gt_obj_com, pred_obj_rot, gt_obj_rot))
    return out


__all__ = ["hand_indices", "hand_jpe", "mpjpe", "mpvpe", "trans_err", "frobenius_rot_dist", "rot_dist",
           "dbscan_labels_1d", "floor_height", "foot_sliding", "hand_object_min_dist", "contact_labels",
           "contact_scores", "object_errors", "object_vertices", "compute_metrics"]
