"""Where a legacy protocol's audit sees less than the clean one's: per metric and corruption
family, the smallest severity a paired test detects under each (docs/audit.md).

    hoibench audit --data demo-out/data --evaluator leaderboards/synthetic/evaluator \\
        --protocol synthetic-legacy --allow-protocol-mismatch --out legacy-audit --executor processes:2
    python benchmarks/audit_legacy_vs_clean.py leaderboards/synthetic/audit/audit.json legacy-audit/audit.json

Prints the (metric, family) cells detected by one protocol only, and those one detects at a
lower severity, with Spearman's rho toward worse under each.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path


def cells(clean: dict, legacy: dict) -> dict[str, list[tuple]]:
    """``{group: [(metric, family, clean severity, legacy severity, clean rho, legacy rho)]}``."""
    out: dict[str, list[tuple]] = {"detected by clean only": [], "detected by legacy only": [],
                                   "legacy needs a higher severity": [], "legacy detects earlier": []}
    for m in sorted(set(clean["summary"]) & set(legacy["summary"])):
        for fam in clean["families"]:
            c, g = clean["summary"][m].get(fam), legacy["summary"][m].get(fam)
            if not c or not g:
                continue
            dc, dg = c.get("detectable_severity"), g.get("detectable_severity")
            row = (m, fam, dc, dg, c.get("spearman_worse"), g.get("spearman_worse"))
            if dc is not None and dg is None:
                out["detected by clean only"].append(row)
            elif dc is None and dg is not None:
                out["detected by legacy only"].append(row)
            elif dc is not None and dg is not None and dg != dc:
                out["legacy needs a higher severity" if dg > dc else "legacy detects earlier"].append(row)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("clean", type=Path)
    ap.add_argument("legacy", type=Path)
    args = ap.parse_args()
    clean, legacy = (json.loads(p.read_text()) for p in (args.clean, args.legacy))
    print(f"clean {clean['provenance']['protocol']}@{clean['provenance']['protocol_version']}, legacy "
          f"{legacy['provenance']['protocol']}@{legacy['provenance']['protocol_version']}; metrics in one only: "
          f"{sorted(set(clean['summary']) ^ set(legacy['summary']))}")
    rho = lambda v: "-" if v is None else f"{v:+.2f}"  # noqa: E731
    for group, rows in cells(clean, legacy).items():
        print(f"\n{group} ({len(rows)})")
        for m, fam, dc, dg, rc, rg in rows:
            print(f"  {m:26s} {fam:16s} clean {dc} legacy {dg}  rho {rho(rc)} / {rho(rg)}")


if __name__ == "__main__":
    main()
