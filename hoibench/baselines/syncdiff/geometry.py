"""SyncDiff's ``rel`` and ``comb`` (paper 004, appendix C.1) on torch tensors, for the
alignment loss and explicit synchronization (the numpy versions, on bodies, are
:func:`hoibench.representations.multibody.relative` / ``combine``).

A rigid motion is ``(..., 7)``: translation ``t`` and quaternion ``q = (w, x, y, z)``
(normalised here before use); joints are ``(..., 3 J)``. ``a`` is always rigid:

* ``rel(a, b)``, b rigid: ``[R_a^T (t_b - t_a), q_a^{-1} q_b]``; b joints: ``R_a^T (p - t_a)``;
* ``comb(a, r)``, r rigid: ``[R_a r_t + t_a, q_a r_q]``; r joints: ``R_a p + t_a``.

``comb(a, rel(a, b)) == b`` (quaternion sign aside). :func:`sign_align` flips a quaternion
to the hemisphere of a reference (q and -q are one rotation).
"""
from __future__ import annotations

import torch

__all__ = ["quat_normalize", "quat_mul", "quat_conj", "quat_rotate", "rel", "comb", "sign_align"]


def quat_normalize(q: torch.Tensor, eps: float = 1e-8) -> torch.Tensor:
    return q / q.norm(dim=-1, keepdim=True).clamp(min=eps)


def quat_mul(p: torch.Tensor, q: torch.Tensor) -> torch.Tensor:
    """Hamilton product ``p q`` (w, x, y, z)."""
    pw, px, py, pz = p.unbind(-1)
    qw, qx, qy, qz = q.unbind(-1)
    return torch.stack([pw * qw - px * qx - py * qy - pz * qz, pw * qx + px * qw + py * qz - pz * qy,
                        pw * qy - px * qz + py * qw + pz * qx, pw * qz + px * qy - py * qx + pz * qw], -1)


def quat_conj(q: torch.Tensor) -> torch.Tensor:
    return q * q.new_tensor([1.0, -1.0, -1.0, -1.0])


def quat_rotate(q: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """``R(q) v`` for unit ``q`` (..., 4) and points ``v`` (..., P, 3) (q broadcast over P)."""
    w, u = q[..., None, :1], q[..., None, 1:]
    uv = torch.cross(u.expand_as(v), v, dim=-1)
    return v + 2 * (w * uv + torch.cross(u.expand_as(v), uv, dim=-1))


def sign_align(q: torch.Tensor, ref: torch.Tensor) -> torch.Tensor:
    """``q`` or ``-q``, whichever has a non-negative dot product with ``ref``."""
    s = torch.where((q * ref).sum(-1, keepdim=True) < 0, -1.0, 1.0).to(q.dtype)
    return q * s


def _canon(q: torch.Tensor) -> torch.Tensor:          # w >= 0, the representation's convention
    return torch.where(q[..., :1] < 0, -q, q)


def rel(a: torch.Tensor, b: torch.Tensor, b_rigid: bool) -> torch.Tensor:
    """``b`` in the frame of rigid ``a`` (a: (..., 7); b: (..., 7) or (..., 3 J))."""
    ta, qa = a[..., :3], quat_normalize(a[..., 3:7])
    qi = quat_conj(qa)
    if b_rigid:
        t = quat_rotate(qi, (b[..., :3] - ta)[..., None, :])[..., 0, :]
        return torch.cat([t, _canon(quat_mul(qi, quat_normalize(b[..., 3:7])))], -1)
    p = b.reshape(*b.shape[:-1], -1, 3) - ta[..., None, :]
    return quat_rotate(qi, p).reshape(b.shape)


def comb(a: torch.Tensor, r: torch.Tensor, r_rigid: bool) -> torch.Tensor:
    """The motion whose motion relative to rigid ``a`` is ``r``."""
    ta, qa = a[..., :3], quat_normalize(a[..., 3:7])
    if r_rigid:
        t = quat_rotate(qa, r[..., None, :3])[..., 0, :] + ta
        return torch.cat([t, _canon(quat_mul(qa, quat_normalize(r[..., 3:7])))], -1)
    p = quat_rotate(qa, r.reshape(*r.shape[:-1], -1, 3)) + ta[..., None, :]
    return p.reshape(r.shape)
