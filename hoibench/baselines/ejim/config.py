"""EJIM configurations: ``paper`` (the sizes the paper gives), ``tiny`` (the parameter count of
ChainHOI's and CATMO's tiny configs) and ``micro`` (the training time of ChainHOI tiny).

=================  ======  ======  ======  ====================================================
field              paper   tiny    micro   meaning
=================  ======  ======  ======  ====================================================
modules            6       2       2       Joint-level Interaction Modules (DHM, DIB, DCI, DIB)
d_model            128     128     16      token width
d_state            16      4       4       SSM state size (paper: not given; Mamba-1 default)
expand             2       1       1       Mamba inner width = expand x d_model (Mamba-1 default)
d_conv             4       4       4       depthwise causal convolution width (Mamba-1 default)
mask_k             3       3       3       joints masked per module (progressive masking)
heads              1       1       1       DIB attention heads (eq. 4 is single-head)
text_encoder       minilm  tokens  tokens  frozen sentence-encoder states, or trainable word tokens
object_points      512     256     256     surface samples for the point encoder (16 tokens)
parameters         8.74 M  1.82 M  0.04 M  (tokens encoder: with a 120-word vocabulary)
=================  ======  ======  ======  ====================================================

Training: losses ``L_diff + 1 L_obj + 0.5 L_smooth`` (EJIM Tab. VII's adopted row), no contact
term; paper AdamW, batch 32, lr 1e-4; tiny and micro batch 8, lr 1e-3, 1,500 steps. ``micro``
(the first synthetic-track row's config, formerly called ``tiny``) is what fits 15 minutes on
2 CPU cores: every Mamba scan materialises (sequences, frames, inner width, state) tensors, 23
joint sequences per clip. ``tiny`` matches the other baselines' tiny parameter counts (ChainHOI
1.78 M, CATMO 1.75 M) and costs several times micro's step time (docs/baselines.md).
Diffusion: the shared core (T = 1000, linear betas 1e-4..0.02, x0, DDIM 50, guidance 2,
text dropped with probability 0.2).
"""
from __future__ import annotations

from dataclasses import dataclass

from ..config import (CONDITIONING_INTS, ConditioningConfig, RunConfig, TrainConfig, check_conditioning,
                      check_divisible, check_ints)


@dataclass(frozen=True)
class ModelConfig(ConditioningConfig):
    modules: int = 6
    d_model: int = 128
    d_state: int = 16
    expand: int = 2
    d_conv: int = 4
    mask_k: int = 3
    heads: int = 1

    def __post_init__(self) -> None:
        check_ints(self, ("modules", "d_model", "d_state", "expand", "d_conv", "heads") + CONDITIONING_INTS, "model",
                   hi=100_000)
        check_ints(self, ("mask_k",), "model", lo=0, hi=22)
        check_conditioning(self)
        check_divisible(self, "d_model", "heads", "model")


def preset(name: str = "tiny") -> RunConfig:
    """``paper``, ``tiny`` (ChainHOI/CATMO tiny's parameter count) or ``micro`` (ChainHOI tiny's
    training time on 2 CPU cores)."""
    paper_train = TrainConfig(steps=50_000, batch_size=32, lr=1e-4, lambda_contact=0.0, lambda_object=1.0,
                              lambda_smooth=0.5)
    if name == "paper":
        return RunConfig(name="paper", model=ModelConfig(), train=paper_train)
    if name in ("tiny", "micro"):
        return RunConfig(
            name=name,
            model=ModelConfig(modules=2, d_model=128 if name == "tiny" else 16, d_state=4, expand=1,
                              object_points=256, object_knn=16, text_encoder="tokens", dropout=0.0),
            train=TrainConfig(steps=1500, batch_size=8, lr=1e-3, max_frames=96, ema_decay=0.99,
                              lambda_contact=0.0, lambda_object=1.0, lambda_smooth=0.5, checkpoint_every=250,
                              log_every=50))
    raise ValueError(f"unknown EJIM config {name!r}; choose 'paper', 'tiny' or 'micro'")
