"""Object corruptions of one clip or sample (arrays as in :mod:`hoibench.audit.motion`; the
object's vertices are ``v = R v_template + t``), and the split-level object swap. Each
returns new arrays of the same shapes, dtypes and length; severity 0 returns copies of the
input unchanged."""
from __future__ import annotations

from typing import Mapping

import numpy as np

from .checks import (Context, check_arrays, check_clips, check_context, check_rng, check_severity,
                     frame_from_fraction, held_from, motion_only, unchanged)
from .streams import check_seed, clip_stream, selected

Arrays = Mapping[str, np.ndarray]

#: below this horizontal pelvis-object distance (m) the direction "away from the body" is
#: the body's facing direction instead
MIN_HORIZONTAL_M = 0.05


def _start(arrays: Arrays, severity, rng, ctx, hi=np.inf, what=""):
    T, _ = check_arrays(arrays, need_object=True)
    s = check_severity(severity, 0.0, hi, what)
    check_rng(rng)
    check_context(ctx)
    return T, s


def object_float(arrays: Arrays, severity: float, rng: np.random.Generator, ctx: Context) -> dict[str, np.ndarray]:
    """The object lifted by ``h`` on every frame: ``t' = t + (0, h, 0)`` (its lowest point
    rises by exactly ``h``); ``severity`` = ``h`` in metres. The body is unchanged."""
    _, h = _start(arrays, severity, rng, ctx, what=" (lift, m)")
    if h == 0:
        return unchanged(arrays)
    out = motion_only(arrays)
    out["obj_trans"] = (arrays["obj_trans"] + np.array([0.0, h, 0.0])).astype(arrays["obj_trans"].dtype)
    return out


def object_detach(arrays: Arrays, severity: float, rng: np.random.Generator, ctx: Context) -> dict[str, np.ndarray]:
    """The object stops following the hands: from ``t0 = floor((1 - f)(T - 1))`` on it keeps
    its pose of frame ``t0`` while the body moves on; ``severity`` = ``f``, the fraction of the
    clip detached (1: the object stays at its frame-0 pose). No randomness."""
    T, f = _start(arrays, severity, rng, ctx, hi=1.0, what=" (fraction of the clip)")
    if f == 0:
        return unchanged(arrays)
    t0 = frame_from_fraction(f, T)
    out = motion_only(arrays)
    out["obj_rot"] = held_from(arrays["obj_rot"], t0, -3)
    out["obj_trans"] = held_from(arrays["obj_trans"], t0, -2)
    return out


def away_from_body(joints: np.ndarray, obj_trans: np.ndarray) -> np.ndarray:
    """(..., T, 3) horizontal unit vectors from the pelvis towards the object origin; where the
    two are closer than :data:`MIN_HORIZONTAL_M` horizontally, the facing direction
    (``up x (right hip - left hip + right shoulder - left shoulder)``, HumanML3D's)."""
    J = np.asarray(joints, dtype=np.float64)
    d = np.asarray(obj_trans, dtype=np.float64) - J[..., 0, :]
    d[..., 1] = 0.0
    across = (J[..., 2, :] - J[..., 1, :]) + (J[..., 17, :] - J[..., 16, :])
    facing = np.cross(np.array([0.0, 1.0, 0.0]), across)
    facing[..., 1] = 0.0
    facing /= np.maximum(np.linalg.norm(facing, axis=-1, keepdims=True), 1e-12)
    norm = np.linalg.norm(d, axis=-1, keepdims=True)
    return np.where(norm >= MIN_HORIZONTAL_M, d / np.maximum(norm, 1e-12), facing)


def _shift(arrays: Arrays, distance: float) -> dict[str, np.ndarray]:
    out = motion_only(arrays)
    u = away_from_body(arrays["joints"], arrays["obj_trans"])
    out["obj_trans"] = (arrays["obj_trans"] + distance * u).astype(arrays["obj_trans"].dtype)
    return out


def grasp_offset(arrays: Arrays, severity: float, rng: np.random.Generator, ctx: Context) -> dict[str, np.ndarray]:
    """The object moved ``d`` away from the body (and so from the hands holding it) on every
    frame: ``t' = t + d u`` with ``u`` :func:`away_from_body` (horizontal); ``severity`` = ``d``
    in metres. No randomness."""
    _, d = _start(arrays, severity, rng, ctx, what=" (offset, m)")
    return unchanged(arrays) if d == 0 else _shift(arrays, d)


def object_penetrate(arrays: Arrays, severity: float, rng: np.random.Generator,
                     ctx: Context) -> dict[str, np.ndarray]:
    """The object pushed ``d`` towards and into the body on every frame: ``t' = t - d u`` with
    ``u`` :func:`away_from_body` (horizontal); ``severity`` = ``d`` in metres. No randomness."""
    _, d = _start(arrays, severity, rng, ctx, what=" (push, m)")
    return unchanged(arrays) if d == 0 else _shift(arrays, -d)


def object_swap(clips: Mapping[str, Arrays], severity: float, seed: int, ctx: Context,
                severity_index: int = 0) -> dict[str, dict[str, np.ndarray]]:
    """A fraction of the split's clips get another object's template: ``object_name`` of a
    selected clip becomes a name drawn uniformly from ``ctx.objects`` less its own (stream of
    (seed, family, ``severity_index``, clip)); the poses are kept, so the new template is
    placed by the same ``R, t``. ``severity`` = the fraction of clips swapped (nested across
    severities; clips without an object are never chosen). The clip's object name is ``arrays["object_name"]``, else
    ``ctx.clip_objects[clip id]``."""
    s = check_severity(severity, 0.0, 1.0, " (fraction of clips)")
    check_context(ctx)
    check_clips(clips)
    chosen = selected([c for c in clips if "obj_rot" in clips[c]], s, check_seed(seed), "object_swap")
    pool = sorted(set(ctx.objects))
    if chosen and len(pool) < 2:
        raise ValueError(f"ctx: objects must name at least two objects to swap between, got {pool}")
    out = {}
    for cid, arrays in clips.items():
        out[cid] = unchanged(arrays)
        if cid not in chosen:
            continue
        own = str(arrays["object_name"]) if "object_name" in arrays else ctx.clip_objects.get(cid, "")
        others = [o for o in pool if o != own]
        rng = clip_stream(seed, "object_swap", severity_index, cid)
        out[cid] = motion_only(arrays)
        out[cid]["object_name"] = np.array(others[int(rng.integers(len(others)))])
    return out
