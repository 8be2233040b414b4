"""Evaluator configuration: the model sizes (``paper``, ``tiny``), variants and training knobs.

A configuration is plain data: it goes verbatim into ``card.json`` and is hashed into the
evaluator id, so two folders with the same id were built by the same recipe.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any

#: Embedding width of both branches (the field's evaluators use 512).
EMBED_DIM = 512
VARIANTS = ("human", "hoi")
SIZES = ("paper", "tiny")

#: inclusive bounds of every architecture field: room around what the ``paper`` and ``tiny``
#: sizes need (a re-signed card cannot make loading allocate gigabytes; the id is a hash,
#: not a signature)
MODEL_BOUNDS = {"width": (8, 2048), "layers": (1, 32), "heads": (1, 64), "ff_dim": (8, 8192),
                "embed_dim": (8, 4096), "max_frames": (2, 4096), "text_max_tokens": (1, 512)}
#: (lower, upper, lower inclusive) of the real-valued model fields
MODEL_REAL_BOUNDS = {"dropout": (0.0, 1.0, True), "init_temperature": (0.0, 10.0, False),
                     "max_logit_scale": (1.0, 1000.0, True)}
TRAIN_BOUNDS = {"epochs": (1, 100_000), "batch_size": (2, 4096), "warmup_epochs": (0, 100_000),
                "text_unfreeze_epoch": (0, 100_000), "text_finetune_layers": (0, 64), "min_frames": (1, 4096),
                "threads": (0, 1024)}
TRAIN_REAL_BOUNDS = {"lr": (0.0, 1.0, False), "text_lr": (0.0, 1.0, True), "weight_decay": (0.0, 1.0, True)}
#: motion-branch parameters may be at most this multiple of the ``paper`` size's
MAX_PARAMETER_FACTOR = 2
#: hml263 rows and the object-relative rows of the ``hoi`` variant (hoibench.evaluator.features)
_BODY_DIM, _OBJ_DIM = 263, 15


def check_fields(cfg, ints: dict, reals: dict, section: str) -> None:
    """ValueError naming ``section.field`` for a value of the wrong type or out of its range."""
    for name, (lo, hi) in ints.items():
        v = getattr(cfg, name)
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise ValueError(f"{section}.{name}: expected an integer in [{lo}, {hi}], got {v!r}")
    for name, (lo, hi, closed) in reals.items():
        v = getattr(cfg, name)
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) and (lo <= v if closed else lo < v) and v <= hi
        if not ok or (name == "dropout" and v >= 1):
            raise ValueError(f"{section}.{name}: expected a number in {'[' if closed else '('}{lo:g}, {hi:g}"
                             f"{')' if name == 'dropout' else ']'}, got {v!r}")


@dataclass(frozen=True)
class ModelConfig:
    """Architecture of both branches.

    ``paper``: width 384, 8 layers, 8 heads, feed-forward 1536, dropout 0.3 (docs/evaluator.md, "Model").
    ``tiny``: width 64, 2 layers, 4 heads, feed-forward 128, dropout 0.1, for CPU tests.
    """

    variant: str = "human"          # "human": hml263 tokens; "hoi": + object-relative tokens
    width: int = 384
    layers: int = 8
    heads: int = 8
    ff_dim: int = 1536
    dropout: float = 0.3
    embed_dim: int = EMBED_DIM
    max_frames: int = 196           # longer motions are cropped (training: seeded window; embedding: first frames)
    text_max_tokens: int = 64
    init_temperature: float = 0.07  # CLIP's initial softmax temperature
    max_logit_scale: float = 100.0  # CLIP's clamp of 1 / temperature

    def __post_init__(self):
        if self.variant not in VARIANTS:
            raise ValueError(f"variant: expected one of {VARIANTS}, got {self.variant!r}")
        check_fields(self, MODEL_BOUNDS, MODEL_REAL_BOUNDS, "model")
        if self.width % self.heads:
            raise ValueError(f"model.width: {self.width} is not divisible by model.heads={self.heads}")
        limit = MAX_PARAMETER_FACTOR * _PAPER_PARAMETERS.get(self.variant, 0)
        if limit and self.motion_parameters() > limit:
            raise ValueError(f"model: width {self.width}, layers {self.layers}, ff_dim {self.ff_dim}, embed_dim "
                             f"{self.embed_dim} give {self.motion_parameters():,} motion-branch parameters, over "
                             f"{MAX_PARAMETER_FACTOR} x the paper size's ({limit:,}): refused before allocating")

    def motion_parameters(self) -> int:
        """Parameters of the motion branch (:class:`hoibench.evaluator.model.MotionEncoder`) from
        the config alone: input projections, class token, ``layers`` pre-norm transformer
        layers (attention 4 w^2 + 4 w, feed-forward 2 w f + f + w, two norms 4 w), the final
        norm and the head."""
        w, f = self.width, self.ff_dim
        n = (_BODY_DIM + 1) * w + w
        if self.variant == "hoi":
            n += (_OBJ_DIM + 1) * w + 2 * w
        n += self.layers * (4 * w * w + 4 * w + 2 * w * f + f + w + 4 * w)
        return n + 2 * w + (w + 1) * self.embed_dim


@dataclass(frozen=True)
class TrainConfig:
    """Optimisation recipe. ``text_unfreeze_epoch``: epochs 0..k-1 train with the sentence
    encoder frozen (its pooled outputs are cached once), epochs k.. fine-tune it with
    ``text_lr``; k >= ``epochs`` keeps it frozen throughout (then its weights are not stored in
    the evaluator folder but named by hash). ``text_finetune_layers``: how many of the top
    transformer layers are fine-tuned (0 = all); only those are stored in the folder.
    ``threads``: torch CPU threads while training (0 = leave torch's setting; training
    results can depend on it, so the presets fix it: 1 for ``tiny``, which also avoids
    OpenMP stalls on a busy machine)."""

    epochs: int = 300
    batch_size: int = 64
    lr: float = 1e-4
    text_lr: float = 1e-5
    weight_decay: float = 0.01
    warmup_epochs: int = 5
    text_unfreeze_epoch: int = 50
    text_finetune_layers: int = 0   # top transformer layers fine-tuned after unfreezing (0 = all)
    min_frames: int = 8             # text segments shorter than this (rows) are skipped
    seed: int = 0
    threads: int = 1                # torch CPU threads while training (0 = torch's setting)
    negatives: str = "mask_same_caption"   # or "all": how identical captions in a batch are treated
    control: str = "none"           # "shuffled_texts": texts permuted across clips (a control run)

    def __post_init__(self):
        if self.negatives not in ("mask_same_caption", "all"):
            raise ValueError(f"negatives: expected 'mask_same_caption' or 'all', got {self.negatives!r}")
        if self.control not in ("none", "shuffled_texts"):
            raise ValueError(f"control: expected 'none' or 'shuffled_texts', got {self.control!r}")
        check_fields(self, TRAIN_BOUNDS, TRAIN_REAL_BOUNDS, "train")


@dataclass(frozen=True)
class EvaluatorConfig:
    size: str
    model: ModelConfig
    train: TrainConfig = field(default_factory=TrainConfig)

    def to_dict(self) -> dict[str, Any]:
        return {"size": self.size, "model": asdict(self.model), "train": asdict(self.train)}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> "EvaluatorConfig":
        known_m = {f.name for f in fields(ModelConfig)}
        known_t = {f.name for f in fields(TrainConfig)}
        return cls(d["size"], ModelConfig(**{k: v for k, v in d["model"].items() if k in known_m}),
                   TrainConfig(**{k: v for k, v in d["train"].items() if k in known_t}))

    def sha256(self) -> str:
        return hashlib.sha256(json.dumps(self.to_dict(), sort_keys=True).encode()).hexdigest()


_PAPER_PARAMETERS: dict[str, int] = {}
_PAPER_PARAMETERS.update({v: ModelConfig(variant=v).motion_parameters() for v in VARIANTS})

#: Share of the epochs trained with the sentence encoder frozen, per size (paper: 50 of 300).
FROZEN_FRACTION = {"paper": 1.0 / 6.0, "tiny": 0.75}


def preset(size: str = "tiny", variant: str = "human", epochs: int | None = None, seed: int = 0,
           **train_overrides) -> EvaluatorConfig:
    """The named configuration ``size`` (``paper`` | ``tiny``) for ``variant`` (``human`` | ``hoi``).

    ``epochs`` overrides the size's default; unless ``text_unfreeze_epoch`` is given too, the
    frozen phase keeps its share of the epochs (:data:`FROZEN_FRACTION`).
    """
    if size == "paper":
        model = ModelConfig(variant=variant)
        train = TrainConfig(threads=0)
    elif size == "tiny":
        model = ModelConfig(variant=variant, width=64, layers=2, heads=4, ff_dim=128, dropout=0.1)
        train = TrainConfig(epochs=60, batch_size=32, lr=1e-3, text_lr=2e-5, warmup_epochs=3,
                            text_unfreeze_epoch=45, text_finetune_layers=2, threads=1)
    else:
        raise ValueError(f"size: expected one of {SIZES}, got {size!r}")
    over = {k: v for k, v in train_overrides.items() if v is not None}
    if epochs is not None:
        over["epochs"] = int(epochs)
        over.setdefault("text_unfreeze_epoch", int(round(FROZEN_FRACTION[size] * int(epochs))))
    over["seed"] = int(seed)
    return EvaluatorConfig(size, model, replace(train, **over))
