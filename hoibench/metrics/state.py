"""Mergeable metric state, torchmetrics-style: declare state once, update per batch or clip,
merge shards, compute at the end.

Every stateful metric in :mod:`hoibench.metrics` derives from :class:`Metric` and declares
its state with :meth:`Metric.add_state`:

* ``reduce="sum"``: numbers or float64/int64 arrays added on merge (FID's ``n``, sums and
  sums of outer products). Float sums merge exactly in exact arithmetic; in float64 the
  result depends on the order of additions at the level of rounding (~1e-16 relative).
* ``reduce="keyed"``: a dict ``key -> value`` (per pool, per clip, per text). Shards must hold
  disjoint keys (a key seen twice raises ``ValueError``); :meth:`Metric.compute` reduces the
  values **in sorted key order**, so serial, sharded, process-pool and Dask runs give
  bit-identical numbers whatever the order in which units finished.
* ``reduce="max"``: elementwise maximum.

Usage::

    shards = [FID(num_features=512) for _ in range(4)]      # one per worker
    ...                                                    # shard.update(...)
    total = Metric.merged(shards)                          # == one metric fed everything
    total.compute()
"""
from __future__ import annotations

import copy
from typing import Any, ClassVar, Iterable

import numpy as np

REDUCTIONS: tuple[str, ...] = ("sum", "keyed", "max")


class Metric:
    """Base class: declared, mergeable state plus metadata.

    ``name`` is the metric's key in the catalogue (:mod:`hoibench.metrics.catalog`), which
    holds its unit, direction and the rest of its metadata (:attr:`info`).
    """

    name: ClassVar[str] = ""

    @property
    def info(self):
        """The catalogue entry of :attr:`name` (KeyError naming the known metrics)."""
        from .catalog import get_metric_info
        return get_metric_info(self.name)

    def __init__(self) -> None:
        self._defaults: dict[str, Any] = {}
        self._reductions: dict[str, str] = {}

    # -------------------------------------------------------------- declaration
    def add_state(self, name: str, default: Any, reduce: str) -> None:
        """Declare a state variable ``name`` with its initial value and merge rule."""
        if reduce not in REDUCTIONS:
            raise ValueError(f"reduce: expected one of {REDUCTIONS}, got {reduce!r}")
        if reduce == "keyed" and not isinstance(default, dict):
            raise ValueError(f"default: a keyed state needs a dict default, got {type(default).__name__}")
        self._defaults[name] = copy.deepcopy(default)
        self._reductions[name] = reduce
        setattr(self, name, copy.deepcopy(default))

    def config(self) -> dict:
        """Hyper-parameters that must agree for two metrics to merge (override)."""
        return {}

    # -------------------------------------------------------------- lifecycle
    def update(self, *args, **kwargs) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def compute(self, *args, **kwargs):  # pragma: no cover - abstract
        raise NotImplementedError

    def reset(self) -> None:
        for name, default in self._defaults.items():
            setattr(self, name, copy.deepcopy(default))

    def state_dict(self) -> dict[str, Any]:
        """A deep copy of the state (picklable; what a worker sends back)."""
        return {name: copy.deepcopy(getattr(self, name)) for name in self._defaults}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        missing = set(self._defaults) - set(state)
        if missing:
            raise ValueError(f"state: missing {sorted(missing)}")
        for name in self._defaults:
            setattr(self, name, copy.deepcopy(state[name]))

    def merge(self, *others: "Metric") -> "Metric":
        """Fold the state of ``others`` into this metric (in place); returns ``self``."""
        for other in others:
            if type(other) is not type(self):
                raise ValueError(f"merge: cannot merge {type(other).__name__} into {type(self).__name__}")
            if other.config() != self.config():
                raise ValueError(f"merge: configurations differ: {self.config()} vs {other.config()}")
            for name, how in self._reductions.items():
                mine, theirs = getattr(self, name), getattr(other, name)
                if how == "sum":
                    setattr(self, name, _add(mine, theirs))
                elif how == "max":
                    setattr(self, name, np.maximum(mine, theirs) if isinstance(mine, np.ndarray)
                            else max(mine, theirs))
                else:
                    dup = sorted(set(mine) & set(theirs), key=str)
                    if dup:
                        raise ValueError(f"merge: state {name!r} has key {dup[0]!r} in two shards "
                                         f"({len(dup)} duplicate key(s)); each unit must be counted once")
                    merged = dict(mine)
                    merged.update(copy.deepcopy(theirs))
                    setattr(self, name, merged)
        return self

    @classmethod
    def merged(cls, metrics: Iterable["Metric"]) -> "Metric":
        """A new metric holding the merged state of ``metrics`` (all of one class)."""
        items = list(metrics)
        if not items:
            raise ValueError("metrics: need at least one metric to merge")
        out = copy.deepcopy(items[0])
        return out.merge(*items[1:])

    def __repr__(self) -> str:
        return f"{type(self).__name__}({', '.join(f'{k}={v!r}' for k, v in self.config().items())})"


def _add(a, b):
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.asarray(a) + np.asarray(b)
    return a + b


def sorted_items(state: dict) -> list[tuple[Any, Any]]:
    """Items of a keyed state in the canonical (sorted) key order used by ``compute``."""
    return [(k, state[k]) for k in sorted(state, key=_sort_key)]


def _sort_key(k):
    # keys may be str, int or tuples of them; compare as (type name, value) to never mix types
    if isinstance(k, tuple):
        return tuple(_sort_key(x) for x in k)
    return (type(k).__name__, k)
