"""``synthetic_defects``: known defects injected into a motion plan, for metric tests.

:class:`Defect` (foot skating, penetration, lost contact) and the injectors that edit a plan
before it is solved, each returning the record kept in the ground truth; see "Injected
defects" in :mod:`hoibench.datasets.synthetic`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .synthetic_actions import _frames, _Plan
from .synthetic_body import _Body, _minjerk, _normalize
from .synthetic_constants import FPS, SEAT_CLEARANCE_M, _HAND_INDEX, _WRISTS, _ry
from .synthetic_objects import ObjectModel


# =========================================================================== defects
@dataclass(frozen=True)
class Defect:
    """A known defect to inject. ``kind``: ``foot_skating`` (``magnitude`` = speed, m/s),
    ``penetration`` (depth, m) or ``lost_contact`` (gap, m). ``side``: 'left'/'right' hand
    or foot, None = automatic (the foot with the longest planted run; the first hand)."""
    kind: str
    magnitude: float
    side: str | None = None

    def __post_init__(self):
        if self.kind not in ("foot_skating", "penetration", "lost_contact"):
            raise ValueError(f"Defect.kind: expected foot_skating, penetration or lost_contact, "
                             f"got {self.kind!r}")
        if not (self.magnitude > 0 and math.isfinite(self.magnitude)):
            raise ValueError(f"Defect.magnitude: expected a positive number, got {self.magnitude!r}")
        if self.side not in (None, "left", "right"):
            raise ValueError(f"Defect.side: expected None, 'left' or 'right', got {self.side!r}")

    @property
    def units(self) -> str:
        return "m/s" if self.kind == "foot_skating" else "m"


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) runs of True."""
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    d = np.diff(m.astype(np.int8))
    return list(zip(np.where(d == 1)[0], np.where(d == -1)[0]))


def _inject_skating(plan: _Plan, d: Defect) -> dict:
    runs = {k: max(_runs(plan.planted[:, k]), key=lambda r: r[1] - r[0]) for k in (0, 1)}
    k = _HAND_INDEX[d.side] if d.side else max((0, 1), key=lambda j: runs[j][1] - runs[j][0])
    a, b = runs[k]
    n = min(b - a, _frames(1.5))
    step = d.magnitude / FPS
    K = max(1, int(math.floor(0.10 / step + 1e-9)))
    j = np.arange(n)
    tri = K - np.abs(j % (2 * K) - K)
    fwd = _ry(plan.heading[a]) @ np.array([0.0, 0.0, 1.0])
    off = np.zeros((plan.T, 3))
    off[a:a + n] = tri[:, None] * step * fwd
    end = off[a + n - 1].copy()
    i = a + n
    while i < plan.T and plan.planted[i, k]:
        off[i] = end
        i += 1
    swing = [r for r in _runs(~plan.planted[:, k]) if r[0] >= i - 1]
    if swing:
        s0, s1 = swing[0]
        u = (np.arange(s0, s1 + 1) - (s0 - 1)) / (s1 - s0 + 1)
        off[s0:s1 + 1] = end * (1 - _minjerk(u))[:, None]
    plan.foot[:, k] += off
    return {"kind": "foot_skating", "magnitude": d.magnitude, "units": "m/s",
            "side": ("left", "right")[k], "joints": [7 + k, 10 + k], "frames": [int(a), int(a + n)],
            "note": "foot joint moves speed/fps every frame in frames[0]..frames[1]-1 while "
                    "labelled planted, reversing at 0.10 m from its plant"}


def _hand_contact_side(plan: _Plan, d: Defect) -> int:
    if d.side:
        k = _HAND_INDEX[d.side]
        if not plan.contacts[:, _WRISTS[k]].any():
            raise ValueError(f"defect {d.kind}: the {d.side} hand never touches the object")
        return k
    for k in (0, 1):
        if plan.contacts[:, _WRISTS[k]].any():
            return k
    raise ValueError(f"defect {d.kind}: no hand contact in this clip")


def _offset_window(plan: _Plan, k: int, a: int, b: int, value: float, ramp: int) -> tuple[int, int]:
    """Add ``value`` to hand k's normal offset on [a, b) with min-jerk ramps of ``ramp``
    frames inside the window where it does not touch the clip ends; returns the full-value
    frames."""
    i = np.arange(plan.T)
    up = 1.0 if a == 0 else _minjerk((i - a) / ramp)
    down = 1.0 if b == plan.T else _minjerk((b - 1 - i) / ramp)
    prof = np.where((i >= a) & (i < b), np.minimum(up, down), 0.0)
    plan.hand_delta[:, k] += value * prof
    full = np.where(prof >= 1.0 - 1e-12)[0]
    return int(full[0]), int(full[-1] + 1)


def _inject_penetration(plan: _Plan, d: Defect, obj: ObjectModel, body: _Body) -> dict:
    if plan.seated is not None:
        if d.magnitude > SEAT_CLEARANCE_M * body.s:
            raise ValueError(f"defect penetration: sitting depth must be <= the seat clearance "
                             f"{SEAT_CLEARANCE_M * body.s:.3f} m, got {d.magnitude}")
        a, b = _runs(plan.seated)[0]
        i = np.arange(plan.T)
        plan.pelvis[:, 1] -= d.magnitude * np.where(i >= a, _minjerk((i - a + 1) / 8), 0.0)
        return {"kind": "penetration", "magnitude": d.magnitude, "units": "m", "side": None,
                "joints": [1, 2], "frames": [int(a + 7), int(b)],
                "note": "pelvis lowered by magnitude from the clean seated pose: the body "
                        "surface (which rests on the seat) sinks magnitude into it; the hip "
                        "joints' signed distance drops by magnitude"}
    if plan.kick is not None:
        k = plan.kick["foot"]
        a, b = plan.kick["contact"]
        fwd = np.array([0.0, 0.0, 1.0])
        n = _normalize(plan.obj_t[a] - plan.foot[a, k] + 0 * fwd)   # inward normal
        plan.foot[a:b, k] += d.magnitude * n
        return {"kind": "penetration", "magnitude": d.magnitude, "units": "m",
                "side": ("left", "right")[k], "joints": [10 + k], "frames": [int(a), int(b)],
                "note": "kicking foot joint pushed magnitude inside the ball while touching it"}
    k = _hand_contact_side(plan, d)
    a, b = _runs(plan.contacts[:, _WRISTS[k]])[0]
    p, n = plan.hand_p[a, k], plan.hand_n[a, k]
    steps = np.arange(1, 2001) * 2.5e-4                   # up to 0.5 m inward, 0.25 mm steps
    depth = -obj.sdf_local(p[None] - steps[:, None] * n[None])
    if depth.max() < d.magnitude:
        raise ValueError(f"defect penetration: {obj.name} is at most {depth.max():.4f} m thick "
                         f"under this grip, cannot push {d.magnitude} m inside")
    j = int(np.argmax(depth >= d.magnitude))
    lo, hi = (steps[j - 1] if j else 0.0), steps[j]
    for _ in range(50):                                   # bisection: sdf(p - delta n) = -depth
        mid = 0.5 * (lo + hi)
        if -obj.sdf_local(p - mid * n) < d.magnitude:
            lo = mid
        else:
            hi = mid
    fa, fb = _offset_window(plan, k, a, b, -0.5 * (lo + hi), 4)
    return {"kind": "penetration", "magnitude": d.magnitude, "units": "m",
            "side": ("left", "right")[k], "joints": [_WRISTS[k]], "frames": [fa, fb],
            "note": "wrist pushed inside along the surface normal to signed distance -magnitude "
                    "while in contact"}


def _inject_lost_contact(plan: _Plan, d: Defect) -> dict:
    if plan.seated is not None or plan.kick is not None:
        raise ValueError("defect lost_contact: needs a hand action (lift, carry, putdown, push, "
                         "pull, hold)")
    k = _hand_contact_side(plan, d)
    a, b = max(_runs(plan.contacts[:, _WRISTS[k]]), key=lambda r: r[1] - r[0])
    n = b - a
    a, b = a + n // 4, b - n // 4
    if np.linalg.norm(plan.obj_t[a:b] - plan.obj_t[a], axis=-1).max() < 0.01:
        raise ValueError("defect lost_contact: the object does not move while the hand holds it")
    fa, fb = _offset_window(plan, k, a, b, d.magnitude, 3)
    return {"kind": "lost_contact", "magnitude": d.magnitude, "units": "m",
            "side": ("left", "right")[k], "joints": [_WRISTS[k]], "frames": [fa, fb],
            "note": "wrist magnitude outside the surface along the normal while the object "
                    "moves; contact labels stay on"}
