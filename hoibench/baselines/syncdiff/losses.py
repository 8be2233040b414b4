"""SyncDiff's training objective (paper 004, section 3.5, eq. 7):

    L = L_low + L_high + lambda_norm L_norm + lambda_align L_align     (decomposition on)
    L = L_rec + lambda_norm L_norm + lambda_align L_align              (``decompose = false``)

``L_low`` / ``L_high``: masked mean squared error of the predicted low part and of the
predicted high part (synthesised back into frames: supervised in the temporal domain) to the
ground truth's, in normalised units; ``L_rec`` the same on the whole sample (the ground truth
then keeps its frequencies above the cutoff, as the paper's C.4 says of "w/o decompose").
``L_norm``: mean of ``(|q| - 1)^2`` over the predicted (de-normalised) quaternions.
``L_align``: :func:`.sync.alignment_terms` (off with ``align_loss = false``).
"""
from __future__ import annotations

import torch

from ...representations.multibody import Block
from ..diffusion import GaussianDiffusion
from .sync import alignment_terms


def masked_mean(sq: torch.Tensor, frames: torch.Tensor, cols: torch.Tensor) -> torch.Tensor:
    m = frames.to(sq.dtype)[..., None] * cols[:, None]
    return (sq * m).sum() / m.sum().clamp(min=1.0)


def quat_columns(blocks: list[Block]) -> list[int]:
    return [c for blk in blocks if blk.kind == "rigid" for c in range(blk.start + 3, blk.start + 7)]


def compute(model, diffusion: GaussianDiffusion, batch: dict, sync_cfg, layouts: list[list[Block]],
            mean: list[torch.Tensor], std: list[torch.Tensor], generator: torch.Generator) -> dict[str, torch.Tensor]:
    """The loss terms of one batch (see the module docstring); ``batch`` from
    :func:`.trainer.make_batch`, ``layouts``/``mean``/``std`` indexed by its ``layout`` ids."""
    x0, frames, cols, cond = batch["x0"], batch["frames"], batch["cols"], batch["cond"]
    pad = frames.to(x0.dtype)[..., None] * cols[:, None]
    B = x0.shape[0]
    lengths = frames.sum(1)
    if sync_cfg.decompose:
        gt_low, gt_high, _ = model.split(x0, lengths)
        gt_high_frames = model.recompose(torch.zeros_like(gt_low), gt_high, lengths)
        target = (gt_low + gt_high_frames) * pad
    else:
        target = x0
    t = diffusion.sample_timesteps(B, generator).to(x0.device)
    noise = torch.randn(x0.shape, generator=generator).to(x0.device)
    x_t = diffusion.q_sample(target, t, noise) * pad
    out = model(x_t, t, frames, cols, cond)
    losses = {}
    if sync_cfg.decompose:
        losses["low"] = masked_mean((out["low"] - gt_low) ** 2, frames, cols)
        p_high = model.recompose(torch.zeros_like(gt_low), out["high"], lengths)
        losses["high"] = masked_mean((p_high - gt_high_frames) ** 2, frames, cols)
        total = losses["low"] + losses["high"]
    else:
        losses["rec"] = masked_mean((out["x0"] - target) ** 2, frames, cols)
        total = losses["rec"]
    norm_sum, norm_n, al_sum, al_n = (x0.new_zeros(()) for _ in range(4))
    for lid in sorted(set(batch["layout"].tolist())):
        sel = batch["layout"] == lid
        D = std[lid].shape[0]
        raw = out["x0"][sel][..., :D] * std[lid] + mean[lid]
        fr = frames[sel]
        qc = quat_columns(layouts[lid])
        if qc:
            q = raw[..., qc].reshape(*raw.shape[:-1], -1, 4)
            norm_sum = norm_sum + (((q.norm(dim=-1) - 1) ** 2) * fr[..., None]).sum()
            norm_n = norm_n + fr.sum() * q.shape[-2]
        if sync_cfg.align_loss:
            s, n = alignment_terms(raw, layouts[lid], std[lid], fr)
            al_sum, al_n = al_sum + s, al_n + n
    losses["norm"] = norm_sum / norm_n.clamp(min=1.0)
    total = total + sync_cfg.lambda_norm * losses["norm"]
    if sync_cfg.align_loss:
        losses["align"] = al_sum / al_n.clamp(min=1.0)
        total = total + sync_cfg.lambda_align * losses["align"]
    return {"loss": total, **losses}
