"""Contact and penetration metrics of one clip: CD, OCD, PS, penetration depth, contact IoU,
hand-object contact ratio, object floating.

Distances are signed distances (m, negative inside the object) from
:mod:`hoibench.bodies.contact` (one raycasting scene per object template, points moved into the
template frame, robust inside test named in the mesh report); nothing here re-implements a
distance. Legacy protocols take CD's joint distances and PS's signs from ChainHOI's
rules instead (:mod:`hoibench.bodies.reference_distance`: :func:`reference_joint_distances`,
:func:`closest_face_frames`). The functions come in two layers:

* geometry: :func:`joint_object_distances` (T, 22) and :func:`body_object_distances` (T, V);
* metrics on those arrays (pure numpy): each returns the per-clip *sufficient statistics*
  (sums and counts) that :class:`hoibench.metrics.physical.PhysicalMetrics` pools over clips.

Frames: a generated clip of T frames is compared with ground-truth labels of T' frames on the
first ``min(T, T')`` frames (ChainHOI evaluates at the ground-truth length).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..core import skeleton as sk
from ..bodies.distance import signed_distance_frames, to_template_frame
from ..bodies.reference_distance import ClosestFaceField, contact_distance_field

HANDS: tuple[int, int] = (20, 21)          # wrists
OCD_LENGTH_TOLERANCE_FRAMES = 8            # group members within +-8 frames (ChainHOI: after cropping)
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


def joint_contacts(joints, obj_rot, obj_trans, field, thresholds, needed=None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Signed distances (T, 22) of the joints to the posed object where ``needed`` (T', 22)
    (its first ``min(T, T')`` frames; NaN elsewhere) and the predicted contact labels
    ``d < tau_j`` (T, 22), with exact distances only where they are needed or where the
    field's guaranteed bounds ``lo <= d <= hi`` (:meth:`SignedDistance.bracket`) do not decide
    the label (``hi < tau``: contact, ``lo >= tau``: none).

    The labels equal :func:`predicted_contacts` of :func:`joint_object_distances`, and the
    distances equal those values where needed (the same points, moved into the template frame
    the same way, go to the same exact queries); CD and OCD read them only under their masks."""
    J = np.asarray(joints, dtype=np.float64)
    local = to_template_frame(J, obj_rot, obj_trans).reshape(-1, 3)
    tau = np.broadcast_to(np.asarray(thresholds, dtype=np.float64), (sk.NUM_JOINTS,))
    tau = np.broadcast_to(tau, J.shape[:2]).reshape(-1)
    lo, hi = field.bracket(local) if len(local) else (np.zeros(0), np.zeros(0))
    undecided = (lo < tau) & (hi >= tau)
    want = undecided.copy()
    if needed is not None:
        m = np.asarray(needed, dtype=bool)
        n = min(len(J), len(m))
        want.reshape(J.shape[:2])[:n] |= m[:n]
    d = np.full(len(local), np.nan)
    where = np.flatnonzero(want)
    if len(where):
        d[where] = field(local[where])
    pred = hi < tau
    pred[undecided] = d[undecided] < tau[undecided]
    return d.reshape(J.shape[:2]), pred.reshape(J.shape[:2])


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


def reference_joint_distances(joints, vertices, faces, obj_rot, obj_trans, variant: str = "reference"
                              ) -> np.ndarray:
    """Unsigned distances (T, 22) of the joints to the posed mesh as ChainHOI's CD measures them
    (its point-to-triangle function with the edge quirk, ``variant`` of
    :data:`hoibench.bodies.reference_distance.CONTACT_VARIANTS`), metres. CD squares them."""
    J = np.asarray(joints, dtype=np.float64)
    local = to_template_frame(J, obj_rot, obj_trans)
    return contact_distance_field(vertices, faces, variant)(local.reshape(-1, 3)).reshape(J.shape[:2])


@dataclass(frozen=True)
class SurfaceFrames:
    """Per-frame penetration and contact of a body surface (V vertices) against the object.

    ``penetrating`` (T,) int: vertices with signed distance ``d < 0``; ``depth`` (T,) m: the
    deepest penetration ``max(-d)`` over the frame's vertices (0 when none penetrates);
    ``touching`` (T,) bool: some vertex has ``d < contact_m``. Fields not asked for are None.
    """

    vertices: int
    penetrating: np.ndarray | None
    depth: np.ndarray | None
    touching: np.ndarray | None


#: rounds of "resolve each frame's most promising depth candidate" before the rest at once
DEPTH_ROUNDS = 1


def surface_frames(field, points, index=None, shape: tuple[int, int] | None = None,
                   contact_m: float = VERTEX_CONTACT_M, penetration: bool = True,
                   touching: bool = True) -> SurfaceFrames:
    """Exact :class:`SurfaceFrames` of body-surface points in the object's template frame, with
    as few exact distance queries as the answers need.

    ``field``: the object's :class:`hoibench.bodies.contact.SignedDistance`. ``points``: (T, V, 3),
    or (N, 3) with ``index`` (N,) their flat indices ``frame * V + vertex`` and ``shape =
    (T, V)`` -- vertices not listed must be known to lie farther than ``contact_m`` from the
    object (e.g. culled body parts). Every point first gets guaranteed bounds ``lo <= d <=
    hi`` from :meth:`SignedDistance.bracket` (nearest grid node); points whose answer those
    bounds leave open get the tighter bounds of their grid cell
    (:meth:`SignedDistance.bracket_cell`, 8 nodes) before any query. Then only

    * where the bounds still straddle 0, the inside test alone (:meth:`SignedDistance.contains`);

    and exact signed distances (:meth:`SignedDistance.__call__`) only

    * for the deepest point of each frame by its lower bound; then, for ``DEPTH_ROUNDS``
      rounds, for each frame's inside point of largest upper bound among those whose upper
      bounds (``-lo`` and :meth:`SignedDistance.distance_upper`) exceed the deepest exact depth
      so far (the per-frame maximum); then for every such point left;
    * on frames not yet decided by the bounds, for points with ``lo < contact_m`` (touching).

    The result equals computing every signed distance exactly (same inside test, same open3d
    distances) and reducing per frame -- a vertex penetrates when the inside test contains it
    (also at distance 0, where ``d < 0`` would not count it); ``tests/test_metrics.py``
    checks that it does.
    """
    pts = np.asarray(points, dtype=np.float64)
    if index is None:
        if pts.ndim != 3 or pts.shape[-1] != 3:
            raise ValueError(f"points: expected shape (T, V, 3), got {pts.shape}")
        T, V = pts.shape[:2]
        pts = pts.reshape(-1, 3)
        frame = np.repeat(np.arange(T), V)
    else:
        T, V = shape
        frame = np.asarray(index, dtype=np.int64) // V
    lo, hi = field.bracket(pts) if len(pts) else (np.zeros(0), np.zeros(0))
    exact = np.zeros(len(pts), bool)
    refined = np.zeros(len(pts), bool)

    def refine(where):
        """Cell bounds for the points ``where`` (indices) not refined or exact yet."""
        where = where[~(refined[where] | exact[where])]
        if len(where):
            cl, ch = field.bracket_cell(pts[where])
            lo[where] = np.maximum(lo[where], cl)
            hi[where] = np.minimum(hi[where], ch)
            refined[where] = True

    def resolve(where):
        """Exact values for the points ``where`` (indices) that are not exact yet."""
        where = where[~exact[where]]
        if len(where):
            lo[where] = hi[where] = field(pts[where])
            exact[where] = True

    def frame_max(values, where):
        out = np.full(T, -np.inf)
        np.maximum.at(out, frame[where], values[where])
        return out

    def top_of_frame(values, where):
        """The points of ``where`` whose ``values`` are their frame's largest."""
        return where[values[where] == frame_max(values, where)[frame[where]]]

    pen = depth = touch = None
    if penetration:
        band = np.flatnonzero((lo < 0) & (hi >= 0))           # sign unknown: cell bounds, then
        refine(band)
        band = band[(lo[band] < 0) & (hi[band] >= 0)]         # the inside test
        inside = hi < 0
        if len(band):
            got = field.contains(pts[band])
            inside[band] = got
            hi[band[got]] = 0.0                               # inside: d <= 0
            lo[band[~got]] = 0.0                              # outside: d >= 0
        ins = np.flatnonzero(inside)
        pen = np.bincount(frame[ins], minlength=T)
        if len(ins):
            resolve(top_of_frame(-hi, ins))                   # depth >= -hi: each frame's deepest lower bound
            best = frame_max(-hi, ins[exact[ins]])
            cand = ins[~exact[ins] & (-lo[ins] > best[frame[ins]])]   # depth <= -lo
            refine(cand)
            cand = cand[-lo[cand] > best[frame[cand]]]
            if len(cand):                                     # depth <= |p - surface point|
                cand = cand[field.distance_upper(pts[cand]) > best[frame[cand]]]
            for _ in range(DEPTH_ROUNDS):
                if not len(cand):
                    break
                resolve(top_of_frame(-lo, cand))              # the largest upper bound of each frame
                best = np.maximum(best, frame_max(-hi, cand[exact[cand]]))
                cand = cand[~exact[cand] & (-lo[cand] > best[frame[cand]])]
            resolve(cand)
        depth = np.maximum(frame_max(-hi, ins), 0.0)
    if touching:
        decided = np.bincount(frame[hi < contact_m], minlength=T) > 0
        cand = np.flatnonzero(~decided[frame] & (lo < contact_m))
        refine(cand)
        decided |= np.bincount(frame[cand[hi[cand] < contact_m]], minlength=T) > 0
        resolve(cand[~decided[frame[cand]] & (lo[cand] < contact_m)])
        touch = np.bincount(frame[hi < contact_m], minlength=T) > 0
    return SurfaceFrames(V, pen, depth, touch)


def closest_face_frames(field: ClosestFaceField, points) -> SurfaceFrames:
    """:class:`SurfaceFrames` (``touching`` None) of body-surface points (T, V, 3) in the
    object's template frame under ChainHOI's PS sign rule (torchsdf's closest face,
    :class:`hoibench.bodies.reference_distance.ClosestFaceField`): a vertex penetrates when its
    closest face's normal says inside and it is not on the surface; every vertex is queried
    (the rule can put far vertices inside). ``depth``: the largest distance of a penetrating
    vertex per frame, m."""
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 3 or pts.shape[-1] != 3:
        raise ValueError(f"points: expected shape (T, V, 3), got {pts.shape}")
    T, V = pts.shape[:2]
    cf = field(pts.reshape(-1, 3))
    pen = cf.penetrating.reshape(T, V)
    depth = np.where(pen, cf.distance.reshape(T, V), 0.0).max(axis=1) if V else np.zeros(T)
    return SurfaceFrames(V, pen.sum(axis=1), depth, None)


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
                             length_tolerance: int = OCD_LENGTH_TOLERANCE_FRAMES,
                             members: str = "tolerance") -> float:
    """OCD of one clip, m^2: the CD minimised over the contact maps of the clip's semantic group.

    Candidates: the clip's own GT map (when it has contact), and the other group members'
    maps. ``members="tolerance"`` (hoibench clean): a member counts when its length T_m is
    within ``length_tolerance`` frames of the generated clip's T. ``members="crop"``
    (ChainHOI, compute.py:625-626): the member is first cut to the generated length,
    ``T_m <- min(T_m, T)``, so a longer member always counts and a shorter one counts when
    ``T - T_m <= length_tolerance``. A member's map covers its first ``min(T, T_m)``
    frames, later frames are unmasked. ``OCD = min_c CD_c`` over candidates with at least
    one contact frame; ``nan`` when none has. Motivation: a text describes several valid
    contact patterns; OCD does not punish a generated motion for choosing another one of
    its group.
    """
    if members not in ("tolerance", "crop"):
        raise ValueError(f"members: expected 'tolerance' or 'crop', got {members!r}")
    d = _dist(distances)
    best = contact_distance(d, gt_contacts)
    for g in group_contacts:
        g = _labels(g, "group_contacts")
        if members == "crop":
            g = g[:len(d)]
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
    """``(max depth, sum of per-frame depths, penetrating frames)`` of one clip, metres, from
    signed distances (T, V).

    The depth of a frame is its deepest penetration ``max_v(-d_tv)`` over vertices with
    ``d < 0``; a frame penetrates when one vertex does. ``penetration_depth_max_m`` = the
    largest frame depth, ``penetration_depth_mean_m`` = sum / count pooled over clips (mean
    depth of penetrating frames; 0 when nothing penetrates). Per frame, not per vertex, so
    the value does not depend on how densely the body surface is sampled (the proxy's hands
    hold 25% of its vertices). Inside unions of overlapping parts the depth is a lower bound
    (see :mod:`hoibench.bodies.contact`)."""
    d = np.asarray(vertex_distances, dtype=np.float64)
    depth = np.where(d < 0, -d, 0.0).max(axis=1) if d.size else np.zeros(len(d))
    return frame_depth_stats(depth, (d < 0).any(axis=1) if d.size else np.zeros(len(d), bool))


def frame_depth_stats(depth, penetrating) -> tuple[float, float, int]:
    """``(max, sum over penetrating frames, penetrating frames)`` of per-frame depths (T,)
    (:func:`penetration_depth_stats`)."""
    depth = np.asarray(depth, dtype=np.float64)
    pen = np.asarray(penetrating, dtype=bool)
    return (float(depth[pen].max()) if pen.any() else 0.0), float(depth[pen].sum()), int(pen.sum())


# ===================================================================== contact labels
def predicted_contacts(distances, thresholds) -> np.ndarray:
    """Per-joint contact labels (T, 22) of a generated clip: ``d < tau_j`` (thresholds a float
    or (22,) array, from :func:`hoibench.bodies.contact.joint_thresholds`)."""
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
