"""``synthetic_actions``: the per-action motion plans of the synthetic HOI dataset.

``_Plan`` holds a clip's per-frame targets in the canonical frame (pelvis, heading, bend,
feet, hands on object-local grips, object pose, contact labels); one planner per action
(lift, putdown, hold, carry, push, pull, sit, kick; ``_PLANNERS``) fills it, drawing its
timings and poses from the clip's random generator.
"""
from __future__ import annotations

import math

import numpy as np

from .synthetic_body import _Body, _minjerk, _quintic
from .synthetic_constants import (FPS, SEAT_CLEARANCE_M, SIT_CONTACT_TOL_M, _HAND_INDEX, _LIFT_NEAR, _PREGRASP,
                                  _WRISTS, _rx, _ry)
from .synthetic_objects import ObjectModel


# =========================================================================== plans
class _Plan:
    """Per-frame targets of a clip in the canonical frame (person starts at the origin
    facing +z). Hand targets are object-local points ``p + delta n`` (n outward)."""

    def __init__(self, T: int, body: _Body):
        self.T = T
        self.pelvis = np.zeros((T, 3))
        self.pelvis[:, 1] = body.stand_y
        self.heading = np.zeros(T)
        self.bend = np.zeros(T)
        self.foot = np.repeat(body.stance((0.0, 0.0))[None], T, 0)
        self.foot_yaw = np.zeros((T, 2))
        self.planted = np.ones((T, 2), bool)
        self.hand_w = np.zeros((T, 2))
        self.hand_p = np.full((T, 2, 3), np.nan)
        self.hand_n = np.full((T, 2, 3), np.nan)
        self.hand_delta = np.zeros((T, 2))
        self.obj_R = np.repeat(np.eye(3)[None], T, 0)
        self.obj_t = np.zeros((T, 3))
        self.contacts = np.zeros((T, 22), bool)
        self.segments: list[tuple[str, int, int, str]] = []   # frames [start, end)
        self.crouch = False
        self.hands: tuple[str, ...] = ()
        self.feet: tuple[str, ...] = ()
        self.kick: dict | None = None
        self.seated: np.ndarray | None = None

    def reversed(self) -> "_Plan":
        out = _Plan.__new__(_Plan)
        out.__dict__.update(self.__dict__)
        for k, v in self.__dict__.items():
            if isinstance(v, np.ndarray) and v.ndim >= 1 and v.shape[0] == self.T:
                setattr(out, k, v[::-1].copy())
        out.segments = [(a, self.T - e, self.T - s, h) for a, s, e, h in reversed(self.segments)]
        return out

    def attach(self, hands: str, grips: dict, frames: slice):
        for h, (p, n) in grips[hands].items():
            k = _HAND_INDEX[h]
            self.hand_p[frames, k] = p
            self.hand_n[frames, k] = n

    def hand_targets(self) -> np.ndarray:
        """(T, 2, 3) world targets of the hands attached to the object."""
        loc = self.hand_p + self.hand_delta[..., None] * self.hand_n
        return np.einsum("tij,tkj->tki", self.obj_R, loc) + self.obj_t[:, None]


def _frames(sec: float) -> int:
    return int(round(sec * FPS))


def _floor_y(obj: ObjectModel) -> float:
    return float(-obj.vertices[:, 1].min())


def _approach(plan: _Plan, k: int, i_a: int, i_g: int):
    """Hand ``k`` moves from hanging free to a pre-grasp point _PREGRASP out along the
    normal (first 60 %), then onto the surface at frame ``i_g`` (weights, offsets)."""
    i = np.arange(plan.T)
    u = np.clip((i - i_a) / max(i_g - i_a, 1), 0.0, 1.0)
    plan.hand_w[:, k] = _minjerk(u / 0.6)
    plan.hand_delta[:, k] = _PREGRASP * (1 - _minjerk((u - 0.5) / 0.5))
    plan.hand_w[i_g:, k] = 1.0
    plan.hand_delta[i_g:, k] = 0.0
    plan.contacts[i_g:, _WRISTS[k]] = True


def _hold_pose(obj: ObjectModel, hands: str, body: _Body, walking: bool = False):
    """Object yaw and position (relative to a pelvis at x = z = 0) when held: hanging at the
    side for a one-hand backpack, else in front, chosen on a grid (hand height, near-face
    distance) closest to hands 0.12 s above the standing pelvis and the near face 0.24 m in
    front of it, with the hands within 90 % of the arm length of the standing shoulders and
    the object clear of the knees (near face >= 0.25 m or bottom >= 0.62 m)."""
    s = body.s
    g = obj.grips["lift"][hands]
    if hands != "both" and obj.name == "backpack":
        side = 1.0 if hands == "left" else -1.0
        yaw = math.pi / 2
        R = _ry(yaw)
        (p, _), = g.values()
        wrist = np.array([side * 0.27 * s, body.stand_y + 0.03 * s, 0.03])
        return yaw, wrist - R @ p
    pts = np.stack([p for p, _ in g.values()])
    m = pts.mean(0)
    lateral = 0.0 if hands == "both" else (0.10 if hands == "left" else -0.10) * s
    zmin, ymin = obj.vertices[:, 2].min(), obj.vertices[:, 1].min()
    ys = body.stand_y + np.arange(0.0, 0.40, 0.01) * s
    cs = np.arange(0.14, 0.41, 0.01)
    Y, C = np.meshgrid(ys, cs, indexing="ij")
    t = np.stack([np.full_like(Y, lateral - m[0]), Y - m[1], C - zmin], -1)
    bottom = t[..., 1] + ymin
    sh = np.array([0.0, body.stand_y - (0.025 * s if walking else 0.0), 0.0]) + body.shoulder_off
    ok = (bottom >= 0.05) & ((C >= 0.25) | (bottom >= 0.62))
    for hname, (p, _) in g.items():
        d = np.linalg.norm(t + p - sh[_HAND_INDEX[hname]], axis=-1)
        ok &= d <= 0.90 * body.arm_len
    hand_y = t[..., 1] + m[1]
    cost = np.abs(hand_y - (body.stand_y + 0.12 * s)) + 2 * np.abs(C - 0.24)
    cost = np.where(ok, cost, np.inf)
    idx = np.unravel_index(np.argmin(cost), cost.shape)
    if not np.isfinite(cost[idx]):
        raise RuntimeError(f"synthetic: no reachable hold pose for {obj.name}/{hands}")
    return 0.0, t[idx]


def _floor_pose(obj: ObjectModel, hands: str, body: _Body, rng, near: float):
    """Yaw and position of the object resting on the floor in front of the person."""
    if hands != "both" and obj.name == "backpack":
        yaw = math.pi / 2 + math.radians(rng.uniform(-6, 6))
        lateral = (0.22 if hands == "left" else -0.22) * body.s
    else:
        yaw = math.radians(rng.uniform(-6, 6))
        lateral = 0.0 if hands in ("both", "none") else (0.08 if hands == "left" else -0.08) * body.s
    R = _ry(yaw)
    v = obj.vertices @ R.T
    t = np.array([lateral, _floor_y(obj), near - v[:, 2].min()])
    return yaw, t


def _plan_lift(obj, hands, body, rng) -> _Plan:
    i_a = _frames(rng.uniform(0.2, 0.45))
    i_g = i_a + _frames(rng.uniform(0.8, 0.95))
    i_l = i_g + _frames(rng.uniform(1.1, 1.4))
    T = i_l + _frames(rng.uniform(0.6, 0.9))
    plan = _Plan(T, body)
    plan.crouch = True
    width = 0.30 * body.s if hands == "both" else None
    plan.foot[:] = body.stance((0.0, 0.0), width=width)
    near = _LIFT_NEAR.get(obj.name, 0.40) + rng.uniform(0.0, 0.03)
    yaw0, t0 = _floor_pose(obj, hands, body, rng, near=near)
    yaw1, t1 = _hold_pose(obj, hands, body)
    i = np.arange(T)
    u = np.clip((i - i_g) / (i_l - i_g), 0.0, 1.0)
    uy, uh = _minjerk(u / 0.8), _minjerk((u - 0.15) / 0.85)
    plan.obj_t = np.stack([t0[0] + (t1[0] - t0[0]) * uh, t0[1] + (t1[1] - t0[1]) * uy,
                           t0[2] + (t1[2] - t0[2]) * uh], -1)
    plan.obj_R = _ry(yaw0 + (yaw1 - yaw0) * uh)
    plan.attach(hands, obj.grips["lift"], slice(None))
    for h in obj.grips["lift"][hands]:
        _approach(plan, _HAND_INDEX[h], i_a, i_g)
    plan.hands = tuple(obj.grips["lift"][hands])
    plan.segments = [("lift", i_g, i_l, hands), ("hold", i_l, T, hands)]
    return plan


def _plan_putdown(obj, hands, body, rng) -> _Plan:
    return _plan_lift(obj, hands, body, rng).reversed()


def _plan_hold(obj, hands, body, rng) -> _Plan:
    T = _frames(rng.uniform(3.0, 3.6))
    plan = _Plan(T, body)
    plan.crouch = True
    yaw, t = _hold_pose(obj, hands, body)
    time = np.arange(T) / FPS
    f = rng.uniform(0.3, 0.6, 4)
    ph = rng.uniform(0, 2 * np.pi, 4)
    ramp = _minjerk(time / 0.5)
    sway = np.stack([0.025 * np.sin(2 * np.pi * f[0] * time + ph[0]),
                     0.020 * np.sin(2 * np.pi * f[1] * time + ph[1]),
                     0.015 * np.sin(2 * np.pi * f[2] * time + ph[2])], -1) * ramp[:, None]
    plan.obj_t = t + sway
    plan.obj_R = _ry(yaw + math.radians(4.0) * np.sin(2 * np.pi * f[3] * time + ph[3]) * ramp)
    plan.pelvis[:, 0] = 0.015 * np.sin(2 * np.pi * 0.4 * time + ph[0]) * ramp
    _grip_whole_clip(plan, obj, hands)
    plan.segments = [("hold", 0, T, hands)]
    return plan


def _grip_whole_clip(plan: _Plan, obj: ObjectModel, hands: str) -> None:
    """The hands hold the object (its lift grips) on every frame of the clip."""
    plan.attach(hands, obj.grips["lift"], slice(None))
    for h in obj.grips["lift"][hands]:
        k = _HAND_INDEX[h]
        plan.hand_w[:, k] = 1.0
        plan.contacts[:, _WRISTS[k]] = True
    plan.hands = tuple(obj.grips["lift"][hands])


def _gait(plan: _Plan, body: _Body, i0: int, n_swings: int, step: float, swing: int, ds: int,
          direction: float, first: int, lift: float = 0.06) -> int:
    """Alternating steps along the heading (+z, or -z for ``direction`` -1). Each swing moves
    one foot (min-jerk horizontally, ``16 u^2 (1-u)^2 * lift`` vertically) to ``step``
    beyond the other foot (the last swing brings the feet together) while the other stays
    planted; the pelvis follows the mean of the feet. Returns the frame the walk ends."""
    T = plan.T
    cur = plan.foot[i0].copy()
    side, i = first, i0
    for k in range(n_swings):
        other = 1 - side
        new = cur[side].copy()
        new[2] = cur[other, 2] + (direction * step if k < n_swings - 1 else 0.0)
        a, b = i, min(i + swing, T - 1)
        idx = np.arange(a, b + 1)
        u = (idx - a) / (b - a)
        m = _minjerk(u)
        plan.foot[a:b + 1, side] = cur[side] + (new - cur[side]) * m[:, None]
        plan.foot[a:b + 1, side, 1] = cur[side, 1] + 16 * u * u * (1 - u) ** 2 * lift
        plan.foot[b:, side] = new
        plan.planted[a + 1:b, side] = False
        cur[side] = new
        side, i = other, b + ds
    mean0 = plan.foot[i0, :, 2].mean()
    plan.pelvis[i0:, 2] += plan.foot[i0:, :, 2].mean(1) - mean0
    return min(i - ds, T)


def _plan_carry(obj, hands, body, rng) -> _Plan:
    n_sw = int(rng.integers(4, 6))
    swing, ds = _frames(rng.uniform(0.42, 0.5)), _frames(0.12)
    i0 = _frames(rng.uniform(0.25, 0.4))
    T = i0 + n_sw * (swing + ds) + _frames(rng.uniform(0.4, 0.6))
    plan = _Plan(T, body)
    plan.crouch = True
    plan.pelvis[:, 1] = body.stand_y - 0.025 * body.s
    _gait(plan, body, i0, n_sw, rng.uniform(0.26, 0.32) * body.s, swing, ds, 1.0,
          int(rng.integers(0, 2)))
    yaw, t = _hold_pose(obj, hands, body, walking=True)
    plan.obj_R[:] = _ry(yaw)
    plan.obj_t = t + np.stack([plan.pelvis[:, 0], np.zeros(T), plan.pelvis[:, 2]], -1)
    _grip_whole_clip(plan, obj, hands)
    plan.segments = [("carry", 0, T, hands)]
    return plan


def _plan_push_pull(obj, hands, body, rng, action: str) -> _Plan:
    direction = 1.0 if action == "push" else -1.0
    grips = obj.grips[action]
    i_a = _frames(rng.uniform(0.2, 0.4))
    i_g = i_a + _frames(rng.uniform(0.7, 0.85))
    i_w = i_g + _frames(rng.uniform(0.15, 0.3))
    n_sw = int(rng.integers(3, 5))
    swing, ds = _frames(rng.uniform(0.45, 0.52)), _frames(0.12)
    T = i_w + n_sw * (swing + ds) + _frames(rng.uniform(0.3, 0.5))
    plan = _Plan(T, body)
    plan.crouch = True
    plan.pelvis[:, 1] = body.stand_y - 0.02 * body.s
    yaw0, t0 = _floor_pose(obj, "both", body, rng, near=0.40 + rng.uniform(0.0, 0.04))
    i_end = _gait(plan, body, i_w, n_sw, rng.uniform(0.22, 0.28) * body.s, swing, ds, direction,
                  int(rng.integers(0, 2)))
    plan.obj_R[:] = _ry(yaw0)
    plan.obj_t = t0 + np.stack([plan.pelvis[:, 0], np.zeros(T), plan.pelvis[:, 2]], -1)
    plan.attach(hands, grips, slice(None))
    for h in grips[hands]:
        _approach(plan, _HAND_INDEX[h], i_a, i_g)
    plan.hands = tuple(grips[hands])
    plan.segments = [(action, i_g, i_end, hands)]
    return plan


def _plan_sit(obj, hands, body, rng) -> _Plan:
    s = body.s
    i0 = _frames(rng.uniform(0.3, 0.6))
    i1 = i0 + _frames(rng.uniform(1.2, 1.5))
    T = i1 + _frames(rng.uniform(1.2, 1.6))
    plan = _Plan(T, body)
    top, sx, sz = obj.seat
    front = obj.vertices[:, 2].max()
    ball = obj.kind == "ball"
    t = np.array([-sx, _floor_y(obj), -(0.16 if ball else 0.14) * s - front])
    plan.obj_t[:] = t
    hip_drop = float(np.mean(body.rest[0, 1] - body.rest[[1, 2], 1]))
    fwd = 0.08 if ball else 0.03           # sit a little forward of the seat centre
    if ball:                               # the sphere's surface is lower there
        r = obj.primitives[0].radius
        top -= r - math.sqrt(r * r - fwd * fwd)
    end = np.array([0.0, t[1] + top + SEAT_CLEARANCE_M * s + hip_drop, t[2] + sz + fwd])
    i = np.arange(T)
    u = np.clip((i - i0) / (i1 - i0), 0.0, 1.0)
    start = plan.pelvis[0].copy()
    plan.pelvis[:, 2] = start[2] + (end[2] - start[2]) * _minjerk(u / 0.85)
    plan.pelvis[:, 1] = start[1] + (end[1] - start[1]) * _minjerk((u - 0.1) / 0.9)
    plan.bend = math.radians(35.0) * np.sin(np.pi * u)
    # hips are labelled from the first frame the settling pelvis is within SIT_CONTACT_TOL_M
    # of its seated position (the min-jerk approach spends several frames within millimetres)
    near = np.hypot(plan.pelvis[:, 1] - end[1], plan.pelvis[:, 2] - end[2]) < SIT_CONTACT_TOL_M
    first = int(np.argmax(near & (i >= i0))) if (near & (i >= i0)).any() else i1
    plan.contacts[min(first, i1):, [1, 2]] = True
    plan.seated = i >= i1
    plan.segments = [("sit", i0, T, "none")]
    return plan


def _plan_kick(obj, hands, body, rng) -> _Plan:
    s = body.s
    k = int(rng.integers(0, 2))                      # kicking foot: 0 left, 1 right
    i_s = _frames(rng.uniform(0.3, 0.5))
    i_c = i_s + _frames(0.5)
    n_c = 3
    i_r = i_c + n_c
    i_p = i_r + _frames(0.55)
    T = i_p + _frames(rng.uniform(1.0, 1.3))
    plan = _Plan(T, body)
    plan.foot[:] = body.stance((0.0, 0.0), dz=(-0.05, 0.0) if k == 0 else (0.0, -0.05))
    f0 = plan.foot[0, k].copy()
    r = obj.primitives[0].radius
    h_c = 0.11
    v_c = rng.uniform(1.1, 1.4)
    z_c = f0[2] + 0.32 * s
    e = math.sqrt(r * r - (r - h_c) ** 2)
    c0 = np.array([f0[0], r, z_c + e])
    plan.obj_t[:] = c0 - np.array([0.0, 0.0, 0.0])
    plan.obj_t[:, 1] = _floor_y(obj)
    i = np.arange(T)
    foot = plan.foot[:, k]
    a = (i > i_s) & (i <= i_c)
    u = (i[a] - i_s) / (i_c - i_s)
    dur = (i_c - i_s) / FPS
    foot[a, 2] = _quintic(np.array([f0[2]]), [0.0], np.array([z_c]), [v_c], dur, u)[:, 0]
    foot[a, 1] = f0[1] + (h_c - f0[1]) * _minjerk(u)
    c = (i > i_c) & (i <= i_r)
    foot[c, 2] = z_c + v_c * (i[c] - i_c) / FPS
    foot[c, 1] = h_c
    z_r = z_c + v_c * n_c / FPS
    b = i > i_r
    u = (i[b] - i_r) / (i_p - i_r)
    z_end = plan.foot[0, 1 - k, 2] + 0.03
    foot[b, 2] = _quintic(np.array([z_r]), [v_c], np.array([z_end]), [0.0], (i_p - i_r) / FPS, u)[:, 0]
    foot[b, 1] = h_c + (f0[1] - h_c) * _minjerk(u)
    plan.planted[i_s + 1:i_p, k] = False
    # ball: still, then pushed by the foot, then rolling with exponential slowdown
    tau = 0.8
    zc = np.full(T, c0[2])
    zc[c] = c0[2] + foot[c, 2] - z_c
    zb = z_r + e             # the kick leaves the light ball 1.6 times faster than the foot
    zc[b] = zb + 1.6 * v_c * tau * (1 - np.exp(-(i[b] - i_r) / FPS / tau))
    plan.obj_t[:, 2] = zc
    plan.obj_R = _rx((zc - c0[2]) / r)            # rolling without slipping along +z
    # weight on the support foot, pelvis a little forward and lower during the kick
    bump = np.sin(np.pi * np.clip((i - i_s + 6) / (i_p - i_s + 12), 0, 1)) ** 2
    plan.pelvis[:, 0] += (0.04 if k == 1 else -0.04) * bump
    plan.pelvis[:, 1] -= 0.03 * s * bump
    plan.pelvis[:, 2] += 0.06 * bump
    plan.contacts[i_c:i_r + 1, 10 + k] = True
    plan.feet = ("left", "right")[k:k + 1]
    plan.kick = {"foot": k, "contact": (i_c, i_r + 1)}
    plan.segments = [("kick", i_s, i_r + 1, "none")]
    return plan


_PLANNERS = {"lift": _plan_lift, "putdown": _plan_putdown, "hold": _plan_hold,
             "carry": _plan_carry, "sit": _plan_sit, "kick": _plan_kick,
             "push": lambda o, h, b, r: _plan_push_pull(o, h, b, r, "push"),
             "pull": lambda o, h, b, r: _plan_push_pull(o, h, b, r, "pull")}
