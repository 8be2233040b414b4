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
    :data:`~hoibench.skeleton.REFERENCE_TARGET_OFFSETS`, root scaled by the lower-leg
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
from scipy.ndimage import gaussian_filter1d

from .. import geometry as geo
from .. import skeleton as sk
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

_Z = np.array([0.0, 0.0, 1.0])


def _config(mode: str) -> Hml263Config:
    if mode not in MODES:
        raise ValueError(f"mode: expected one of {sorted(MODES)}, got {mode!r}")
    return MODES[mode]


def _dtype(cfg: Hml263Config):
    return np.float32 if cfg.float32 else np.float64


def _forward(pos: np.ndarray, swap_hips: bool) -> np.ndarray:
    """Horizontal facing direction cross(y, across) of (..., 22, 3) positions, unnormalised.

    ``across`` = (right - left hip) + (right - left shoulder), normalised; with
    ``swap_hips`` the hip difference is reversed (HumanML3D's IK quirk).
    """
    hips = pos[..., sk.LEFT_HIP, :] - pos[..., sk.RIGHT_HIP, :]
    if not swap_hips:
        hips = -hips
    across = hips + (pos[..., sk.RIGHT_SHOULDER, :] - pos[..., sk.LEFT_SHOULDER, :])
    across = across / np.sqrt((across ** 2).sum(-1))[..., None]
    fwd = np.zeros(across.shape, dtype=np.result_type(across.dtype, np.float64))
    fwd[..., 0] = across[..., 2]   # cross((0,1,0), a) = (a_z, 0, -a_x)
    fwd[..., 2] = -across[..., 0]
    return fwd


def _heading_quats(pos: np.ndarray, cfg: Hml263Config, sigma: float) -> np.ndarray:
    """(B, T, 4) quaternions rotating each frame's facing direction onto +Z."""
    fwd = _forward(pos, cfg.swap_hips_in_ik)
    if sigma > 0:
        fwd = gaussian_filter1d(fwd, sigma, axis=1, mode="nearest")
    fwd = fwd / np.sqrt((fwd ** 2).sum(-1))[..., None]
    dt = _dtype(cfg)
    quat = geo.quaternion_between(fwd.astype(dt), np.broadcast_to(_Z.astype(dt), fwd.shape))
    if cfg.identity_first_root:
        quat[:, 0] = (1.0, 0.0, 0.0, 0.0)
    return quat


def _inverse_kinematics(pos: np.ndarray, root_quat: np.ndarray, cfg: Hml263Config) -> np.ndarray:
    """HumanML3D's IK: per joint, the parent-relative quaternion of the shortest arc from
    the raw T-pose bone direction to the observed bone direction. (B, T, 22, 4)."""
    dt = _dtype(cfg)
    quats = np.zeros(pos.shape[:-1] + (4,), dtype=dt)
    quats[..., 0, :] = root_quat
    for chain in sk.KINEMATIC_CHAINS:
        rot = root_quat
        for parent, child in zip(chain[:-1], chain[1:]):
            bone = pos[..., child, :] - pos[..., parent, :]
            bone = bone / np.sqrt((bone ** 2).sum(-1))[..., None]
            u = np.broadcast_to(sk.RAW_OFFSETS[child].astype(dt), bone.shape)
            arc = geo.quaternion_between(u, bone.astype(dt))
            local = geo.quaternion_multiply(geo.quaternion_inverse(rot), arc)
            quats[..., child, :] = local
            rot = geo.quaternion_multiply(rot, local)
    return quats


def _retarget(pos: np.ndarray, cfg: Hml263Config) -> np.ndarray:
    """Legacy ``uniform_skeleton``: keep bone directions, set bone lengths to the reference
    skeleton's, scale the root trajectory by the lower-leg length ratio."""
    tgt = sk.REFERENCE_TARGET_OFFSETS
    lengths0 = np.sqrt(((pos[:, 0, 1:] - pos[:, 0, list(sk.PARENTS[1:])]) ** 2).sum(-1))
    lengths0 = np.concatenate([np.zeros((len(pos), 1)), lengths0], axis=1).astype(np.float32)
    a, b = sk.LEG_SCALE_JOINTS
    src_leg = lengths0[:, a] + lengths0[:, b]
    tgt_leg = np.float32(np.abs(tgt[a]).max() + np.abs(tgt[b]).max())
    scale = (tgt_leg / src_leg).astype(np.float32)          # float32 as the reference
    root = pos[:, :, 0] * scale[:, None, None].astype(pos.dtype)
    heading = _heading_quats(pos, cfg, sigma=0.0)
    quats = _inverse_kinematics(pos, heading, cfg)
    dt = _dtype(cfg)
    out = np.zeros(pos.shape, dtype=np.float64)
    out[:, :, 0] = root
    for chain in sk.KINEMATIC_CHAINS:
        rot = quats[:, :, 0].astype(dt)
        for parent, child in zip(chain[:-1], chain[1:]):
            rot = geo.quaternion_multiply(rot, quats[:, :, child].astype(dt))
            off = np.broadcast_to(tgt[child].astype(dt), rot.shape[:-1] + (3,))
            out[:, :, child] = geo.quaternion_apply(rot, off) + out[:, :, parent]
    return out


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
    return _canonicalize(pos, cfg)


def _canonicalize(pos: np.ndarray, cfg: Hml263Config):
    pos = pos.astype(np.float64) if not cfg.float32 else pos
    if cfg.retarget:
        pos = _retarget(pos, cfg)
    else:
        pos = pos.copy()
    if cfg.floor == "global_min":
        floor = pos[..., 1].min(axis=(1, 2))
    else:
        floor = np.zeros(len(pos), dtype=pos.dtype)
    pos[..., 1] -= floor[:, None, None]
    origin = pos[:, 0, 0] * np.array([1.0, 0.0, 1.0])
    pos = pos - origin[:, None, None]
    fwd0 = _forward(pos[:, 0], swap_hips=False)
    fwd0 = fwd0 / np.sqrt((fwd0 ** 2).sum(-1))[..., None]
    dt = _dtype(cfg)
    init_quat = geo.quaternion_between(fwd0.astype(dt), np.broadcast_to(_Z.astype(dt), fwd0.shape))
    q = np.broadcast_to(init_quat[:, None, None], pos.shape[:-1] + (4,)).astype(dt)
    pos = geo.quaternion_apply(q, pos.astype(dt))
    return pos, floor, origin, init_quat


def _foot_contacts(pos: np.ndarray, cfg: Hml263Config, fps: float) -> np.ndarray:
    """(B, T-1, 4) contacts for L ankle, L foot, R ankle, R foot."""
    feet = list(sk.LEFT_FOOT_JOINTS + sk.RIGHT_FOOT_JOINTS)
    disp = pos[:, 1:, feet] - pos[:, :-1, feet]
    sq = (disp[..., 0] ** 2 + disp[..., 1] ** 2) + disp[..., 2] ** 2
    if cfg.foot_sq_disp_thresh is not None:
        contact = sq < cfg.foot_sq_disp_thresh
    else:
        contact = np.sqrt(sq) * fps < cfg.foot_speed_mps
    if cfg.foot_height_m is not None:
        limits = np.array(cfg.foot_height_m * 2)  # ankle, foot, ankle, foot
        contact &= pos[:, :-1, feet, 1] < limits
    return contact.astype(np.float32)


def _encode_batch(pos: np.ndarray, cfg: Hml263Config, fps: float):
    """Features (B, T-1, 263), canonical positions and the (floor, origin, quat) frame."""
    gpos, floor, origin, init_quat = _canonicalize(pos, cfg)
    dt = _dtype(cfg)
    feet = _foot_contacts(gpos, cfg, fps)
    heading = _heading_quats(gpos, cfg, cfg.heading_sigma_frames)
    quats = _inverse_kinematics(gpos, heading, cfg)
    mats = geo.quaternion_to_matrix(quats[:, :, 1:])
    rot6d = geo.matrix_to_rot6d(mats)                       # (B, T, 21, 6)
    r_rot = quats[:, :, 0].astype(dt)
    root = gpos[:, :, 0]
    vel = geo.quaternion_apply(r_rot[:, 1:], (root[:, 1:] - root[:, :-1]).astype(dt))
    r_vel = geo.quaternion_multiply(r_rot[:, 1:], geo.quaternion_inverse(r_rot[:, :-1]))
    if cfg.signed_heading_step:
        sign = np.where(r_vel[..., 0] < 0, -1.0, 1.0)
        step = np.arctan2(sign * r_vel[..., 2], sign * r_vel[..., 0])
    else:
        step = np.arcsin(r_vel[..., 2])
    local = gpos.copy()
    local[..., 0] -= root[:, :, None, 0]
    local[..., 2] -= root[:, :, None, 2]
    q_all = np.broadcast_to(r_rot[:, :, None], local.shape[:-1] + (4,))
    local = geo.quaternion_apply(q_all, local.astype(dt))
    jvel = geo.quaternion_apply(q_all[:, :-1], (gpos[:, 1:] - gpos[:, :-1]).astype(dt))
    B, T = gpos.shape[:2]
    out = np.empty((B, T - 1, DIM), dtype=np.float32)
    out[..., 0] = step
    out[..., 1:3] = vel[..., [0, 2]]
    out[..., 3] = local[:, :-1, 0, 1]
    out[..., RIC] = local[:, :-1, 1:].reshape(B, T - 1, 63)
    out[..., ROT6D] = rot6d[:, :-1].reshape(B, T - 1, 126)
    out[..., LOCAL_VEL] = jvel.reshape(B, T - 1, 66)
    out[..., FOOT_CONTACT] = feet
    return out, gpos, (floor, origin, init_quat)


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
    feats, gpos, _ = _encode_batch(pos, cfg, float(fps))
    if not batched:
        feats, gpos = feats[0], gpos[0]
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
