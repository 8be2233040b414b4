"""HumanML3D's 263-dim motion representation, in ``legacy`` and ``clean`` modes.

Layout of one row (frame t of T-1; the last input frame only contributes velocities):

====== ===== ================================================================
slice   dims  content
====== ===== ================================================================
0       1     root angular velocity about y: half the heading change t -> t+1 (rad)
1:3     2     root linear velocity in x, z, heading frame of t+1 (m / frame)
3       1     root height y (m)
4:67    63    joints 1-21 relative to the root, xz at the root, heading frame (m)
67:193  126   rot6d of joints 1-21 (first two matrix columns), parent-relative
193:259 66    velocity of the 22 joints in the heading frame of t (m / frame)
259:263 4     foot contacts: L ankle, L foot, R ankle, R foot (0/1)
====== ===== ================================================================

Modes (see docs/representations.md for the measured difference):

``legacy``
    Reproduces HumanML3D's ``process_file`` (motion_representation.ipynb) including its
    quirks: retargeting to the reference skeleton (bone directions kept, lengths set to
    :data:`~hoibench.core.skeleton.REFERENCE_TARGET_OFFSETS`, root scaled by the lower-leg
    ratio), floor at the clip's global minimum y, first root xz to the origin, frame 0
    facing +Z, per-frame heading from the *swapped* hip pair (left - right hip plus right
    - left shoulder) smoothed by a Gaussian of sigma 20 frames, identity heading for frame
    0, float32 quaternion arithmetic, ``arcsin`` of the relative quaternion's y component
    (wrong sign when a heading step crosses +-180 deg relative to +Z), and foot contact =
    squared displacement per frame < 0.002 with no height test.
``legacy-hoidiff``
    HOI-Diff's variant used for the 269-dim HOI layout: as ``legacy`` but without
    retargeting (HOI-Diff comments it out) and with its height test (ankle < 3.0, foot <
    2.0, in metres: never false in practice).
``clean``
    Same layout, quirks fixed: no retargeting (hands stay where they touch the object),
    floor taken from the input (the canonical world has its floor at y = 0), heading from
    the correct hip/shoulder pairs with no smoothing, the true heading on frame 0, float64
    arithmetic, a robust signed heading step (``atan2`` of the sign-fixed relative
    quaternion), and foot contact = speed < 0.894 m/s (HumanML3D's threshold at 20 fps,
    made fps-independent) and height above the floor < 0.12 m (ankle) / 0.08 m (foot).

Decoding (:func:`decode`) recovers joint positions from the root and the 63 relative
positions (HumanML3D's ``recover_from_ric``) in float64; it returns T-1 frames.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core import skeleton as sk
from ._checks import as_float_array

DIM = 263
ROOT_ROT_VEL = slice(0, 1)
ROOT_LIN_VEL = slice(1, 3)
ROOT_Y = slice(3, 4)
RIC = slice(4, 67)
ROT6D = slice(67, 193)
LOCAL_VEL = slice(193, 259)
FOOT_CONTACT = slice(259, 263)

#: Feature groups (name -> slice) used for grouped normalisation and reports.
GROUPS: dict[str, slice] = {
    "root_rot_vel": ROOT_ROT_VEL,
    "root_lin_vel": ROOT_LIN_VEL,
    "root_y": ROOT_Y,
    "ric": RIC,
    "rot6d": ROT6D,
    "local_vel": LOCAL_VEL,
    "foot_contact": FOOT_CONTACT,
}

VERSION = {"legacy": "hml263-legacy-1.0", "legacy-hoidiff": "hml263-legacy-hoidiff-1.0",
           "clean": "hml263-clean-1.0"}


@dataclass(frozen=True)
class Hml263Config:
    """Every switch that separates the modes. Use :data:`MODES` rather than building one."""

    retarget: bool
    floor: str                    # "global_min" | "input"
    swap_hips_in_ik: bool         # HumanML3D IK unpacks (r_hip, l_hip) in the wrong order
    identity_first_root: bool     # IK forces frame 0's heading to the identity
    heading_sigma_frames: float   # Gaussian smoothing of the facing direction (0: none)
    float32: bool                 # round quaternion arithmetic to float32 as the reference
    signed_heading_step: bool     # atan2 on the sign-fixed quaternion instead of arcsin
    foot_sq_disp_thresh: float | None   # legacy: squared displacement per frame
    foot_speed_mps: float | None        # clean: speed threshold (m/s)
    foot_height_m: tuple[float, float] | None  # (ankle, foot) height thresholds


MODES: dict[str, Hml263Config] = {
    "legacy": Hml263Config(True, "global_min", True, True, 20.0, True, False, 0.002, None, None),
    "legacy-hoidiff": Hml263Config(False, "global_min", True, True, 20.0, True, False, 0.002,
                                   None, (3.0, 2.0)),
    "clean": Hml263Config(False, "input", False, False, 0.0, False, True, None,
                          float(np.sqrt(0.002) * 20.0), (0.12, 0.08)),
}

def _config(mode: str) -> Hml263Config:
    if mode not in MODES:
        raise ValueError(f"mode: expected one of {sorted(MODES)}, got {mode!r}")
    return MODES[mode]


def _dtype(cfg: Hml263Config):
    return np.float32 if cfg.float32 else np.float64


# The encoder works on a component-first layout: positions P[j][c] are contiguous (B, T)
# arrays (j joint, c = x, y, z), quaternions are (w, x, y, z) tuples of such arrays. Every
# step is then a handful of elementwise ufuncs over B*T values per joint, which is what makes
# batched encoding fast; the formulas are the textbook ones (see hoibench.core.geometry).

def _qmul(a, b):
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


def _qinv(q):
    return (q[0], -q[1], -q[2], -q[3])


def _qrot(q, v):
    """v + 2 (w (u x v) + u x (u x v)) for unit q = (w, u)."""
    w, x, y, z = q
    vx, vy, vz = v
    ax, ay, az = y * vz - z * vy, z * vx - x * vz, x * vy - y * vx
    bx, by, bz = y * az - z * ay, z * ax - x * az, x * ay - y * ax
    return (vx + 2 * (w * ax + bx), vy + 2 * (w * ay + by), vz + 2 * (w * az + bz))


def _unit(v):
    n = np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return (v[0] / n, v[1] / n, v[2] / n)


def _arc_from_axis(axis: int, sign: float, v):
    """Shortest-arc quaternion from ``u = sign * e_axis`` to unit ``v``: normalise
    (|u||v| + u.v, u x v) (|v| kept, as the reference, so float32 rounding matches); a half
    turn about a perpendicular axis when v = -u."""
    zero = np.zeros_like(v[0])
    if axis == 0:
        cross = (zero, -sign * v[2], sign * v[1])
    elif axis == 1:
        cross = (sign * v[2], zero, -sign * v[0])
    else:
        cross = (-sign * v[1], sign * v[0], zero)
    w = np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) + sign * v[axis]
    n = np.sqrt(w * w + cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2])
    bad = n < 1e-6
    if bad.any():  # antiparallel (the reference returns NaN here)
        flip = [zero, zero, zero]
        flip[(axis + 1) % 3] = np.ones_like(zero)
        w, cross, n = (np.where(bad, 0, w), tuple(np.where(bad, f, c) for f, c in zip(flip, cross)),
                       np.where(bad, 1, n))
    return (w / n, cross[0] / n, cross[1] / n, cross[2] / n)


def _heading(P, cfg: Hml263Config, sigma: float, identity_first: bool):
    """Per-frame quaternions about y rotating the facing direction onto +Z.

    facing = cross(y, across), across = (R - L hip) + (R - L shoulder) normalised (hips
    reversed under ``swap_hips_in_ik``); optional Gaussian smoothing over time (frames).
    cross(f, +Z) = (0, -f_x, 0), so the arc is normalise(1 + f_z, 0, -f_x, 0).
    """
    hips = [P[sk.RIGHT_HIP][c] - P[sk.LEFT_HIP][c] for c in range(3)]
    if cfg.swap_hips_in_ik:
        hips = [-h for h in hips]
    across = _unit([hips[c] + (P[sk.RIGHT_SHOULDER][c] - P[sk.LEFT_SHOULDER][c]) for c in range(3)])
    fx = across[2].astype(np.float64)
    fz = -across[0].astype(np.float64)
    if sigma > 0:
        from scipy.ndimage import gaussian_filter1d   # only the legacy heading smoothing needs scipy
        fx = gaussian_filter1d(fx, sigma, axis=-1, mode="nearest")
        fz = gaussian_filter1d(fz, sigma, axis=-1, mode="nearest")
    n = np.sqrt(fx * fx + fz * fz)
    dt = _dtype(cfg)
    fx, fz = (fx / n).astype(dt), (fz / n).astype(dt)
    w, y = 1 + fz, -fx
    m = np.sqrt(w * w + y * y)
    back = m < 1e-6                       # facing exactly -Z: half turn about y
    w, y, m = np.where(back, 0, w), np.where(back, 1, y), np.where(back, 1, m)
    zero = np.zeros_like(w)
    q = [w / m, zero, y / m, zero]
    if identity_first:
        q[0] = q[0].copy()
        q[2] = q[2].copy()
        q[0][..., 0], q[2][..., 0] = 1, 0
    return tuple(q)


def _inverse_kinematics(P, root, cfg: Hml263Config, visit) -> None:
    """HumanML3D's IK. For each bone (parent -> child) along the kinematic chains, the
    parent-relative rotation R_loc = R^-1 * arc(raw direction -> observed direction), where
    R is the accumulated rotation (starting at the root heading for every chain). Calls
    ``visit(child, parent, R_loc, R_child)``."""
    dt = _dtype(cfg)
    for chain in sk.KINEMATIC_CHAINS:
        rot = root
        for parent, child in zip(chain[:-1], chain[1:]):
            bone = _unit([(P[child][c] - P[parent][c]) for c in range(3)])
            bone = tuple(b.astype(dt, copy=False) for b in bone)
            axis = int(np.flatnonzero(sk.RAW_OFFSETS[child])[0])
            arc = _arc_from_axis(axis, float(sk.RAW_OFFSETS[child][axis]), bone)
            local = _qmul(_qinv(rot), arc)
            rot = _qmul(rot, local)
            visit(child, parent, local, rot)


def _to_soa(pos: np.ndarray) -> list[list[np.ndarray]]:
    """(B, T, 22, 3) -> P[j][c] contiguous (B, T) arrays."""
    t = np.ascontiguousarray(np.moveaxis(pos, (2, 3), (0, 1)))
    return [[t[j, c] for c in range(3)] for j in range(sk.NUM_JOINTS)]


def _from_soa(P) -> np.ndarray:
    return np.stack([np.stack(P[j], -1) for j in range(len(P))], -2)


def _retarget(P, cfg: Hml263Config):
    """Legacy ``uniform_skeleton``: keep bone directions (IK then FK with the accumulated
    rotations), set bone lengths to the reference skeleton's, scale the root trajectory by
    the lower-leg length ratio (float32, as the reference)."""
    tgt = sk.REFERENCE_TARGET_OFFSETS
    a, b = sk.LEG_SCALE_JOINTS

    def length0(j):
        p = sk.PARENTS[j]
        return np.sqrt(sum((P[j][c][:, 0] - P[p][c][:, 0]) ** 2 for c in range(3))).astype(np.float32)

    scale = (np.float32(np.abs(tgt[a]).max() + np.abs(tgt[b]).max()) / (length0(a) + length0(b)))
    scale = scale.astype(np.float32)[:, None].astype(P[0][0].dtype)
    out = [None] * sk.NUM_JOINTS
    out[0] = [P[0][c] * scale for c in range(3)]
    dt = _dtype(cfg)

    def visit(child, parent, local, rot):
        off = tuple(np.asarray(tgt[child][c], dtype=dt) for c in range(3))
        moved = _qrot(rot, tuple(np.broadcast_to(o, rot[0].shape) for o in off))
        out[child] = [moved[c] + out[parent][c] for c in range(3)]

    _inverse_kinematics(P, _heading(P, cfg, 0.0, cfg.identity_first_root), cfg, visit)
    return out


def _canonicalize(pos: np.ndarray, cfg: Hml263Config):
    """Canonical frame in component-first layout: (P, floor (B,), origin (B, 3), quat (B, 4))."""
    src = pos if cfg.float32 else pos.astype(np.float64)
    P = _to_soa(src)
    if cfg.retarget:
        P = _retarget(P, cfg)
    B = len(pos)
    if cfg.floor == "global_min":
        floor = np.min([P[j][1].min(axis=1) for j in range(sk.NUM_JOINTS)], axis=0)
    else:
        floor = np.zeros(B)
    ox, oz = P[0][0][:, 0].copy(), P[0][2][:, 0].copy()
    P = [[P[j][0] - ox[:, None], P[j][1] - floor[:, None], P[j][2] - oz[:, None]]
         for j in range(sk.NUM_JOINTS)]
    P0 = [[P[j][c][:, :1] for c in range(3)] for j in range(sk.NUM_JOINTS)]
    nocfg = Hml263Config(**{**cfg.__dict__, "swap_hips_in_ik": False})
    init = _heading(P0, nocfg, 0.0, False)                     # (B, 1) components
    dt = _dtype(cfg)
    init = tuple(c.astype(dt) for c in init)
    P = [list(_qrot(init, tuple(P[j][c].astype(dt) for c in range(3)))) for j in range(sk.NUM_JOINTS)]
    origin = np.stack([ox, np.zeros(B), oz], -1)
    return P, floor, origin, np.concatenate(init, -1)


def canonicalize(joints: np.ndarray, mode: str = "clean"):
    """Put a batch of clips in HumanML3D's canonical frame.

    Returns ``(positions, floor_y, origin_xz, init_quat)``: positions (B, T, 22, 3) after
    (legacy) retargeting, flooring, moving the first root xz to the origin and rotating
    frame 0 to face +Z; ``floor_y`` (B,) subtracted from y; ``origin_xz`` (B, 3) the
    subtracted translation (y = 0); ``init_quat`` (B, 4) the applied rotation about y.
    A world point p maps to ``rotate(init_quat, p - (0, floor_y, 0) - origin_xz)``.
    """
    cfg = _config(mode)
    pos, _ = as_float_array(joints, "joints", (22, 3), min_frames=2)
    P, floor, origin, quat = _canonicalize(pos, cfg)
    return _from_soa(P), floor, origin, quat


def _foot_contacts(P, cfg: Hml263Config, fps: float) -> list[np.ndarray]:
    """Contacts (B, T-1) for L ankle, L foot, R ankle, R foot."""
    out = []
    for k, j in enumerate(sk.LEFT_FOOT_JOINTS + sk.RIGHT_FOOT_JOINTS):
        d = [P[j][c][:, 1:] - P[j][c][:, :-1] for c in range(3)]
        sq = (d[0] ** 2 + d[1] ** 2) + d[2] ** 2
        if cfg.foot_sq_disp_thresh is not None:
            contact = sq < cfg.foot_sq_disp_thresh
        else:
            contact = np.sqrt(sq) * fps < cfg.foot_speed_mps
        if cfg.foot_height_m is not None:
            contact &= P[j][1][:, :-1] < cfg.foot_height_m[k % 2]
        out.append(contact)
    return out


def _encode_batch(pos: np.ndarray, cfg: Hml263Config, fps: float):
    """Features (B, T-1, 263), canonical positions (component-first) and the frame."""
    P, floor, origin, init_quat = _canonicalize(pos, cfg)
    B, T = P[0][0].shape
    out = np.empty((B, T - 1, DIM), dtype=np.float32)
    for k, contact in enumerate(_foot_contacts(P, cfg, fps)):
        out[..., FOOT_CONTACT.start + k] = contact
    root = _heading(P, cfg, cfg.heading_sigma_frames, cfg.identity_first_root)

    def visit(child, parent, local, rot):
        w, x, y, z = local
        s = 2.0 / (w * w + x * x + y * y + z * z)
        col = ROT6D.start + 6 * (child - 1)
        for k, v in enumerate((1 - s * (y * y + z * z), s * (x * y + z * w), s * (x * z - y * w),
                               s * (x * y - z * w), 1 - s * (x * x + z * z), s * (y * z + x * w))):
            out[..., col + k] = v[:, :-1]

    _inverse_kinematics(P, root, cfg, visit)
    prev = tuple(c[:, :-1] for c in root)
    nxt = tuple(c[:, 1:] for c in root)
    vel = _qrot(nxt, tuple(P[0][c][:, 1:] - P[0][c][:, :-1] for c in range(3)))
    r_vel = _qmul(nxt, _qinv(prev))
    if cfg.signed_heading_step:
        sign = np.where(r_vel[0] < 0, -1.0, 1.0)
        step = np.arctan2(sign * r_vel[2], sign * r_vel[0])
    else:
        step = np.arcsin(r_vel[2])
    out[..., 0] = step
    out[..., 1] = vel[0]
    out[..., 2] = vel[2]
    out[..., 3] = P[0][1][:, :-1]
    rx, rz = P[0][0], P[0][2]
    for j in range(sk.NUM_JOINTS):
        if j > 0:
            loc = _qrot(root, (P[j][0] - rx, P[j][1], P[j][2] - rz))
            for c in range(3):
                out[..., RIC.start + 3 * (j - 1) + c] = loc[c][:, :-1]
        jv = _qrot(prev, tuple(P[j][c][:, 1:] - P[j][c][:, :-1] for c in range(3)))
        for c in range(3):
            out[..., LOCAL_VEL.start + 3 * j + c] = jv[c]
    return out, P, (floor, origin, init_quat)


def encode(joints: np.ndarray, mode: str = "clean", fps: float = 20.0,
           return_positions: bool = False):
    """Encode joint positions into hml263 features.

    Args:
        joints: (T, 22, 3) or (B, T, 22, 3) float32/float64 positions, metres, y-up, SMPL
            joint order, T >= 2.
        mode: ``"clean"`` (default), ``"legacy"`` or ``"legacy-hoidiff"``.
        fps: frame rate of ``joints``; used by clean-mode foot contacts only (legacy
            thresholds are per frame, as in HumanML3D at 20 fps).
        return_positions: also return the repositioned (canonical) joints the features
            describe, (T, 22, 3) or (B, T, 22, 3).

    Returns:
        float32 features (T-1, 263) or (B, T-1, 263) [, canonical positions].

    Raises:
        ValueError: naming ``joints``, ``mode`` or ``fps`` when they are not as above.
    """
    cfg = _config(mode)
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps: expected a positive frame rate, got {fps!r}")
    pos, batched = as_float_array(joints, "joints", (22, 3), min_frames=2)
    feats, P, _ = _encode_batch(pos, cfg, float(fps))
    gpos = _from_soa(P) if return_positions else None
    if not batched:
        feats, gpos = feats[0], (gpos[0] if return_positions else None)
    return (feats, gpos) if return_positions else feats


def recover_root(features: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Heading and root trajectory from hml263 rows (``recover_root_rot_pos``), float64.

    Returns ``yaw`` (..., T) in radians, the rotation about y from the canonical world to
    the heading frame (``local = R_y(yaw) world``; twice the cumulated feature 0, frame 0
    = 0; ChainHOI's "y-angle"), and
    ``root`` (..., T, 3) the root position (xz integrated from feature 1:3, y = feature 3).
    """
    f = np.asarray(features, dtype=np.float64)
    half = np.zeros(f.shape[:-1])
    half[..., 1:] = np.cumsum(f[..., :-1, 0], axis=-1)
    yaw = 2.0 * half
    c, s = np.cos(yaw), np.sin(yaw)
    step = np.zeros(f.shape[:-1] + (3,))
    vx, vz = f[..., :-1, 1], f[..., :-1, 2]
    # world = R_y(-yaw) @ heading-frame vector, R_y(a) = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
    step[..., 1:, 0] = c[..., 1:] * vx - s[..., 1:] * vz
    step[..., 1:, 2] = s[..., 1:] * vx + c[..., 1:] * vz
    root = np.cumsum(step, axis=-2)
    root[..., 1] = f[..., 3]
    return yaw, root


def decode(features: np.ndarray) -> np.ndarray:
    """Joint positions (T, 22, 3) or (B, T, 22, 3) from hml263 features, float64.

    Inverse of :func:`encode` up to the positions it returns (``return_positions``): frames
    0..T-2 of the canonical joints. Only the root channels and the relative positions are
    used (HumanML3D's ``recover_from_ric``).
    """
    f, batched = as_float_array(features, "features", (DIM,), min_frames=1)
    yaw, root = recover_root(f)
    ric = f[..., RIC].astype(np.float64).reshape(f.shape[:-1] + (21, 3))
    c, s = np.cos(yaw)[..., None], np.sin(yaw)[..., None]
    out = np.empty(f.shape[:-1] + (22, 3))
    out[..., 0, :] = root
    out[..., 1:, 0] = c * ric[..., 0] - s * ric[..., 2] + root[..., None, 0]
    out[..., 1:, 1] = ric[..., 1]
    out[..., 1:, 2] = s * ric[..., 0] + c * ric[..., 2] + root[..., None, 2]
    return out if batched else out[0]
