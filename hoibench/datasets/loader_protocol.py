"""The contract of a raw-data loader module (what ``hoibench prepare`` calls) and a check of a
module against it.

A loader is a module with a ``prepare_jobs`` function::

    prepare_jobs(root, body_models, out, config, split_file=None, **options) -> list[tuple]

returning one :func:`hoibench.datasets.store.run_unit` job per raw sequence; ``config`` is a
:class:`hoibench.datasets.store.PrepareConfig`, ``body_models`` may be None when the loader
does not need model files, and ``options`` are the extra ``prepare`` options the loader's
catalog row names (interact: ``sources``, ``split``). The optional hooks a row names are
plain functions of the shapes :class:`DatasetNameHook`, :class:`WarningsHook` and
:class:`TextsHook`."""
from __future__ import annotations

import inspect
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

__all__ = ["DatasetLoader", "DatasetNameHook", "WarningsHook", "TextsHook", "PREPARE_JOBS_PARAMS",
           "loader_problems"]

#: the positional parameters of every ``prepare_jobs``, in order
PREPARE_JOBS_PARAMS = ("root", "body_models", "out", "config", "split_file")


@runtime_checkable
class DatasetLoader(Protocol):
    """A loader module: ``isinstance(module, DatasetLoader)`` checks that it has ``prepare_jobs``."""

    def prepare_jobs(self, root: str | Path, body_models: str | Path | None, out: str | Path, config: Any,
                     split_file: str | Path | None = None) -> list[tuple]: ...


class DatasetNameHook(Protocol):
    def __call__(self, root: str | Path) -> str: ...


class WarningsHook(Protocol):
    def __call__(self, root: str | Path, body_models: str | Path | None) -> list[str]: ...


class TextsHook(Protocol):
    def __call__(self, out: str | Path, manifest: dict) -> Any: ...


def _arity_problem(what: str, fn: Any, n: int) -> str | None:
    """None when ``fn`` takes exactly ``n`` positional arguments (others defaulted)."""
    if not callable(fn):
        return f"{what}: not callable"
    params = list(inspect.signature(fn).parameters.values())
    positional = [p for p in params if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    required = [p for p in positional if p.default is p.empty]
    if len(required) > n or len(positional) < n:
        return f"{what}: expected {n} positional parameter(s), got ({', '.join(p.name for p in params)})"
    return None


def loader_problems(loader) -> list[str]:
    """What keeps the catalog row ``loader`` (a :class:`hoibench.datasets.catalog.Loader`) from
    being run by ``prepare``: its module against :class:`DatasetLoader`, its options against
    ``prepare_jobs``'s keywords, its hooks against their shapes. Empty when it runs."""
    from ..core.registry import load_object
    module = loader.load()
    where = f"{loader.name} ({loader.module_name})"
    if not isinstance(module, DatasetLoader):
        return [f"{where}: no prepare_jobs function"]
    params = inspect.signature(module.prepare_jobs).parameters
    probs = []
    names = tuple(params)[:len(PREPARE_JOBS_PARAMS)]
    if names != PREPARE_JOBS_PARAMS:
        probs.append(f"{where}: prepare_jobs{tuple(params)}: expected the parameters {PREPARE_JOBS_PARAMS} first")
    elif params["split_file"].default is not None:
        probs.append(f"{where}: prepare_jobs: split_file must default to None")
    for option in loader.options:
        if option not in params or params[option].default is inspect.Parameter.empty:
            probs.append(f"{where}: prepare_jobs has no keyword {option!r} with a default (its row names it)")
    if loader.body_model_type not in ("smplh", "smplx"):
        probs.append(f"{where}: body_model_type {loader.body_model_type!r}: expected smplh or smplx")
    for hook, n in (("dataset_name", 1), ("warnings", 2), ("texts", 2)):
        ref = getattr(loader, hook)
        if ref is not None:
            problem = _arity_problem(f"{where}: {hook} {ref}", load_object(ref), n)
            if problem:
                probs.append(problem)
    return probs
