"""What validation read and encoded, kept for scoring: each sample file is read and encoded
once per evaluation (``hoibench evaluate`` validates, then scores the same files).

:class:`ReadCache` holds the arrays of the files that validated and the features each of
their samples encoded to, within a byte budget (:data:`DEFAULT_BUDGET_BYTES`); what does
not fit is read and encoded again when scored, with the same result."""
from __future__ import annotations

from typing import Callable, Iterable, Mapping

import numpy as np

#: the most bytes of arrays and features kept between validation and scoring
DEFAULT_BUDGET_BYTES = 1 << 30


class ReadCache:
    """Arrays by id and encoded features by (id, sample), each taken once (:meth:`take_arrays`,
    :meth:`take_features`): an entry is dropped when scoring uses it. ``on_keep(sid, arrays)``
    is called with each file's arrays as they are kept (the scorer starts work on them)."""

    def __init__(self, budget_bytes: int = DEFAULT_BUDGET_BYTES,
                 on_keep: Callable[[str, dict[str, np.ndarray]], None] | None = None):
        self.budget = int(budget_bytes)
        self.on_keep = on_keep
        self.used = 0
        self.arrays: dict[str, dict[str, np.ndarray]] = {}
        self.encoded: dict[tuple[str, int], np.ndarray] = {}
        self.hits = self.misses = 0

    def _fits(self, nbytes: int) -> bool:
        if self.used + nbytes > self.budget:
            return False
        self.used += nbytes
        return True

    def keep_arrays(self, sid: str, arrays: Mapping[str, np.ndarray]) -> None:
        """Keep the arrays of ``sid`` (within the budget); ``on_keep(sid, arrays)`` then sees them."""
        if self._fits(sum(int(a.nbytes) for a in arrays.values())):
            self.arrays[sid] = dict(arrays)
            if self.on_keep is not None:
                self.on_keep(sid, self.arrays[sid])

    def keep_features(self, key: tuple[str, int], feats: np.ndarray) -> None:
        if self._fits(int(feats.nbytes)):
            self.encoded[key] = feats

    def take_arrays(self, sid: str, keys: Iterable[str] | None = None) -> dict[str, np.ndarray] | None:
        """The kept arrays of ``sid`` (only ``keys`` when given), or None."""
        got = self.arrays.pop(sid, None)
        if got is None:
            self.misses += 1
            return None
        self.used -= sum(int(a.nbytes) for a in got.values())
        self.hits += 1
        return got if keys is None else {k: v for k, v in got.items() if k in set(keys)}

    def drop(self, sid: str) -> None:
        """Forget the arrays and features of ``sid`` (a file found invalid after it was kept)."""
        got = self.arrays.pop(sid, None)
        if got is not None:
            self.used -= sum(int(a.nbytes) for a in got.values())
        for key in [key for key in self.encoded if key[0] == sid]:
            self.used -= int(self.encoded.pop(key).nbytes)

    def take_features(self, sid: str, k: int) -> np.ndarray | None:
        got = self.encoded.pop((sid, k), None)
        if got is not None:
            self.used -= int(got.nbytes)
        return got


class _FeatureSink(dict):
    """The ``encoded`` mapping validation writes into: forwards to the cache's budget."""

    def __init__(self, cache: ReadCache):
        super().__init__()
        self.cache = cache

    def __setitem__(self, key, value) -> None:
        self.cache.keep_features(key, value)


def feature_sink(cache: ReadCache | None) -> dict | None:
    """The mapping a :class:`~hoibench.scoring.validate_arrays.ClipContext` keeps features in."""
    return None if cache is None else _FeatureSink(cache)


__all__ = ["ReadCache", "DEFAULT_BUDGET_BYTES", "feature_sink"]
