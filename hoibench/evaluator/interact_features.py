"""Motion inputs of InterAct's evaluator: 77 body markers + object BPS deltas, 615 per frame.

One frame's row (metres, the clip's y-up frame, as InterAct's canonical sequences store it):

* columns 0..230: the 77 markers (:mod:`hoibench.bodies.markers`), ``x, y, z`` per marker;
* columns 231..614: for each of the 128 basis points ``b_k`` (a fixed set around the origin,
  ``bps_basis_set_128_1.npy`` of InterAct's release, shape (128, 3)), placed at the object's
  translation ``t`` (not rotated): ``delta_k = p* - (b_k + t)`` where ``p*`` is the object
  point nearest (Euclidean) to ``b_k + t`` among the object's sample points posed as
  ``p = R @ p0 + t`` (``p0``: the object's sample points in its own frame, ``R``, ``t``: the
  frame's object rotation and translation). Ties go to the lowest point index.

The evaluator normalises the rows with its own mean/std (card) before embedding them.
"""
from __future__ import annotations

import numpy as np

from ..bodies.markers import NUM_MARKERS

MARKER_COLUMNS = 3 * NUM_MARKERS          # 231
BPS_POINTS = 128
ROW_WIDTH = MARKER_COLUMNS + 3 * BPS_POINTS   # 615


def bps_deltas(points: np.ndarray, basis: np.ndarray, trans: np.ndarray) -> np.ndarray:
    """``(T, K, 3)`` deltas from each basis point ``basis[k] + trans[t]`` to its nearest point
    of ``points[t]`` (``points``: (T, P, 3) posed object points; ``basis``: (K, 3);
    ``trans``: (T, 3)). Distances in float64."""
    pts = np.asarray(points, np.float64)
    b = np.asarray(basis, np.float64)
    tr = np.asarray(trans, np.float64)
    if pts.ndim != 3 or pts.shape[-1] != 3 or b.ndim != 2 or b.shape[-1] != 3 or tr.shape != (len(pts), 3):
        raise ValueError(f"bps: expected points (T, P, 3), basis (K, 3), trans (T, 3); got {pts.shape}, "
                         f"{b.shape}, {tr.shape}")
    out = np.empty((len(pts), len(b), 3))
    for t in range(len(pts)):
        anchors = b + tr[t]
        d2 = ((anchors[:, None, :] - pts[t][None, :, :]) ** 2).sum(-1)     # (K, P)
        out[t] = pts[t][np.argmin(d2, axis=1)] - anchors
    return out


def interact_rows(markers: np.ndarray, object_points: np.ndarray, obj_rot: np.ndarray, obj_trans: np.ndarray,
                  basis: np.ndarray, origin: np.ndarray | None = None) -> np.ndarray:
    """``(T, 615)`` float32 evaluator rows of one clip.

    ``markers``: (T, 77, 3) or (T, 231); ``object_points``: (P, 3) sample points in the
    object's frame; ``obj_rot``: (T, 3, 3) rotation matrices; ``obj_trans``: (T, 3);
    ``basis``: (128, 3) InterAct's evaluation BPS basis. ``origin``: where InterAct's object
    frame has its origin, in the template frame of ``object_points`` (hoibench centres
    templates on their vertex mean, InterAct does not: ``origin = -mean``); the basis sits at
    the posed origin ``R @ origin + t``. None: at ``t`` (points already in InterAct's frame)."""
    m = np.asarray(markers, np.float64)
    T = len(m)
    m = m.reshape(T, -1)
    if m.shape[1] != MARKER_COLUMNS:
        raise ValueError(f"interact rows: markers must be (T, {NUM_MARKERS}, 3), got {np.shape(markers)}")
    R = np.asarray(obj_rot, np.float64)
    t = np.asarray(obj_trans, np.float64)
    p0 = np.asarray(object_points, np.float64)
    if R.shape != (T, 3, 3) or t.shape != (T, 3) or p0.ndim != 2 or p0.shape[1] != 3:
        raise ValueError(f"interact rows: expected obj_rot ({T}, 3, 3), obj_trans ({T}, 3), object points (P, 3); "
                         f"got {R.shape}, {t.shape}, {p0.shape}")
    if np.shape(basis) != (BPS_POINTS, 3):
        raise ValueError(f"interact rows: the BPS basis must be ({BPS_POINTS}, 3), got {np.shape(basis)}")
    posed = np.einsum("tij,pj->tpi", R, p0) + t[:, None, :]
    anchor = t if origin is None else t + R @ np.asarray(origin, np.float64).reshape(3)
    d = bps_deltas(posed, basis, anchor).reshape(T, -1)
    return np.concatenate([m, d], axis=1).astype(np.float32)


def clip_rows(clip: dict, basis: np.ndarray, k: int | None = None) -> np.ndarray:
    """Rows of a stored clip or of sample ``k`` of a submission file: ``markers``, ``obj_rot``
    (or ``obj_rotvec``), ``obj_trans``, ``object_sample_points`` and ``object_origin``
    (what ``hoibench prepare interact`` stores per clip)."""
    def take(key):
        a = np.asarray(clip[key])
        return a if k is None else a[k]
    for key in ("markers", "obj_trans", "object_sample_points"):
        if key not in clip:
            raise ValueError(f"interact rows: no {key!r} (the interact evaluator needs markers, the object pose and "
                             f"InterAct's object sample points)")
    if "obj_rot" in clip:
        R = take("obj_rot")
    else:
        from ..core.geometry import axis_angle_to_matrix
        R = np.asarray(axis_angle_to_matrix(take("obj_rotvec")))
    return interact_rows(take("markers"), clip["object_sample_points"], R, take("obj_trans"), basis,
                         clip.get("object_origin"))


__all__ = ["MARKER_COLUMNS", "BPS_POINTS", "ROW_WIDTH", "bps_deltas", "interact_rows", "clip_rows"]
