"""Leaderboard entries (DESIGN section 11): one strict-JSON file per method and track.

``leaderboards/<track>/entries/<slug>.json`` holds what a reader needs to compare a row:
method, source (``reproduced`` by hoibench from a submission it scored, or ``reported`` in
a paper), metrics with 95% CIs, evaluator id, protocol id and version, representation and
toolkit versions, sample counts and missing ids, flags, whether the result was complete,
which metrics were undefined, and where the submission came from (for a baseline: its
checkpoint id and config). Rendering the tables (``hoibench leaderboard build``) reads these.
"""
from __future__ import annotations

import re
from pathlib import Path

from .io import atomic_write_json

ENTRY_FORMAT = "hoibench-entry-1"
SOURCES = ("reproduced", "reported")


def slug(method: str) -> str:
    """File name of an entry: lower-case letters, digits and '-' (``"ChainHOI (tiny)"`` ->
    ``chainhoi-tiny``)."""
    s = re.sub(r"[^a-z0-9]+", "-", method.lower()).strip("-")
    if not s:
        raise ValueError(f"method {method!r}: no letters or digits to name its entry")
    return s[:100]


def entry_from_result(result: dict, *, method: str, track: str, source: str = "reproduced",
                      submission_meta: dict | None = None, notes: str = "") -> dict:
    """An entry for a result of ``hoibench evaluate`` (``submission_meta``: the submission's
    ``submission.json``, for its ``source`` block)."""
    if source not in SOURCES:
        raise ValueError(f"source: expected one of {SOURCES}, got {source!r}")
    counts = result.get("counts", {})
    metrics = {k: {"mean": v["mean"], "ci95": v["ci95"], "n": v.get("n")}
               for k, v in sorted(result.get("metrics", {}).items())}
    return {
        "format": ENTRY_FORMAT, "track": track, "method": method, "source": source,
        "metrics": metrics, "undefined_metrics": result.get("undefined_metrics", {}),
        "evaluator_id": result.get("evaluator_id"), "protocol": result.get("protocol"),
        "protocol_version": result.get("protocol_version"), "representation": result.get("representation"),
        "toolkit_version": result.get("toolkit_version"), "replications": result.get("replications"),
        "samples_per_prompt": counts.get("samples_per_prompt"), "scored_ids": counts.get("scored_ids"),
        "test_ids": counts.get("test_ids"), "missing_ids": counts.get("missing_ids", []),
        "flags": result.get("submission", {}).get("flags", {}), "complete": bool(result.get("complete")),
        "overrides": result.get("overrides", []),
        "submission_source": (submission_meta or {}).get("source", {}), "notes": notes,
    }


def write_entry(entry: dict, entries_dir: str | Path) -> Path:
    """Write ``entries_dir/<slug(method)>.json`` atomically (strict JSON, sorted keys)."""
    return atomic_write_json(Path(entries_dir) / f"{slug(entry['method'])}.json", entry)
