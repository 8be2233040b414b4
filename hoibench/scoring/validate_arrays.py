"""Value checks of one sample file's arrays, once their shapes are known to be right:
finite values, plausibility bounds (units, speeds, distances), the up axis, object rotations,
and that every sample encodes to finite features (:func:`check_arrays`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from ..core.plausibility import ROTATION_TOL
from .submission_read import ArrayHeader, Problem

#: height of the proxy body (the SMPL mean shape), metres; a skeleton's height is estimated as
#: this times its bone-length scale (:func:`hoibench.bodies.contact.body_scale`)
MEAN_BODY_HEIGHT_M = 1.72
BODY_HEIGHT_RANGE_M = (0.5, 3.0)
#: median object-pelvis distance above which a sample is in the wrong units
MAX_OBJECT_DISTANCE_M = 20.0
#: object-pelvis distance no single frame may exceed
MAX_OBJECT_DISTANCE_FRAME_M = 100.0
#: no joint or object coordinate may lie further than this from the origin, metres
MAX_ABS_COORD_M = 1000.0
#: root (pelvis) and object speed no frame may exceed, metres per second
MAX_SPEED_MPS = 50.0
#: bound on |obj_rotvec| (radians) and on every hml263 value
MAX_ROTVEC_RAD = 100.0
MAX_FEATURE_ABS = 1e6
#: array -> (bound on every |value|, unit named in the message)
_VALUE_BOUNDS = {"joints": (MAX_ABS_COORD_M, "m"), "obj_trans": (MAX_ABS_COORD_M, "m"),
                 "markers": (MAX_ABS_COORD_M, "m"),
                 "obj_rotvec": (MAX_ROTVEC_RAD, "rad"), "hml263": (MAX_FEATURE_ABS, "units")}


ACCEPTED_DTYPES = (np.dtype("float32"), np.dtype("float64"))


def expect_shape(h: ArrayHeader | None, tail: tuple, name: str, sid: str, dtype: str | None = None,
                  where: str = "") -> list[Problem]:
    """Problems of array ``name``'s header: shape (K, T, *tail) and dtype (``dtype``, else
    float32 or float64); ``where`` prefixes each message (the task tracks name the file)."""
    if h is None:
        return []
    out = []
    ndim = 2 + len(tail)
    if len(h.shape) != ndim or tuple(h.shape[2:]) != tail:
        want = "(K, T" + "".join(f", {t}" for t in tail) + ")"
        out.append(Problem(sid, name, f"{where}expected shape {want}, got {h.shape}"))
    if dtype is not None and h.dtype != np.dtype(dtype):
        out.append(Problem(sid, name, f"{where}expected dtype {dtype}, got {h.dtype} "
                                      f"(convert with .astype(np.{dtype}))"))
    elif h.dtype not in ACCEPTED_DTYPES:
        out.append(Problem(sid, name, f"{where}expected float32 or float64, got {h.dtype} (half precision, extended "
                                      "precision, integer and complex arrays are not accepted)"))
    return out


@dataclass(frozen=True)
class ClipContext:
    """What checking one sample file needs from the store and the submission."""

    gt_frames: int
    has_object: bool
    fps: float
    uses_gt_length: bool
    max_samples: int
    mode: str = "clean"            # representation mode used to encode (hoi269 clean|legacy)
    required: tuple = ()           # further arrays the track's evaluator reads (interact: markers)
    human_only: bool = False       # flags.human_only: joints only on an HOI store (object metrics n/a)
    #: where the features each sample encodes to are kept ({(id, k): rows}), so that scoring
    #: does not encode them again (None: not kept)
    encoded: dict | None = field(default=None, compare=False, repr=False)
    #: encodes the samples in batches, its problems reported at the end (None: one at a time, now)
    batcher: "EncodeBatcher | None" = field(default=None, compare=False, repr=False)


def check_arrays(sid: str, arrays: Mapping[str, np.ndarray], ctx: ClipContext) -> tuple[list[Problem], str | None]:
    """Value checks of one sample file's arrays (shapes already checked): finite values,
    plausibility bounds per sample and per frame, rotations, and that every sample encodes
    to finite features (what evaluate computes). Returns (problems, up-axis guess)."""
    probs: list[Problem] = []
    good = {}
    for k, a in arrays.items():
        nonfinite = ~np.isfinite(a)
        if nonfinite.any():
            first = np.argwhere(nonfinite)[0]
            probs.append(Problem(sid, k, f"{int(nonfinite.sum())} non-finite value(s) (NaN or inf), first at index "
                                         f"{tuple(int(i) for i in first)}"))
            continue
        bound = _VALUE_BOUNDS.get(k)          # obj_rot: checked as rotations below
        if bound is not None:
            limit, unit = bound
            big = np.abs(a) > limit
            if big.any():
                first = tuple(int(i) for i in np.argwhere(big)[0])
                probs.append(Problem(sid, k, f"{int(big.sum())} value(s) beyond +-{limit:g} ({unit}), "
                                             f"first {float(a[first]):.3g} at index {first}: implausible"))
                continue
        good[k] = a
    up = None
    finite = dict(good)          # finite and within the bounds: the object check can use the joints
    if "joints" in good:
        jp, up = _check_joints(sid, good["joints"], ctx.fps)
        probs += jp
        if any(p.severity == "error" for p in jp):
            good.pop("joints")
    if "obj_rot" in good:
        rp = _check_rotations(sid, good["obj_rot"])
        probs += rp
        if rp:
            good.pop("obj_rot")
    if "markers" in good and "joints" in finite:
        mp = _check_markers(sid, good["markers"], finite["joints"])
        probs += mp
        if mp:
            good.pop("markers")
    if "obj_trans" in good and "joints" in finite:
        tp = _check_object_trans(sid, good["obj_trans"], finite["joints"], ctx.fps)
        probs += tp
        if tp:
            good.pop("obj_trans")
    if not any(p.severity == "error" for p in probs):
        probs += _check_encodes(sid, good, ctx)
    return probs, up


def _check_joints(sid: str, joints: np.ndarray, fps: float) -> tuple[list[Problem], str | None]:
    """Units per sample (body height from bone lengths), per frame (no frame's skeleton
    outside the height range), root speed per frame; the up axis the feet suggest."""
    from ..core.skeleton import PARENTS, SMPL_REST_JOINTS
    J = joints.astype(np.float64)
    par = np.array(PARENTS[1:])
    ref = np.linalg.norm(SMPL_REST_JOINTS[1:] - SMPL_REST_JOINTS[par], axis=-1).sum()
    frame_h = MEAN_BODY_HEIGHT_M * np.linalg.norm(J[..., 1:, :] - J[..., par, :], axis=-1).sum(-1) / ref  # (K, T)
    heights = np.median(frame_h, axis=1)
    lo, hi = BODY_HEIGHT_RANGE_M
    worst_k = int(np.argmax(np.abs(np.log(np.maximum(heights, 1e-12) / MEAN_BODY_HEIGHT_M))))
    worst = heights[worst_k]
    if not (lo <= worst <= hi):
        hint = " (millimetres?)" if worst > 300 else " (centimetres?)" if worst > 30 else ""
        return [Problem(sid, "joints", f"implausible units: sample {worst_k}'s bone lengths give a body "
                                       f"{worst:.3g} m tall (expected {lo}-{hi} m){hint}")], None
    out_frames = (frame_h < lo / 2) | (frame_h > 2 * hi)
    if out_frames.any():
        k, t = (int(i) for i in np.argwhere(out_frames)[0])
        return [Problem(sid, "joints", f"{int(out_frames.sum())} frame(s) whose skeleton is implausibly sized; "
                                       f"first sample {k} frame {t}: {frame_h[k, t]:.3g} m tall (the sample's "
                                       f"median is {heights[k]:.3g} m)")], None
    if J.shape[1] > 1:
        speed = np.linalg.norm(np.diff(J[:, :, 0], axis=1), axis=-1) * fps
        if speed.max() > MAX_SPEED_MPS:
            k, t = (int(i) for i in np.unravel_index(np.argmax(speed), speed.shape))
            return [Problem(sid, "joints", f"the pelvis moves {speed[k, t]:.3g} m/s between frames {t} and {t + 1} "
                                           f"of sample {k} (limit {MAX_SPEED_MPS:g} m/s): implausible")], None
    # Up axis: along the true up axis the lowest joint is an ankle or foot in nearly every
    # frame (standing, walking, sitting, kicking); along a horizontal axis it is arbitrary.
    feet = np.array([7, 8, 10, 11])
    frac = {}
    for a, axis in enumerate("xyz"):
        for sign in (1, -1):
            frac[("" if sign > 0 else "-") + axis] = float(np.isin((sign * J[..., a]).argmin(-1), feet).mean())
    # a tie (a foot is also the extreme joint along the facing direction): the up axis is the
    # one along which the head stands highest above the lowest foot
    top = max(frac.values())
    rise = {k: float(np.median((1 if k[0] != "-" else -1) * (J[..., 15, "xyz".index(k[-1])]
                                                             - J[..., feet, "xyz".index(k[-1])].min(-1))))
            if J.shape[-2] > 15 else 0.0 for k in frac}
    best = max((k for k in frac if frac[k] >= top - 0.05), key=lambda k: rise[k])
    if best != "y" and frac[best] >= 0.8 and (frac["y"] < 0.5 or rise[best] > 2 * rise["y"]):
        return [Problem(sid, "joints", f"looks {best}-up: the feet are the lowest joints along {best} in "
                                       f"{100 * frac[best]:.0f}% of frames but along y in {100 * frac['y']:.0f}%; "
                                       "hoibench is y-up", "warning")], best
    return [], None


#: a body-surface marker lies at most this far from its nearest joint (metres): markers sit on
#: the skin, within ~0.2 m of a joint; a larger gap means another frame, unit or sample
MAX_MARKER_JOINT_M = 0.35


def _check_markers(sid: str, markers: np.ndarray, joints: np.ndarray) -> list[Problem]:
    """Markers (K, T, 77, 3) must sit on the body of the same sample and frame."""
    d = np.linalg.norm(markers[:, :, :, None, :] - joints[:, :, None, :, :], axis=-1).min(-1)   # (K, T, 77)
    far = d > MAX_MARKER_JOINT_M
    if not far.any():
        return []
    k, t, m = (int(i) for i in np.argwhere(far)[0])
    return [Problem(sid, "markers", f"{int(far.sum())} marker position(s) more than {MAX_MARKER_JOINT_M:g} m from "
                                    f"every joint of the same sample and frame, first marker {m} of sample {k} frame "
                                    f"{t} ({float(d[k, t, m]):.3g} m): not on this body (other frame or units?)")]


def _check_object_trans(sid: str, trans: np.ndarray, joints: np.ndarray, fps: float) -> list[Problem]:
    """Object translation units per sample (median distance to the pelvis), per frame
    (maximum distance) and object speed per frame."""
    dist = np.linalg.norm(trans.astype(np.float64) - joints[:, :, 0].astype(np.float64), axis=-1)   # (K, T)
    med = np.median(dist, axis=1)
    if med.max() > MAX_OBJECT_DISTANCE_M:
        k = int(np.argmax(med))
        return [Problem(sid, "obj_trans", f"the object is {med[k]:.3g} m from the pelvis (median over sample {k}): "
                                          "implausible units (centimetres?)")]
    if dist.max() > MAX_OBJECT_DISTANCE_FRAME_M:
        k, t = (int(i) for i in np.unravel_index(np.argmax(dist), dist.shape))
        return [Problem(sid, "obj_trans", f"the object is {dist[k, t]:.3g} m from the pelvis at sample {k} frame "
                                          f"{t} (limit {MAX_OBJECT_DISTANCE_FRAME_M:g} m): implausible")]
    if trans.shape[1] > 1:
        speed = np.linalg.norm(np.diff(trans.astype(np.float64), axis=1), axis=-1) * fps
        if speed.max() > MAX_SPEED_MPS:
            k, t = (int(i) for i in np.unravel_index(np.argmax(speed), speed.shape))
            return [Problem(sid, "obj_trans", f"the object moves {speed[k, t]:.3g} m/s between frames {t} and "
                                              f"{t + 1} of sample {k} (limit {MAX_SPEED_MPS:g} m/s): implausible")]
    return []


def _check_rotations(sid: str, R: np.ndarray) -> list[Problem]:
    R = R.astype(np.float64)
    orth = np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)).max(axis=(-1, -2))
    det = np.linalg.det(R)
    bad = (orth > ROTATION_TOL) | (det < 0)
    if not bad.any():
        return []
    k, t = (int(i) for i in np.argwhere(bad)[0])
    what = "a reflection (det < 0)" if det[k, t] < 0 else f"max |R^T R - I| = {orth[k, t]:.3g}"
    return [Problem(sid, "obj_rot", f"{int(bad.sum())} of {bad.size} matrices are not rotations; first at "
                                    f"sample {k} frame {t}: {what}")]


def encode_sample(arrays: Mapping[str, np.ndarray], k: int, mode: str, fps: float) -> np.ndarray:
    """Features evaluate embeds for sample ``k``: hoi269 rows when the object pose is given,
    hml263 rows otherwise (``mode``: ``clean`` | ``legacy``)."""
    return _encode_parts(*_encode_inputs(arrays, k), mode, fps)


def _encode_parts(joints, rot, trans, mode: str, fps: float) -> np.ndarray:
    """hoi269 rows of ``joints``, ``rot``, ``trans``, or hml263 rows when ``rot`` is None; one
    sample (T, ...) or a batch (B, T, ...)."""
    from ..representations import hml263, hoi269
    if rot is None:
        return hml263.encode(joints, mode=mode, fps=fps)
    return hoi269.encode(joints, rot, trans, mode=mode, fps=fps)


def _encode_inputs(arrays: Mapping[str, np.ndarray], k: int) -> tuple:
    """(joints, rotation or None, translation or None) of sample ``k``, as :func:`encode_sample` reads them."""
    if "obj_trans" in arrays and ("obj_rot" in arrays or "obj_rotvec" in arrays):
        rot = arrays["obj_rot"][k] if "obj_rot" in arrays else arrays["obj_rotvec"][k]
        return arrays["joints"][k], rot, arrays["obj_trans"][k]
    return arrays["joints"][k], None, None


def _encode_problem(sid: str, k: int, feats: np.ndarray | None, error: Exception | None) -> Problem | None:
    """The problem of sample ``k``'s encoding (an exception, or non-finite features), or None."""
    if error is not None:
        return Problem(sid, "joints", f"sample {k} cannot be encoded: {error}")
    if not np.isfinite(feats).all():
        t = int(np.argwhere(~np.isfinite(feats))[0][0])
        return Problem(sid, "joints", f"sample {k} encodes to non-finite features from frame {t} (a "
                                      "degenerate pose: coincident hips or shoulders?)")
    return None


_ENCODE_ERRORS = (ValueError, FloatingPointError, np.linalg.LinAlgError)


class EncodeBatcher:
    """Samples whose features validation checks, encoded together: samples with the same
    arrays, shapes and dtypes are stacked and encoded as one batch of up to ``size``
    (hoi269/hml263 of a batch are bit-identical to one sample at a time, and about twice as
    fast: the per-call overhead of small arrays is shared). A batch that raises is encoded
    again one sample at a time, so every message is the single sample's. :meth:`finish`
    returns, per file, the problem of its first failing sample (what checking the samples in
    order reports) and puts every other file's features in ``encoded``."""

    def __init__(self, mode: str, fps: float, encoded: dict | None = None, size: int = 64):
        self.mode, self.fps, self.encoded, self.size = mode, float(fps), encoded, int(size)
        self.groups: dict[tuple, list[tuple[str, int, tuple]]] = {}
        self.done: dict[str, dict[int, np.ndarray]] = {}
        self.failed: dict[str, tuple[int, Problem]] = {}

    def add(self, sid: str, arrays: Mapping[str, np.ndarray]) -> None:
        for k in range(len(arrays["joints"])):
            parts = _encode_inputs(arrays, k)
            key = tuple(None if a is None else (np.asarray(a).shape, np.asarray(a).dtype.str) for a in parts)
            group = self.groups.setdefault(key, [])
            group.append((sid, k, parts))
            if len(group) >= self.size:
                self._encode(self.groups.pop(key))

    def _encode(self, group: list) -> None:
        parts = [p for _, _, p in group]
        stacked = [None if parts[0][i] is None else np.stack([p[i] for p in parts]) for i in range(3)]
        feats, error = _try_encode(stacked, self.mode, self.fps)
        if error is not None:                  # found again one sample at a time, with its own message
            for sid, k, p in group:
                self._keep(sid, k, *_try_encode(p, self.mode, self.fps))
            return
        for (sid, k, _), f in zip(group, feats):
            self._keep(sid, k, np.ascontiguousarray(f), None)

    def _keep(self, sid: str, k: int, feats: np.ndarray | None, error: Exception | None) -> None:
        problem = _encode_problem(sid, k, feats, error)
        if problem is not None:
            if sid not in self.failed or self.failed[sid][0] > k:
                self.failed[sid] = (k, problem)
        else:
            self.done.setdefault(sid, {})[k] = feats

    def finish(self) -> dict[str, Problem]:
        """Encode what is queued; ``{file id: its problem}`` for the files with a failing sample."""
        for key in list(self.groups):
            self._encode(self.groups.pop(key))
        if self.encoded is not None:
            for sid in sorted(self.done):
                if sid not in self.failed:
                    for k in sorted(self.done[sid]):
                        self.encoded[(sid, k)] = self.done[sid][k]
        self.done.clear()
        return {sid: problem for sid, (_, problem) in self.failed.items()}


def _try_encode(parts, mode: str, fps: float) -> tuple[np.ndarray | None, Exception | None]:
    """``(features, None)`` of :func:`_encode_parts`, or ``(None, the error)`` it raised; without
    floating-point warnings (non-finite features are reported by :func:`_encode_problem`)."""
    try:
        with np.errstate(invalid="ignore", divide="ignore"):
            return _encode_parts(*parts, mode, fps), None
    except _ENCODE_ERRORS as e:
        return None, e


def _check_encodes(sid: str, arrays: Mapping[str, np.ndarray], ctx: ClipContext) -> list[Problem]:
    if "joints" not in arrays or (ctx.has_object and not ctx.human_only and "obj_trans" not in arrays):
        return []
    if ctx.batcher is not None:            # checked when the batch is encoded (EncodeBatcher.finish)
        ctx.batcher.add(sid, arrays)
        return []
    for k in range(len(arrays["joints"])):
        feats, error = _try_encode(_encode_inputs(arrays, k), ctx.mode, ctx.fps)
        problem = _encode_problem(sid, k, feats, error)
        if problem is not None:
            return [problem]
        if ctx.encoded is not None:
            ctx.encoded[(sid, k)] = feats
    return []
