"""The Frechet distance's two forms side by side: time and agreement.

``eigh`` (hoibench's default): ``tr(sqrt(sigma1 sigma2))`` from two symmetric
eigendecompositions. ``sqrtm`` (the reference implementation's numerics, kept for legacy
protocols): ``scipy.linalg.sqrtm`` of the non-symmetric product, with its retry. Cases:
evaluator-sized embeddings (512-D, unit norm) with fewer samples than dimensions (a test split
of 34 or 200 clips: rank-deficient covariances, where ``sqrtm`` goes complex) and more (1,000
and 5,000 samples), plus an evaluation as ``hoibench evaluate`` runs it at K = 30 (20
replications over 20 distinct sample indices: the real statistics once, one FID per index).

    python benchmarks/fid.py [--repeats 3]
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

from hoibench.metrics import embedding as E


def unit(x: np.ndarray) -> np.ndarray:
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def best_of(fn, repeats: int) -> tuple[float, float]:
    times, value = [], None
    for _ in range(repeats):
        t = time.perf_counter()
        value = fn()
        times.append(time.perf_counter() - t)
    return min(times), value


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--dim", type=int, default=512)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    D = args.dim
    print(f"# Frechet distance, {D}-D embeddings, best of {args.repeats}, load {os.getloadavg()[0]:.2f}")
    print("| case | sqrtm (s) | eigh (s) | speed-up | FID (sqrtm) | relative difference |")
    print("|---|---:|---:|---:|---:|---:|")
    worst = 0.0
    for n in (34, 200, 1000, 5000):
        mix = rng.normal(size=(D, D)) / np.sqrt(D)
        real = unit(rng.normal(size=(n, D)) @ mix)
        gen = unit(rng.normal(size=(n, D)) @ mix + 0.05 * rng.normal(size=(n, D)))
        s_real, s_gen = E.activation_statistics(real), E.activation_statistics(gen)
        t_ref, v_ref = best_of(lambda: E.frechet_distance(*s_real, *s_gen, method="sqrtm"), args.repeats)
        t_new, v_new = best_of(lambda: E.frechet_distance(*s_real, *s_gen, method="eigh"), args.repeats)
        rel = abs(v_new - v_ref) / abs(v_ref)
        worst = max(worst, rel)
        print(f"| N = {n} per set{' (rank-deficient)' if n <= D else ''} | {t_ref:.3f} | {t_new:.3f} | "
              f"{t_ref / t_new:.1f}x | {v_ref:.6f} | {rel:.1e} |", flush=True)
    # an evaluation at K = 30: 20 replications use sample indices 0..19
    n = 200
    real = unit(rng.normal(size=(n, D)))
    gens = [unit(rng.normal(size=(n, D)) + 0.02 * k) for k in range(20)]
    for method in ("sqrtm", "eigh"):
        t = time.perf_counter()
        stats = E.activation_statistics(real)
        vals = [E.fid(stats, g, method=method) for g in gens]
        print(f"K = 30 evaluation ({n} test ids, 20 sample indices), {method}: {time.perf_counter() - t:.2f} s "
              f"(mean FID {np.mean(vals):.6f})")
    print(f"largest relative difference: {worst:.1e}")


if __name__ == "__main__":
    main()
