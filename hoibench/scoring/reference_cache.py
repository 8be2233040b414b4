"""The ground truth's statistics of an evaluation, kept on disk between evaluations.

Every ``hoibench evaluate`` of a single-body store starts by embedding the test split's
ground-truth clips and captions and measuring the evaluator's sanity gate on them (about 10 s
for 1,000 clips of 196 frames on 2 cores). They depend only on the store, the evaluator, the
protocol and the toolkit, so, like clean-fid's reference statistics, they are computed once
and read back afterwards: ``<cache>/reference/<key>.npz`` holds the ground-truth embeddings,
the caption embeddings of every test clip and the gate record.

The key (sha256) covers everything the statistics are computed from: the toolkit version and
its source files' bytes, the store's manifest sha256, each scored test clip's id, file size
and modification time, its caption lines (text and tokens), the evaluator id (its weights and
card), the protocol's sha256, the representation mode and frame rate. Anything else changing
gives another key. An evaluator without a verified content id (one built in memory) is never
cached. A cached file holds the very arrays a fresh computation gives (float32 embeddings saved
losslessly, the gate as the same JSON), so results are byte-identical with or without it
(tested). A file that cannot be read is ignored and recomputed; a cache that cannot be
written is skipped.

``HOIBENCH_CACHE``: the cache folder (default ``~/.cache/hoibench``; :mod:`hoibench.core.disk_cache`);
``off`` (or ``0``, or empty) turns it off.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from .. import __version__
from ..core.disk_cache import code_digest, read_cached, write_cached

KIND = "reference"
FORMAT = "hoibench-reference-1"
#: a cached file is read within this size (1,000 clips x 512 floats x a few captions is ~10 MB)
MAX_BYTES = 1 << 30


def reference_key(store, protocol, evaluator_id: str, test_ids: Sequence[str], lines: Mapping[str, Sequence],
                  mode: str, fps: float) -> str:
    """sha256 of everything the ground truth's statistics are computed from (module docstring)."""
    h = hashlib.sha256(json.dumps({"format": FORMAT, "toolkit": __version__, "code": code_digest(),
                                   "store": store.manifest_sha256(),
                                   "protocol": protocol.sha256, "evaluator": str(evaluator_id), "mode": mode,
                                   "fps": float(fps)}, sort_keys=True).encode())
    for cid in test_ids:
        try:
            st = (Path(store.root) / "clips" / f"{cid}.npz").stat()
            stamp = f"{st.st_size}:{st.st_mtime_ns}"
        except OSError:
            stamp = "-"
        h.update(f"{cid}\0{stamp}\0".encode())
        h.update(repr([(c.text, tuple(c.tokens or ())) for c in lines[cid]]).encode())
    return h.hexdigest()


def load_reference(key: str, n_clips: int) -> tuple[np.ndarray, list[np.ndarray], dict] | None:
    """``(real embeddings (N, D), caption embeddings per clip, gate record)`` of ``key``, or
    None when the cache is off, has no such file, or the file is not one it wrote for N clips."""
    z = read_cached(KIND, key, FORMAT, MAX_BYTES)
    if z is None:
        return None
    try:
        real, captions, counts = z["real"], z["captions"], z["caption_counts"]
        gate = json.loads(str(z["gate"]))   # read-ok: a member of the npz read through load_raw_npz
    except (KeyError, ValueError, TypeError):
        return None
    if len(real) != n_clips or len(counts) != n_clips or int(counts.sum()) != len(captions):
        return None
    sets = np.split(captions, np.cumsum(counts)[:-1]) if n_clips else []
    return real, [np.ascontiguousarray(s) for s in sets], gate


def save_reference(key: str, real: np.ndarray, sets: Sequence[np.ndarray], gate: dict) -> Path | None:
    """Write the statistics of ``key`` (atomically); None when the cache is off or cannot be written."""
    try:
        record = json.dumps(gate, sort_keys=True, allow_nan=True)
    except (TypeError, ValueError):          # a record JSON cannot hold exactly: not cached
        return None
    arrays = {"real": np.asarray(real),
              "captions": np.concatenate([np.asarray(s) for s in sets]) if len(sets) else np.zeros((0, real.shape[1]),
                                                                                                   real.dtype),
              "caption_counts": np.array([len(s) for s in sets], np.int64), "gate": np.array(record)}
    return write_cached(KIND, key, FORMAT, arrays)


__all__ = ["reference_key", "load_reference", "save_reference"]
