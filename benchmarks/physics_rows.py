"""The physics tier of a track's rows: a markdown table from results scored under a protocol
version with a ``physics:`` block, checked against the track's entries.

    python benchmarks/physics_rows.py --results W --entries leaderboards/synthetic/entries

``W`` holds one result per row, named like the row's entry (``<slug>.json``; the ground
truth's entry is ``gt-real-motion.json``, its result may be ``gt.json``), each scored with
``hoibench evaluate SUB --protocol synthetic-clean@1.2 ... --out W/<slug>.json``. A result is
used only when it was scored with the entry's evaluator and every metric the entry shows has
the same mean in it (so the physics figures belong to the very samples the row ranks); rows
are listed in the order of their physics support error. Cells: mean [95% clip-bootstrap
interval] for the two distances (a K > 1 row: mean ± its interval over the protocol's
replications), plain means for the ratios. The last column is ``phys_balance_ratio``: the
share of releases after which the object rests (moved < ``unsupported_m``, turned <
``balance_turn_deg``), higher is better.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

PHYSICS = ("phys_support_err_m", "phys_unsupported_ratio", "phys_settle_m", "phys_balance_ratio")
ALIASES = {"gt-real-motion": "gt"}


def _result_for(results: Path, slug: str) -> Path | None:
    for name in (slug, ALIASES.get(slug, slug)):
        path = results / f"{name}.json"
        if path.is_file():
            return path
    return None


def _same_samples(entry: dict, result: dict) -> str:
    """Empty when ``result`` scores the entry's samples (same evaluator, equal means), else why not."""
    if result.get("evaluator_id") != entry.get("evaluator_id"):
        return "another evaluator"
    for name, m in entry["metrics"].items():
        got = result["metrics"].get(name)
        if got is None or m.get("mean") is None:
            continue
        if abs(float(got["mean"]) - float(m["mean"])) > 1e-9 * max(1.0, abs(float(m["mean"]))):
            return f"{name} differs ({got['mean']:.6g} vs the entry's {m['mean']:.6g})"
    return ""


def _cell(metric: dict, interval: bool) -> str:
    mean = float(metric["mean"])
    lo_hi = (metric.get("clips") or {}).get("ci95")
    if interval and lo_hi:
        return f"{mean:.3f} [{lo_hi[0]:.3f}, {lo_hi[1]:.3f}]"
    if interval and float(metric.get("ci95") or 0.0) > 0:      # K > 1: the interval over replications
        return f"{mean:.3f} ± {float(metric['ci95']):.3f} (reps)"
    return f"{mean:.3f}"


def table(results: Path, entries: Path) -> tuple[str, list[str]]:
    """(markdown table, lines naming the rows left out and why)."""
    rows, skipped = [], []
    for path in sorted(entries.glob("*.json")):
        entry = json.loads(path.read_text())
        if entry.get("source") != "reproduced":
            continue
        found = _result_for(results, path.stem)
        if found is None:
            skipped.append(f"{entry['method']}: no result in {results}")
            continue
        result = json.loads(found.read_text())
        why = _same_samples(entry, result)
        if why:
            skipped.append(f"{entry['method']}: {found.name}: {why}")
            continue
        if any(m not in result["metrics"] for m in PHYSICS):
            skipped.append(f"{entry['method']}: {found.name}: no physics metrics "
                           f"(protocol {result.get('protocol')}@{result.get('protocol_version')})")
            continue
        rows.append((float(result["metrics"]["phys_support_err_m"]["mean"]), entry["method"], result))
    head = ("| row | support error (m) ↓ | unsupported windows ↓ | settle (m) ↓ | releases at rest ↑ |\n"
            "|---|---:|---:|---:|---:|")
    lines = [head]
    for _, method, r in sorted(rows, key=lambda x: (x[0], x[1])):
        m = r["metrics"]
        lines.append(f"| {method} | {_cell(m['phys_support_err_m'], True)} | "
                     f"{_cell(m['phys_unsupported_ratio'], False)} | {_cell(m['phys_settle_m'], True)} | "
                     f"{_cell(m['phys_balance_ratio'], False)} |")
    protos = sorted({f"{r['protocol']}@{r['protocol_version']}" for _, _, r in rows})
    lines.append(f"\n{len(rows)} rows; protocol {', '.join(protos) or '-'}.")
    return "\n".join(lines), skipped


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--results", type=Path, required=True, help="folder of the rows' results with physics metrics")
    ap.add_argument("--entries", type=Path, required=True, help="the track's entries folder")
    args = ap.parse_args(argv)
    if not args.entries.is_dir() or not args.results.is_dir():
        print(f"{args.entries if not args.entries.is_dir() else args.results}: no such folder", file=sys.stderr)
        return 2
    text, skipped = table(args.results, args.entries)
    print(text)
    for line in skipped:
        print(f"left out: {line}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
