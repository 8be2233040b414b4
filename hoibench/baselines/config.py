"""Configuration shared by the joint-level diffusion baselines: training recipe and run config.

A run config is ``name`` + a baseline's model config + :class:`TrainConfig` +
:class:`~hoibench.baselines.diffusion.DiffusionConfig`; it round-trips through the JSON of a
run card (:meth:`RunConfig.to_dict`, :meth:`RunConfig.from_dict`), and unknown or
out-of-range fields are refused naming the field.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields, is_dataclass
from typing import Callable

from .diffusion import DiffusionConfig


TEXT_ENCODERS = ("tokens", "minilm")

#: inclusive upper bound of every architecture field, by name, in every baseline's config
#: sections: room around what the ``paper`` sizes need (CATMO's GPT: width 1024, 18 layers,
#: 16 heads), so a re-signed card cannot make loading allocate gigabytes
ARCH_LIMITS = {"blocks": 48, "modules": 48, "layers": 48, "depth": 16, "text_layers": 12, "d_model": 4096,
               "d_text": 4096, "width": 4096, "hidden": 4096, "code_dim": 4096, "heads": 64, "ff_mult": 8,
               "expand": 8, "d_state": 256, "d_conv": 31, "temporal_kernel": 31, "dilation_growth": 8,
               "object_points": 8192, "object_tokens": 512, "object_knn": 512, "text_max_tokens": 512,
               "max_tokens": 512, "motion_codes": 16384, "contact_codes": 16384, "window": 4096, "max_units": 1024,
               "max_frames": 4096, "batch_size": 4096, "contact_points": 65536}
#: a config's parameters may be at most this multiple of its baseline's ``paper`` size's
MAX_PARAMETER_FACTOR = 2


def check_ints(cfg, names: tuple[str, ...], section: str, lo: int = 1, hi: int = 10_000_000) -> None:
    """ValueError naming ``section.field`` unless every field in ``names`` is an int in [lo, hi]."""
    for name in names:
        v = getattr(cfg, name)
        if not (isinstance(v, int) and not isinstance(v, bool) and lo <= v <= hi):
            raise ValueError(f"{section}.{name}: expected an integer in [{lo}, {hi}], got {v!r}")


def check_interval(cfg, names: tuple[str, ...], section: str, interval: str) -> None:
    """ValueError naming ``section.field`` unless every field in ``names`` lies in ``interval``,
    written ``"[lo, hi)"``, ``"(lo, hi]"``, ... (a square bracket includes its end)."""
    lo_mark, body, hi_mark = interval[0], interval[1:-1], interval[-1]
    lo, hi = (float(x) for x in body.split(","))
    for name in names:
        v = getattr(cfg, name)
        above = v >= lo if lo_mark == "[" else v > lo
        below = v <= hi if hi_mark == "]" else v < hi
        if not (above and below):
            raise ValueError(f"{section}.{name}: expected {interval}, got {v!r}")


def check_nonnegative(cfg, names: tuple[str, ...], section: str) -> None:
    """ValueError naming ``section.field`` for a field of ``names`` that is not ``>= 0`` (NaN included)."""
    for name in names:
        if not getattr(cfg, name) >= 0:
            raise ValueError(f"{section}.{name}: expected >= 0, got {getattr(cfg, name)!r}")


def check_choice(cfg, name: str, section: str, choices: tuple[str, ...]) -> None:
    """ValueError naming ``section.field`` unless the field is one of ``choices``."""
    if getattr(cfg, name) not in choices:
        raise ValueError(f"{section}.{name}: expected one of {choices}, got {getattr(cfg, name)!r}")


def check_divisible(cfg, name: str, by: str, section: str) -> None:
    """ValueError naming both fields unless ``section.name`` is a multiple of ``section.by``."""
    if getattr(cfg, name) % getattr(cfg, by):
        raise ValueError(f"{section}.{name} ({getattr(cfg, name)}) must be divisible by {section}.{by} "
                         f"({getattr(cfg, by)})")


def check_architecture(cfg, section: str) -> None:
    """ValueError naming ``section.field`` for a field of :data:`ARCH_LIMITS` over its bound."""
    for f in own_fields_first(cfg):
        if f.name in ARCH_LIMITS:
            check_ints(cfg, (f.name,), section, lo=1, hi=ARCH_LIMITS[f.name])


def meta_parameters(build: Callable[[], object]) -> int:
    """Parameters of the module ``build()`` makes, built on torch's ``meta`` device (shapes
    only, nothing allocated)."""
    import torch
    with torch.device("meta"):
        module = build()
    return int(sum(p.numel() for p in module.parameters()))


#: hidden size of the packaged sentence encoder (all-MiniLM-L6-v2): sizes a config that reads it
MINILM_WIDTH = 384


def sizing(cfg, vocab: int, text_width: int) -> tuple[int, int]:
    """(vocab, text width) to build ``cfg`` with for counting its parameters: a config whose
    text encoder is the sentence encoder gets its hidden size when the run's conditioner has
    none (the paper config is counted next to a run with word tokens), a word-token config at
    least a two-word vocabulary."""
    encoder = getattr(getattr(cfg, "model", None), "text_encoder", None) or \
        getattr(getattr(cfg, "text", None), "encoder", None)
    if encoder == "minilm":
        return vocab, text_width or MINILM_WIDTH
    return max(vocab, 2), text_width


def check_parameter_count(build: Callable[[object], object], cfg, paper, where: str) -> int:
    """The parameter count of ``build(cfg)``, measured without allocating; ValueError naming
    the fields larger than the ``paper`` config's when it exceeds :data:`MAX_PARAMETER_FACTOR`
    times ``build(paper)``'s."""
    n = meta_parameters(lambda: build(cfg))
    limit = MAX_PARAMETER_FACTOR * meta_parameters(lambda: build(paper))
    if n > limit:
        a, b = _flat_ints(cfg.to_dict()), _flat_ints(paper.to_dict())
        larger = [f"{k} = {v}" for k, v in a.items() if k in b and v > b[k] and k.split(".")[0] != "train"]
        raise ValueError(f"{where}: {n:,} parameters, over {MAX_PARAMETER_FACTOR} x the paper size's ({limit:,}; "
                         f"larger than paper: {', '.join(larger[:4]) or 'none'}): refused before allocating")
    return n


def _flat_ints(d: dict, prefix: str = "") -> dict[str, int]:
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flat_ints(v, f"{prefix}{k}."))
        elif isinstance(v, int) and not isinstance(v, bool):
            out[f"{prefix}{k}"] = v
    return out


@dataclass(frozen=True)
class ConditioningConfig:
    """The object and text conditioning fields of ChainHOI's and EJIM's model configs (their
    ``ModelConfig`` derives from this). A dataclass lists a base's fields first; checks and
    :meth:`RunConfig.to_dict` take a model's own fields first (:func:`own_fields_first`)."""
    dropout: float = 0.1
    object_points: int = 512         # surface samples given to the point encoder
    object_tokens: int = 16
    object_knn: int = 32
    text_encoder: str = "minilm"
    text_max_tokens: int = 32
    text_layers: int = 1             # transformer layers of the ``tokens`` encoder


#: the integer fields of :class:`ConditioningConfig`, in the order a model config checks them
CONDITIONING_INTS = ("object_points", "object_tokens", "object_knn", "text_max_tokens", "text_layers")


def own_fields_first(cfg) -> list:
    """``fields(cfg)``, those it shares from :class:`ConditioningConfig` last: the order in
    which a model config's fields are checked and reported (its architecture first)."""
    shared = {f.name for f in fields(ConditioningConfig)} if isinstance(cfg, ConditioningConfig) else set()
    return sorted(fields(cfg), key=lambda f: f.name in shared)


def check_conditioning(cfg) -> None:
    """The checks of :class:`ConditioningConfig`'s fields other than the integer ranges (a
    model config checks :data:`CONDITIONING_INTS` with its own): object sampling, dropout, text
    encoder."""
    check_object_sampling(cfg, "model")
    check_interval(cfg, ("dropout",), "model", "[0, 1)")
    check_choice(cfg, "text_encoder", "model", TEXT_ENCODERS)


def check_object_sampling(cfg, section: str) -> None:
    """ValueError unless ``object_tokens`` and ``object_knn`` are at most ``object_points``."""
    if cfg.object_tokens > cfg.object_points or cfg.object_knn > cfg.object_points:
        raise ValueError(f"{section}.object_tokens and {section}.object_knn must not exceed {section}.object_points")


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


def sections_from_dict(d, kinds: dict[str, type], where: str = "config", strict: bool = True) -> dict:
    """``name`` and one section object per key of ``kinds`` (each read by :func:`section_from_dict`)
    from a config dict; ``strict`` refuses a top-level key that is neither ``name`` nor a section."""
    if not isinstance(d, dict):
        raise ValueError(f"{where}: expected an object")
    unknown = sorted(set(d) - set(kinds) - {"name"})
    if strict and unknown:
        raise ValueError(f"{where}: unknown section(s) {', '.join(unknown)}")
    parts = {key: section_from_dict(kind, d.get(key, {}), f"{where}.{key}", where) for key, kind in kinds.items()}
    return {"name": str(d.get("name", "custom")), **parts}


def sections_to_dict(cfg, sections: tuple[str, ...]) -> dict:
    """``{"name": cfg.name, section: asdict(cfg.<section>), ...}``."""
    return {"name": cfg.name, **{s: asdict(getattr(cfg, s)) for s in sections}}


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
class TrainLoopConfig:
    """The optimiser and bookkeeping fields of every baseline's ``train`` section: the
    diffusion baselines' :class:`TrainConfig` and CATMO's ``CatmoTrainConfig`` (which sets its
    own defaults of four) derive from this, each checking them with its own fields."""
    batch_size: int = 32
    lr: float = 1e-4
    weight_decay: float = 0.01
    grad_clip: float = 1.0
    min_frames: int = 8
    checkpoint_every: int = 500
    log_every: int = 50
    seed: int = 0


@dataclass(frozen=True)
class TrainConfig(TrainLoopConfig):
    steps: int = 50_000
    max_frames: int = 196
    ema_decay: float = 0.999
    lambda_contact: float = 2.0      # ChainHOI lambda_1 (L_h); 0 for EJIM
    lambda_object: float = 1.0       # ChainHOI lambda_2 / EJIM lambda_o (L_o)
    lambda_smooth: float = 0.0       # EJIM lambda_s (L_smooth); 0 for ChainHOI
    contact_points: int = 256        # GT object surface samples for L_h ("samples")
    contact_distance: str = "samples"   # L_h distance: nearest of contact_points samples | exact point-to-mesh

    def __post_init__(self) -> None:
        check_ints(self, ("steps",), "train", lo=0)
        check_ints(self, ("batch_size", "max_frames", "min_frames", "contact_points", "checkpoint_every", "log_every"),
                   "train")
        check_architecture(self, "train")
        check_interval(self, ("lr",), "train", "(0, 1)")
        check_interval(self, ("ema_decay",), "train", "[0, 1)")
        check_choice(self, "contact_distance", "train", CONTACT_DISTANCES)
        check_nonnegative(self, ("lambda_contact", "lambda_object", "lambda_smooth"), "train")


@dataclass(frozen=True)
class RunConfig:
    name: str
    model: object                   # the baseline's frozen model-config dataclass
    train: TrainConfig = field(default_factory=TrainConfig)
    diffusion: DiffusionConfig = field(default_factory=DiffusionConfig)

    def __post_init__(self) -> None:
        if not is_dataclass(self.model):
            raise ValueError(f"config.model: expected a model config dataclass, got {type(self.model).__name__}")
        check_architecture(self.model, "model")

    def to_dict(self) -> dict:
        d = sections_to_dict(self, ("model", "train", "diffusion"))
        model = d["model"]
        d["model"] = {f.name: list(model[f.name]) if isinstance(model[f.name], tuple) else model[f.name]
                      for f in own_fields_first(self.model)}
        return d

    @classmethod
    def from_dict(cls, d: dict, model_cls: type, where: str = "config") -> "RunConfig":
        kinds = {"model": model_cls, "train": TrainConfig, "diffusion": DiffusionConfig}
        return cls(**sections_from_dict(d, kinds, where, strict=False))

    def replace(self, **changes) -> "RunConfig":
        """A copy with dotted overrides, e.g. ``replace(**{"train.steps": 10, "model.mask": "released"})``."""
        return RunConfig.from_dict(dotted_replace(self.to_dict(), ("model", "train", "diffusion"), changes),
                                   type(self.model))
