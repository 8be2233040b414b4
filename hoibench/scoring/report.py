"""A result as text (what ``hoibench evaluate`` prints), for every track kind.

Metrics are grouped by the catalogue's display groups (:mod:`hoibench.metrics.catalog`:
semantic, physical, extras), each with its direction (↑ higher is better, ↓ lower, ≈GT
closest to the ground truth), its 95% interval and what the interval is over, its unit, and
the ground truth's own value where the result records one. Counts, undefined metrics,
overrides and notes follow. A tiny negative FID shows as 0 (one rule,
:func:`hoibench.metrics.catalog.shown_value`); the JSON keeps the raw value.
"""
from __future__ import annotations

from ..metrics.catalog import GROUPS, METRICS, shown_value
from .results import upgrade_result

#: what the ± of a printed row is over
_OVER = {"replications": "reps", "clips": "clips", "samples": "samples", "none": ""}


def _scalar(m: dict) -> tuple[float, float | None]:
    mean, ci = m["mean"], m.get("ci95")
    if isinstance(mean, list):
        mean, ci = mean[0], (ci[0] if isinstance(ci, list) else ci)
    return float(mean), (None if ci is None else float(ci))


def _row(name: str, m: dict, gt) -> str:
    mean, ci = _scalar(m)
    info = METRICS.get(name)
    arrow, unit = (info.arrow, info.unit) if info else ("", m.get("unit") or "")
    spread = "" if ci is None else f"± {ci:<10.3g}"
    over = _OVER.get(m.get("interval") or "none", "")
    gt_text = "" if gt is None else f"  (GT {shown_value(name, float(gt)):.5g})"
    return (f"  {name:26s} {arrow:>3s} {shown_value(name, mean):12.5g} {spread:12s} {over:7s} {unit}"
            f"{gt_text}").rstrip()


def _header(result: dict) -> str:
    state = "complete" if result.get("complete") else "INCOMPLETE"
    c = result.get("counts") or {}
    method = (result.get("submission") or {}).get("method")
    lead = f"{method}  " if method else ""
    backend = result.get("evaluator_backend")
    return (f"{lead}{result.get('protocol')}@{result.get('protocol_version')}  evaluator "
            f"{str(result.get('evaluator_id'))[:12]}{f' ({backend})' if backend else ''}  {state}  "
            f"({c.get('scored_ids')}/{c.get('test_ids')} ids, K={c.get('samples_per_prompt')})")


def format_result(result: dict) -> str:
    """The result as a reader wants it (module docstring)."""
    result = upgrade_result(result)
    metrics = result["metrics"]
    gt = result.get("ground_truth") or {}
    lines = [_header(result)]
    if result.get("protocol_preview"):
        lines.append("preview protocol: scored only when named with its version; its numbers are not the track's")
    shown = set()
    for group in GROUPS:
        rows = [n for n, i in METRICS.items() if i.group == group and n in metrics and i.kind != "count"]
        if not rows:
            continue
        lines.append(f"{group}:")
        for name in rows:
            lines.append(_row(name, metrics[name], gt.get(name)))
            shown.add(name)
    counts = [n for n in metrics if n not in shown and METRICS.get(n) is not None and METRICS[n].kind == "count"]
    for name in (n for n in metrics if n not in shown and n not in counts):
        lines.append(_row(name, metrics[name], gt.get(name)))
    if counts:
        lines.append("counts: " + ", ".join(f"{n} {metrics[n]['mean']:g}" for n in counts))
    if (result.get("counts") or {}).get("samples") is not None:
        lines.append(f"samples scored: {result['counts']['samples']}")
    by_reason: dict[str, list[str]] = {}
    for n, why in sorted((result.get("undefined_metrics") or {}).items()):
        by_reason.setdefault(str(why), []).append(n)
    lines += [f"undefined: {', '.join(names)}: {why}" for why, names in by_reason.items()]
    lines += [f"override: {o['override']}: {'; '.join(o['reasons'])}" for o in result.get("overrides", [])]
    undefined = result.get("undefined_metrics") or {}
    lines += [f"note: {n}" for n in result.get("notes", []) if not any(n.startswith(u + ":") for u in undefined)]
    table = result.get("per_clip")
    if isinstance(table, dict) and table.get("rows"):
        from .per_clip import sortable_columns, worst
        head = f"per-clip table: {len(table['rows'])} test clips (sample {table.get('sample', 0)})"
        if "mm_dist" in table["rows"][0]:
            w = worst(result, 1, "mm_dist")
            lines.append(head + (f"; farthest from its text: {w[0]['id']} (mm_dist {w[0]['mm_dist']:.3g})" if w else "")
                         + "; draw the worst: hoibench render RESULT --worst 5 --by mm_dist --data DATA --out DIR")
        else:                                   # a task track: its first per-clip metric, no renderer hint
            cols = sortable_columns()
            by = next((m for m in result.get("metrics", {}) if m in table["rows"][0] and m in cols), None)
            w = worst(result, 1, by) if by else []
            lines.append(head + (f"; worst by {by}: {w[0]['id']} ({w[0][by]:.3g})" if w else ""))
    return "\n".join(lines)


__all__ = ["format_result"]
