"""Contact metrics of multi-body interaction (SyncDiff): per-frame hand-object and
root-object contact, CSR, CRR and CSIoU, as functions and as mergeable metrics.
"""
from __future__ import annotations

import numpy as np

from .multibody_common import (CRR_THRESHOLD_M, CSR_THRESHOLD_M, _distance_kind, _frame_origin, _frame_sets,
                               _frames, _meshes, _nearest, _PerClipMean, _points, _positive, _sequence)

# ===================================================================== contact (CSR, CRR)
def hand_object_distance(hand_vertices, object_meshes, distance: str = "surface") -> np.ndarray:
    """Per-frame distance (T,) m from a hand mesh to the nearest object:
    ``d_t = min_{v in hand vertices} min_{o} dist(v, surface_o(t))``, exact point-to-triangle
    distance (open3d ``compute_distance``), unsigned -- a vertex inside an object counts by
    its distance to that object's surface. ``distance="vertex"``: to the nearest object
    vertex instead (see :data:`DISTANCES`)."""
    return _hand_object_distance(hand_vertices, object_meshes, "hand_vertices", "object_meshes", distance)


def _hand_object_distance(hand_vertices, object_meshes, hand_field: str, obj_field: str,
                          distance: str = "surface") -> np.ndarray:
    distance = _distance_kind(distance)
    hand = _points(hand_vertices, hand_field, 3, "(T, V, 3)")
    objs = _meshes(object_meshes, obj_field, len(hand))
    out = np.empty(len(hand))
    for t in range(len(hand)):
        c = _frame_origin(hand[t], *(o.vertices[t] for o in objs))
        out[t] = _nearest(hand[t] - c, [(o.vertices[t] - c, o.faces) for o in objs], distance).min()
    return out


def contact_frames_hand(hand_vertices, object_meshes, threshold_m: float = CSR_THRESHOLD_M,
                        distance: str = "surface") -> np.ndarray:
    """Surface contact frames (T,) bool of one hand (SyncDiff's CSR contact, appendix C.5):
    ``c_t = [hand_object_distance_t <= threshold_m]`` -- some hand vertex within
    ``threshold_m`` of the surface of at least one object (see :func:`hand_object_distance`).
    ``hand_vertices`` (T, V, 3); ``object_meshes``: list of :class:`PosedMesh` or
    ``(vertices (T, V_o, 3), faces (F_o, 3))``."""
    thr = _positive(threshold_m, "threshold_m")
    return hand_object_distance(hand_vertices, object_meshes, distance) <= thr


def root_object_distances(points, object_meshes, distance: str = "surface") -> np.ndarray:
    """Distances (T, K, M) m from K points per frame (T, K, 3) -- hand roots -- to the surface
    (exact, unsigned; or nearest vertex, ``distance="vertex"``) of each of the M objects."""
    return _root_object_distances(points, object_meshes, "points", distance)


def _root_object_distances(points, object_meshes, field: str, distance: str = "surface") -> np.ndarray:
    distance = _distance_kind(distance)
    p = _points(points, field, 3, "(T, K, 3)")
    objs = _meshes(object_meshes, "object_meshes", len(p))
    out = np.empty((len(p), p.shape[1], len(objs)))
    for t in range(len(p)):
        c = _frame_origin(p[t], *(o.vertices[t] for o in objs))
        for m, o in enumerate(objs):
            out[t, :, m] = _nearest(p[t] - c, [(o.vertices[t] - c, o.faces)], distance)
    return out


def contact_frames_human_roots(left_root, right_root, object_meshes, threshold_m: float = CRR_THRESHOLD_M,
                               same_object: bool = True, distance: str = "surface") -> np.ndarray:
    """Root contact frames (T,) bool of one human (SyncDiff's CRR contact, appendix C.5):
    both hand roots (wrists, (T, 3) each) within ``threshold_m`` of an object's surface.
    ``same_object=True``: ``c_t = OR_o [d(l_t, o) <= thr AND d(r_t, o) <= thr]`` (one object
    held by both hands); ``False``: each root near any object, possibly different ones."""
    thr = _positive(threshold_m, "threshold_m")
    left = _points(left_root, "left_root", 2, "(T, 3)")
    right = _points(right_root, "right_root", 2, "(T, 3)")
    if len(left) != len(right):
        raise ValueError(f"right_root: expected {len(left)} frames like left_root, got {len(right)}")
    near = _root_object_distances(np.stack([left, right], axis=1), object_meshes, "roots", distance) <= thr
    if same_object:
        return (near[:, 0, :] & near[:, 1, :]).any(axis=1)
    return near[:, 0, :].any(axis=1) & near[:, 1, :].any(axis=1)


def contact_ratio(frames) -> float:
    """Fraction of frames in contact, ``sum_t c_t / T``."""
    return float(_frames(frames, "frames").mean())


def contact_surface_ratio(frames_per_hand) -> float:
    """CSR of one clip: the contact ratio of each hand, averaged over the hands (fraction;
    SyncDiff's tables print %)."""
    return float(np.mean([f.mean() for f in _frame_sets(frames_per_hand, "frames_per_hand")]))


def contact_root_ratio(frames_per_human) -> float:
    """CRR of one clip: the root-contact ratio of each human, averaged over the humans."""
    return float(np.mean([f.mean() for f in _frame_sets(frames_per_human, "frames_per_human")]))


def frame_iou(frames, gt_frames, empty_union: float | None = 1.0) -> float:
    """IoU of two contact-frame sets of equal length: ``|P & G| / |P | G|``. When neither has
    a contact frame the union is empty: ``empty_union`` (default 1.0: both agree there is
    no contact), or ``nan`` when ``empty_union`` is None (the body is left out of means)."""
    p, g = _frames(frames, "frames"), _frames(gt_frames, "gt_frames")
    if len(p) != len(g):
        raise ValueError(f"gt_frames: expected {len(p)} frames like frames, got {len(g)}")
    union = int((p | g).sum())
    if union == 0:
        return float("nan") if empty_union is None else float(empty_union)
    return int((p & g).sum()) / union


def contact_surface_iou(frames_per_hand, gt_frames_per_hand, empty_union: float | None = 1.0) -> float:
    """CSIoU of one clip: :func:`frame_iou` of each hand's generated vs ground-truth contact
    frames, averaged over the hands whose IoU is defined (``nan`` if none is)."""
    gen = _frame_sets(frames_per_hand, "frames_per_hand")
    gt = _frame_sets(gt_frames_per_hand, "gt_frames_per_hand")
    if len(gen) != len(gt):
        raise ValueError(f"gt_frames_per_hand: expected {len(gen)} hands like frames_per_hand, got {len(gt)}")
    if len(gen[0]) != len(gt[0]):
        raise ValueError(f"gt_frames_per_hand: expected {len(gen[0])} frames like frames_per_hand, "
                         f"got {len(gt[0])}")
    ious = np.array([frame_iou(p, g, empty_union) for p, g in zip(gen, gt)])
    ious = ious[~np.isnan(ious)]
    return float(ious.mean()) if len(ious) else float("nan")


# ===================================================================== mergeable metrics
class CSR(_PerClipMean):
    """Contact Surface Ratio (SyncDiff, hand-object settings): per clip the fraction of frames
    with a hand vertex within ``threshold_m`` of an object, averaged over hands; the mean over
    clips (fraction; the paper prints %)."""

    name = "csr"

    def __init__(self, threshold_m: float = CSR_THRESHOLD_M, distance: str = "surface"):
        super().__init__()
        self.threshold_m = _positive(threshold_m, "threshold_m")
        self.distance = _distance_kind(distance)

    def config(self) -> dict:
        return {"threshold_m": self.threshold_m, "distance": self.distance}

    def update(self, clip_id, hand_vertices, object_meshes) -> None:
        """``hand_vertices``: list of (T, V, 3), one per hand; ``object_meshes``: list of
        posed meshes (see :func:`contact_frames_hand`)."""
        self._new_key(clip_id)
        hands = _sequence(hand_vertices, "hand_vertices")
        frames = [_hand_object_distance(h, object_meshes, f"hand_vertices[{i}]", "object_meshes", self.distance)
                  <= self.threshold_m for i, h in enumerate(hands)]
        self.update_frames(clip_id, frames)

    def update_frames(self, clip_id, frames_per_hand) -> None:
        """Add a clip from precomputed contact frames, one (T,) bool array per hand."""
        self._new_key(clip_id)
        self._put(clip_id, contact_surface_ratio(frames_per_hand))


class CRR(_PerClipMean):
    """Contact Root Ratio (SyncDiff, human-object settings): per clip the fraction of frames
    with both hand roots of a human within ``threshold_m`` of an object, averaged over humans;
    the mean over clips (fraction)."""

    name = "crr"

    def __init__(self, threshold_m: float = CRR_THRESHOLD_M, same_object: bool = True, distance: str = "surface"):
        super().__init__()
        self.threshold_m = _positive(threshold_m, "threshold_m")
        self.same_object = bool(same_object)
        self.distance = _distance_kind(distance)

    def config(self) -> dict:
        return {"threshold_m": self.threshold_m, "same_object": self.same_object, "distance": self.distance}

    def update(self, clip_id, roots, object_meshes) -> None:
        """``roots``: list of ``(left_root (T, 3), right_root (T, 3))``, one per human."""
        self._new_key(clip_id)
        frames = []
        for i, r in enumerate(_sequence(roots, "roots")):
            try:
                left, right = r
            except (TypeError, ValueError):
                raise ValueError(f"roots[{i}]: expected a (left_root, right_root) pair") from None
            try:
                frames.append(contact_frames_human_roots(left, right, object_meshes, self.threshold_m,
                                                         self.same_object, self.distance))
            except ValueError as e:
                raise ValueError(f"roots[{i}]: {e}") from None
        self.update_frames(clip_id, frames)

    def update_frames(self, clip_id, frames_per_human) -> None:
        self._new_key(clip_id)
        self._put(clip_id, contact_root_ratio(frames_per_human))


class CSIoU(_PerClipMean):
    """Contact-frame IoU between generated and ground-truth motion (SyncDiff): per clip
    :func:`contact_surface_iou` (per hand, averaged over hands), then the mean over clips
    (fraction). ``empty_union``: the IoU of a hand with no contact frame in either (1.0, or
    None to leave that hand out)."""

    name = "csiou"

    def __init__(self, threshold_m: float = CSR_THRESHOLD_M, empty_union: float | None = 1.0,
                 distance: str = "surface"):
        super().__init__()
        self.threshold_m = _positive(threshold_m, "threshold_m")
        self.distance = _distance_kind(distance)
        if empty_union is not None and not (0.0 <= float(empty_union) <= 1.0):
            raise ValueError(f"empty_union: expected a value in [0, 1] or None, got {empty_union!r}")
        self.empty_union = None if empty_union is None else float(empty_union)

    def config(self) -> dict:
        return {"threshold_m": self.threshold_m, "empty_union": self.empty_union, "distance": self.distance}

    def update(self, clip_id, hand_vertices, object_meshes, gt_hand_vertices, gt_object_meshes=None) -> None:
        """Generated and ground-truth hands (lists of (T, V, 3), same hands in the same order)
        against their own objects; ``gt_object_meshes`` None: the generated objects."""
        self._new_key(clip_id)
        gt_objects = object_meshes if gt_object_meshes is None else gt_object_meshes
        gt_field = "object_meshes" if gt_object_meshes is None else "gt_object_meshes"
        gen = [_hand_object_distance(h, object_meshes, f"hand_vertices[{i}]", "object_meshes", self.distance)
               <= self.threshold_m for i, h in enumerate(_sequence(hand_vertices, "hand_vertices"))]
        gt = [_hand_object_distance(h, gt_objects, f"gt_hand_vertices[{i}]", gt_field, self.distance)
              <= self.threshold_m for i, h in enumerate(_sequence(gt_hand_vertices, "gt_hand_vertices"))]
        self.update_frames(clip_id, gen, gt)

    def update_frames(self, clip_id, frames_per_hand, gt_frames_per_hand) -> None:
        self._new_key(clip_id)
        self._put(clip_id, contact_surface_iou(frames_per_hand, gt_frames_per_hand, self.empty_union))
