"""Body-motion corruptions of one clip or sample: arrays ``joints`` (..., T, 22, 3) metres,
y-up, and ``obj_rot`` (..., T, 3, 3) / ``obj_trans`` (..., T, 3) with object vertices
``v = R v_template + t``. Each returns new arrays of the same shapes, dtypes and length;
severity 0 (speed: factor 1) returns copies of the input unchanged; a corrupted clip keeps
only ``joints``, ``obj_rot``, ``obj_trans`` and ``object_name`` (features derived from
them, e.g. ``hml263``, would be stale)."""
from __future__ import annotations

from typing import Mapping

import numpy as np

from ..core.geometry import axis_angle_to_matrix, matrix_to_axis_angle
from ..core.skeleton import FEET, MIRROR_JOINTS
from .checks import (Context, check_arrays, check_clips, check_context, check_rng, check_severity,
                     frame_from_fraction, held_from, motion_only, unchanged)
from .streams import check_seed, selected

Arrays = Mapping[str, np.ndarray]

#: a foot is planted at frame t when it is less than this above the sample's lowest foot
#: point and moved less than PLANTED_SPEED_MPS horizontally from frame t - 1 (FSR's height,
#: GMD's speed)
PLANTED_HEIGHT_M = 0.05
PLANTED_SPEED_MPS = 0.5
#: the reflection x -> -x
MIRROR = np.diag([-1.0, 1.0, 1.0])


def _start(arrays: Arrays, severity, rng, ctx, lo=0.0, hi=np.inf, what="", need_object=False):
    T, has_obj = check_arrays(arrays, need_object)
    s = check_severity(severity, lo, hi, what)
    check_rng(rng)
    check_context(ctx)
    return T, has_obj, s


def joint_noise(arrays: Arrays, severity: float, rng: np.random.Generator, ctx: Context) -> dict[str, np.ndarray]:
    """Gaussian noise on every joint coordinate: ``J' = J + sigma * N(0, 1)``, i.i.d. per
    sample, frame, joint and axis; ``severity`` = sigma in metres. The object is unchanged."""
    _, _, sigma = _start(arrays, severity, rng, ctx, what=" (sigma, m)")
    if sigma == 0:
        return unchanged(arrays)
    out = motion_only(arrays)
    J = arrays["joints"]
    out["joints"] = (J + sigma * rng.standard_normal(J.shape)).astype(J.dtype)
    return out


def jitter(arrays: Arrays, severity: float, rng: np.random.Generator, ctx: Context) -> dict[str, np.ndarray]:
    """High-frequency jitter at half the frame rate: ``J'[t, j] = J[t, j] + a (-1)^t u_j`` with
    ``u_j`` a random unit vector per sample and joint (fixed over time); ``severity`` = the
    amplitude ``a`` in metres (each frame moves by ``2a`` relative to its neighbours). The
    object is unchanged."""
    T, _, a = _start(arrays, severity, rng, ctx, what=" (amplitude, m)")
    if a == 0:
        return unchanged(arrays)
    out = motion_only(arrays)
    J = arrays["joints"]
    u = rng.standard_normal(J.shape[:-3] + (1,) + J.shape[-2:])
    u /= np.linalg.norm(u, axis=-1, keepdims=True)
    sign = np.where(np.arange(T) % 2 == 0, 1.0, -1.0)[:, None, None]
    out["joints"] = (J + a * sign * u).astype(J.dtype)
    return out


def planted_frames(joints: np.ndarray, fps: float) -> np.ndarray:
    """(..., T) bool: frame ``t >= 1`` where a foot (joints 10, 11) is planted (see
    :data:`PLANTED_HEIGHT_M`, :data:`PLANTED_SPEED_MPS`); frame 0 is never planted."""
    F = np.asarray(joints, dtype=np.float64)[..., list(FEET), :]                 # (..., T, 2, 3)
    floor = F[..., 1].min(axis=(-2, -1))[..., None, None]                        # (..., 1, 1)
    low = F[..., 1:, :, 1] - floor < PLANTED_HEIGHT_M
    speed = np.linalg.norm(np.diff(F[..., [0, 2]], axis=-3), axis=-1) * fps     # (..., T-1, 2)
    planted = (low & (speed < PLANTED_SPEED_MPS)).any(axis=-1)
    return np.concatenate([np.zeros(planted.shape[:-1] + (1,), bool), planted], axis=-1)


def foot_sliding(arrays: Arrays, severity: float, rng: np.random.Generator, ctx: Context) -> dict[str, np.ndarray]:
    """Root drift while a foot is planted: the whole body (and the object with it) moves by
    ``v / fps`` along a random horizontal unit direction (one per sample) on every frame
    :func:`planted_frames` marks, and keeps that offset afterwards:
    ``offset[t] = (v / fps) * d * #planted frames in 1..t``. ``severity`` = ``v`` in m/s."""
    _, has_obj, v = _start(arrays, severity, rng, ctx, what=" (drift speed, m/s)")
    if v == 0:
        return unchanged(arrays)
    out = motion_only(arrays)
    J = arrays["joints"]
    angle = rng.uniform(0.0, 2 * np.pi, size=J.shape[:-3])
    d = np.stack([np.cos(angle), np.zeros_like(angle), np.sin(angle)], axis=-1)   # (..., 3)
    steps = np.cumsum(planted_frames(J, ctx.fps), axis=-1)                        # (..., T)
    offset = (v / ctx.fps) * steps[..., None] * d[..., None, :]                  # (..., T, 3)
    out["joints"] = (J + offset[..., None, :]).astype(J.dtype)
    if has_obj:
        out["obj_trans"] = (arrays["obj_trans"] + offset).astype(arrays["obj_trans"].dtype)
    return out


def freeze(arrays: Arrays, severity: float, rng: np.random.Generator, ctx: Context) -> dict[str, np.ndarray]:
    """Hold a frame: every frame from ``t0 = floor((1 - f)(T - 1))`` on repeats frame ``t0``
    (body and object); ``severity`` = ``f``, the fraction of the clip frozen (1: the whole clip
    held at frame 0). Frame 0 is never changed. No randomness."""
    T, has_obj, f = _start(arrays, severity, rng, ctx, hi=1.0, what=" (fraction of the clip)")
    if f == 0:
        return unchanged(arrays)
    t0 = frame_from_fraction(f, T)
    out = motion_only(arrays)
    out["joints"] = held_from(arrays["joints"], t0, -3)
    if has_obj:
        out["obj_rot"] = held_from(arrays["obj_rot"], t0, -3)
        out["obj_trans"] = held_from(arrays["obj_trans"], t0, -2)
    return out


def reverse(arrays: Arrays, severity: float, rng: np.random.Generator, ctx: Context) -> dict[str, np.ndarray]:
    """Time reversal of the last ``n = floor(f T + 0.5)`` frames (body and object):
    ``X'[T - n + i] = X[T - 1 - i]``; ``severity`` = ``f``, the fraction of the clip reversed
    (1: the whole clip). Reversing twice with the same ``f`` is the identity. No randomness."""
    T, has_obj, f = _start(arrays, severity, rng, ctx, hi=1.0, what=" (fraction of the clip)")
    n = int(np.floor(f * T + 0.5))
    if n < 2:
        return unchanged(arrays)
    out = motion_only(arrays)
    for k, axis in (("joints", -3), ("obj_rot", -3), ("obj_trans", -2)):
        if k == "joints" or has_obj:
            a = out[k]
            index = [slice(None)] * a.ndim
            index[axis] = slice(T - n, T)
            a[tuple(index)] = np.flip(arrays[k][tuple(index)], axis=axis)
    return out


def _sample_rotations(R: np.ndarray, i0: np.ndarray, i1: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Rotations at fractional frames: ``R[i0] exp(w log(R[i0]^T R[i1]))`` (slerp)."""
    Ra, Rb = R[..., i0, :, :].astype(np.float64), R[..., i1, :, :].astype(np.float64)
    rel = matrix_to_axis_angle(np.swapaxes(Ra, -1, -2) @ Rb)
    return Ra @ axis_angle_to_matrix(rel * w[:, None])


def speed(arrays: Arrays, severity: float, rng: np.random.Generator, ctx: Context) -> dict[str, np.ndarray]:
    """Playback at ``c`` times the speed, resampled to the same length: frame ``t`` shows the
    original time ``s_t = min(c t, T - 1)`` frames, positions interpolated linearly and object
    rotations by slerp; ``c > 1`` (faster) ends early and holds the last frame, ``c < 1``
    (slower) shows the first ``c (T - 1)`` frames' worth. ``severity`` = ``c`` (1: unchanged);
    its magnitude is ``|log2 c|``. No randomness."""
    T, has_obj, c = _start(arrays, severity, rng, ctx, lo=1e-3, hi=1e3, what=" (speed factor)")
    if c == 1.0:
        return unchanged(arrays)
    s = np.minimum(c * np.arange(T, dtype=np.float64), T - 1)
    i0 = np.floor(s).astype(int)
    i1 = np.minimum(i0 + 1, T - 1)
    w = s - i0
    out = motion_only(arrays)
    J = arrays["joints"].astype(np.float64)
    out["joints"] = ((1 - w)[:, None, None] * J[..., i0, :, :] + w[:, None, None] * J[..., i1, :, :]) \
        .astype(arrays["joints"].dtype)
    if has_obj:
        t = arrays["obj_trans"].astype(np.float64)
        out["obj_trans"] = ((1 - w)[:, None] * t[..., i0, :] + w[:, None] * t[..., i1, :]) \
            .astype(arrays["obj_trans"].dtype)
        out["obj_rot"] = _sample_rotations(arrays["obj_rot"], i0, i1, w).astype(arrays["obj_rot"].dtype)
    return out


def mirror_arrays(arrays: Arrays) -> dict[str, np.ndarray]:
    """The left-right mirror image of one clip (exact, involutive): joints ``J'[j] = M J[m(j)]``
    with ``M = diag(-1, 1, 1)`` and ``m`` swapping left and right joints; object
    ``R' = M R M``, ``t' = M t`` (``R'`` stays a rotation). The mirrored object is ``R'``
    applied to the mirrored template ``M v_template`` (:func:`mirror_template`); for a template
    symmetric in its own x, that is the template itself."""
    check_arrays(arrays)
    out = motion_only(arrays)
    sign = np.array([-1.0, 1.0, 1.0])
    J = arrays["joints"][..., list(MIRROR_JOINTS), :]
    out["joints"] = (J * sign).astype(J.dtype)
    if "obj_rot" in arrays:
        R = arrays["obj_rot"]
        out["obj_rot"] = (R * sign[:, None] * sign[None, :]).astype(R.dtype)
        out["obj_trans"] = (arrays["obj_trans"] * sign).astype(arrays["obj_trans"].dtype)
    return out


def mirror_template(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """An object template mirrored in its own x (``M v``), faces reversed so normals point out."""
    v, f = np.asarray(vertices), np.asarray(faces)
    if v.ndim != 2 or v.shape[-1] != 3:
        raise ValueError(f"vertices: expected shape (V, 3), got {v.shape}")
    if f.ndim != 2 or f.shape[-1] != 3:
        raise ValueError(f"faces: expected shape (F, 3), got {f.shape}")
    return v * np.array([-1.0, 1.0, 1.0], dtype=v.dtype), f[:, ::-1].copy()


def mirror(clips: Mapping[str, Arrays], severity: float, seed: int, ctx: Context,
           severity_index: int = 0) -> dict[str, dict[str, np.ndarray]]:
    """Left-right mirror (:func:`mirror_arrays`) of a fraction of the split's clips:
    ``severity`` = the fraction mirrored, the clips chosen by
    :func:`~hoibench.audit.streams.selected` (nested across severities); the others are
    returned unchanged. ``severity_index`` is not used (no per-clip randomness)."""
    s = check_severity(severity, 0.0, 1.0, " (fraction of clips)")
    check_context(ctx)
    check_clips(clips)
    chosen = set(selected(clips, s, check_seed(seed), "mirror"))
    return {cid: mirror_arrays(a) if cid in chosen else unchanged(a) for cid, a in clips.items()}


def follow_markers(markers: np.ndarray, joints: np.ndarray, new_joints: np.ndarray) -> np.ndarray:
    """Body-surface markers (T, 77, 3) moved as a corruption moved the joints (T, 22, 3) ->
    ``new_joints``: ``m' = m + P(J') - P(J)``, with ``P`` the 77 markers of the proxy body
    posed to the joints (:func:`hoibench.metrics.body_surface.proxy_markers`). Each marker
    keeps its offset from the proxy surface, so noise, jitter, drift, held or reversed frames,
    a new speed and a mirror reach the markers the way they reach the joints (exactly for
    rigid shifts of the whole body, to the proxy's fit otherwise); equal joints return the
    markers unchanged (a copy). Same dtype as ``markers``."""
    from ..metrics.body_surface import proxy_markers
    m = np.asarray(markers)
    J, J2 = np.asarray(joints), np.asarray(new_joints)
    if m.ndim != 3 or m.shape[1:] != (77, 3):
        raise ValueError(f"markers: expected shape (T, 77, 3), got {m.shape}")
    if J.shape != J2.shape or J.ndim != 3 or len(J) != len(m):
        raise ValueError(f"new_joints: expected the joints' shape {J.shape} with T = {len(m)}, got {J2.shape}")
    if np.array_equal(J, J2):
        return m.copy()
    return (m + (proxy_markers(J2) - proxy_markers(J))).astype(m.dtype)
