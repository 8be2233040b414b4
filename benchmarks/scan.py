"""The selective scan on CPU: hoibench's Blelloch scan against the alternatives, side by side.

Times ``h_t = a_t h_{t-1} + b_t`` over (batch, L, inner, state) tensors the size EJIM's
temporal scans use, forward only and forward + backward, for

- ``blelloch``: :func:`hoibench.baselines.scan.linear_scan` (work-efficient, adjoint backward);
- ``doubling``: recursive doubling (Hillis-Steele), hoibench's first version;
- ``mambapy``: the ``mambapy`` package's pure-PyTorch ``pscan`` (when installed);
- ``loop``: a Python loop over time with autograd (the reference the tests compare with).

    python benchmarks/scan.py [--threads 1]
"""
from __future__ import annotations

import argparse
import os
import time

import torch

from hoibench.baselines.scan import linear_scan, linear_scan_reference


def doubling(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    A, H = a, b
    k = 1
    while k < a.shape[1]:
        H = torch.cat([H[:, :k], H[:, k:] + A[:, k:] * H[:, :-k]], 1)
        A = torch.cat([A[:, :k], A[:, k:] * A[:, :-k]], 1)
        k *= 2
    return H


def timed(fn, a, b, backward: bool, repeat: int = 3) -> float:
    best = float("inf")
    for _ in range(repeat):
        aa = a.detach().clone().requires_grad_(backward)
        bb = b.detach().clone().requires_grad_(backward)
        t0 = time.perf_counter()
        h = fn(aa, bb)
        if backward:
            h.sum().backward()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    fns = {"blelloch": linear_scan, "doubling": doubling, "loop": linear_scan_reference}
    try:
        from mambapy.pscan import pscan
        fns["mambapy"] = lambda a, b: pscan(a, b) if a.requires_grad else pscan(a.clone(), b.clone())
    except ImportError:
        print("(mambapy not installed: pip install mambapy to compare)")
    sizes = {"EJIM paper temporal (B 32 x 23 joints, 196 frames, 256 x 16)": (32 * 23 // 8, 196, 256, 16),
             "EJIM micro temporal (B 8 x 23 joints, 96 frames, 16 x 4)": (8 * 23, 96, 16, 4)}
    print(f"# threads {torch.get_num_threads()}, load {os.getloadavg()[0]:.2f}, torch {torch.__version__}; "
          f"best of 3, seconds (paper row: 1/8 of a batch)")
    print("| tensor | scan | forward | forward + backward | max error vs loop |")
    print("|---|---|---:|---:|---:|")
    g = torch.Generator().manual_seed(0)
    for label, shape in sizes.items():
        a = torch.rand(shape, generator=g) * 0.5 + 0.5
        b = torch.randn(shape, generator=g)
        ref = linear_scan_reference(a, b)
        for name, fn in fns.items():
            err = (fn(a, b) - ref).abs().max().item()
            print(f"| {label} | {name} | {timed(fn, a, b, False):.3f} | {timed(fn, a, b, True):.3f} | {err:.1e} |",
                  flush=True)


if __name__ == "__main__":
    main()
