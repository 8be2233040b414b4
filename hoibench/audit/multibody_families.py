"""The corruption families of a multi-body audit: :data:`MULTIBODY_FAMILIES` (name ->
:class:`~hoibench.audit.corruptions.FamilySpec`) over :class:`~hoibench.bodies.multibody.MultiBodyClip`.

A ``clip``-scope function is ``fn(clip, severity, rng, ctx)`` and returns a new clip with the
same bodies, frames and dtypes (its contacts are left empty: the scorer recomputes them from
the bodies); severity 0 (speed: factor 1) returns an equal copy. Skeletons (hands, humans) are
moved through their joints (the root follows joint 0, as in a submission), objects through
their ``rot`` and ``trans``. The one ``split``-scope family, ``action_swap``, corrupts the
prompts (the action labels the recognizer's RA is scored against), not the motion:
``fn(actions, severity, seed, ctx, severity_index)`` returns the new labels.

The temporal families (freeze, reverse, speed, desync) move every body on the same time map
(desync: the first skeleton only), so a hand and the object it holds stay together unless the
family is meant to part them.
"""
from __future__ import annotations

import dataclasses
from typing import Mapping

import numpy as np

from ..bodies.multibody import Body, MultiBodyClip
from .checks import frame_from_fraction
from .corruptions import FAMILIES, FamilySpec
from .motion import _sample_rotations
from .streams import check_seed, selected


def _copy(clip: MultiBodyClip, bodies: list[Body]) -> MultiBodyClip:
    return dataclasses.replace(clip, bodies=bodies, contacts={})


def _body(b: Body, joints=None, trans=None, rot=None) -> Body:
    """``b`` with new arrays (a skeleton's root is its joint 0)."""
    if joints is not None:
        joints = np.asarray(joints, b.joints.dtype)
        return dataclasses.replace(b, joints=joints, trans=joints[:, 0].astype(b.trans.dtype))
    return dataclasses.replace(b, trans=b.trans if trans is None else np.asarray(trans, b.trans.dtype),
                               rot=b.rot if rot is None else np.asarray(rot, b.rot.dtype))


def _identity(clip: MultiBodyClip) -> MultiBodyClip:
    return _copy(clip, [dataclasses.replace(b, trans=b.trans.copy(), rot=None if b.rot is None else b.rot.copy(),
                                            joints=None if b.joints is None else b.joints.copy())
                        for b in clip.bodies])


def _check(severity: float, lo: float = 0.0, hi: float = np.inf, what: str = "") -> float:
    s = float(severity)
    if not np.isfinite(s) or s < lo or s > hi:
        raise ValueError(f"severity: {severity!r} outside [{lo:g}, {hi:g}]{what}")
    return s


def _retime(b: Body, i0: np.ndarray, i1: np.ndarray | None = None, w: np.ndarray | None = None) -> Body:
    """``b`` shown at frames ``i0`` (or between ``i0`` and ``i1`` at weight ``w``: positions
    linearly, rotations by slerp)."""
    def lerp(a):
        a64 = a.astype(np.float64)
        if w is None:
            return a64[i0]
        ww = w.reshape((-1,) + (1,) * (a.ndim - 1))
        return (1 - ww) * a64[i0] + ww * a64[i1]
    if not b.is_rigid:
        return _body(b, joints=lerp(b.joints))
    rot = b.rot[i0] if w is None else _sample_rotations(b.rot, i0, i1, w)
    return _body(b, trans=lerp(b.trans), rot=rot)


def _skeletons(clip: MultiBodyClip) -> list[int]:
    return [i for i, b in enumerate(clip.bodies) if not b.is_rigid]


# ---------------------------------------------------------------------------- families
def joint_noise(clip: MultiBodyClip, severity: float, rng: np.random.Generator, ctx=None) -> MultiBodyClip:
    """Gaussian noise on every skeleton joint coordinate: ``J' = J + sigma N(0, 1)``; ``severity``
    = sigma (m). Objects unchanged."""
    s = _check(severity, what=" (m)")
    if s == 0:
        return _identity(clip)
    return _copy(clip, [b if b.is_rigid else _body(b, joints=b.joints + s * rng.standard_normal(b.joints.shape))
                        for b in clip.bodies])


def jitter(clip: MultiBodyClip, severity: float, rng: np.random.Generator, ctx=None) -> MultiBodyClip:
    """Jitter at half the frame rate: ``J'[t, j] = J[t, j] + a (-1)^t u_j`` with ``u_j`` a random
    unit vector per skeleton joint; ``severity`` = a (m)."""
    a = _check(severity, what=" (m)")
    if a == 0:
        return _identity(clip)
    out = []
    for b in clip.bodies:
        if b.is_rigid:
            out.append(b)
            continue
        u = rng.standard_normal((b.joints.shape[1], 3))
        u /= np.linalg.norm(u, axis=-1, keepdims=True)
        sign = np.where(np.arange(b.num_frames) % 2 == 0, 1.0, -1.0)[:, None, None]
        out.append(_body(b, joints=b.joints + a * sign * u))
    return _copy(clip, out)


def freeze(clip: MultiBodyClip, severity: float, rng=None, ctx=None) -> MultiBodyClip:
    """Every body holds frame ``t0 = floor((1 - f)(T - 1))`` from ``t0`` on; ``severity`` = f."""
    f = _check(severity, 0.0, 1.0, " (fraction of the clip)")
    if f == 0:
        return _identity(clip)
    T = clip.num_frames
    idx = np.minimum(np.arange(T), frame_from_fraction(f, T))
    return _copy(clip, [_retime(b, idx) for b in clip.bodies])


def reverse(clip: MultiBodyClip, severity: float, rng=None, ctx=None) -> MultiBodyClip:
    """The last ``n = floor(f T + 0.5)`` frames of every body played backwards; ``severity`` = f."""
    f = _check(severity, 0.0, 1.0, " (fraction of the clip)")
    T = clip.num_frames
    n = int(np.floor(f * T + 0.5))
    if n < 2:
        return _identity(clip)
    idx = np.arange(T)
    idx[T - n:] = idx[T - n:][::-1]
    return _copy(clip, [_retime(b, idx) for b in clip.bodies])


def speed(clip: MultiBodyClip, severity: float, rng=None, ctx=None) -> MultiBodyClip:
    """Every body played ``c`` times as fast, resampled to the same length (frame ``t`` shows
    time ``min(c t, T - 1)``); ``severity`` = c."""
    c = _check(severity, 1e-3, 1e3, " (speed factor)")
    if c == 1.0:
        return _identity(clip)
    T = clip.num_frames
    s = np.minimum(c * np.arange(T, dtype=np.float64), T - 1)
    i0 = np.floor(s).astype(int)
    i1 = np.minimum(i0 + 1, T - 1)
    return _copy(clip, [_retime(b, i0, i1, s - i0) for b in clip.bodies])


def desync(clip: MultiBodyClip, severity: float, rng=None, ctx=None) -> MultiBodyClip:
    """The first skeleton lags the rest of the scene by ``round(s fps)`` frames (frame ``t``
    shows its frame ``max(t - lag, 0)``); ``severity`` = s (seconds)."""
    s = _check(severity, what=" (s)")
    lag = int(round(s * clip.fps))
    first = _skeletons(clip)[:1]
    if lag == 0 or not first:
        return _identity(clip)
    idx = np.clip(np.arange(clip.num_frames) - lag, 0, clip.num_frames - 1)
    return _copy(clip, [_retime(b, idx) if i in first else b for i, b in enumerate(clip.bodies)])


def object_float(clip: MultiBodyClip, severity: float, rng=None, ctx=None) -> MultiBodyClip:
    """Every object lifted by ``h`` (m) on every frame (+y)."""
    h = _check(severity, what=" (m)")
    if h == 0:
        return _identity(clip)
    return _copy(clip, [_body(b, trans=b.trans + np.array([0.0, h, 0.0])) if b.is_rigid else b
                        for b in clip.bodies])


def grasp_offset(clip: MultiBodyClip, severity: float, rng: np.random.Generator, ctx=None) -> MultiBodyClip:
    """Every object moved ``d`` (m) horizontally along one random direction per clip: the
    hands close on air."""
    d = _check(severity, what=" (m)")
    if d == 0:
        return _identity(clip)
    angle = rng.uniform(0.0, 2.0 * np.pi)
    shift = d * np.array([np.cos(angle), 0.0, np.sin(angle)])
    return _copy(clip, [_body(b, trans=b.trans + shift) if b.is_rigid else b for b in clip.bodies])


def penetrate(clip: MultiBodyClip, severity: float, rng=None, ctx=None) -> MultiBodyClip:
    """The first skeleton pushed ``d`` (m) into the first object: every joint moves ``d``
    towards the object's origin on every frame."""
    d = _check(severity, what=" (m)")
    first = _skeletons(clip)[:1]
    held = next((b for b in clip.bodies if b.is_rigid), None)
    if d == 0 or not first or held is None:
        return _identity(clip)
    b = clip.bodies[first[0]]
    push = held.trans[:, None].astype(np.float64) - b.joints
    push = d * push / np.maximum(np.linalg.norm(push, axis=-1, keepdims=True), 1e-9)
    return _copy(clip, [_body(x, joints=x.joints + push) if i == first[0] else x for i, x in enumerate(clip.bodies)])


def action_swap(actions: Mapping[str, str], severity: float, seed: int, ctx=None,
                severity_index: int = 0) -> dict[str, str]:
    """The action labels of a fraction ``f`` of the clips (:func:`~hoibench.audit.streams.selected`,
    nested in ``f``) passed round a cycle in the selection's order: clip ``k`` is prompted with
    clip ``k + 1``'s action (the multiset of labels is kept)."""
    f = _check(severity, 0.0, 1.0, " (fraction of clips)")
    chosen = selected(sorted(actions), f, check_seed(seed), "action_swap", minimum=2)
    out = dict(actions)
    if len(chosen) >= 2:
        for k, cid in enumerate(chosen):
            out[cid] = actions[chosen[(k + 1) % len(chosen)]]
    return out


def _same_as_single(name: str, fn, description: str) -> tuple:
    """A family with the single-body family ``name``'s severities, unit and scope."""
    single = FAMILIES[name]
    return (name, fn, single.severities, single.unit, single.corrupts, single.scope, description, single.distance)


_SPECS = (
    _same_as_single("joint_noise", joint_noise, "Gaussian noise on every skeleton joint coordinate"),
    _same_as_single("jitter", jitter, "every skeleton joint oscillates +-a along a fixed random direction at fps/2"),
    _same_as_single("freeze", freeze, "the last fraction of the clip holds one frame (every body)"),
    _same_as_single("reverse", reverse, "the last fraction of the clip played backwards (every body)"),
    _same_as_single("speed", speed, "every body played c times as fast, resampled to the same length"),
    ("desync", desync, (0.0, 0.05, 0.1, 0.2, 0.4, 0.8), "s", "motion", "clip",
     "the first skeleton lags the rest of the scene"),
    _same_as_single("object_float", object_float, "every object lifted by h on every frame"),
    _same_as_single("grasp_offset", grasp_offset, "every object moved d horizontally: the hands close on air"),
    ("penetrate", penetrate, (0.0, 0.01, 0.02, 0.05, 0.1, 0.2), "m", "motion", "clip",
     "the first skeleton pushed d into the first object"),
    ("action_swap", action_swap, FAMILIES["caption_swap"].severities, "fraction of clips", "text", "split",
     "the action labels (the prompts) passed round a cycle of clips"),
)
#: the multi-body families, in audit order
MULTIBODY_FAMILIES: dict[str, FamilySpec] = {s[0]: FamilySpec(*s) for s in _SPECS}


__all__ = ["MULTIBODY_FAMILIES", "joint_noise", "jitter", "freeze", "reverse", "speed", "desync", "object_float",
           "grasp_offset", "penetrate", "action_swap"]
