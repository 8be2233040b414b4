"""``synthetic_solve``: a motion plan turned into SMPL joint rotations.

The per-frame crouch that brings the hand targets within reach (``_crouch``), the soft
pelvis-height clamp that keeps the legs reachable, and the leg and arm two-bone IK
(``_solve``); see "Motion model" in :mod:`hoibench.datasets.synthetic`.
"""
from __future__ import annotations

import numpy as np

from ..core import skeleton as sk
from .synthetic_actions import _Plan
from .synthetic_body import _Body, _normalize, _torso_locals, _two_bone
from .synthetic_constants import (_ARM_POLE, _ARM_REST_POLE, _ARMS, _CROUCH_BACK, _CROUCH_BEND, _CROUCH_DROP,
                                  _FREE_HAND, _LEG_FRAC, _LEG_POLE, _LEGS, _REACH_FRAC, _TORSO_CLEARANCE, _ry)
from .synthetic_objects import ObjectModel


# =========================================================================== solving
def _crouch(plan: _Plan, body: _Body, obj: ObjectModel, A: np.ndarray,
            need: np.ndarray) -> tuple[np.ndarray, int, int]:
    """Per-frame crouch ``c`` in [0, 1]: pelvis drop ``_CROUCH_DROP s c``, back-shift
    ``_CROUCH_BACK s c``, spine bend ``_CROUCH_BEND c``. Per frame, the smallest value on a
    41-point grid that puts every needed hand target within ``_REACH_FRAC`` of the arm
    length while the torso and head joints stay ``_TORSO_CLEARANCE`` outside the object;
    then ``c = gauss(max_filter(c_req))`` (sigma 1.5 frames, support 4 = filter half-width,
    so it never drops below ``c_req``); frames where the smoothed value breaks a constraint
    fall back to ``c_req``. Returns (c, fallback frames, frames with no feasible value)."""
    from scipy.ndimage import gaussian_filter1d, maximum_filter1d
    frames = np.where(need.any(1))[0]
    cs = np.linspace(0.0, 1.0, 41)
    torso = [0, 3, 6, 9, 12, 13, 14, 15, 16, 17]

    def evaluate(c_sel, fr):
        shape = c_sel.shape
        psi = np.broadcast_to(plan.heading[fr], shape)
        beta = plan.bend[fr] + _CROUCH_BEND * c_sel
        L = _torso_locals(psi, beta)
        off = np.stack([0 * c_sel, -_CROUCH_DROP * body.s * c_sel, -_CROUCH_BACK * body.s * c_sel], -1)
        P = plan.pelvis[fr] + np.einsum("...ij,...j->...i", _ry(psi), off)
        J, _ = sk.forward_kinematics(L, body.rest, P - body.rest[0])
        d = np.linalg.norm(A[fr] - J[..., [16, 17], :], axis=-1)
        reach = ((d <= _REACH_FRAC * body.arm_len) | ~need[fr]).all(-1)
        pts = J[..., torso, :].reshape(-1, len(fr), len(torso), 3)
        sd = np.stack([obj.sdf(p, plan.obj_R[fr], plan.obj_t[fr]) for p in pts]).reshape(
            shape + (len(torso),))
        clear = sd.min(-1) >= _TORSO_CLEARANCE
        return reach, clear, np.where(need[fr], d, 0.0).max(-1)

    reach, clear, dmax = evaluate(np.broadcast_to(cs[:, None], (len(cs), len(frames))), frames)
    feas = reach & clear
    first = np.where(feas.any(0), feas.argmax(0),
                     np.where(reach.any(0), reach.argmax(0), dmax.argmin(0)))
    infeasible = int((~feas.any(0)).sum())
    req = np.zeros(plan.T)
    req[frames] = cs[first]
    c = gaussian_filter1d(maximum_filter1d(req, 9, mode="nearest"), 1.5, truncate=2.67,
                          mode="nearest")
    c = np.clip(c, req, 1.0)
    r2, c2, _ = evaluate(c[frames], frames)
    ok_req = feas[first, np.arange(len(frames))] | ~feas.any(0)
    bad = frames[~(r2 & c2) & ok_req & (c[frames] != req[frames])]
    c[bad] = req[bad]
    return c, int(len(bad)), infeasible


def _softclamp(y, ymax, k=0.01):
    """Smooth ``min(y, ymax)`` that stays strictly below ``ymax``."""
    return ymax - k * np.logaddexp(0.0, (ymax - y) / k)


def _solve(plan: _Plan, body: _Body, obj: ObjectModel) -> dict:
    """Targets -> local rotations (T,22,3,3), trans, joints and residuals."""
    T, s, rest = plan.T, body.s, body.rest
    psi = plan.heading
    Rpsi = _ry(psi)
    A = plan.hand_targets()
    need = plan.hand_w > 0
    c, fallback, infeasible = (_crouch(plan, body, obj, A, need) if plan.crouch and need.any()
                               else (np.zeros(T), 0, 0))
    P = plan.pelvis + np.einsum("tij,tj->ti", Rpsi, np.stack(
        [0 * c, -_CROUCH_DROP * s * c, -_CROUCH_BACK * s * c], -1))
    L = _torso_locals(psi, plan.bend + _CROUCH_BEND * c)
    G0 = L[:, 0]
    Ryf = _ry(plan.foot_yaw)                                            # (T, 2, 3, 3)
    ankles = plan.foot + np.einsum("tkij,kj->tki", Ryf, body.ankle_from_foot)
    for k, (hip, _, _, _) in enumerate(_LEGS):
        off = G0 @ (rest[hip] - rest[0])
        dxz = np.hypot(P[:, 0] + off[:, 0] - ankles[:, k, 0], P[:, 2] + off[:, 2] - ankles[:, k, 2])
        R = _LEG_FRAC * body.leg_len[k]
        ymax = ankles[:, k, 1] - off[:, 1] + np.sqrt(np.maximum(R * R - dxz * dxz, 0.0))
        P[:, 1] = _softclamp(P[:, 1], ymax)
    trans = P - rest[0]
    J, G = sk.forward_kinematics(L, rest, trans)
    for k, (hip, knee, ankle, _) in enumerate(_LEGS):
        pole = np.einsum("tij,j->ti", Ryf[:, k], _LEG_POLE[k])
        b1, b2 = body.leg[k]
        n_rest = np.cross(_LEG_POLE[k], _normalize(b1))
        G1, G2, _ = _two_bone(J[:, hip], ankles[:, k], pole, b1, b2, n_rest)
        L[:, hip] = G0.transpose(0, 2, 1) @ G1
        L[:, knee] = G1.transpose(0, 2, 1) @ G2
        L[:, ankle] = G2.transpose(0, 2, 1) @ Ryf[:, k]
    targets = np.empty((T, 2, 3))
    for k, (collar, sh, elbow, _) in enumerate(_ARMS):
        S = J[:, sh]
        free = S + np.einsum("tij,j->ti", Rpsi, _FREE_HAND[k] * s)
        w = plan.hand_w[:, k, None]
        tgt = np.where(w > 0, (1 - w) * free + w * np.nan_to_num(A[:, k]), free)
        targets[:, k] = tgt
        pole = np.einsum("tij,j->ti", Rpsi, _ARM_POLE[k])
        b1, b2 = body.arm[k]
        n_rest = np.cross(_ARM_REST_POLE, _normalize(b1))
        G1, G2, _ = _two_bone(S, tgt, pole, b1, b2, n_rest)
        L[:, sh] = G[:, collar].transpose(0, 2, 1) @ G1
        L[:, elbow] = G1.transpose(0, 2, 1) @ G2
    joints, _ = sk.forward_kinematics(L, rest, trans)
    return {"L": L, "trans": trans, "joints": joints, "hand_targets": targets, "ankles": ankles,
            "crouch": c, "crouch_fallback_frames": fallback, "crouch_infeasible_frames": infeasible}
