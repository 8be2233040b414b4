"""SyncDiff's two synchronization mechanisms (paper 004, sections 3.5 and 3.6, appendix A.2,
A.3), on raw (de-normalised) representation arrays ``x`` (..., T, D) of one block layout
(:func:`hoibench.representations.multibody.layout`).

Alignment loss (eq. 6 / 17): for every edge ``(a, b)`` (``a`` rigid, ``b != a``), the
relative motion computed from the two generated individual motions, ``rel(x_a, x_b)``, is
pulled toward the generated relative motion ``x_{b|a}``::

    L_align = mean over edges, frames, columns of ((rel(x_a, x_b) - x_{b|a}) / s_{b|a})^2

with ``s`` the relative block's per-column scale (the run's normalisation std floored at
:data:`ALIGN_FLOOR`: a held object's near-constant relative motion would otherwise make early
training all alignment); quaternions compared sign-aligned.

Explicit synchronization (eq. 9-11, Alg. 1): the maximum-likelihood fusion of each part's
own prediction (variance ``sigma^2``) with the predictions implied through its edges (each
of variance ``sigma_s^2``; ``w = sigma^2 / sigma_s^2``), computed from the pre-synchronization
values of every part (all parts updated at once)::

    rigid b:     x_b'     = (x_b + w sum_{a rigid != b} comb(x_a, x_{b|a})) / (1 + w n_b)
    skeleton b:  x_b'     = (x_b + w sum_{a rigid}      comb(x_a, x_{b|a})) / (1 + w n_b)
    relative:    x_{b|a}' = (x_{b|a} + w rel(x_a, x_b)) / (1 + w)

(quaternions averaged sign-aligned to the part's own, then renormalised) and the fused
Gaussian's noise scale ``sigma' = sigma / sqrt(1 + w n)`` per column (:func:`explicit_sync`
returns ``1 + w n``). A rigid body with no other rigid body (``n_b = 0``) is unchanged.
"""
from __future__ import annotations

import torch

from ...representations.multibody import Block
from .geometry import comb, quat_normalize, rel, sign_align

__all__ = ["edges", "alignment_terms", "explicit_sync", "ALIGN_FLOOR"]

#: smallest per-column scale of the alignment loss (metres; quaternion components)
ALIGN_FLOOR = 0.1


def edges(blocks: list[Block]) -> list[tuple[Block, Block, Block]]:
    """``(a, b, b|a)`` individual/individual/relative block triples of a layout."""
    ind = {blk.body: blk for blk in blocks if blk.ref is None}
    return [(ind[blk.ref], ind[blk.body], blk) for blk in blocks if blk.ref is not None]


def _quat_diff(pred: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    return torch.cat([pred[..., :3] - target[..., :3], sign_align(pred[..., 3:7], target[..., 3:7]) - target[..., 3:7]],
                     -1)


def alignment_terms(x: torch.Tensor, blocks: list[Block], scale: torch.Tensor, frames: torch.Tensor
                    ) -> tuple[torch.Tensor, torch.Tensor]:
    """(sum of squared scaled differences, number of terms) of the alignment loss over the
    valid ``frames`` (..., T) bool of ``x`` (..., T, D); ``scale`` (D,)."""
    total, count = x.new_zeros(()), x.new_zeros(())
    m = frames.to(x.dtype)[..., None]
    for a, b, ba in edges(blocks):
        rigid = ba.kind == "rigid"
        r = rel(x[..., a.columns], x[..., b.columns], rigid)
        target = x[..., ba.columns]
        d = (_quat_diff(r, target) if rigid else r - target) / scale[ba.columns].clamp(min=ALIGN_FLOOR)
        total = total + (d ** 2 * m).sum()
        count = count + m.sum() * ba.width
    return total, count


def _fuse_rigid(own: torch.Tensor, implied: list[torch.Tensor], w: float) -> torch.Tensor:
    t = (own[..., :3] + w * sum(i[..., :3] for i in implied)) / (1 + w * len(implied))
    q = (own[..., 3:7] + w * sum(sign_align(i[..., 3:7], own[..., 3:7]) for i in implied)) / (1 + w * len(implied))
    q = quat_normalize(q)
    return torch.cat([t, torch.where(q[..., :1] < 0, -q, q)], -1)


def explicit_sync(x: torch.Tensor, blocks: list[Block], weight: float) -> tuple[torch.Tensor, torch.Tensor]:
    """(synchronized ``x``, per-column precision gain ``1 + w n`` (D,)) for one layout; see the
    module docstring. ``weight`` = ``w`` >= 0 (0: unchanged)."""
    out = x.clone()
    gain = x.new_ones(x.shape[-1])
    trip = edges(blocks)
    for blk in blocks:
        if blk.ref is None:
            implied = [comb(x[..., a.columns], x[..., ba.columns], blk.kind == "rigid")
                       for a, b, ba in trip if b.body == blk.body]
            if not implied or weight == 0:
                continue
            own = x[..., blk.columns]
            if blk.kind == "rigid":
                out[..., blk.columns] = _fuse_rigid(own, implied, weight)
            else:
                out[..., blk.columns] = (own + weight * sum(implied)) / (1 + weight * len(implied))
            gain[blk.columns] = 1 + weight * len(implied)
        elif weight > 0:
            a = next(t[0] for t in trip if t[2] is blk)
            b = next(t[1] for t in trip if t[2] is blk)
            implied = rel(x[..., a.columns], x[..., b.columns], blk.kind == "rigid")
            own = x[..., blk.columns]
            out[..., blk.columns] = (_fuse_rigid(own, [implied], weight) if blk.kind == "rigid"
                                     else (own + weight * implied) / (1 + weight))
            gain[blk.columns] = 1 + weight
    return out, gain
