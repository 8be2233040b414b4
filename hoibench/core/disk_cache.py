"""Arrays kept on disk between runs: what is costly to compute, depends only on its inputs, and
is read back bit for bit (the evaluation's ground-truth statistics, the signed-distance grids
of object templates).

``<cache>/<kind>/<key>.npz``: ``key`` is a sha256 its caller computes over everything the
arrays are computed from, this toolkit's source included (:func:`code_digest`), so a changed
line of code gives new keys. Each file records its format and key; a file that cannot be read,
or records another key, is ignored (the caller recomputes); a cache that cannot be written is
skipped. Writes are atomic, so two processes writing the same entry leave one whole file.

``HOIBENCH_CACHE``: the cache folder (default ``~/.cache/hoibench``); ``off`` (or ``0``, or
empty) turns it off.
"""
from __future__ import annotations

import hashlib
import os
from functools import lru_cache
from pathlib import Path
from typing import Mapping

import numpy as np

from .io import atomic_write_bytes, load_raw_npz, npz_bytes

CACHE_ENV = "HOIBENCH_CACHE"


def cache_dir() -> Path | None:
    """The cache folder, or None when ``HOIBENCH_CACHE`` turns it off."""
    value = os.environ.get(CACHE_ENV)
    if value is not None and value.strip().lower() in ("", "0", "off", "none", "false"):
        return None
    return Path(value).expanduser() if value else Path.home() / ".cache" / "hoibench"


@lru_cache(maxsize=1)
def code_digest() -> str:
    """sha256 of the toolkit's own source files (names and bytes)."""
    package = Path(__file__).resolve().parents[1]
    h = hashlib.sha256()
    for path in sorted(package.rglob("*.py")):
        h.update(str(path.relative_to(package)).encode() + b"\0")
        h.update(path.read_bytes())       # read-ok: the package's own source, hashed
    return h.hexdigest()


def cached_path(kind: str, key: str) -> Path | None:
    """Where the entry ``key`` of ``kind`` lives; None when the cache is off."""
    root = cache_dir()
    return None if root is None else root / kind / f"{key}.npz"


def read_cached(kind: str, key: str, fmt: str, max_bytes: int) -> dict[str, np.ndarray] | None:
    """The arrays of entry ``key`` (written by :func:`write_cached` with format ``fmt``), or
    None when the cache is off, holds no such file, or the file is unreadable or another's."""
    path = cached_path(kind, key)
    if path is None or not path.is_file():
        return None
    try:
        z = load_raw_npz(path, max_bytes, f"cached {kind}")
        if str(z.pop("format")) != fmt or str(z.pop("key")) != key:
            return None
    except (KeyError, ValueError, OSError):
        return None
    return z


def write_cached(kind: str, key: str, fmt: str, arrays: Mapping[str, np.ndarray]) -> Path | None:
    """Write entry ``key`` of ``kind`` (uncompressed, atomically); None when the cache is off or
    cannot be written."""
    path = cached_path(kind, key)
    if path is None:
        return None
    try:
        return atomic_write_bytes(path, npz_bytes({"format": np.array(fmt), "key": np.array(key), **arrays},
                                                  compressed=False))
    except OSError:
        return None


__all__ = ["CACHE_ENV", "cache_dir", "code_digest", "cached_path", "read_cached", "write_cached"]
