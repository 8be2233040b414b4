"""What makes ChainHOI ChainHOI for the shared trainer and sampler: model and losses.

Loss (ChainHOI eq. 8): ``L = L_diff + lambda_1 L_h + lambda_2 L_o`` (lambda_1 = 2, lambda_2 = 1);
:mod:`hoibench.baselines.joint_losses` defines the terms.
"""
from __future__ import annotations

import torch

from ..diffusion import GaussianDiffusion, masked_mse
from ..joint_losses import contact_term, denoise, object_loss
from .config import ModelConfig, preset  # noqa: F401  (the spec's preset and model config)
from .model import ChainHOI


def build_model(cfg, vocab: int, text_width: int) -> ChainHOI:
    return ChainHOI(cfg.model, vocab=vocab, text_width=text_width)


def losses(model, diffusion: GaussianDiffusion, batch: dict, cfg, mean: torch.Tensor, std: torch.Tensor,
           generator: torch.Generator) -> dict[str, torch.Tensor]:
    pred, x0 = denoise(model, diffusion, batch, cfg, generator)
    valid = batch["valid"]
    l_diff = masked_mse(pred, x0, valid)
    raw_pred, raw_gt = pred * std + mean, x0 * std + mean
    l_h = contact_term(raw_pred, raw_gt, batch, valid) \
        if cfg.train.lambda_contact > 0 else pred.sum() * 0.0
    l_o = object_loss(raw_pred, raw_gt, valid)
    total = l_diff + cfg.train.lambda_contact * l_h + cfg.train.lambda_object * l_o
    return {"loss": total, "diffusion": l_diff, "contact": l_h, "object": l_o}
