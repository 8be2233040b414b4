"""InterAct's metrics for its object-to-human and human-to-object tasks, as its code computes them.

Besides text-to-interaction, InterAct (Xu et al., CVPR 2025; GitHub ``wzyabcas/InterAct`` @
``daa7945``) benchmarks generating the human from the object's motion (``object2human/``) and
the object from the human's motion (``human2object/``). Both are scored on body-surface
markers (77 per frame, metres, :mod:`hoibench.bodies.markers`) and posed object vertices by
``object2human/evaluation_metrics.py`` / ``human2object/evaluation_metrics.py``, per sequence
over K samples (10 and 5) of which one is kept by a selection metric (``eval_saved.py``), then
averaged over sequences. These functions reproduce them on arrays (float64 numpy); they are
the building blocks of tracks for those tasks, not yet registered as result metrics.

Shared definitions (``compute_body_contact_metrics`` / ``compute_metrics_obj_marker``):

* ``d_t = min over the chosen markers m and object points p of |m - p|`` (a KD-tree query);
  a frame is in contact when ``d_t < threshold`` (0.05 m in both tasks' scripts);
* precision ``TP / (TP + FP)`` (0 when nothing is predicted in contact), recall
  ``TP / (TP + FN)`` (0 when the ground truth never is), accuracy, F1 (0 when both are 0),
  over frames;
* contact distance: the mean of the prediction's ``d_t`` over the ground truth's contact
  frames (0 when there are none), and the ground truth's own.

Object-to-human (``compute_metrics_marker``), ``pred``/``gt`` markers (T, 77, 3):

* hand JPE: mean marker error of the left hand (markers 72-76) and right hand (67-71), in
  **centimetres** (x 100), and their average;
* MPVPE: mean error of the markers relative to marker 0, metres;
* foot sliding (``compute_foot_sliding_for_marker``): the markers are first lowered so that
  their lowest y is 0; for the toe markers ``[32, 25, 20, 21, 16, 54, 55, 59, 64, 50, 55]``
  (55 twice, as listed) ``sum |dxz_t| (2 - 2^(y_t / 0.04)) [y_t < 0.04]`` over frames
  t < T - 1, divided by ``T x 11``, x 1000 (the prediction's and the ground truth's);
* quirk kept: that lowering is done **in place** on ``pred`` and ``gt`` before the contact
  metrics, so the per-group JPE (cm) and every marker-object distance use the lowered
  markers against the object vertices as given;
* contact metrics and JPE for four marker groups: ``hand`` (the 10 hand markers),
  ``non_hand`` (the other 67), ``foot`` (the toe list) and ``full`` (all 77).

Human-to-object (``compute_metrics_obj_marker``), ``pred``/``gt`` posed object vertices
(T, M, 3) and the human's ``markers`` (T, 77, 3): MPVPE of the vertices relative to vertex
0 and MPMPE of the vertices (metres); contact from ``d_t`` between the markers and the
vertices at 0.05 m (the script's ``--contact_thre`` is not used by this function);
``eval_saved.py`` adds the translation error ``mean |t_pred - t_gt|`` (m) and the rotation
error ``mean ||I - R_pred R_gt^-1||_F``.

Selection (``eval_saved.py``): per sequence the sample with the lowest ``full`` JPE (or MPVPE,
or the highest ``full`` contact F1) for object-to-human, the lowest MPVPE (or MPMPE, or the
highest contact F1) for human-to-object; every metric is read from that sample.
"""
from __future__ import annotations

import numpy as np

__all__ = ["LEFT_HAND", "RIGHT_HAND", "TOES", "GROUPS", "marker_foot_sliding", "contact_scores",
           "object2human_metrics", "human2object_metrics", "rotation_error", "best_sample"]

LEFT_HAND = (72, 73, 74, 75, 76)
RIGHT_HAND = (67, 68, 69, 70, 71)
#: the toe markers of InterAct's foot-sliding and foot-contact lists, as listed (55 twice)
TOES = (32, 25, 20, 21, 16, 54, 55, 59, 64, 50, 55)
_HANDS = LEFT_HAND + RIGHT_HAND
GROUPS: dict[str, tuple[int, ...]] = {"hand": _HANDS, "non_hand": tuple(i for i in range(77) if i not in _HANDS),
                                      "foot": TOES, "full": tuple(range(77))}
FOOT_HEIGHT_M = 0.04


def _arr(x, name: str, shape_tail: tuple | None = None) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 3 or (shape_tail is not None and a.shape[1:] != shape_tail) or not np.isfinite(a).all():
        want = f"(T, {shape_tail[0]}, {shape_tail[1]})" if shape_tail else "(T, N, 3)"
        raise ValueError(f"{name}: expected a finite {want} array, got shape {a.shape}")
    return a


def marker_foot_sliding(markers) -> float:
    """InterAct's foot sliding of (T, 77, 3) markers (module docstring), x 1000."""
    m = _arr(markers, "markers", (77, 3)).copy()
    m[..., 1] -= m[..., 1].min()
    feet = m[:, list(TOES)]
    disp = np.linalg.norm(feet[1:][..., [0, 2]] - feet[:-1][..., [0, 2]], axis=-1)
    h = feet[:-1, :, 1]
    stats = np.abs(disp * (2 - 2 ** (h / FOOT_HEIGHT_M))) * (h < FOOT_HEIGHT_M)
    return float(stats.sum() / (len(m) * len(TOES)) * 1000)


def _min_dist(points: np.ndarray, cloud: np.ndarray) -> np.ndarray:
    """Per frame, the smallest distance from any of ``points[t]`` to ``cloud[t]`` (KD-tree)."""
    from scipy.spatial import KDTree
    return np.array([KDTree(cloud[t]).query(points[t])[0].min() for t in range(len(points))])


def contact_scores(pred_dist: np.ndarray, gt_dist: np.ndarray, threshold: float) -> dict[str, float]:
    """Precision, recall, accuracy, F1 of per-frame contact (``d < threshold``) and the
    contact distances over the ground truth's contact frames (module docstring)."""
    pc, gc = pred_dist < threshold, gt_dist < threshold
    tp, fp = int(np.sum(pc & gc)), int(np.sum(pc & ~gc))
    tn, fn = int(np.sum(~pc & ~gc)), int(np.sum(~pc & gc))
    precision = tp / (tp + fp) if tp + fp else 0.0
    recall = tp / (tp + fn) if tp + fn else 0.0
    f1 = 2 * precision * recall / (precision + recall) if precision or recall else 0.0
    n = int(gc.sum())
    return {"contact_precision": precision, "contact_recall": recall, "contact_acc": (tp + tn) / len(pc),
            "contact_f1_score": f1, "contact_dist": float(pred_dist[gc].sum() / n) if n else 0.0,
            "gt_contact_dist": float(gt_dist[gc].sum() / n) if n else 0.0}


def object2human_metrics(pred, gt, obj_verts, threshold: float = 0.05) -> dict:
    """InterAct's object-to-human metrics of one sample: ``pred``/``gt`` markers (T, 77, 3),
    ``obj_verts`` (T, M, 3) the posed object; ``{lhand_jpe, rhand_jpe, hand_jpe (cm), mpvpe (m),
    foot_sliding, gt_foot_sliding, <group>: {jpe (cm), contact_*}}``."""
    p, g = _arr(pred, "pred", (77, 3)), _arr(gt, "gt", (77, 3))
    o = _arr(obj_verts, "obj_verts")
    if not len(p) == len(g) == len(o):
        raise ValueError(f"pred, gt, obj_verts: frame counts differ: {len(p)}, {len(g)}, {len(o)}")
    out = {"lhand_jpe": float(np.linalg.norm(p[:, list(LEFT_HAND)] - g[:, list(LEFT_HAND)], axis=-1).mean() * 100),
           "rhand_jpe": float(np.linalg.norm(p[:, list(RIGHT_HAND)] - g[:, list(RIGHT_HAND)], axis=-1).mean() * 100)}
    out["hand_jpe"] = (out["lhand_jpe"] + out["rhand_jpe"]) / 2.0
    out["mpvpe"] = float(np.linalg.norm((p - p[:, :1]) - (g - g[:, :1]), axis=-1).mean())
    out["foot_sliding"], out["gt_foot_sliding"] = marker_foot_sliding(p), marker_foot_sliding(g)
    p, g = p.copy(), g.copy()                      # the reference lowers them in place: the groups see it
    p[..., 1] -= p[..., 1].min()
    g[..., 1] -= g[..., 1].min()
    for name, idx in GROUPS.items():
        pm, gm = p[:, list(idx)], g[:, list(idx)]
        group = {"jpe": float(np.linalg.norm(pm - gm, axis=-1).mean() * 100)}
        group.update(contact_scores(_min_dist(pm, o), _min_dist(gm, o), threshold))
        out[name] = group
    return out


def rotation_error(pred_rot, gt_rot) -> float:
    """``mean_t ||I - R_pred R_gt^-1||_F`` over (T, 3, 3) rotations (human2object's O_err)."""
    a, b = np.asarray(pred_rot, np.float64), np.asarray(gt_rot, np.float64)
    return float(np.mean([np.linalg.norm(np.eye(3) - x @ np.linalg.inv(y), "fro") for x, y in zip(a, b)]))


def human2object_metrics(pred_verts, gt_verts, markers, threshold: float = 0.05, pred_trans=None, gt_trans=None,
                         pred_rot=None, gt_rot=None) -> dict:
    """InterAct's human-to-object metrics of one sample: posed object vertices ``pred_verts``/
    ``gt_verts`` (T, M, 3), the human's ``markers`` (T, 77, 3); with the object poses also
    ``t_err`` (m) and ``o_err`` (module docstring)."""
    p, g, m = _arr(pred_verts, "pred_verts"), _arr(gt_verts, "gt_verts"), _arr(markers, "markers", (77, 3))
    if not (p.shape == g.shape and len(m) == len(p)):
        raise ValueError(f"pred_verts, gt_verts, markers: shapes differ: {p.shape}, {g.shape}, {m.shape}")
    out = {"mpvpe": float(np.linalg.norm((p - p[:, :1]) - (g - g[:, :1]), axis=-1).mean()),
           "mpmpe": float(np.linalg.norm(p - g, axis=-1).mean())}
    out.update(contact_scores(_min_dist(m, p), _min_dist(m, g), threshold))
    if pred_trans is not None and gt_trans is not None:
        t = np.asarray(pred_trans, np.float64)
        out["t_err"] = float(np.linalg.norm(t - np.asarray(gt_trans, np.float64)[:len(t)], axis=-1).mean())
    if pred_rot is not None and gt_rot is not None:
        out["o_err"] = rotation_error(pred_rot, np.asarray(gt_rot)[:len(pred_rot)])
    return out


def best_sample(values, higher_is_better: bool = False) -> int:
    """The sample ``eval_saved.py`` keeps: ``argmin`` (``argmax`` when higher is better),
    the first on ties."""
    v = np.asarray(values, np.float64)
    return int(np.argmax(v) if higher_is_better else np.argmin(v))
