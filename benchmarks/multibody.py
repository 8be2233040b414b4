"""Multi-body track timings and reference rows (docs/multibody.md, docs/benchmarks.md).

    python benchmarks/multibody.py [--clips 216] [--out /tmp/mb_bench] [--executor processes:2]

Writes the synthetic multi-body data, prepares it, trains the recognizer, writes the
reference submissions and evaluates them, printing the time of each stage and the metrics
of each row.
"""
from __future__ import annotations

import argparse
import shutil
import time
from pathlib import Path

from hoibench.datasets import multibody as mbl
from hoibench.datasets import synthetic_multibody as syn
from hoibench.scoring.evaluate import evaluate
from hoibench.scoring.multibody import write_multibody_submission
from hoibench.evaluator.recognizer import train_recognizer
from hoibench.datasets.store import PrepareConfig, prepare

ROWS = (("gt", 1), ("gt-noise", 3), ("desync", 1), ("lost_contact", 1), ("interpenetration", 1), ("static", 1))
KEYS = ("csr", "crr", "csiou", "iv_cm3", "id_mm", "sd", "od", "ra", "fid")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--clips", type=int, default=216)
    ap.add_argument("--out", type=Path, default=Path("/tmp/mb_bench"))
    ap.add_argument("--executor", default="processes:2")
    args = ap.parse_args()
    shutil.rmtree(args.out, ignore_errors=True)
    t = time.perf_counter()
    mbl.write_synthetic_layout(args.out / "raw", args.clips, seed=0)
    print(f"synth {args.clips} clips: {time.perf_counter() - t:.1f} s")
    t = time.perf_counter()
    cfg = PrepareConfig("multibody-synthetic", fps=syn.FPS)
    m = prepare(mbl.prepare_jobs(args.out / "raw", None, args.out / "data", cfg), args.out / "data", cfg)
    print(f"prepare: {time.perf_counter() - t:.1f} s ({m['counts']['by_split']})")
    t = time.perf_counter()
    card = train_recognizer(args.out / "data", args.out / "rec")
    print(f"train-recognizer (400 steps): {time.perf_counter() - t:.1f} s, accuracy {card['gt_accuracy']}, "
          f"chance {card['chance_accuracy']:.3f}")
    print(f"{'row':18s} {'s':>6s} " + " ".join(f"{k:>8s}" for k in KEYS))
    for kind, k in ROWS:
        sub = write_multibody_submission(args.out / "data", args.out / f"sub_{kind}", kind=kind, samples=k)
        t = time.perf_counter()
        res = evaluate(sub, args.out / "data", args.out / "rec", executor=args.executor)
        vals = " ".join(f"{res['metrics'][x]['mean']:8.3f}" if x in res["metrics"] else f"{'--':>8s}" for x in KEYS)
        print(f"{kind:18s} {time.perf_counter() - t:6.1f} {vals}")


if __name__ == "__main__":
    main()
