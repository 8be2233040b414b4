"""The baselines hoibench trains: one :class:`Spec` per baseline.

The joint-level diffusion baselines (ChainHOI, EJIM; ``kind = "diffusion"``) share the trainer
(:func:`.trainer.train_joint`) and the run loader (:class:`.sampler.LoadedRun`); CATMO
(``kind = "tokens"``) trains in stages (:mod:`.catmo.trainer`) and loads its own run
(:class:`.catmo.sampler.LoadedCatmo`), sharing the run folder and the sampler's submission path;
SyncDiff (``kind = "multibody"``) trains on multi-body stores (:mod:`.syncdiff.trainer`) and
writes multi-body submissions (:class:`.syncdiff.sampler.LoadedSyncDiff`).
A spec names both entry points (``train``, ``sample``: ``"<module>:<name>"`` under
``hoibench.baselines``), so :func:`.trainer.train` and :func:`.sampler.load_run` dispatch through
this registry and import no model package:

- ``train(spec, data, out, config, *, device, resume, stop_after, threads, log)`` -> ``TrainResult``
- ``sample(folder, device, verified=(card, weights bytes))`` -> a loaded run (``options``,
  ``generate_sample``, ``check_store``, ``spec``, ``config``, ``id``, ``requires_object``,
  ``object_points``)

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
    train: str = "trainer:train_joint"          # train entry point, "<module>:<name>" under hoibench.baselines
    sample: str = "sampler:LoadedRun"           # run loader (sample entry point), same form

    def _mod(self):
        return import_module(f"hoibench.baselines.{self.module}")

    def entry_point(self, which: str) -> Callable:
        """The callable the spec names for ``which`` (``"train"`` or ``"sample"``), imported on first use."""
        if which not in ("train", "sample"):
            raise ValueError(f"entry point {which!r}: expected 'train' or 'sample'")
        module, _, name = getattr(self, which).partition(":")
        return getattr(import_module(f"hoibench.baselines.{module}"), name)

    @property
    def preset(self) -> Callable:
        return self._mod().preset

    @property
    def model_config(self) -> type:
        return self._mod().ModelConfig

    def config_class(self, config: dict) -> type:
        """The model-config class of a run card's ``config`` (a baseline with several config
        families, such as ChainHOI ``released``, names it through ``config_class``)."""
        chooser = getattr(self._mod(), "config_class", None)
        return chooser(config) if chooser is not None else self.model_config

    def build_model(self, cfg, vocab: int, text_width: int):
        return self._mod().build_model(cfg, vocab, text_width)

    def losses(self, model, diffusion, batch, cfg, mean, std, generator) -> dict:
        return self._mod().losses(model, diffusion, batch, cfg, mean, std, generator)


SPECS: dict[str, Spec] = {
    "chainhoi": Spec("chainhoi", "ChainHOI", "chainhoi.spec"),
    "ejim": Spec("ejim", "EJIM", "ejim.spec"),
    "catmo": Spec("catmo", "CATMO", "catmo.config", kind="tokens", train="catmo.trainer:train_baseline",
                  sample="catmo.sampler:LoadedCatmo"),
    "syncdiff": Spec("syncdiff", "SyncDiff", "syncdiff.config", kind="multibody",
                     train="syncdiff.trainer:train_syncdiff", sample="syncdiff.sampler:LoadedSyncDiff"),
}


def get_spec(name: str) -> Spec:
    try:
        return SPECS[name]
    except KeyError:
        raise ValueError(f"unknown baseline {name!r}; choose one of {', '.join(sorted(SPECS))}") from None
