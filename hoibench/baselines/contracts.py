"""The written contracts of a baseline (:mod:`hoibench.baselines.registry` names each
baseline's two entry points; ``tests/test_contracts.py`` checks every registered one):

* its trainer, ``train(spec, data, out, config, *, device, resume, stop_after, threads, log)
  -> TrainResult`` (:data:`TRAINER_KEYWORDS`);
* its loaded run (the ``sample`` entry point): :class:`LoadedBaseline` for single-body
  baselines, whose samples the shared sampler (:mod:`hoibench.baselines.sampler`) writes as
  a standard submission, :class:`LoadedMultiBodyBaseline` for multi-body ones, which write
  their own multi-body submission."""
from __future__ import annotations

from typing import Any, Protocol, runtime_checkable


@runtime_checkable
class LoadedRun(Protocol):
    """A trained run, loaded and verified: ``id`` (its checkpoint id), ``spec``, ``config``,
    ``requires_object``; ``options(...)`` (its sampling options, recorded in the
    submission); ``check_store(store)`` refuses a store it cannot sample for."""

    id: str
    spec: Any
    config: Any
    requires_object: bool

    def options(self, *args, **kwargs) -> dict: ...

    def check_store(self, store) -> None: ...


@runtime_checkable
class LoadedBaseline(LoadedRun, Protocol):
    """A single-body run: ``generate_sample(caption, points, length, k, seed_parts, ...)``
    draws one sample of one prompt."""

    def generate_sample(self, *args, **kwargs) -> Any: ...


@runtime_checkable
class LoadedMultiBodyBaseline(LoadedRun, Protocol):
    """A multi-body run: ``write_store_submission(data, out, ...)`` samples a store's split."""

    def write_store_submission(self, *args, **kwargs) -> Any: ...


#: the contract of each baseline kind (a spec's ``kind``)
CONTRACTS: dict[str, Any] = {"diffusion": LoadedBaseline, "tokens": LoadedBaseline,
                             "multibody": LoadedMultiBodyBaseline}
#: what a trainer entry point accepts (keywords after the four positional arguments)
TRAINER_KEYWORDS = ("device", "resume", "stop_after", "threads", "log")

__all__ = ["LoadedRun", "LoadedBaseline", "LoadedMultiBodyBaseline", "CONTRACTS", "TRAINER_KEYWORDS"]
