"""Configuration shared by the joint-level diffusion baselines: training recipe and run config.

A run config is ``name`` + a baseline's model config + :class:`TrainConfig` +
:class:`~hoibench.baselines.diffusion.DiffusionConfig`; it round-trips through the JSON of a
run card (:meth:`RunConfig.to_dict`, :meth:`RunConfig.from_dict`), and unknown or
out-of-range fields are refused naming the field.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields, is_dataclass

from .diffusion import DiffusionConfig


TEXT_ENCODERS = ("tokens", "minilm")


def check_ints(cfg, names: tuple[str, ...], section: str, lo: int = 1, hi: int = 10_000_000) -> None:
    """ValueError naming ``section.field`` unless every field in ``names`` is an int in [lo, hi]."""
    for name in names:
        v = getattr(cfg, name)
        if not (isinstance(v, int) and not isinstance(v, bool) and lo <= v <= hi):
            raise ValueError(f"{section}.{name}: expected an integer in [{lo}, {hi}], got {v!r}")


def check_conditioning(cfg) -> None:
    """The fields every baseline model config shares: text encoder, object points, dropout."""
    if cfg.object_tokens > cfg.object_points or cfg.object_knn > cfg.object_points:
        raise ValueError("model.object_tokens and model.object_knn must not exceed model.object_points")
    if not 0 <= cfg.dropout < 1:
        raise ValueError(f"model.dropout: expected [0, 1), got {cfg.dropout!r}")
    if cfg.text_encoder not in TEXT_ENCODERS:
        raise ValueError(f"model.text_encoder: expected one of {TEXT_ENCODERS}, got {cfg.text_encoder!r}")


def section_from_dict(cls: type, block, where: str, outer: str = "config"):
    """``cls(**block)`` for one config section read from JSON (lists become tuples); a
    ValueError naming ``where`` and the field for a non-object, unknown or invalid field."""
    if not isinstance(block, dict):
        raise ValueError(f"{where}: expected an object")
    known = {f.name for f in fields(cls)}
    unknown = sorted(set(block) - known)
    if unknown:
        raise ValueError(f"{where}: unknown field(s) {', '.join(unknown)}")
    block = {k: tuple(v) if isinstance(v, list) else v for k, v in block.items()}
    try:
        return cls(**block)
    except TypeError as exc:
        raise ValueError(f"{where}: {exc}") from None
    except ValueError as exc:
        raise ValueError(f"{outer}: {exc}") from None


def dotted_replace(d: dict, sections: tuple[str, ...], changes: dict) -> dict:
    """A copy of the config dict ``d`` with ``section.field`` overrides (ValueError naming an
    unknown section or field)."""
    import copy
    d = copy.deepcopy(d)
    for dotted, value in changes.items():
        section, _, key = dotted.partition(".")
        if section not in sections or not key:
            raise ValueError(f"override {dotted!r}: expected one of {', '.join(s + '.<field>' for s in sections)}")
        if key not in d[section]:
            raise ValueError(f"override {dotted!r}: unknown field {key!r} of {section}")
        d[section][key] = value
    return d


CONTACT_DISTANCES = ("samples", "exact")


@dataclass(frozen=True)
class TrainConfig:
    steps: int = 50_000
    batch_size: int = 32
    lr: float = 1e-4
    weight_decay: float = 0.01
    max_frames: int = 196
    min_frames: int = 8
    ema_decay: float = 0.999
    grad_clip: float = 1.0
    lambda_contact: float = 2.0      # ChainHOI lambda_1 (L_h); 0 for EJIM
    lambda_object: float = 1.0       # ChainHOI lambda_2 / EJIM lambda_o (L_o)
    lambda_smooth: float = 0.0       # EJIM lambda_s (L_smooth); 0 for ChainHOI
    contact_points: int = 256        # GT object surface samples for L_h ("samples")
    contact_distance: str = "samples"   # L_h distance: nearest of contact_points samples | exact point-to-mesh
    checkpoint_every: int = 500
    log_every: int = 50
    seed: int = 0

    def __post_init__(self) -> None:
        check_ints(self, ("steps",), "train", lo=0)
        check_ints(self, ("batch_size", "max_frames", "min_frames", "contact_points", "checkpoint_every", "log_every"),
                   "train")
        if not 0 < self.lr < 1:
            raise ValueError(f"train.lr: expected (0, 1), got {self.lr!r}")
        if not 0 <= self.ema_decay < 1:
            raise ValueError(f"train.ema_decay: expected [0, 1), got {self.ema_decay!r}")
        if self.contact_distance not in CONTACT_DISTANCES:
            raise ValueError(f"train.contact_distance: expected one of {CONTACT_DISTANCES}, got {self.contact_distance!r}")
        for name in ("lambda_contact", "lambda_object", "lambda_smooth"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"train.{name}: expected >= 0, got {getattr(self, name)!r}")


@dataclass(frozen=True)
class RunConfig:
    name: str
    model: object                   # the baseline's frozen model-config dataclass
    train: TrainConfig = field(default_factory=TrainConfig)
    diffusion: DiffusionConfig = field(default_factory=DiffusionConfig)

    def __post_init__(self) -> None:
        if not is_dataclass(self.model):
            raise ValueError(f"config.model: expected a model config dataclass, got {type(self.model).__name__}")

    def to_dict(self) -> dict:
        d = {"name": self.name, "model": asdict(self.model), "train": asdict(self.train),
             "diffusion": asdict(self.diffusion)}
        for k, v in d["model"].items():
            if isinstance(v, tuple):
                d["model"][k] = list(v)
        return d

    @classmethod
    def from_dict(cls, d: dict, model_cls: type, where: str = "config") -> "RunConfig":
        if not isinstance(d, dict):
            raise ValueError(f"{where}: expected an object")
        parts = {key: section_from_dict(sub, d.get(key, {}), f"{where}.{key}", where)
                 for key, sub in (("model", model_cls), ("train", TrainConfig), ("diffusion", DiffusionConfig))}
        return cls(name=str(d.get("name", "custom")), **parts)

    def replace(self, **changes) -> "RunConfig":
        """A copy with dotted overrides, e.g. ``replace(**{"train.steps": 10, "model.mask": "released"})``."""
        return RunConfig.from_dict(dotted_replace(self.to_dict(), ("model", "train", "diffusion"), changes),
                                   type(self.model))
