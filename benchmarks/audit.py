"""Cost of ``hoibench audit`` on the synthetic track: every corruption family at every
severity on the README store's test split, scored with the tiny evaluator, paired tests with
2,000 resamples.

    python benchmarks/audit.py --data demo-out/data --evaluator leaderboards/synthetic/evaluator \
        --out WORK/audit [--executor processes:2] [--families a,b] [--resamples 2000]
    python benchmarks/audit.py --build WORK --evaluator ...   # build the README store first (120 clips, seed 0)

Prints the wall time and the CPU time (this process and its workers) of the audit (and its
stages' wall times, from the audit's own log line), the
number of scored sets and clips, the load average before and after (``os.getloadavg``), and
the process's peak memory. The audit's files land in ``--out``.
"""
from __future__ import annotations

import argparse
import os
import resource
import sys
import time
from pathlib import Path


def _cpu_s() -> float:
    """User + system CPU seconds of this process and its finished children (the pool's workers)."""
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def _build(work: Path) -> Path:
    from hoibench.datasets.synthetic_store import build_synthetic_store
    from hoibench.text.annotate import annotate_store
    _, data, _ = build_synthetic_store(work, 120, seed=0)
    annotate_store(data)
    return data


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", type=Path, default=None, help="the README store (demo-out/data)")
    p.add_argument("--build", type=Path, default=None, help="build the README store into this folder first")
    p.add_argument("--evaluator", type=Path, required=True)
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--executor", default="serial")
    p.add_argument("--families", default=None)
    p.add_argument("--resamples", type=int, default=None)
    args = p.parse_args(argv)
    if (args.data is None) == (args.build is None):
        p.error("give --data or --build")
    data = _build(args.build) if args.build is not None else args.data
    from hoibench.audit.document import run_audit
    from hoibench.audit.runner import conditions
    from hoibench.audit.corruptions import FAMILIES
    families = args.families.split(",") if args.families else list(FAMILIES)
    load0 = os.getloadavg()
    t0 = time.perf_counter()
    c0 = _cpu_s()
    doc = run_audit(data, args.evaluator, args.out, families=families, resamples=args.resamples,
                    executor=args.executor, overwrite=True)
    wall = time.perf_counter() - t0
    cpu = _cpu_s() - c0
    load1 = os.getloadavg()
    n = doc["provenance"]["test_clips"]
    print(f"audit of {len(conditions(families))} corrupted sets x {n} test clips ({len(families)} families), "
          f"executor {args.executor}: {wall:.1f} s ({wall / 60:.1f} min) wall, {cpu:.1f} s CPU (this process and "
          f"its workers: what the audit costs on idle cores, over their number when it parallelises)")
    print(f"load average before {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}, after {load1[0]:.2f} {load1[1]:.2f} "
          f"{load1[2]:.2f}; {os.cpu_count()} cores; peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB")


if __name__ == "__main__":
    sys.exit(main())
