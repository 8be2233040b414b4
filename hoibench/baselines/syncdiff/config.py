"""SyncDiff configurations: ``paper`` and ``tiny``, and the ``syncdiff`` section (its three
mechanisms and their ablation switches).

The numbers of the paper's tables D.2/D.3 (Tables 13-17) and of sections 3.3/3.6 do not
survive the text copy hoibench works from; every value marked *chosen* is hoibench's choice
(docs/baselines.md, "SyncDiff", lists them).

==================  =======  ======  =========================================================
field               paper    tiny    meaning
==================  =======  ======  =========================================================
model.latent        512      64      transformer width (*chosen*)
model.layers        8        2       transformer encoder layers (*chosen*)
model.heads         8        4       attention heads (*chosen*)
model.cond_width    256      32      label / geometry MLP outputs (*chosen*)
model.text_encoder  minilm   tokens  offline sentence encoder (stands in for CLIP ViT-B/32)
model.bps_points    1024     128     BPS basis points (*chosen*), radius 1 m (*chosen*)
syncdiff.cutoff     16       16      highest kept frequency index L (*chosen* from Table 6's rows)
syncdiff.low        3        3       highest low-part index l (*chosen*)
syncdiff.sync_every 5        5       explicit sync every k of the sampling steps (*chosen*)
syncdiff.sync_weight 1.0     1.0     w = sigma_t^2 / sigma_s^2 per edge (*chosen*)
syncdiff.lambda_align 1.0    1.0     weight of L_align (*chosen*)
syncdiff.lambda_norm 0.1     0.1     weight of the quaternion-norm loss (*chosen*)
syncdiff.freq_position rate  rate   frequency tokens' position: ``rate`` k / n, or the row ``index`` (*chosen*)
syncdiff.high_groups 1       1       high-part tokens per coefficient row (column groups) (*chosen*)
==================  =======  ======  =========================================================

Training: paper Adam, batch 32, lr 1e-4 (*chosen*), 100k steps; tiny batch 16, lr 1e-3, 3,000
steps (about 15 min on one CPU core), EMA 0.99. A card without ``syncdiff.freq_position`` was
trained with ``index`` (the field's default, and the presets' before 0.7.0). Diffusion:
T = 1000 linear betas, x0-prediction (the paper's A.2 choice), 50 ancestral (DDPM) sampling
steps, no classifier-free guidance (the paper names none).
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field

from ..config import (TEXT_ENCODERS, TrainConfig, check_choice, check_divisible, check_interval, check_ints,
                      dotted_replace, sections_from_dict, sections_to_dict)
from ..diffusion import DiffusionConfig

SECTIONS = ("model", "syncdiff", "train", "diffusion")
FREQ_POSITIONS = ("index", "rate")


@dataclass(frozen=True)
class ModelConfig:
    latent: int = 512
    layers: int = 8
    heads: int = 8
    ff_mult: int = 2
    cond_width: int = 256
    time_width: int = 256
    dropout: float = 0.1
    text_encoder: str = "minilm"
    text_max_tokens: int = 16
    bps_points: int = 1024
    bps_radius: float = 1.0
    bps_seed: int = 0
    surface_points: int = 2048

    def __post_init__(self) -> None:
        check_ints(self, ("latent", "layers", "heads", "ff_mult", "cond_width", "time_width", "text_max_tokens",
                          "bps_points", "surface_points"), "model", hi=100_000)
        check_ints(self, ("bps_seed",), "model", lo=0)
        check_divisible(self, "latent", "heads", "model")
        check_interval(self, ("dropout",), "model", "[0, 1)")
        check_choice(self, "text_encoder", "model", TEXT_ENCODERS)
        if not 0 < self.bps_radius < 100:
            raise ValueError(f"model.bps_radius: expected (0, 100) metres, got {self.bps_radius!r}")


@dataclass(frozen=True)
class SyncConfig:
    decompose: bool = True
    align_loss: bool = True
    explicit_sync: bool = True
    cutoff: int = 16
    low: int = 3
    sync_every: int = 5
    sync_weight: float = 1.0
    lambda_align: float = 1.0
    lambda_norm: float = 0.1
    #: what the high part's tokens are told about their frequency: ``index`` (the row: k
    #: cycles per clip, whatever the clip's length) or ``rate`` (k / n cycles per frame, a
    #: physical rate: one stroke frequency is one embedding in every clip length)
    freq_position: str = "index"
    #: tokens per coefficient row of the high part: its columns split into this many groups,
    #: one token each (1: one token per row over all columns)
    high_groups: int = 1

    def __post_init__(self) -> None:
        check_choice(self, "freq_position", "syncdiff", FREQ_POSITIONS)
        for name in ("decompose", "align_loss", "explicit_sync"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"syncdiff.{name}: expected true or false, got {getattr(self, name)!r}")
        check_ints(self, ("cutoff", "sync_every", "high_groups"), "syncdiff", hi=10_000)
        check_ints(self, ("low",), "syncdiff", lo=0, hi=10_000)
        if self.low >= self.cutoff:
            raise ValueError(f"syncdiff.low ({self.low}) must be below syncdiff.cutoff ({self.cutoff})")
        for name in ("sync_weight", "lambda_align", "lambda_norm"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and not isinstance(v, bool) and 0 <= v < 1e6):
                raise ValueError(f"syncdiff.{name}: expected a number >= 0, got {v!r}")


@dataclass(frozen=True)
class SyncRunConfig:
    name: str
    model: ModelConfig = field(default_factory=ModelConfig)
    syncdiff: SyncConfig = field(default_factory=SyncConfig)
    train: TrainConfig = field(default_factory=TrainConfig)
    diffusion: DiffusionConfig = field(default_factory=DiffusionConfig)

    def to_dict(self) -> dict:
        return sections_to_dict(self, SECTIONS)

    @classmethod
    def from_dict(cls, d: dict, model_cls: type = ModelConfig, where: str = "config") -> "SyncRunConfig":
        kinds = {"model": model_cls, "syncdiff": SyncConfig, "train": TrainConfig, "diffusion": DiffusionConfig}
        return cls(**sections_from_dict(d, kinds, where))

    def replace(self, **changes) -> "SyncRunConfig":
        """A copy with dotted overrides, e.g. ``replace(**{"syncdiff.decompose": False})``."""
        return SyncRunConfig.from_dict(dotted_replace(self.to_dict(), SECTIONS, changes))

    def sha(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)


def preset(name: str = "tiny") -> SyncRunConfig:
    """``paper`` or ``tiny`` (trains on the synthetic multi-body store on 2 CPU cores)."""
    diffusion = DiffusionConfig(steps=1000, ddim_steps=50, guidance=1.0, cond_drop=0.0)
    if name == "paper":
        return SyncRunConfig(name="paper", model=ModelConfig(), syncdiff=SyncConfig(freq_position="rate"),
                             train=TrainConfig(steps=100_000, batch_size=32, lr=1e-4, weight_decay=0.0,
                                               max_frames=196, min_frames=8, lambda_contact=0.0,
                                               checkpoint_every=1000, log_every=100),
                             diffusion=diffusion)
    if name == "tiny":
        return SyncRunConfig(
            name="tiny",
            model=ModelConfig(latent=64, layers=2, heads=4, cond_width=32, time_width=64, dropout=0.0,
                              text_encoder="tokens", bps_points=128, surface_points=512),
            syncdiff=SyncConfig(freq_position="rate"),
            train=TrainConfig(steps=3000, batch_size=16, lr=1e-3, weight_decay=0.0, max_frames=120, min_frames=8,
                              ema_decay=0.99, lambda_contact=0.0, checkpoint_every=250, log_every=50),
            diffusion=diffusion)
    raise ValueError(f"unknown SyncDiff config {name!r}; choose 'paper' or 'tiny'")
