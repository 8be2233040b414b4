"""What makes ChainHOI ChainHOI for the shared trainer and sampler: model and losses.

Loss (ChainHOI eq. 8): ``L = L_diff + lambda_1 L_h + lambda_2 L_o`` (lambda_1 = 2, lambda_2 = 1);
:mod:`hoibench.baselines.joint_losses` defines the terms.
"""
from __future__ import annotations

import torch

from ..diffusion import GaussianDiffusion, masked_mse
from ..joint_losses import contact_term, denoise, object_loss
from .config import ModelConfig  # noqa: F401  (the spec's model config)
from .config import preset as _preset
from .model import ChainHOI
from .released_config import ReleasedConfig, released_preset


def preset(name: str = "tiny"):
    """``paper``, ``tiny`` (:mod:`.config`) or ``released`` (:mod:`.released_config`)."""
    if name == "released":
        return released_preset()
    if name not in ("paper", "tiny"):
        raise ValueError(f"unknown ChainHOI config {name!r}; choose 'paper', 'released' or 'tiny'")
    return _preset(name)


def config_class(config: dict) -> type:
    """The model-config class of a run card's ``config`` (``released`` runs carry ``model.variant``)."""
    model = config.get("model") if isinstance(config, dict) else None
    return ReleasedConfig if isinstance(model, dict) and model.get("variant") == "released" else ModelConfig


def build_model(cfg, vocab: int, text_width: int):
    if isinstance(cfg.model, ReleasedConfig):
        from .released import ReleasedChainHOI
        return ReleasedChainHOI(cfg.model, vocab=vocab, text_width=text_width)
    return ChainHOI(cfg.model, vocab=vocab, text_width=text_width)


def losses(model, diffusion: GaussianDiffusion, batch: dict, cfg, mean: torch.Tensor, std: torch.Tensor,
           generator: torch.Generator) -> dict[str, torch.Tensor]:
    if isinstance(cfg.model, ReleasedConfig):
        from . import released_losses
        return released_losses.losses(model, diffusion, batch, cfg, mean, std, generator)
    pred, x0 = denoise(model, diffusion, batch, cfg, generator)
    valid = batch["valid"]
    l_diff = masked_mse(pred, x0, valid)
    raw_pred, raw_gt = pred * std + mean, x0 * std + mean
    l_h = contact_term(raw_pred, raw_gt, batch, valid) \
        if cfg.train.lambda_contact > 0 else pred.sum() * 0.0
    l_o = object_loss(raw_pred, raw_gt, valid)
    total = l_diff + cfg.train.lambda_contact * l_h + cfg.train.lambda_object * l_o
    return {"loss": total, "diffusion": l_diff, "contact": l_h, "object": l_o}
