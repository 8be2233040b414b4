"""Reading result files (what ``hoibench evaluate --out`` writes), for comparing and publishing."""
from __future__ import annotations

from pathlib import Path

#: the largest result file read (a result with per-replication rows is a few hundred KB)
MAX_RESULT_BYTES = 64 << 20


class ResultError(ValueError):
    """A file that is not a readable result; the message names the file and field."""


def read_result(path: str | Path) -> dict:
    """A result of ``hoibench evaluate`` (strict JSON with a ``metrics`` object), or
    :class:`ResultError` naming the file and field."""
    from ..core.io import load_json_bytes, read_regular_file
    path = Path(path)
    try:
        result = load_json_bytes(read_regular_file(path, MAX_RESULT_BYTES, "result"), path)
    except ValueError as exc:
        raise ResultError(str(exc)) from None
    if not isinstance(result, dict) or not isinstance(result.get("metrics"), dict):
        raise ResultError(f"{path}: field metrics: not a result of `hoibench evaluate`")
    return result


__all__ = ["ResultError", "read_result", "MAX_RESULT_BYTES"]
