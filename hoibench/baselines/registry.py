"""The baselines hoibench trains: one :class:`Spec` per baseline.

The joint-level diffusion baselines (ChainHOI, EJIM; ``kind = "diffusion"``) share the trainer
below; CATMO (``kind = "tokens"``) trains in stages (:mod:`.catmo.trainer`) and shares the run
folder and the sampler's submission path.

A spec names what differs between baselines -- the model config class, the presets, how to
build the denoiser and which losses train it -- while the trainer (:mod:`.trainer`), the run
folder (:mod:`.checkpoint`) and the sampler (:mod:`.sampler`) are shared. Every model takes
``encode_text(text, pad)``, ``encode_object(points)`` and
``forward(x_t, t, keep, text_tokens, text_pad, obj_tokens, valid) -> x0``.
"""
from __future__ import annotations

from dataclasses import dataclass
from importlib import import_module
from typing import Callable


@dataclass(frozen=True)
class Spec:
    name: str
    title: str                       # method name in submissions and tables
    module: str                      # hoibench.baselines.<module> with preset, ModelConfig, build_model, losses
    kind: str = "diffusion"          # "diffusion": the shared trainer/sampler; "tokens": CATMO's own stages

    def _mod(self):
        return import_module(f"hoibench.baselines.{self.module}")

    @property
    def preset(self) -> Callable:
        return self._mod().preset

    @property
    def model_config(self) -> type:
        return self._mod().ModelConfig

    def build_model(self, cfg, vocab: int, text_width: int):
        return self._mod().build_model(cfg, vocab, text_width)

    def losses(self, model, diffusion, batch, cfg, mean, std, generator) -> dict:
        return self._mod().losses(model, diffusion, batch, cfg, mean, std, generator)


SPECS: dict[str, Spec] = {
    "chainhoi": Spec("chainhoi", "ChainHOI", "chainhoi.spec"),
    "ejim": Spec("ejim", "EJIM", "ejim.spec"),
    "catmo": Spec("catmo", "CATMO", "catmo.config", kind="tokens"),
}


def get_spec(name: str) -> Spec:
    try:
        return SPECS[name]
    except KeyError:
        raise ValueError(f"unknown baseline {name!r}; choose one of {', '.join(sorted(SPECS))}") from None
