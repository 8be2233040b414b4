"""Contacts between the body and the object: per-joint labels, thresholds, timelines.

* Signed distances (m, negative inside) from points to a triangle mesh live in
  :mod:`hoibench.bodies.distance` (:class:`SignedDistance`, :func:`signed_distance`,
  :func:`signed_distance_frames`, :func:`prepare_mesh`, :func:`winding_number`, ...); they
  are re-exported here.
* Contact labels: :func:`joint_contact_labels` (T, 22) and :func:`vertex_contact_labels`
  (T, V), ``d < tau``, thresholds from ``annotators/contact_thresholds.json``
  (:func:`load_contact_thresholds`; modes ``chainhoi`` and ``surface``), and
  :func:`contact_precision_recall` against reference labels.
* Timelines turn per-joint, per-frame labels (T, 22) into segments per body part; the
  annotator describes the segments, and ignores *transitions* (segments shorter than
  ``min_frames``, 5 by default), which are kept so nothing is lost but are never described.
"""
from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..core import skeleton as sk
from .distance import SignedDistance, _check_points, signed_distance_frames
from .distance import (INSIDE_TESTS, SIGNED_DISTANCE_METHODS, MeshReport,  # noqa: F401  (re-exported)
                       prepare_mesh, signed_distance, signed_distance_field, to_template_frame,
                       winding_number)


@dataclass(frozen=True)
class ContactSegment:
    """Frames ``[start, end)`` during which ``part`` touches the object."""

    part: str
    start: int
    end: int
    transition: bool          # shorter than the timeline's min_frames: kept, not described

    @property
    def num_frames(self) -> int:
        return self.end - self.start

    def seconds(self, fps: float) -> tuple[float, float]:
        return self.start / fps, self.end / fps

    def to_dict(self) -> dict:
        return asdict(self)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) runs of True in a 1-D boolean array."""
    padded = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]])
    edges = np.flatnonzero(np.diff(padded.astype(np.int8)))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2])]


def contact_timeline(labels: np.ndarray, parts: Mapping[str, Sequence[int]] | None = None,
                     min_frames: int = 5) -> list[ContactSegment]:
    """Segments per body part from per-joint contact labels.

    Args:
        labels: (T, 22) bool, joint j of frame t touches the object.
        parts: part name -> joints; a part is in contact on a frame when any of its joints
            is. Default: :data:`hoibench.core.skeleton.BODY_PARTS`.
        min_frames: segments shorter than this are marked ``transition``.

    Returns:
        Segments sorted by (start, part).
    """
    lab = np.asarray(labels)
    if lab.ndim != 2 or lab.shape[1] != sk.NUM_JOINTS:
        raise ValueError(f"labels: expected shape (T, 22), got {lab.shape}")
    if lab.dtype != bool:
        raise ValueError(f"labels: expected bool, got {lab.dtype}")
    parts = sk.BODY_PARTS if parts is None else parts
    segs = []
    for name, joints in parts.items():
        for a, b in _runs(lab[:, list(joints)].any(axis=1)):
            segs.append(ContactSegment(name, a, b, (b - a) < min_frames))
    return sorted(segs, key=lambda s: (s.start, s.part))


# =====================================================================================
# Contact thresholds and labels
# =====================================================================================
CONTACT_THRESHOLDS_FILE = "contact_thresholds.json"
CONTACT_MODES: tuple[str, ...] = ("chainhoi", "surface")


def annotators_dir() -> Path:
    """The annotator specs folder: ``$HOIBENCH_ANNOTATORS_DIR`` if set, else ``annotators/``
    beside the package (a source checkout or an editable install)."""
    env = os.environ.get("HOIBENCH_ANNOTATORS_DIR")
    return Path(env) if env else Path(__file__).resolve().parents[2] / "annotators"


def load_contact_thresholds(path=None) -> dict:
    """Read the contact-threshold spec (``annotators/contact_thresholds.json`` by default).

    Returns the parsed JSON (see the file: ``version``, ``modes.chainhoi.objects`` /
    ``default``, ``modes.surface`` per-joint-group ``radius_m`` / ``tolerance_m``,
    ``vertex.threshold_m``). Raises ``FileNotFoundError`` naming the path looked for.
    """
    p = Path(path) if path is not None else annotators_dir() / CONTACT_THRESHOLDS_FILE
    if not p.is_file():
        raise FileNotFoundError(f"contact thresholds: no file at {p} (set HOIBENCH_ANNOTATORS_DIR "
                                "or pass path=)")
    from ..core.io import read_json_file
    spec = read_json_file(p, what="contact thresholds")
    for key in ("version", "modes"):
        if key not in spec:
            raise ValueError(f"contact thresholds {p}: missing key {key!r}")
    return spec


def object_threshold(object_name: str, thresholds: dict | None = None) -> float:
    """ChainHOI-mode threshold (m) of an object: its entry in ``modes.chainhoi.objects``
    (name lower-cased, BEHAVE-style suffixes such as ``_f1000`` dropped), else ``default``."""
    spec = load_contact_thresholds() if thresholds is None else thresholds
    ch = spec["modes"]["chainhoi"]
    name = str(object_name).lower().strip()
    objs = ch["objects"]
    if name not in objs and "_" in name:
        name = name.split("_")[0]
    return float(objs.get(name, ch["default"]))


def body_scale(joints) -> float:
    """Body scale ``s`` of a clip: the median over frames of the summed 21 bone lengths
    divided by that of :data:`hoibench.core.skeleton.SMPL_REST_JOINTS` (exact for the proxy body,
    which scales uniformly by ``1 + 0.05 beta_0``). joints (T, 22, 3) or (22, 3), metres."""
    J = np.asarray(joints, dtype=np.float64)
    if J.shape[-2:] != (sk.NUM_JOINTS, 3):
        raise ValueError(f"joints: expected shape (..., 22, 3), got {J.shape}")
    par = np.array(sk.PARENTS[1:])
    bones = np.linalg.norm(J[..., 1:, :] - J[..., par, :], axis=-1).sum(-1)
    ref = np.linalg.norm(sk.SMPL_REST_JOINTS[1:] - sk.SMPL_REST_JOINTS[par], axis=-1).sum()
    return float(np.median(bones) / ref)


def joint_thresholds(object_name: str, mode: str = "chainhoi", joints=None,
                     scale: float | None = None, thresholds: dict | None = None) -> np.ndarray:
    """Per-joint contact thresholds (22,), metres.

    ``chainhoi``: :func:`object_threshold` for every joint. ``surface``: per joint group
    ``tau_j = radius_m * s + tolerance_m`` (groups and values from the spec file), ``s``
    = ``scale`` or :func:`body_scale` of ``joints``.
    """
    if mode not in CONTACT_MODES:
        raise ValueError(f"mode: expected one of {CONTACT_MODES}, got {mode!r}")
    spec = load_contact_thresholds() if thresholds is None else thresholds
    if mode == "chainhoi":
        return np.full(sk.NUM_JOINTS, object_threshold(object_name, spec))
    surf = spec["modes"]["surface"]
    if scale is None:
        if joints is None:
            raise ValueError("surface mode: pass joints= or scale= (the body scale)")
        scale = body_scale(joints)
    d = surf["default"]
    tau = np.full(sk.NUM_JOINTS, d["radius_m"] * scale + d["tolerance_m"])
    for g in surf.get("groups", {}).values():
        radius, tol = g.get("radius_m", d["radius_m"]), g.get("tolerance_m", d["tolerance_m"])
        tau[list(g["joints"])] = radius * scale + tol
    return tau


def joint_contact_labels(joints, template_vertices, faces, rot, trans, object_name: str,
                         thresholds=None, mode: str = "chainhoi", scale: float | None = None,
                         field: SignedDistance | None = None, **options
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Per-joint, per-frame contact labels from signed distances to the posed object.

    ``labels[t, j] = d[t, j] < tau_j``, ``d`` the signed distance (m, negative inside) of
    joint j at frame t to the object ``v = R_t v_template + t_t`` (:func:`signed_distance_frames`,
    one scene per template). Inside counts as contact.

    Args:
        joints: (T, 22, 3) world positions, metres.
        template_vertices, faces: object template (V, 3), (F, 3).
        rot, trans: (T, 3, 3), (T, 3) object pose.
        object_name: selects the ChainHOI threshold (``default`` when unknown).
        thresholds: None (read ``annotators/contact_thresholds.json``), a parsed spec dict,
            a float (every joint), or a (22,) array of per-joint thresholds.
        mode: ``"chainhoi"`` (per-object, BEHAVE) or ``"surface"`` (tight, per joint group,
            scaled by the body, see the spec file); ignored for float/array thresholds.
        scale: body scale for ``surface`` (default: :func:`body_scale` of ``joints``).

    Returns:
        ``(labels (T, 22) bool, distances (T, 22) float64)``. Joints farther than
        ``max(tau) + 0.05`` m from the object's bounding box are culled: their distance is
        the box distance, a lower bound (they are never in contact).
    """
    J = _check_points(joints, "joints")
    if J.ndim != 3 or J.shape[1] != sk.NUM_JOINTS:
        raise ValueError(f"joints: expected shape (T, 22, 3), got {J.shape}")
    if thresholds is None or isinstance(thresholds, dict):
        tau = joint_thresholds(object_name, mode, joints=J, scale=scale, thresholds=thresholds)
    else:
        tau = np.broadcast_to(np.asarray(thresholds, dtype=np.float64), (sk.NUM_JOINTS,)).copy()
    d, _ = signed_distance_frames(J, template_vertices, faces, rot, trans,
                                  max_distance=float(tau.max()) + 0.05, field=field, **options)
    return d < tau, d


def vertex_contact_labels(vertices, template_vertices, faces, rot, trans,
                          threshold: float | None = None, field: SignedDistance | None = None,
                          **options) -> tuple[np.ndarray, np.ndarray]:
    """Contact labels of body-surface vertices (T, V, 3) (SMPL or the proxy body):
    ``d < threshold`` with ``threshold`` default ``vertex.threshold_m`` of the spec (0.02 m,
    BEHAVE's definition). Negative distances are penetration (PS counts ``d < 0``).

    Returns ``(labels (T, V) bool, distances (T, V) float64)``; vertices farther than
    ``threshold + 0.05`` m from the object's bounding box get the box distance (lower bound).
    """
    if threshold is None:
        threshold = float(load_contact_thresholds()["vertex"]["threshold_m"])
    d, _ = signed_distance_frames(vertices, template_vertices, faces, rot, trans,
                                  max_distance=float(threshold) + 0.05, field=field, **options)
    return d < threshold, d


def contact_precision_recall(pred, gt, parts: Mapping[str, Sequence[int]] | None = None,
                             boundary_frames: int = 0) -> dict:
    """Frame-level precision and recall of part contacts, ``pred``/``gt`` (T, 22) bool (or
    lists of them, pooled over clips). A part is in contact on a frame when any of its joints
    is. ``boundary_frames = k`` leaves out the non-contact frames within k frames before a
    ground-truth run of that part starts or after it ends (a predicted run may start or end
    up to k frames early/late; recall stays strict). Returns ``{part: {tp, fp, fn, precision,
    recall}}`` (precision/recall ``nan`` when undefined)."""
    preds = [pred] if isinstance(pred, np.ndarray) else list(pred)
    gts = [gt] if isinstance(gt, np.ndarray) else list(gt)
    parts = sk.BODY_PARTS if parts is None else parts
    out = {}
    for name, js in parts.items():
        tp = fp = fn = 0
        for p, g in zip(preds, gts):
            a, b = np.asarray(p)[:, list(js)].any(1), np.asarray(g)[:, list(js)].any(1)
            keep = np.ones(len(b), bool)
            if boundary_frames > 0:  # frames outside GT contact but within k of a GT run
                for s0, e0 in _runs(b):
                    keep[max(0, s0 - boundary_frames):s0] = False
                    keep[e0:e0 + boundary_frames] = False
            tp += int((a & b & keep).sum())
            fp += int((a & ~b & keep).sum())
            fn += int((~a & b & keep).sum())
        out[name] = {"tp": tp, "fp": fp, "fn": fn,
                     "precision": tp / (tp + fp) if tp + fp else float("nan"),
                     "recall": tp / (tp + fn) if tp + fn else float("nan")}
    return out
