"""Contact and penetration metrics of one clip: CD, OCD, PS, penetration depth, contact IoU,
hand-object contact ratio, object floating.

Distances are signed distances (m, negative inside the object) from
:mod:`hoibench.contact` (one raycasting scene per object template, points moved into the
template frame, robust inside test named in the mesh report); nothing here re-implements a
distance. The functions come in two layers:

* geometry: :func:`joint_object_distances` (T, 22) and :func:`body_object_distances` (T, V);
* metrics on those arrays (pure numpy): each returns the per-clip *sufficient statistics*
  (sums and counts) that :class:`hoibench.metrics.physical.PhysicalMetrics` pools over clips.

Frames: a generated clip of T frames is compared with ground-truth labels of T' frames on the
first ``min(T, T')`` frames (ChainHOI evaluates at the ground-truth length).
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from .. import skeleton as sk
from ..contact import signed_distance_frames

HANDS: tuple[int, int] = (20, 21)          # wrists
OCD_LENGTH_TOLERANCE_FRAMES = 8            # ChainHOI: group members within +-8 frames
VERTEX_CONTACT_M = 0.02                    # BEHAVE: body vertices within 2 cm touch
FLOOR_TOLERANCE_M = 0.02


# ===================================================================== geometry
def joint_object_distances(joints, template_vertices, faces, obj_rot, obj_trans, field=None,
                           **options) -> np.ndarray:
    """Exact signed distances (T, 22) float64 of the joints to the posed object
    (``v = R v_template + t``), metres, negative inside. No culling."""
    d, _ = signed_distance_frames(joints, template_vertices, faces, obj_rot, obj_trans,
                                  max_distance=None, field=field, **options)
    return d


def body_object_distances(vertices, template_vertices, faces, obj_rot, obj_trans,
                          margin_m: float = 0.05, field=None, chunk_frames: int = 64,
                          **options) -> np.ndarray:
    """Signed distances (T, V) of body-surface vertices (T, V, 3) to the posed object.

    Culling by bounding box: vertices farther than ``margin_m`` from the object's box get the
    box distance (a lower bound of their true, positive distance), so signs are exact
    everywhere and values are exact below ``margin_m``. Frames go in chunks of
    ``chunk_frames`` to bound memory.
    """
    V = np.asarray(vertices)
    out = np.empty(V.shape[:2])
    for s in range(0, len(V), chunk_frames):
        sl = slice(s, s + chunk_frames)
        out[sl], _ = signed_distance_frames(V[sl], template_vertices, faces, np.asarray(obj_rot)[sl],
                                            np.asarray(obj_trans)[sl], max_distance=margin_m,
                                            field=field, **options)
    return out


def object_lowest_point(template_vertices, obj_rot, obj_trans) -> np.ndarray:
    """Height (T,) of the posed object's lowest vertex, metres."""
    v = np.asarray(template_vertices, dtype=np.float64)
    R = np.asarray(obj_rot, dtype=np.float64)
    t = np.asarray(obj_trans, dtype=np.float64)
    return (np.einsum("tj,vj->tv", R[:, 1, :], v) + t[:, 1, None]).min(axis=1)


# ===================================================================== helpers
def _labels(x, name: str) -> np.ndarray:
    a = np.asarray(x)
    if a.ndim != 2 or a.shape[1] != sk.NUM_JOINTS:
        raise ValueError(f"{name}: expected shape (T, 22), got {a.shape}")
    return a.astype(bool)


def _dist(x, name: str = "distances") -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != sk.NUM_JOINTS:
        raise ValueError(f"{name}: expected shape (T, 22), got {a.shape}")
    return a


# ===================================================================== CD / OCD
def contact_distance_sums(distances, gt_contacts) -> tuple[float, int]:
    """CD of one clip as ``(sum of d^2 over masked joint-frames, masked joint-frames)``.

    ``CD = sum_{t,j} m_tj d_tj^2 / sum_{t,j} m_tj`` (m^2), ``d`` the signed distance of
    generated joint j at frame t to the posed object, ``m`` the ground-truth contact label,
    over the first ``min(T, T')`` frames (ChainHOI: squared distance masked by the GT
    contact map, per clip). Undefined (count 0) when the GT has no contact.
    """
    d, m = _dist(distances), _labels(gt_contacts, "gt_contacts")
    n = min(len(d), len(m))
    mask = m[:n]
    return float(np.square(d[:n])[mask].sum()), int(mask.sum())


def contact_distance(distances, gt_contacts) -> float:
    """CD of one clip, m^2 (``nan`` without GT contact); see :func:`contact_distance_sums`."""
    s, n = contact_distance_sums(distances, gt_contacts)
    return s / n if n else float("nan")


def optimal_contact_distance(distances, gt_contacts, group_contacts: Sequence = (),
                             length_tolerance: int = OCD_LENGTH_TOLERANCE_FRAMES) -> float:
    """OCD of one clip, m^2: the CD minimised over the contact maps of the clip's semantic group.

    Candidates: the clip's own GT map (when it has contact), and every other group member's
    map whose length is within ``length_tolerance`` frames of the generated clip's
    (ChainHOI's +-8 frames); a member's map covers its first ``min(T, T_m)`` frames, later
    frames are unmasked. ``OCD = min_c CD_c`` over candidates with at least one contact
    frame; ``nan`` when none has. Motivation: a text describes several valid contact
    patterns; OCD does not punish a generated motion for choosing another one of its group.
    """
    d = _dist(distances)
    best = contact_distance(d, gt_contacts)
    for g in group_contacts:
        g = _labels(g, "group_contacts")
        if abs(len(g) - len(d)) > length_tolerance:
            continue
        cd = contact_distance(d, g)
        if not np.isnan(cd) and (np.isnan(best) or cd < best):
            best = cd
    return best


# ===================================================================== penetration
def penetration_counts(vertex_distances) -> tuple[int, int]:
    """PS of one clip as ``(penetrating vertex-frames, all vertex-frames)``: a body-surface
    vertex penetrates when its signed distance is negative. ``PS = n_neg / n_all`` pooled
    over clips (ChainHOI's PS: SMPL vertices fitted to the joints, all vertex-frames).
    Lower is better."""
    d = np.asarray(vertex_distances)
    return int((d < 0).sum()), int(d.size)


def penetration_depth_stats(vertex_distances) -> tuple[float, float, int]:
    """``(max depth, sum of depths, penetrating vertex-frames)`` of one clip, metres; depth =
    ``-d`` of penetrating vertices. Mean depth = sum / count pooled over clips (0 when nothing
    penetrates). Inside unions of overlapping parts the depth is a lower bound (see
    :mod:`hoibench.contact`)."""
    d = np.asarray(vertex_distances, dtype=np.float64)
    neg = -d[d < 0]
    return (float(neg.max()) if neg.size else 0.0), float(neg.sum()), int(neg.size)


# ===================================================================== contact labels
def predicted_contacts(distances, thresholds) -> np.ndarray:
    """Per-joint contact labels (T, 22) of a generated clip: ``d < tau_j`` (thresholds a float
    or (22,) array, from :func:`hoibench.contact.joint_thresholds`)."""
    d = _dist(distances)
    tau = np.broadcast_to(np.asarray(thresholds, dtype=np.float64), (sk.NUM_JOINTS,))
    return d < tau


def contact_iou_counts(pred_contacts, gt_contacts) -> tuple[int, int]:
    """Contact IoU of one clip as ``(|P and G|, |P or G|)`` over joint-frames of the first
    ``min(T, T')`` frames. IoU pooled over clips = sum / sum. Higher is better."""
    p, g = _labels(pred_contacts, "pred_contacts"), _labels(gt_contacts, "gt_contacts")
    n = min(len(p), len(g))
    return int((p[:n] & g[:n]).sum()), int((p[:n] | g[:n]).sum())


def hand_contact_frames(pred_contacts, hands: Sequence[int] = HANDS) -> tuple[int, int]:
    """Hand-object contact ratio of one clip as ``(frames where a hand touches the object,
    frames)``; a hand touches when its wrist joint's label is on. Best when closest to the
    real motion's value (``higher_is_better = None``)."""
    p = _labels(pred_contacts, "pred_contacts")
    return int(p[:, list(hands)].any(axis=1).sum()), int(len(p))


def floating_frames(object_lowest_y, body_contact, floor_tolerance_m: float = FLOOR_TOLERANCE_M
                    ) -> tuple[int, int]:
    """Object floating of one clip as ``(floating frames, frames)``: the object's lowest point
    is more than ``floor_tolerance_m`` above the floor (y = 0) while nothing of the body
    touches it (``body_contact`` (T,) bool, e.g. any body vertex within 2 cm). Objects
    resting on furniture count as floating (BEHAVE's floor is the only support hoibench
    knows). Lower is better."""
    y = np.asarray(object_lowest_y, dtype=np.float64)
    c = np.asarray(body_contact, dtype=bool)
    if y.shape != c.shape or y.ndim != 1:
        raise ValueError(f"object_lowest_y, body_contact: expected two (T,) arrays, got {y.shape} and {c.shape}")
    return int(((y > floor_tolerance_m) & ~c).sum()), int(len(y))
