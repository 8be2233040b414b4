"""Atomic file writes: write to a temporary file in the target folder, then rename.

A crash never leaves a half-written file under the final name, so interrupted runs can
resume by checking which outputs exist.
"""
from __future__ import annotations

import io
import json
import os
import tempfile
import zipfile
from pathlib import Path

import numpy as np


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    return atomic_write_bytes(path, text.encode("utf-8"))


def strict_json_dumps(obj, **kwargs) -> str:
    """``json.dumps`` that refuses NaN and infinities (``allow_nan=False``): the JSON
    standard has no such tokens, and a number that is not finite must be caught where it
    is made, not written as ``NaN``/``Infinity`` for another tool to choke on."""
    try:
        return json.dumps(obj, allow_nan=False, **kwargs)
    except ValueError as e:
        raise ValueError(f"refusing to write JSON with a non-finite number ({e}): {_first_nonfinite(obj)}") from None


def _first_nonfinite(obj, path: str = "$") -> str:
    """Where the first NaN/inf sits in a JSON-like object (for the error message)."""
    import math
    if isinstance(obj, float) and not math.isfinite(obj):
        return f"{path} = {obj}"
    if isinstance(obj, dict):
        for k, v in obj.items():
            hit = _first_nonfinite(v, f"{path}.{k}")
            if hit:
                return hit
    elif isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            hit = _first_nonfinite(v, f"{path}[{i}]")
            if hit:
                return hit
    return ""


def atomic_write_json(path: str | os.PathLike, obj) -> Path:
    """Write ``obj`` as strict JSON (no NaN/Infinity tokens), atomically."""
    return atomic_write_text(path, strict_json_dumps(obj, indent=2, sort_keys=True) + "\n")


def atomic_save_npy(path: str | os.PathLike, array: np.ndarray) -> Path:
    buf = io.BytesIO()
    np.save(buf, np.asarray(array), allow_pickle=False)
    return atomic_write_bytes(path, buf.getvalue())


def npz_bytes(arrays: dict[str, np.ndarray], compressed: bool = True) -> bytes:
    """A byte-reproducible .npz: members in the given order, fixed 1980-01-01 timestamps
    (``numpy.savez`` stamps the current time, so its bytes change from run to run), no
    pickled objects (``np.load(..., allow_pickle=False)`` reads it)."""
    buf = io.BytesIO()
    method = zipfile.ZIP_DEFLATED if compressed else zipfile.ZIP_STORED
    with zipfile.ZipFile(buf, "w", compression=method) as zf:
        for name, value in arrays.items():
            member = io.BytesIO()
            np.save(member, np.asarray(value), allow_pickle=False)
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = method
            info.external_attr = 0o644 << 16
            zf.writestr(info, member.getvalue())
    return buf.getvalue()


def atomic_save_npz(path: str | os.PathLike, compressed: bool = True, **arrays) -> Path:
    """Write :func:`npz_bytes` atomically."""
    return atomic_write_bytes(path, npz_bytes(arrays, compressed))
