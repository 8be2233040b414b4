"""Plausibility and unit checks for raw data and for every clip before it is stored.

Each loader checks the raw arrays it reads (real dtype, finite values, translations within
bounds and moving at bounded speed, object meshes) with the helpers here, naming the
sequence, the file and the field; :func:`check_sequence` then checks the canonical
:class:`~hoibench.datasets.sequence.HOISequence` (metres, seconds, y-up) per clip -- every
frame, never a median over clips -- before :func:`hoibench.datasets.store.run_unit` writes it.

Values in millimetres or centimetres show up as positions beyond
:data:`MAX_ABS_POSITION_M`, speeds beyond :data:`MAX_SPEED_M_S`, a skeleton outside
:data:`BODY_HEIGHT_RANGE_M` or an object outside :data:`OBJECT_EXTENT_RANGE_M`; the message
then says which unit the numbers fit (e.g. "divided by 1000 it is 1.7 m: millimetres?").
"""
from __future__ import annotations

import math
from collections import Counter
from typing import Any, Mapping

import numpy as np

from .ids import check_id

#: Largest accepted absolute coordinate, metres. Capture volumes (BEHAVE's Kinect frame,
#: OMOMO's mocap hall, RICH's scans) span a few tens of metres at most; millimetres (a 2 m
#: camera distance reads 2000) and corrupt values (1e30) exceed it.
MAX_ABS_POSITION_M = 100.0
#: Largest accepted speed of the body root and of the object between consecutive frames,
#: ``|x[t+1] - x[t]| / dt``, m/s. Sprinting is about 10 m/s and a thrown ball about 30 m/s;
#: a one-frame jump of 1.7 m at 30 fps already exceeds it.
MAX_SPEED_M_S = 50.0
#: Accepted skeletal height, metres: head-to-pelvis chain (15-12-9-6-3-0) plus the mean of the
#: two pelvis-to-foot chains (0-1-4-7-10, 0-2-5-8-11), per frame (pose-independent: about
#: 1.6 m for SMPL's mean shape). Millimetres read about 1600, centimetres about 160.
BODY_HEIGHT_RANGE_M = (0.5, 3.0)
#: Accepted diagonal of an object template's axis-aligned bounding box, metres (a cup is
#: about 0.1 m, a table 1.5 m). Millimetres or centimetres make it 100x-1000x larger.
OBJECT_EXTENT_RANGE_M = (0.01, 10.0)
#: Accepted clip frame rate, frames per second (``--fps`` and the stored ``fps``).
FPS_RANGE = (1.0, 1000.0)
#: Fewest frames of a clip (velocities and the hml263 features need two).
MIN_FRAMES = 2
#: Longest accepted raw sequence, seconds: resampling a sequence whose time stamps span
#: more (e.g. one corrupt stamp 't9999999.0') would allocate millions of frames.
MAX_DURATION_S = 3600.0
#: Fewest vertices and faces of an object template (a tetrahedron).
MESH_MIN_VERTICES, MESH_MIN_FACES = 4, 1
#: Most shape coefficients (``betas``) of a body (SMPL-X has 300 shape components).
MAX_BETAS = 300
#: Body models and genders a clip may name (the gender picks a model file).
MODEL_TYPES = ("smpl", "smplh", "smplx")
GENDERS = ("male", "female", "neutral")
#: Tolerance on ``R R^T = I`` and ``det R = 1`` of object rotations.
ROTATION_TOL = 1e-3

_HEAD_CHAIN = (15, 12, 9, 6, 3, 0)
_LEG_CHAINS = ((0, 1, 4, 7, 10), (0, 2, 5, 8, 11))
_UNITS = (("millimetres", 1000.0), ("centimetres", 100.0))


class ImplausibleDataError(ValueError):
    """Raw or canonical data that cannot be metres/seconds of a real capture."""


# --------------------------------------------------------------------------- helpers
def unit_hint(value: float, lo: float, hi: float, typical: float) -> str:
    """``"; divided by 1000 it is 1.7 m: millimetres? (metres expected)"`` for each of
    millimetres (1000) and centimetres (100) whose factor brings ``value`` (metres) into
    ``[lo, hi]``, the one nearest ``typical`` (log scale) first; ``""`` when none does."""
    if not (math.isfinite(value) and value > 0):
        return ""
    fits = sorted(((n, f) for n, f in _UNITS if lo <= value / f <= hi),
                  key=lambda c: abs(math.log(value / c[1] / typical)))
    if not fits:
        return ""
    return "; " + " or ".join(f"divided by {f:g} it is {value / f:.3g} m: {n}?" for n, f in fits) + " (metres expected)"


def real_array(value: Any, field: str, where: str) -> np.ndarray:
    """``value`` as a float64 array when its dtype is real (integer or floating) and every
    entry is finite; :class:`ImplausibleDataError` naming ``where: field`` otherwise
    (complex values are refused, never cast to real)."""
    if hasattr(value, "detach"):                 # a torch tensor
        value = value.detach().cpu().numpy()
    try:
        a = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise ImplausibleDataError(f"{where}: {field}: not an array ({type(exc).__name__}: {exc})") from None
    if a.dtype.kind == "c":
        raise ImplausibleDataError(f"{where}: {field}: complex values ({a.dtype}) refused: expected real numbers")
    if a.dtype.kind not in "iuf":
        raise ImplausibleDataError(f"{where}: {field}: expected real numbers, got dtype {a.dtype}")
    a = a.astype(np.float64)
    bad = ~np.isfinite(a)
    if bad.any():
        idx = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ImplausibleDataError(f"{where}: {field}: non-finite value {a[idx]} at index {idx}")
    return a


def check_fps(fps: Any, field: str, where: str) -> float:
    """``fps`` as a float in :data:`FPS_RANGE`, else :class:`ImplausibleDataError`."""
    try:
        v = float(fps)
    except (TypeError, ValueError):
        raise ImplausibleDataError(f"{where}: {field}: expected a number, got {fps!r}") from None
    if not (math.isfinite(v) and FPS_RANGE[0] <= v <= FPS_RANGE[1]):
        raise ImplausibleDataError(f"{where}: {field}: {v!r} frames per second is outside "
                                   f"{FPS_RANGE[0]:g}..{FPS_RANGE[1]:g}")
    return v


def common_frame_count(counts: Mapping[str, int], where: str, min_frames: int | None = None) -> int:
    """The frame count that most per-frame fields share; :class:`ImplausibleDataError`
    naming the field(s) that differ (or all counts when no majority), saying the sequence
    has zero frames, or (with ``min_frames``) fewer frames than a clip needs."""
    empty = [k for k, c in counts.items() if c == 0]
    if empty:
        raise ImplausibleDataError(f"{where}: zero frames: {', '.join(empty)} "
                                   f"{'is' if len(empty) == 1 else 'are'} empty")
    tally = Counter(counts.values()).most_common()
    top, n = tally[0]
    if len(tally) > 1:
        odd = [k for k, c in counts.items() if c != top]
        if n * 2 > len(counts):
            same = ", ".join(k for k, c in counts.items() if c == top)
            raise ImplausibleDataError(f"{where}: " + "; ".join(f"{k} has {counts[k]} frames" for k in odd)
                                       + f", the other per-frame fields ({same}) have {top}")
        raise ImplausibleDataError(f"{where}: per-frame fields disagree on the number of frames: "
                                   + ", ".join(f"{k} {c}" for k, c in counts.items()))
    if min_frames is not None and top < min_frames:
        raise ImplausibleDataError(f"{where}: only {top} frame(s), a clip needs at least {min_frames}")
    return top


def check_positions(x: np.ndarray, field: str, where: str) -> None:
    """Every coordinate of ``x`` (metres) within :data:`MAX_ABS_POSITION_M`."""
    a = np.abs(np.asarray(x, dtype=np.float64))
    if a.size and float(a.max()) > MAX_ABS_POSITION_M:
        idx = tuple(int(i) for i in np.unravel_index(int(a.argmax()), a.shape))
        top = float(a.max())
        raise ImplausibleDataError(
            f"{where}: {field}: |value| {top:.4g} at index {idx} exceeds {MAX_ABS_POSITION_M:g} m"
            + unit_hint(top, 0.05, MAX_ABS_POSITION_M, 1.5))


def check_speed(x: np.ndarray, field: str, where: str, times: np.ndarray | None = None,
                fps: float | None = None) -> None:
    """Speed ``|x[t+1] - x[t]| / (t_{t+1} - t_t)`` (m/s) of a (T, 3) track at most
    :data:`MAX_SPEED_M_S`; times are ``times`` (seconds) or ``arange(T) / fps``."""
    x = np.asarray(x, dtype=np.float64)
    if len(x) < 2:
        return
    dt = np.diff(np.asarray(times, dtype=np.float64)) if times is not None else np.full(len(x) - 1, 1.0 / fps)
    speed = np.linalg.norm(np.diff(x, axis=0), axis=-1) / dt
    bad = np.flatnonzero(speed > MAX_SPEED_M_S)
    if len(bad):
        t = int(bad[0])
        raise ImplausibleDataError(
            f"{where}: {field}: speed {float(speed[t]):.4g} m/s between frames {t} and {t + 1} exceeds "
            f"{MAX_SPEED_M_S:g} m/s (a jump of {float(speed[t] * dt[t]):.4g} m in {float(dt[t]):.4g} s: "
            "a corrupt frame, or millimetres/centimetres?)")


def check_track(x: np.ndarray, field: str, where: str, times: np.ndarray | None = None,
                fps: float | None = None) -> None:
    """:func:`check_positions` and :func:`check_speed` of a (T, 3) translation track."""
    check_positions(x, field, where)
    check_speed(x, field, where, times, fps)


def skeletal_height(joints: np.ndarray) -> np.ndarray:
    """(T,) head-to-pelvis plus mean pelvis-to-foot bone-chain length (metres) of (T, 22, 3)
    joints: pose-independent body height from joints (see :data:`BODY_HEIGHT_RANGE_M`)."""
    j = np.asarray(joints, dtype=np.float64)

    def chain(c):
        return sum(np.linalg.norm(j[:, b] - j[:, a], axis=-1) for a, b in zip(c[:-1], c[1:]))
    return chain(_HEAD_CHAIN) + 0.5 * (chain(_LEG_CHAINS[0]) + chain(_LEG_CHAINS[1]))


def check_body_height(joints: np.ndarray, where: str) -> None:
    """Every frame's :func:`skeletal_height` within :data:`BODY_HEIGHT_RANGE_M`."""
    h = skeletal_height(joints)
    lo, hi = BODY_HEIGHT_RANGE_M
    bad = np.flatnonzero((h < lo) | (h > hi))
    if len(bad):
        t = int(bad[0])
        raise ImplausibleDataError(
            f"{where}: joints: body height {float(h[t]):.4g} m at frame {t} is outside {lo:g}..{hi:g} m"
            + unit_hint(float(h[t]), lo, hi, 1.6))


def check_mesh(vertices: Any, faces: Any, what: str) -> tuple[np.ndarray, np.ndarray]:
    """Structure of a triangle mesh: (V, 3) real finite vertices, V >= 4, (F, 3) integer
    faces, F >= 1, indices in 0..V-1, total area > 0 (not every face degenerate).
    Returns (float64 vertices, int64 faces); ``what`` names the object and the mesh file."""
    v = real_array(vertices, "vertices", what)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3:
        raise ImplausibleDataError(f"{what}: vertices: expected shape (V, 3), got {v.shape}")
    if len(v) < MESH_MIN_VERTICES:
        raise ImplausibleDataError(f"{what}: {len(v)} vertices, a solid needs at least {MESH_MIN_VERTICES}")
    if f.dtype.kind not in "iu":
        raise ImplausibleDataError(f"{what}: faces: expected integer vertex indices, got dtype {f.dtype}")
    if f.ndim != 2 or f.shape[1] != 3 or len(f) < MESH_MIN_FACES:
        raise ImplausibleDataError(f"{what}: faces: expected at least {MESH_MIN_FACES} triangle(s) of shape "
                                   f"(F, 3), got {f.shape} (a point cloud?)")
    f = f.astype(np.int64)
    if int(f.min()) < 0 or int(f.max()) >= len(v):
        k = int(np.argwhere((f < 0) | (f >= len(v)))[0, 0])
        raise ImplausibleDataError(f"{what}: faces: face {k} = {f[k].tolist()} indexes outside the "
                                   f"{len(v)} vertices")
    tri = v[f]
    area = 0.5 * float(np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=-1).sum())
    if not area > 0.0:
        raise ImplausibleDataError(f"{what}: degenerate mesh: every face has zero area")
    return v, f


def check_extent(vertices: np.ndarray, what: str) -> float:
    """Bounding-box diagonal (metres) of ``vertices`` within :data:`OBJECT_EXTENT_RANGE_M`."""
    v = np.asarray(vertices, dtype=np.float64)
    d = float(np.linalg.norm(v.max(0) - v.min(0)))
    lo, hi = OBJECT_EXTENT_RANGE_M
    if not lo <= d <= hi:
        raise ImplausibleDataError(f"{what}: bounding-box diagonal {d:.4g} m is outside {lo:g}..{hi:g} m"
                                   + unit_hint(d, lo, hi, 0.5))
    return d


def check_template(vertices: Any, faces: Any, what: str) -> tuple[np.ndarray, np.ndarray]:
    """:func:`check_mesh` and :func:`check_extent`."""
    v, f = check_mesh(vertices, faces, what)
    check_extent(v, what)
    return v, f


def check_rotations(R: Any, field: str, where: str) -> np.ndarray:
    """(T, 3, 3) real finite rotation matrices (``R R^T = I``, ``det R = 1`` within
    :data:`ROTATION_TOL`)."""
    R = real_array(R, field, where)
    if R.ndim != 3 or R.shape[1:] != (3, 3):
        raise ImplausibleDataError(f"{where}: {field}: expected shape (T, 3, 3), got {R.shape}")
    err = np.abs(R @ R.swapaxes(-1, -2) - np.eye(3)).max(axis=(-2, -1))
    bad = np.flatnonzero((err > ROTATION_TOL) | (np.abs(np.linalg.det(R) - 1.0) > ROTATION_TOL))
    if len(bad):
        raise ImplausibleDataError(f"{where}: {field}: not a rotation matrix at frame {int(bad[0])}")
    return R


# --------------------------------------------------------------------------- one clip
def check_sequence(seq, source: str = "") -> None:
    """Refuse a canonical clip that is not plausible metres/seconds (every check above, on
    every frame of this clip): id-safe name and object name, fps in :data:`FPS_RANGE`,
    at least :data:`MIN_FRAMES` frames, real finite arrays, positions within
    :data:`MAX_ABS_POSITION_M`, root and object speeds within :data:`MAX_SPEED_M_S`, body
    height within :data:`BODY_HEIGHT_RANGE_M`, a valid object template within
    :data:`OBJECT_EXTENT_RANGE_M`, known body model and gender, texts and provenance that
    are strict JSON. ``source`` names the raw file(s) the clip came from."""
    name = check_id(seq.name, "clip name", source or None)
    where = f"{name} (from {source})" if source else name
    fps = check_fps(seq.fps, "fps", where)
    J = real_array(seq.joints, "joints", where)
    if J.ndim != 3 or J.shape[1:] != (22, 3):
        raise ImplausibleDataError(f"{where}: joints: expected shape (T, 22, 3), got {J.shape}")
    T = len(J)
    if T < MIN_FRAMES:
        raise ImplausibleDataError(f"{where}: joints: {T} frame(s), a clip needs at least {MIN_FRAMES}")
    check_positions(J, "joints", where)
    check_speed(J[:, 0], "root joint (pelvis)", where, fps=fps)
    check_body_height(J, where)
    _check_object(seq, T, fps, where)
    _check_parts(seq, T, fps, where)
    if seq.body is not None:
        _check_body(seq.body, T, where)
    if seq.contacts is not None and np.shape(seq.contacts) != (T, 22):
        raise ImplausibleDataError(f"{where}: contacts: expected shape ({T}, 22), got {np.shape(seq.contacts)}")
    _check_texts(seq.texts, where)
    _check_json(seq.provenance, "provenance", where)


def _check_object(seq, T: int, fps: float, where: str) -> None:
    parts = (seq.object_name, seq.object_vertices, seq.obj_rot, seq.obj_trans)
    if all(p is None for p in parts):
        return
    if any(p is None for p in parts) or seq.object_faces is None:
        raise ImplausibleDataError(f"{where}: object: name, template and pose must all be present")
    obj = check_id(seq.object_name, "object name", where)
    mesh = seq.provenance.get("template") if isinstance(seq.provenance, dict) else None
    check_template(seq.object_vertices, seq.object_faces, f"{where}: object {obj!r}" + (f" ({mesh})" if mesh else ""))
    R = check_rotations(seq.obj_rot, "obj_rot", where)
    t = real_array(seq.obj_trans, "obj_trans", where)
    if len(R) != T or t.shape != (T, 3):
        raise ImplausibleDataError(f"{where}: object pose: obj_rot {R.shape} / obj_trans {t.shape}, "
                                   f"joints have {T} frames")
    check_track(t, "obj_trans", where, fps=fps)


def _check_parts(seq, T: int, fps: float, where: str) -> None:
    """Every part of a multi-part object: id-safe distinct names, a valid template, a pose
    over the clip; the first part is the primary object."""
    parts = list(getattr(seq, "parts", None) or [])
    if not parts:
        return
    if len(parts) < 2 or seq.object_name is None:
        raise ImplausibleDataError(f"{where}: parts: a multi-part object needs >= 2 parts and a primary object")
    names = [check_id(p.name, "object part name", where) for p in parts]
    if len({n.casefold() for n in names}) != len(names) or names[0] != seq.object_name:
        raise ImplausibleDataError(f"{where}: parts: names {names} must be distinct, the first being the "
                                   f"object {seq.object_name!r}")
    for p in parts:
        check_template(p.vertices, p.faces, f"{where}: object part {p.name!r}")
        R = check_rotations(p.rot, f"part {p.name} rot", where)
        t = real_array(p.trans, f"part {p.name} trans", where)
        if len(R) != T or t.shape != (T, 3):
            raise ImplausibleDataError(f"{where}: object part {p.name!r}: pose {R.shape} / {t.shape}, joints have "
                                       f"{T} frames")
        check_track(t, f"part {p.name} trans", where, fps=fps)


def _check_body(body, T: int, where: str) -> None:
    if body.model_type not in MODEL_TYPES:
        raise ImplausibleDataError(f"{where}: body model {body.model_type!r}: expected one of {MODEL_TYPES}")
    if body.gender not in GENDERS:
        raise ImplausibleDataError(f"{where}: gender {body.gender!r}: expected one of {GENDERS}")
    betas = real_array(body.betas, "betas", where)
    if betas.ndim not in (1, 2) or not 1 <= betas.shape[-1] <= MAX_BETAS or (betas.ndim == 2 and len(betas) != T):
        raise ImplausibleDataError(f"{where}: betas: expected (B,) or ({T}, B) with 1 <= B <= {MAX_BETAS}, "
                                   f"got {betas.shape}")
    poses = real_array(body.poses, "poses", where)
    if poses.ndim != 2 or len(poses) != T or poses.shape[1] % 3:
        raise ImplausibleDataError(f"{where}: poses: expected ({T}, 3K) axis-angle, got {poses.shape}")
    trans = real_array(body.trans, "trans", where)
    if trans.shape != (T, 3):
        raise ImplausibleDataError(f"{where}: trans: expected ({T}, 3), got {trans.shape}")
    check_positions(trans, "trans", where)
    if getattr(body, "expression", None) is not None:
        expr = real_array(body.expression, "expression", where)
        if expr.ndim != 2 or len(expr) != T or not 1 <= expr.shape[1] <= 100:
            raise ImplausibleDataError(f"{where}: expression: expected ({T}, E) with 1 <= E <= 100, got {expr.shape}")


def _check_texts(texts, where: str) -> None:
    for i, t in enumerate(texts or []):
        if not isinstance(t, dict) or not isinstance(t.get("text"), str):
            raise ImplausibleDataError(f"{where}: texts[{i}]: expected {{'text': str, ...}}, got {t!r:.80}")
        for k in ("start", "end"):
            v = t.get(k)
            if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v)):
                raise ImplausibleDataError(f"{where}: texts[{i}].{k}: expected a finite number or null, got {v!r}")
    _check_json(texts, "texts", where)


def _check_json(obj, field: str, where: str) -> None:
    from .io import strict_json_dumps
    try:
        strict_json_dumps(obj, sort_keys=True)
    except (TypeError, ValueError) as exc:
        raise ImplausibleDataError(f"{where}: {field}: not strict JSON ({exc})") from None


__all__ = ["MAX_ABS_POSITION_M", "MAX_SPEED_M_S", "BODY_HEIGHT_RANGE_M", "OBJECT_EXTENT_RANGE_M", "FPS_RANGE",
           "MIN_FRAMES", "MAX_DURATION_S", "MESH_MIN_VERTICES", "MESH_MIN_FACES", "MAX_BETAS", "MODEL_TYPES",
           "GENDERS", "ROTATION_TOL", "ImplausibleDataError", "unit_hint", "real_array", "check_fps",
           "common_frame_count", "check_positions", "check_speed", "check_track", "skeletal_height",
           "check_body_height", "check_mesh", "check_extent", "check_template", "check_rotations",
           "check_sequence"]
