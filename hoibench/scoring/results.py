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
    if result.get("kind") == "multibody":      # plain values, half-widths in ``ci95``
        problem = multibody_metrics_problem(result)
    else:
        problem = metrics_problem(result["metrics"]) or counts_problem(result.get("counts", {}), "counts")
    if problem:
        raise ResultError(f"{path}: {problem}")
    return result


def _number(v) -> bool:
    import math
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def metrics_problem(metrics: dict, prefix: str = "metrics") -> str | None:
    """What is wrong with a ``metrics`` block (``field ...: ...``), or None: each metric an
    object whose ``mean`` is a number or a non-empty list of numbers, ``ci95`` absent, null
    or of the same form, ``n`` absent, null or a whole number."""
    for name, m in metrics.items():
        at = f"field {prefix}.{name}"
        if not isinstance(m, dict):
            return f"{at}: expected an object {{\"mean\", \"ci95\", \"n\"}}, got {type(m).__name__}"
        mean, ci = m.get("mean"), m.get("ci95")
        if isinstance(mean, list):
            if not mean or not all(_number(x) for x in mean):
                return f"{at}.mean: expected a non-empty list of numbers"
            if ci is not None and not (isinstance(ci, list) and len(ci) == len(mean) and all(_number(x) for x in ci)):
                return f"{at}.ci95: expected a list of {len(mean)} numbers, like mean"
        elif not _number(mean):
            return f"{at}.mean: expected a number, got {type(mean).__name__}"
        elif ci is not None and not _number(ci):
            return f"{at}.ci95: expected a number, got {type(ci).__name__}"
        n = m.get("n")
        if n is not None and (isinstance(n, bool) or not isinstance(n, int)):
            return f"{at}.n: expected a whole number, got {type(n).__name__}"
    return None


def multibody_metrics_problem(result: dict) -> str | None:
    """What is wrong with a multi-body result's ``metrics`` (each a number, or null when
    undefined) and ``ci95`` (an object of numbers or nulls), or None."""
    ci = result.get("ci95", {})
    if not isinstance(ci, dict):
        return f"field ci95: expected an object, got {type(ci).__name__}"
    for block, values in (("metrics", result["metrics"]), ("ci95", ci)):
        for name, v in values.items():
            if v is not None and not _number(v):
                return f"field {block}.{name}: expected a number or null, got {type(v).__name__}"
    return None


def counts_problem(counts, prefix: str = "counts") -> str | None:
    """What is wrong with a ``counts`` block (or a leaderboard entry's top-level counts)."""
    if not isinstance(counts, dict):
        return f"field {prefix}: expected an object, got {type(counts).__name__}"
    for key in ("samples_per_prompt", "scored_ids", "test_ids"):
        v = counts.get(key)
        if v is not None and (isinstance(v, bool) or not isinstance(v, int) or v < 0):
            return f"field {prefix}.{key}: expected a whole number, got {v!r:.40}"
    ids = counts.get("missing_ids")
    if ids is not None and not (isinstance(ids, list) and all(isinstance(i, str) for i in ids)):
        return f"field {prefix}.missing_ids: expected a list of ids, got {type(ids).__name__}"
    return None


__all__ = ["ResultError", "read_result", "MAX_RESULT_BYTES", "metrics_problem", "multibody_metrics_problem",
           "counts_problem"]
