"""``compare --paired`` at scale: 4 results x 1,000 test clips (3 pairs against the first).

    python benchmarks/compare_paired.py [--clips 1000] [--dim 512] [--resamples 2000] [--executor processes:2]

The per-clip data are made up (seeded Gaussian embeddings of dimension ``--dim`` with 3
captions per clip, 11 physical metrics per clip; the other results are the first one with
growing noise), with the shape a real 1,000-clip result has; the metrics are those a
synthetic-clean result carries. Times :func:`hoibench.scoring.paired.compare_many` of the
first result against the 3 others: what ``compare A B C D --paired``
(:func:`~hoibench.scoring.paired.paired_compare`) spends after reading the files, which takes
well under a second. Prints wall seconds in all, the load average (before and after), and the
seconds per stage (per-clip data of the shared clips; set-level draws: per draw the FID of
each result against the shared real statistics, and the Diversities; set-level points; the
per-clip draws and tests).
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np


def fake_arrays(n: int, d: int, rng: np.random.Generator, base: dict | None, noise: float) -> dict:
    real = base["real"] if base else rng.normal(size=(n, d)).astype(np.float32)
    text = base["text"] if base else np.repeat(real, 3, 0) + 0.1 * rng.normal(size=(3 * n, d)).astype(np.float32)
    motion = real + noise * rng.normal(size=(n, d)).astype(np.float32)
    names = np.array(["cd", "contact_iou", "fsr", "fsr_gmd", "hand_contact_ratio", "jitter_mps3", "object_floating_ratio",
                      "ocd", "penetration_depth_max_m", "penetration_depth_mean_m", "ps"])
    return {"ids": np.array([f"clip{i:05d}" for i in range(n)]), "motion": motion[None].astype(np.float32),
            "real": real, "text": text.astype(np.float32), "text_offsets": np.arange(0, 3 * n + 1, 3, dtype=np.int64),
            "physical": np.abs(rng.normal(0.05, 0.02 + noise / 10, size=(1, n, len(names)))),
            "physical_samples": np.zeros(1, np.int64), "physical_names": names}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--clips", type=int, default=1000)
    ap.add_argument("--dim", type=int, default=512)
    ap.add_argument("--resamples", type=int, default=2000)
    ap.add_argument("--executor", default="processes:2")
    args = ap.parse_args()
    from hoibench.metrics.catalog import METRICS
    from hoibench.tracks.protocol import get_protocol
    proto = get_protocol("synthetic-clean")
    rng = np.random.default_rng(0)
    first = fake_arrays(args.clips, args.dim, rng, None, 0.1)
    others = [fake_arrays(args.clips, args.dim, rng, first, s) for s in (0.1, 0.12, 0.2)]
    names = [m for m in proto.metrics if m in METRICS and m != "multimodality"]
    result = {"metrics": {m: {"mean": 0.0} for m in names}}
    from hoibench.scoring.paired import compare_many
    print(f"{args.clips} clips, {args.dim}-D embeddings, {args.resamples} resamples, {args.executor}, "
          f"4 results (3 pairs); load {' '.join(f'{x:.2f}' for x in os.getloadavg())} (1, 5, 15 min)")
    stages: dict[str, float] = {}
    t0 = time.perf_counter()
    pairs = compare_many(result, first, [(result, arr) for arr in others], proto, args.resamples, 0, args.executor,
                         stages)
    total = time.perf_counter() - t0
    for i, pair in enumerate(pairs, 1):
        print(f"pair {i}: FID diff {pair['metrics']['fid']['diff']:+.4f} ci95 "
              f"[{pair['metrics']['fid']['ci95'][0]:+.4f}, {pair['metrics']['fid']['ci95'][1]:+.4f}] "
              f"({pair['metrics']['fid']['verdict']})")
    for name, sec in stages.items():
        print(f"  {name:36s} {sec:7.1f} s")
    print(f"4 results (3 pairs): {total:.1f} s (load {' '.join(f'{x:.2f}' for x in os.getloadavg())} at the end)")


if __name__ == "__main__":
    main()
