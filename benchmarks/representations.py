"""Throughput of hml263 encoding: 1,000 clips x 196 frames, batched, legacy and clean.

    python benchmarks/representations.py [--clips 1000] [--frames 196]
                                         [--reference-dir PATH/TO/HumanML3D] [--reference-clips 50]

With ``--reference-dir`` (a clone of EricGuo5513/HumanML3D) the reference ``process_file``
runs on the first ``--reference-clips`` of the same clips in the same process, and the
speed-up is printed. Peak memory is the tracemalloc peak of encoding one chunk (a separate, untimed pass);
the input clips themselves take clips x frames x 22 x 3 x 8 bytes on top.
"""
from __future__ import annotations

import argparse
import time
import tracemalloc
import warnings

import numpy as np

from hoibench.datasets.random_motion import random_motion
from hoibench.representations import hml263


def encode_chunked(clips: np.ndarray, mode: str, chunk: int) -> np.ndarray:
    return np.concatenate([hml263.encode(clips[i:i + chunk], mode=mode) for i in range(0, len(clips), chunk)])


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--clips", type=int, default=1000)
    ap.add_argument("--frames", type=int, default=196)
    ap.add_argument("--chunk", type=int, default=100, help="clips per vectorised batch")
    ap.add_argument("--repeats", type=int, default=3, help="timed repeats; the best is reported")
    ap.add_argument("--reference-dir", default=None)
    ap.add_argument("--reference-clips", type=int, default=50)
    args = ap.parse_args(argv)

    t0 = time.perf_counter()
    clips = random_motion(args.frames, seed=0, batch=args.clips)
    print(f"generated {args.clips} clips x {args.frames} frames in {time.perf_counter() - t0:.1f} s")
    frames = args.clips * args.frames
    ours = {}
    for mode in ("legacy", "clean"):
        times = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            feats = encode_chunked(clips, mode, args.chunk)
            times.append(time.perf_counter() - t0)
        dt = min(times)
        tracemalloc.start()  # separate pass: tracing allocations slows numpy down
        encode_chunked(clips[:args.chunk], mode, args.chunk)
        peak = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
        ours[mode] = args.clips / dt
        print(f"hoibench hml263 {mode:6s}: {dt:6.2f} s  {args.clips / dt:8.1f} clips/s  "
              f"{frames / dt:10.0f} frames/s  peak {peak:7.1f} MiB  (chunk {args.chunk}, best of "
              f"{args.repeats}, median {sorted(times)[len(times) // 2]:.2f} s)")
        assert feats.shape == (args.clips, args.frames - 1, 263)
    if args.reference_dir:
        process_file = __import__("_humanml3d_reference").load_process_file(args.reference_dir)
        n = min(args.reference_clips, args.clips)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            t0 = time.perf_counter()
            ref = [process_file(c.copy(), 0.002)[0] for c in clips[:n]]
            dt = time.perf_counter() - t0
        err = max(np.abs(r - f).max() for r, f in zip(ref, hml263.encode(clips[:n], mode="legacy")))
        print(f"reference process_file:  {dt:6.2f} s  {n / dt:8.1f} clips/s  {n * args.frames / dt:10.0f} "
              f"frames/s  (first {n} clips; max |legacy - reference| = {err:.1e})")
        print(f"speed-up legacy: {ours['legacy'] / (n / dt):.1f}x   clean: {ours['clean'] / (n / dt):.1f}x")


if __name__ == "__main__":
    main()
