"""A result's per-clip data: what a paired comparison and a clip-bootstrap interval need,
kept beside the result JSON (``<result>.clips.npz``) and referenced from it by sha256.

Arrays (one ``.npz``, no pickles):

- ``ids`` (N,): the scored test ids, sorted;
- ``motion`` (K, N, D): the evaluator embedding of every generated sample; ``real`` (N, D):
  the ground truth's;
- ``text`` (M, D) and ``text_offsets`` (N + 1,): every caption embedding of clip i in
  ``text[text_offsets[i]:text_offsets[i + 1]]``;
- ``physical`` (S, N, P), ``physical_samples`` (S,), ``physical_names`` (P,): the physical
  metrics' per-clip values of each scored sample (NaN where undefined).

A multi-body result (:func:`hoibench.scoring.multibody.multibody_clip_arrays`) keeps the same
arrays with the recognizer's features as ``motion`` and ``real``, no caption embeddings
(``text`` (0, D)), every per-sample metric (CSR, CRR, CSIoU, IV, ID, RA's correctness) in
``physical``, and ``reference`` (N, P): the ground truth's per-clip values of those metrics.

The result records ``per_clip_data: {"file", "sha256", "bytes"}`` with the file's name only
(not its folder), so moving the pair of files together changes nothing in the result."""
from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

#: the suffix of the per-clip file written beside ``result.json``
SUFFIX = ".clips.npz"
#: the largest per-clip file read (10,000 clips x K = 30 x 512 float32 embeddings is 0.6 GB)
MAX_CLIP_DATA_BYTES = 1 << 30


def clip_arrays(ids: Sequence[str], motion: np.ndarray, real: np.ndarray, text_sets: Sequence[np.ndarray],
                physical: Mapping[int, Mapping[str, Mapping[str, float]]]) -> dict[str, np.ndarray]:
    """The per-clip arrays (module docstring) from a scorer's embeddings and per-clip physical rows."""
    from ..metrics.catalog import METRICS
    samples = sorted(physical)
    names = sorted({n for rows in physical.values() for row in rows.values() for n in row
                    if n in METRICS and METRICS[n].kind == "physical"})
    phys = np.full((len(samples), len(ids), len(names)), np.nan, np.float64)
    for s, k in enumerate(samples):
        for i, cid in enumerate(ids):
            row = physical[k].get(cid, {})
            phys[s, i] = [float(row.get(n, np.nan)) for n in names]
    offsets = np.cumsum([0] + [len(t) for t in text_sets]).astype(np.int64)
    return {"ids": np.array(list(ids)), "motion": np.asarray(motion, np.float32), "real": np.asarray(real, np.float32),
            "text": np.concatenate([np.asarray(t, np.float32) for t in text_sets]), "text_offsets": offsets,
            "physical": phys, "physical_samples": np.array(samples, np.int64), "physical_names": np.array(names)}


def clip_file(result_path: str | Path) -> Path:
    """Where the per-clip data of ``result_path`` goes: ``result.json`` -> ``result.clips.npz``."""
    p = Path(result_path)
    return p.with_name((p.name[:-5] if p.name.endswith(".json") else p.name) + SUFFIX)


def write_clip_data(result: dict, arrays: Mapping[str, np.ndarray], result_path: str | Path) -> Path:
    """Write ``arrays`` beside ``result_path`` (atomic, byte-reproducible) and record the file's
    name, sha256 and size in ``result["per_clip_data"]``."""
    from ..core.io import atomic_write_bytes, npz_bytes
    data = npz_bytes(dict(arrays))
    path = atomic_write_bytes(clip_file(result_path), data)
    result["per_clip_data"] = {"file": path.name, "sha256": hashlib.sha256(data).hexdigest(), "bytes": len(data)}
    return path


def read_clip_data(result: dict, result_path: str | Path) -> dict[str, np.ndarray]:
    """The per-clip arrays a result references, checked against its sha256; ValueError naming
    the file and field when absent, unreadable or changed."""
    ref = result.get("per_clip_data")
    if not isinstance(ref, dict) or not isinstance(ref.get("file"), str):
        raise ValueError(f"{result_path}: field per_clip_data: absent (scored before per-clip data was kept, or "
                         f"written without --out); evaluate the submission again with --out")
    from ..core.io import read_regular_file
    path = Path(result_path).resolve().parent / Path(ref["file"]).name
    if not path.is_file():
        raise ValueError(f"{path}: per_clip_data.file: not found; keep it beside the result")
    data = read_regular_file(path, MAX_CLIP_DATA_BYTES, "per-clip data")
    if hashlib.sha256(data).hexdigest() != ref.get("sha256"):
        raise ValueError(f"{path}: per_clip_data.sha256: the file does not match the result (changed or replaced)")
    import io
    with np.load(io.BytesIO(data), allow_pickle=False) as z:  # read-ok: hashed against the result
        return {k: z[k] for k in z.files}


__all__ = ["SUFFIX", "clip_arrays", "clip_file", "write_clip_data", "read_clip_data"]
