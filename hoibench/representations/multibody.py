"""SyncDiff's multi-body motion representation (paper 004, section 3.2 and appendix C.1):
every body's individual motion plus the relative motion of every body in each rigid body's
frame, concatenated per frame.

Individual motions (world frame):

* a rigid body: ``[t (3), q (4)]`` -- translation and unit quaternion ``(w, x, y, z)``
  (``w >= 0``, hoibench's canonical sign) of its rotation;
* a skeleton (human or hand): its joint positions ``(J * 3)``.

Relative motion of body ``b`` in the frame of a rigid body ``a`` (``R_a``, ``t_a``), for
every ordered pair with ``a`` rigid and ``b != a`` (none between two skeletons, as the
paper states):

* ``b`` rigid: ``[R_a^T (t_b - t_a), q_a^{-1} q_b]``;
* ``b`` a skeleton: every joint ``R_a^T (p - t_a)``.

:func:`encode` gives the (T, D) array and its :class:`Block` layout; :func:`decode` reads the
individual blocks back into bodies (exact up to float rounding); :func:`relative` and
:func:`combine` are SyncDiff's ``rel`` and ``comb``: ``combine(a, relative(a, b)) == b``.
The relative blocks are redundant by construction: :func:`consistency` measures how far a
generated array's relative blocks are from those its individual blocks imply (0 for any
encoded clip).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core import geometry as geo
from ..bodies.multibody import Body, MultiBodyClip

__all__ = ["VERSION", "Block", "layout", "encode", "decode", "relative", "combine", "consistency"]

VERSION = "multibody-syncdiff-1.0"


@dataclass(frozen=True)
class Block:
    """Columns ``start:start + width`` of the representation: the individual motion of
    ``body`` (``ref`` None) or its motion relative to rigid body ``ref``; ``kind`` is
    "rigid" (7 columns) or "joints" (J * 3)."""

    body: str
    ref: str | None
    kind: str
    start: int
    width: int

    @property
    def columns(self) -> slice:
        return slice(self.start, self.start + self.width)


def _width(b: Body) -> tuple[str, int]:
    return ("rigid", 7) if b.is_rigid else ("joints", 3 * int(np.shape(b.joints)[1]))


def layout(clip: MultiBodyClip) -> list[Block]:
    """The blocks of :func:`encode` for ``clip``'s bodies: individual motions in body
    order, then relative motions for each rigid ``ref`` (body order) and each other body."""
    blocks, col = [], 0
    for b in clip.bodies:
        kind, w = _width(b)
        blocks.append(Block(b.name, None, kind, col, w))
        col += w
    for a in clip.bodies:
        if not a.is_rigid:
            continue
        for b in clip.bodies:
            if b.name == a.name:
                continue
            kind, w = _width(b)
            blocks.append(Block(b.name, a.name, kind, col, w))
            col += w
    return blocks


def _quat(R: np.ndarray) -> np.ndarray:
    return np.asarray(geo.matrix_to_quaternion(np.asarray(R, np.float64)))


def relative(a: Body, b: Body) -> np.ndarray:
    """(T, 7) or (T, J*3): ``b``'s motion in the frame of rigid body ``a``."""
    if not a.is_rigid:
        raise ValueError(f"relative: the reference {a.name!r} must be a rigid body, it is a {a.kind}")
    Ra, ta = np.asarray(a.rot, np.float64), np.asarray(a.trans, np.float64)
    if b.is_rigid:
        t = np.einsum("tji,tj->ti", Ra, np.asarray(b.trans, np.float64) - ta)
        q = _quat(np.einsum("tji,tjk->tik", Ra, np.asarray(b.rot, np.float64)))
        return np.concatenate([t, q], -1)
    p = np.einsum("tji,tkj->tki", Ra, np.asarray(b.joints, np.float64) - ta[:, None])
    return p.reshape(len(p), -1)


def combine(a: Body, rel: np.ndarray, like: Body) -> Body:
    """SyncDiff's ``comb``: the body whose motion relative to rigid ``a`` is ``rel``
    (``like`` gives its name, kind and metadata)."""
    Ra, ta = np.asarray(a.rot, np.float64), np.asarray(a.trans, np.float64)
    rel = np.asarray(rel, np.float64)
    if like.is_rigid:
        t = np.einsum("tij,tj->ti", Ra, rel[:, :3]) + ta
        R = np.einsum("tij,tjk->tik", Ra, np.asarray(geo.quaternion_to_matrix(rel[:, 3:7])))
        return Body(like.name, like.kind, t, R, None, like.template, like.side, like.owner)
    p = np.einsum("tij,tkj->tki", Ra, rel.reshape(len(rel), -1, 3)) + ta[:, None]
    return Body(like.name, like.kind, p[:, 0].copy(), None, p, like.template, like.side, like.owner)


def _individual(b: Body) -> np.ndarray:
    if b.is_rigid:
        return np.concatenate([np.asarray(b.trans, np.float64), _quat(b.rot)], -1)
    J = np.asarray(b.joints, np.float64)
    return J.reshape(len(J), -1)


def encode(clip: MultiBodyClip) -> tuple[np.ndarray, list[Block]]:
    """(T, D) float64 representation of ``clip`` and its layout."""
    blocks = layout(clip)
    T = clip.num_frames
    out = np.zeros((T, blocks[-1].start + blocks[-1].width))
    for blk in blocks:
        b = clip.body(blk.body)
        out[:, blk.columns] = _individual(b) if blk.ref is None else relative(clip.body(blk.ref), b)
    return out, blocks


def _check_array(x, blocks: list[Block]) -> np.ndarray:
    x = np.asarray(x, np.float64)
    D = blocks[-1].start + blocks[-1].width
    if x.ndim != 2 or x.shape[1] != D:
        raise ValueError(f"representation: expected (T, {D}) for this layout, got {x.shape}")
    if not np.isfinite(x).all():
        raise ValueError("representation: non-finite values")
    return x


def decode(x, like: MultiBodyClip) -> list[Body]:
    """The bodies of a representation array (its individual blocks; rotations from the
    quaternions, renormalised), with names and metadata from ``like``."""
    blocks = layout(like)
    x = _check_array(x, blocks)
    out = []
    for blk in blocks:
        if blk.ref is not None:
            continue
        b = like.body(blk.body)
        v = x[:, blk.columns]
        if blk.kind == "rigid":
            q = v[:, 3:7] / np.maximum(np.linalg.norm(v[:, 3:7], axis=-1, keepdims=True), 1e-12)
            out.append(Body(b.name, b.kind, v[:, :3].copy(), np.asarray(geo.quaternion_to_matrix(q)), None,
                            b.template, b.side, b.owner))
        else:
            J = v.reshape(len(v), -1, 3)
            out.append(Body(b.name, b.kind, J[:, 0].copy(), None, J, b.template, b.side, b.owner))
    return out


def consistency(x, like: MultiBodyClip) -> float:
    """Largest difference between the relative blocks of ``x`` and the relative motions its
    own individual blocks imply (metres for positions, quaternion components for
    rotations; sign-aware). 0 up to rounding for any :func:`encode` output."""
    blocks = layout(like)
    x = _check_array(x, blocks)
    bodies = {b.name: b for b in decode(x, like)}
    worst = 0.0
    for blk in blocks:
        if blk.ref is None:
            continue
        want = relative(bodies[blk.ref], bodies[blk.body])
        got = x[:, blk.columns]
        if blk.kind == "rigid":
            d_t = np.abs(got[:, :3] - want[:, :3]).max()
            d_q = np.minimum(np.abs(got[:, 3:] - want[:, 3:]).max(-1), np.abs(got[:, 3:] + want[:, 3:]).max(-1)).max()
            worst = max(worst, float(d_t), float(d_q))
        else:
            worst = max(worst, float(np.abs(got - want).max()))
    return worst
