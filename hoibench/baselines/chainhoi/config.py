"""ChainHOI configurations: ``paper`` (published sizes, appendix B.1) and ``tiny`` (CPU minutes).

=================  ========  ======  ==========================================================
field              paper     tiny    meaning
=================  ========  ======  ==========================================================
blocks             6         2       N blocks, each GST-GCN + KIM
d_model            64        32      D_m, width per graph node
d_text             256       64      D_t, width of HOI, chain, text and object tokens
heads              8         4       attention heads in every decoder
object_tokens      16        16      object-geometry tokens (farthest-point centres)
text_encoder       minilm    tokens  frozen sentence-encoder token states, or a trainable
                                     word-embedding encoder over the training captions
max_frames         196       96      training window (rows); longer clips are cropped
batch_size         32        16
lr                 1e-4      1e-3    AdamW
steps              50000     1500    optimiser steps (paper: 200 epochs)
dropout            0.1       0       (tiny: dropout costs 17% of a CPU step)
=================  ========  ======  ==========================================================

Diffusion (both): T = 1000, linear betas 1e-4..0.02, x0 prediction, DDIM 50 steps, guidance 2,
text dropped with probability 0.2. Losses: ``L_diff + lambda_1 L_h + lambda_2 L_o`` with
lambda_1 = 2, lambda_2 = 1; ``L_h`` with the exact point-to-mesh distance (``train.contact_distance``;
``"samples"``, the nearest of ``contact_points`` surface samples, errs by 1-4 cm on average at
256 samples: benchmarks/chainhoi_contact_distance.py). The paper's "head" count and the temporal kernel are not given
in the paper; 8 heads and kernel 3 with dilations (1, 2) are hoibench's choices.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..config import (CONDITIONING_INTS, ConditioningConfig, RunConfig, TrainConfig, check_choice, check_conditioning,
                      check_divisible, check_ints)

MASK_MODES = ("paper", "released")


@dataclass(frozen=True)
class ModelConfig(ConditioningConfig):
    blocks: int = 6
    d_model: int = 64
    d_text: int = 256
    heads: int = 8
    ff_mult: int = 2
    temporal_kernel: int = 3
    temporal_dilations: tuple[int, ...] = (1, 2)
    mask: str = "paper"              # Kinematic-aware Decoder mask: "paper" (boolean) | "released"

    def __post_init__(self) -> None:
        check_ints(self, ("blocks", "d_model", "d_text", "heads", "ff_mult", "temporal_kernel") + CONDITIONING_INTS,
                   "model", hi=100_000)
        check_conditioning(self)
        check_divisible(self, "d_text", "heads", "model")
        check_choice(self, "mask", "model", MASK_MODES)
        if self.temporal_kernel % 2 == 0:
            raise ValueError(f"model.temporal_kernel: expected an odd integer, got {self.temporal_kernel}")
        if not self.temporal_dilations or any(not isinstance(d, int) or d < 1 for d in self.temporal_dilations):
            raise ValueError(f"model.temporal_dilations: expected positive integers, got {self.temporal_dilations!r}")


def preset(name: str = "tiny") -> RunConfig:
    """``paper`` (appendix B.1 sizes) or ``tiny`` (trains on the synthetic track on 2 CPU cores)."""
    if name == "paper":
        return RunConfig(name="paper", model=ModelConfig(), train=TrainConfig(contact_distance="exact"))
    if name == "tiny":
        return RunConfig(
            name="tiny",
            model=ModelConfig(blocks=2, d_model=32, d_text=64, heads=4, object_points=256, object_knn=16,
                              text_encoder="tokens", dropout=0.0),
            train=TrainConfig(steps=1500, batch_size=16, lr=1e-3, max_frames=96, ema_decay=0.99,
                              contact_points=128, contact_distance="exact", checkpoint_every=250, log_every=50))
    raise ValueError(f"unknown ChainHOI config {name!r}; choose 'paper' or 'tiny'")
