"""The result format, ``hoibench-result-2``: what ``hoibench evaluate --out`` writes for every
track, and the one function that reads older results into it.

One schema for every track kind (docs/protocol.md, "Result files"):

- ``format``: :data:`RESULT_FORMAT`; ``kind``: the track's scorer (``hoi``, ``multibody``:
  informative only, no reader branches on it);
- ``metrics``: ``{name: {"mean", "ci95", "n", "unit", "direction", "interval"}}``: the mean,
  the half-width of its 95% interval (null where none exists), the number of values the
  interval is over, unit and direction from the metric catalogue
  (:mod:`hoibench.metrics.catalog`), and what the interval is over (:data:`INTERVALS`);
- ``evaluator_id`` and ``evaluator_backend`` (``contrastive``, ``recognizer``, ``t2m``, ...);
- ``counts``: ``test_ids``, ``scored_ids``, ``samples_per_prompt``, ``missing_ids``;
- ``undefined_metrics``, ``notes``, ``complete`` and the protocol header.

Older results are read through :func:`upgrade_result`: single-body results before 0.8.0
(no ``format`` field, metrics ``{mean, ci95, n}``) and multi-body ones (plain values, a
separate ``ci95`` block, ``recognizer_id``).
"""
from __future__ import annotations

import math
from pathlib import Path

from ..metrics.catalog import METRICS

RESULT_FORMAT = "hoibench-result-2"
#: what a metric's 95% interval is over: the protocol's replications, the scored test clips
#: (a clip bootstrap or a normal interval over per-clip values), the scored samples, or nothing
INTERVALS = ("replications", "clips", "samples", "none")
#: the largest result file read (a result with per-replication rows is a few hundred KB)
MAX_RESULT_BYTES = 64 << 20


class ResultError(ValueError):
    """A file that is not a readable result; the message names the file and field."""


def metric_entry(name: str, mean, ci95=None, n: int | None = None, interval: str = "replications",
                 **extra) -> dict:
    """One ``metrics`` block: the values plus the catalogue's unit and direction (``extra``:
    further fields, e.g. ``std``)."""
    if interval not in INTERVALS:
        raise ValueError(f"interval: expected one of {INTERVALS}, got {interval!r}")
    info = METRICS.get(name)
    return {"mean": mean, "ci95": ci95, "n": n, "unit": info.unit if info else None,
            "direction": info.direction if info else None, "interval": interval if ci95 is not None else "none",
            **extra}


def half_width_95(values) -> float | None:
    """Half-width of the 95% normal interval of a mean, ``1.96 * std / sqrt(n)`` (population
    std); None for fewer than 2 values."""
    import numpy as np
    v = np.asarray(values, np.float64)
    return float(1.96 * v.std() / np.sqrt(len(v))) if len(v) >= 2 else None


def upgrade_result(result: dict) -> dict:
    """``result`` in :data:`RESULT_FORMAT` (a new dict; a current result is returned as it is).
    Numbers are never changed: only the layout of the metrics, counts and evaluator fields."""
    if result.get("format") == RESULT_FORMAT:
        return result
    out = dict(result)
    out["format"] = RESULT_FORMAT
    if result.get("kind") == "multibody":           # plain values, half-widths in ``ci95``
        ci = result.get("ci95") or {}
        counts = result.get("counts") or {}
        samples = counts.get("samples")
        out["metrics"] = {k: metric_entry(k, v, ci.get(k), samples, "samples")
                          for k, v in result.get("metrics", {}).items() if v is not None}
        out.pop("ci95", None)
        out["evaluator_id"] = result.get("recognizer_id")
        out["evaluator_backend"] = "recognizer"
        out["counts"] = {"test_ids": counts.get("clips"), "scored_ids": counts.get("clips"),
                         "samples_per_prompt": (result.get("protocol_settings") or {}).get("samples_per_prompt"),
                         "samples": samples, "missing_ids": []}
        return out
    out.setdefault("kind", "hoi")
    out["metrics"] = {k: metric_entry(k, m.get("mean"), m.get("ci95"), m.get("n"), "replications",
                                      **{f: m[f] for f in ("std",) if f in m}) if isinstance(m, dict) else m
                      for k, m in result.get("metrics", {}).items()}
    if result.get("evaluator_id"):
        out.setdefault("evaluator_backend", "contrastive")
    return out


def read_result(path: str | Path) -> dict:
    """A result of ``hoibench evaluate`` in :data:`RESULT_FORMAT` (older ones upgraded), or
    :class:`ResultError` naming the file and field."""
    from ..core.io import load_json_bytes, read_regular_file
    path = Path(path)
    try:
        result = load_json_bytes(read_regular_file(path, MAX_RESULT_BYTES, "result"), path)
    except ValueError as exc:
        raise ResultError(str(exc)) from None
    if not isinstance(result, dict) or not isinstance(result.get("metrics"), dict):
        raise ResultError(f"{path}: field metrics: not a result of `hoibench evaluate`")
    problem = (multibody_metrics_problem(result) if result.get("kind") == "multibody"
               and result.get("format") != RESULT_FORMAT else None)
    if problem:
        raise ResultError(f"{path}: {problem}")
    result = upgrade_result(result)
    problem = metrics_problem(result["metrics"]) or counts_problem(result.get("counts", {}), "counts")
    if problem:
        raise ResultError(f"{path}: {problem}")
    return result


def _number(v) -> bool:
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
        if m.get("interval", "none") not in INTERVALS:
            return f"{at}.interval: expected one of {', '.join(INTERVALS)}, got {m.get('interval')!r:.40}"
    return None


def multibody_metrics_problem(result: dict) -> str | None:
    """What is wrong with a pre-0.8.0 multi-body result's ``metrics`` (each a number, or null
    when undefined) and ``ci95`` (an object of numbers or nulls), or None."""
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


__all__ = ["RESULT_FORMAT", "INTERVALS", "ResultError", "read_result", "upgrade_result", "metric_entry",
           "half_width_95", "MAX_RESULT_BYTES", "metrics_problem", "multibody_metrics_problem", "counts_problem"]
