"""What makes EJIM EJIM for the shared trainer and sampler: model and losses.

Loss (EJIM eq. 5, Tab. VII's adopted weights): ``L = L_diff + 1 L_obj + 0.5 L_smooth``, no
contact term (:mod:`hoibench.baselines.joint_losses` defines the terms).
"""
from __future__ import annotations

import torch

from ..diffusion import GaussianDiffusion, masked_mse
from ..joint_losses import contact_term, denoise, object_loss, smooth_loss
from .config import ModelConfig, preset  # noqa: F401  (the spec's preset and model config)
from .model import EJIM


def build_model(cfg, vocab: int, text_width: int) -> EJIM:
    return EJIM(cfg.model, vocab=vocab, text_width=text_width)


def losses(model, diffusion: GaussianDiffusion, batch: dict, cfg, mean: torch.Tensor, std: torch.Tensor,
           generator: torch.Generator) -> dict[str, torch.Tensor]:
    pred, x0 = denoise(model, diffusion, batch, cfg, generator)
    valid = batch["valid"]
    raw_pred, raw_gt = pred * std + mean, x0 * std + mean
    out = {"diffusion": masked_mse(pred, x0, valid), "object": object_loss(raw_pred, raw_gt, valid),
           "smooth": smooth_loss(pred, x0, valid)}
    total = out["diffusion"] + cfg.train.lambda_object * out["object"] + cfg.train.lambda_smooth * out["smooth"]
    if cfg.train.lambda_contact > 0:
        out["contact"] = contact_term(raw_pred, raw_gt, batch, valid)
        total = total + cfg.train.lambda_contact * out["contact"]
    return {"loss": total, **out}
