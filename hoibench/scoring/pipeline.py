"""The scoring pipeline's stages and the scorer registry.

:func:`hoibench.scoring.evaluate.evaluate` is the one evaluation function for every track:

    store -> track (registry) -> protocol -> evaluator (backend registry) -> scorer
    scorer.prepare()                      fit checks, ground-truth statistics
    with scorer.open_submission() as sub:
        ids = scorer.validate(sub)        refusals and what is scored
        for out in map_units(scorer.unit, scorer.stream(sub, ids), executor):
            scorer.update(out)            per-clip metric states, on any executor
    rows = scorer.replications()          per-replication metric values
    result = scorer.summary(rows)         the result dict (every version recorded)

A :class:`Scorer` implements those stages for one kind of track (a track names its scorer;
:mod:`hoibench.tracks.registry`). Units are keyed and reduced in sorted order, so every
executor gives identical numbers. Adding a kind of track is one :func:`register_scorer`.
"""
from __future__ import annotations

import time
from abc import ABC, abstractmethod
from contextlib import AbstractContextManager
from typing import Any, Callable, Iterable

from ..core.registry import Registry, load_object


class EvaluationRefused(ValueError):
    """The evaluation cannot be run as asked (a protocol or evaluator that does not fit the
    store, a failed gate, nothing valid to score, an incomplete multi-body submission); the
    message names the file and field, and which override exists. Every scorer raises it."""


class Scorer(ABC):
    """The stages of one evaluation (see the module docstring): the written contract of a
    scorer. Subclasses set ``name``, ``evaluator_options`` (passed to the evaluator's loader)
    and ``map_options`` (passed to :func:`hoibench.core.parallel.map_units`), and
    ``fills_clip_data`` when it fills the per-clip arrays an evaluation asks for
    (:mod:`hoibench.scoring.clip_data`: the result then gets slices), set ``unit``
    (the picklable per-unit function) by :meth:`stream` at the latest, and implement every
    abstract stage; the result they write is ``hoibench-result-2``
    (:mod:`hoibench.scoring.results`) and :func:`hoibench.scoring.report.format_result`
    prints it."""

    name: str = ""
    evaluator_options: dict = {}
    map_options: dict = {}
    fills_clip_data: bool = False

    def __init__(self, store, protocol, evaluator, track, submission, options: dict, started: float | None = None):
        self.store, self.proto, self.ev, self.track = store, protocol, evaluator, track
        self.submission, self.options = submission, dict(options)
        self.started = time.perf_counter() if started is None else started
        self.timings: dict[str, float] = {}
        #: the open executor the units will run on (set by the evaluation before ``validate``;
        #: a scorer may start units on it early), or None
        self.pool = None

    @classmethod
    def check_fit(cls, store, protocol, card: dict, options: dict) -> None:
        """Refuse, before the evaluator is loaded, what its ``card`` (read without weights;
        ``{}`` when unknown) already shows does not fit the store or protocol."""

    @classmethod
    def warm_up(cls, store, protocol) -> tuple[Callable, tuple] | None:
        """``(fn, args)`` each pool worker runs before its first unit (building what every
        unit would otherwise build on first use: :func:`hoibench.core.parallel.warm_executor`),
        or None. It must not change any result."""
        return None

    # --- stages
    def prepare(self) -> None:
        """Checks that need no submission, and the ground truth's statistics."""

    @abstractmethod
    def open_submission(self) -> AbstractContextManager:
        raise NotImplementedError

    @abstractmethod
    def validate(self, sub) -> list[str]:
        """The test ids to score (refusing what cannot be scored)."""
        raise NotImplementedError

    @abstractmethod
    def stream(self, sub, ids: list[str]) -> Iterable:
        """The per-clip work units, read one file at a time."""
        raise NotImplementedError

    #: the per-unit function run on the executor (picklable)
    unit: Callable[[Any], Any]

    @abstractmethod
    def update(self, out) -> None:
        """Fold one unit's output into the metric states."""
        raise NotImplementedError

    @abstractmethod
    def replications(self) -> list[dict]:
        raise NotImplementedError

    @abstractmethod
    def summary(self, rows: list[dict]) -> dict:
        raise NotImplementedError


_SCORERS: Registry[str] = Registry("scorer")


def register_scorer(name: str, path: str) -> None:
    """Register a scorer class by ``"module:Class"`` (relative to this package or absolute)."""
    _SCORERS.add(name, path)


register_scorer("hoi", ".hoi:HOIScorer")
register_scorer("multibody", ".multibody:MultiBodyScorer")
register_scorer("interact-task", ".interact_task:InteractTaskScorer")


def get_scorer(name: str) -> type[Scorer]:
    return load_object(_SCORERS.get(name), __package__)


__all__ = ["Scorer", "EvaluationRefused", "register_scorer", "get_scorer"]
