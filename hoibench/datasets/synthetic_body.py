"""``synthetic_body``: the subject bodies and kinematic primitives of the synthetic motion model.

Per-subject betas and proxy-body rest joints (:func:`subject_betas`, :func:`rest_joints`,
``_Body``), min-jerk and quintic profiles, the analytic two-bone IK and the torso rotations
(heading and spine bend) described under "Motion model" in :mod:`hoibench.datasets.synthetic`.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..core import skeleton as sk
from .synthetic_constants import SUBJECT_BETA0, SUBJECTS, _ARMS, _LEGS, _PELVIS_SHARE, _rx, _ry


# =========================================================================== body
def subject_betas(subject: str) -> np.ndarray:
    """(10,) betas of a subject: ``beta_0`` from :data:`SUBJECT_BETA0` (body scale), the rest
    small and fixed per subject (the proxy ignores them)."""
    if subject not in SUBJECT_BETA0:
        raise ValueError(f"subject: expected one of {SUBJECTS}, got {subject!r}")
    rng = np.random.default_rng([int(subject[3:]), 7919])
    b = np.round(rng.normal(0.0, 0.5, 10), 3)
    b[0] = SUBJECT_BETA0[subject]
    return b


def rest_joints(betas: np.ndarray) -> np.ndarray:
    """(22, 3) rest joints of the proxy body for ``betas`` (model frame, metres)."""
    from ..bodies.proxy import proxy_rest_joints
    return np.asarray(proxy_rest_joints(np.asarray(betas, dtype=np.float64)), dtype=np.float64)


@lru_cache(maxsize=None)
def _sole_below_foot_joint() -> tuple[float, float]:
    """Height of the proxy's left/right foot joint above its lowest sole vertex at scale 1
    (foot kept in its rest orientation): a planted foot joint sits this high times scale."""
    from ..bodies.proxy import ProxyBody
    body = ProxyBody()
    v, pj = body.v_template, body.part_joint
    out = []
    for ankle, foot in ((7, 10), (8, 11)):
        sole = v[(pj == ankle) | (pj == foot), 1].min()
        out.append(float(sk.SMPL_REST_JOINTS[foot, 1] - sole))
    return out[0], out[1]


class _Body:
    """Subject-specific skeleton quantities (metres)."""

    def __init__(self, betas: np.ndarray):
        self.betas = np.asarray(betas, dtype=np.float64)
        self.rest = rest_joints(self.betas)
        r = self.rest
        self.s = float(np.linalg.norm(r[20] - r[21]) / np.linalg.norm(
            sk.SMPL_REST_JOINTS[20] - sk.SMPL_REST_JOINTS[21]))
        soles = _sole_below_foot_joint()
        self.foot_y = np.array([soles[0] * self.s, soles[1] * self.s])
        self.leg = [(r[k] - r[h], r[a] - r[k]) for h, k, a, _ in _LEGS]
        self.arm = [(r[e] - r[s_], r[w] - r[e]) for _, s_, e, w in _ARMS]
        self.arm_len = float(np.linalg.norm(self.arm[0][0]) + np.linalg.norm(self.arm[0][1]))
        self.leg_len = [float(np.linalg.norm(a) + np.linalg.norm(b)) for a, b in self.leg]
        self.foot_off = np.stack([r[10] - r[0], r[11] - r[0]])        # foot joints - pelvis
        self.ankle_from_foot = np.stack([r[7] - r[10], r[8] - r[11]])
        # standing pelvis height: planted feet, knees 1.5 cm short of straight
        self.stand_y = float(np.mean(self.foot_y - self.foot_off[:, 1])) - 0.015 * self.s
        self.shoulder_off = np.stack([r[16] - r[0], r[17] - r[0]])

    def stance(self, pelvis_xz, psi: float = 0.0, width: float | None = None,
               dz=(0.0, 0.0)) -> np.ndarray:
        """(2, 3) foot-joint targets of a standing stance under the pelvis."""
        off = self.foot_off.copy()
        if width is not None:
            off[:, 0] = np.array([0.5, -0.5]) * width
        off[:, 2] += np.asarray(dz)
        R = _ry(psi)
        out = off @ R.T
        out[:, 0] += pelvis_xz[0]
        out[:, 2] += pelvis_xz[1]
        out[:, 1] = self.foot_y
        return out


# =========================================================================== kinematics
def _minjerk(u):
    u = np.clip(u, 0.0, 1.0)
    return u * u * u * (10 - 15 * u + 6 * u * u)


def _quintic(p0, v0, p1, v1, dur, u):
    """Quintic Hermite with zero end accelerations: position at ``u`` in [0, 1] of a move
    from ``p0`` (velocity ``v0``) to ``p1`` (velocity ``v1``) lasting ``dur`` seconds."""
    u = np.clip(u, 0.0, 1.0)[..., None]
    h0 = 1 - 10 * u ** 3 + 15 * u ** 4 - 6 * u ** 5
    h1 = u - 6 * u ** 3 + 8 * u ** 4 - 3 * u ** 5
    h4 = -4 * u ** 3 + 7 * u ** 4 - 3 * u ** 5
    h5 = 10 * u ** 3 - 15 * u ** 4 + 6 * u ** 5
    return h0 * p0 + h1 * (np.asarray(v0) * dur) + h4 * (np.asarray(v1) * dur) + h5 * p1


def _normalize(v, axis=-1):
    return v / np.linalg.norm(v, axis=axis, keepdims=True)


def _frame(u, n):
    """Right-handed orthonormal frame (columns u, n_perp, u x n_perp)."""
    n = n - (n * u).sum(-1, keepdims=True) * u
    n = _normalize(n)
    return np.stack([u, n, np.cross(u, n)], -1)


def _two_bone(A, T, pole, b1, b2, n_rest):
    """Analytic two-bone IK. A, T, pole (N, 3); rest bones b1, b2 (3,); rest hinge axis
    n_rest. Returns global rotations of both bones (N,3,3) and the reached end point."""
    l1, l2 = float(np.linalg.norm(b1)), float(np.linalg.norm(b2))
    v = T - A
    d = np.linalg.norm(v, axis=-1)
    dc = np.clip(d, abs(l1 - l2) + 1e-6, (l1 + l2) * (1 - 1e-9))
    u = v / np.maximum(d, 1e-12)[:, None]
    w = pole - (pole * u).sum(-1, keepdims=True) * u
    wn = np.linalg.norm(w, axis=-1, keepdims=True)
    alt = np.cross(u, np.array([1.0, 0.0, 0.0]))
    w = np.where(wn > 1e-6, w / np.maximum(wn, 1e-12), _normalize(alt + 1e-9))
    ca = (l1 * l1 + dc * dc - l2 * l2) / (2 * l1 * dc)
    sa = np.sqrt(np.clip(1 - ca * ca, 0.0, 1.0))
    K = A + l1 * (ca[:, None] * u + sa[:, None] * w)
    E = A + dc[:, None] * u
    n = np.cross(w, u)
    F1r = _frame(b1 / l1, n_rest)
    F2r = _frame(b2 / l2, n_rest)
    G1 = _frame((K - A) / l1, n) @ F1r.T
    G2 = _frame((E - K) / l2, n) @ F2r.T
    return G1, G2, E


def _torso_locals(psi: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """Local rotations (..., 22, 3, 3): heading, spine bend ``beta`` (rad), limbs identity."""
    psi, beta = np.broadcast_arrays(np.asarray(psi, float), np.asarray(beta, float))
    L = np.broadcast_to(np.eye(3), psi.shape + (22, 3, 3)).copy()
    L[..., 0, :, :] = _ry(psi) @ _rx(_PELVIS_SHARE * beta)
    spine = _rx((0.95 - _PELVIS_SHARE) / 3 * beta)
    for j in (3, 6, 9):
        L[..., j, :, :] = spine
    L[..., 12, :, :] = L[..., 15, :, :] = _rx(-0.15 * beta)
    return L
