"""Random streams of the audit corruptions: stable integer keys and one numpy stream per
(seed, family, severity index, clip), so a corrupted clip never depends on the order of the
clips or on how many workers corrupt them.

Keys are the first 8 bytes of ``sha256(text)`` read big-endian (never Python's ``hash``,
which changes between runs). A clip is keyed by its id, not its position in a list.
"""
from __future__ import annotations

import hashlib
import math
from typing import Iterable

import numpy as np

#: the severity slot of the selection stream (no severity's index): selections are nested
SELECTION_SLOT = 2 ** 32


def stable_key(text: str) -> int:
    """``int.from_bytes(sha256(text)[:8], "big")``: a 64-bit key that is the same everywhere."""
    if not isinstance(text, str):
        raise ValueError(f"text: expected a string, got {type(text).__name__}")
    return int.from_bytes(hashlib.sha256(text.encode("utf-8")).digest()[:8], "big")


def check_seed(seed) -> int:
    """``seed`` as a non-negative int (ValueError naming ``seed`` otherwise)."""
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed: expected a non-negative integer, got {seed!r}")
    return int(seed)


def clip_stream(seed: int, family: str, severity_index: int, clip_id: str) -> np.random.Generator:
    """The generator of one (family, severity, clip): ``default_rng(SeedSequence([seed,
    stable_key(family), severity_index, stable_key(clip_id)]))``."""
    if isinstance(severity_index, bool) or not isinstance(severity_index, (int, np.integer)) or severity_index < 0:
        raise ValueError(f"severity_index: expected a non-negative integer, got {severity_index!r}")
    entropy = [check_seed(seed), stable_key(family), int(severity_index), stable_key(clip_id)]
    return np.random.default_rng(np.random.SeedSequence(entropy))


def selection_order(seed: int, family: str, clip_ids: Iterable[str]) -> list[str]:
    """``clip_ids`` sorted by one uniform key each, drawn from the stream of the
    (seed, family, :data:`SELECTION_SLOT`, clip) -- no severity in it, so the clips a fraction
    ``s`` selects (the first :func:`fraction_count` of this order) are a subset of those a
    larger fraction selects. Ties (never in practice) break by id."""
    ids = list(clip_ids)
    if len(set(ids)) != len(ids):
        raise ValueError("clip_ids: an id appears twice")
    keys = {c: float(clip_stream(seed, family, SELECTION_SLOT, c).random()) for c in ids}
    return sorted(ids, key=lambda c: (keys[c], c))


def fraction_count(fraction: float, n: int) -> int:
    """How many of ``n`` clips a ``fraction`` selects: ``floor(fraction * n + 0.5)``."""
    return int(math.floor(float(fraction) * n + 0.5))


def selected(clip_ids: Iterable[str], fraction: float, seed: int, family: str, minimum: int = 0) -> list[str]:
    """The clips a ``fraction`` of the split selects: the first ``fraction_count(fraction, n)``
    of :func:`selection_order` (at least ``minimum`` when ``fraction > 0`` and there are that
    many clips), in that order."""
    order = selection_order(seed, family, clip_ids)
    n = fraction_count(fraction, len(order))
    if fraction > 0 and len(order) >= minimum:
        n = max(n, minimum)
    return order[:n]
