"""ChainHOI tiny sampling time per sample on an idle and on a busy machine, by thread count
and OpenMP wait policy (docs/benchmarks.md, "Threads on a busy machine").

    python benchmarks/threads.py [--busy 2] [--samples 2] [--frames 120]

Each configuration runs in its own process (``OMP_WAIT_POLICY`` must be set before torch
loads): ``torch.set_num_threads(N)`` for N in 1, 2 and hoibench's choice
(:func:`hoibench.core.threads.choose_threads` of the load at that moment), wait policy
OpenMP's default (active spinning for a while) or ``PASSIVE``. The same set runs with no
extra load and next to ``--busy`` processes spinning ``while True: pass`` (killed at the
end). One sample: 50 DDIM steps with guidance, random weights (the time does not depend on
them), T = ``--frames``; one 2-step warm-up first.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def child(threads: str, samples: int, frames: int) -> None:
    """One configuration: print a JSON line with the seconds per sample."""
    import torch
    sys.path.insert(0, str(HERE))
    from baselines import make_sampler
    from hoibench.core.threads import choose_threads, machine_load
    n = choose_threads(*machine_load()) if threads == "auto" else int(threads)
    torch.set_num_threads(n)
    one, _ = make_sampler("chainhoi", "tiny", torch.device("cpu"))
    one(frames, 999, steps=2)
    t0 = time.perf_counter()
    for s in range(samples):
        one(frames, s)
    print(json.dumps({"threads": n, "s_per_sample": (time.perf_counter() - t0) / samples}))


def run_config(threads: str, policy: str | None, samples: int, frames: int) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("OMP_WAIT_POLICY", "OMP_NUM_THREADS", "HOIBENCH_THREADS")}
    if policy:
        env["OMP_WAIT_POLICY"] = policy
    env["PYTHONPATH"] = str(HERE.parent) + os.pathsep + env.get("PYTHONPATH", "")
    out = subprocess.run([sys.executable, __file__, "--child", threads, "--samples", str(samples),
                          "--frames", str(frames)], capture_output=True, text=True, env=env, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--busy", type=int, default=2, help="busy processes for the loaded half")
    ap.add_argument("--samples", type=int, default=2)
    ap.add_argument("--frames", type=int, default=120)
    ap.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child is not None:
        child(args.child, args.samples, args.frames)
        return
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    print(f"# ChainHOI tiny, CPU, {cores} cores, T = {args.frames}, {args.samples} samples per configuration; "
          f"load at start {os.getloadavg()[0]:.2f}", flush=True)
    print("| background | threads | OMP_WAIT_POLICY | s/sample | load before |")
    print("|---|---:|---|---:|---:|", flush=True)
    for busy in (0, args.busy):
        hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(busy)]
        try:
            if hogs:
                time.sleep(3)
            for threads in ("1", "2", "auto"):
                for policy in (None, "PASSIVE"):
                    load = os.getloadavg()[0]
                    r = run_config(threads, policy, args.samples, args.frames)
                    label = f"{r['threads']}" + (" (auto)" if threads == "auto" else "")
                    print(f"| {busy} busy | {label} | {policy or 'default'} | {r['s_per_sample']:.2f} | {load:.2f} |",
                          flush=True)
        finally:
            for h in hogs:
                h.kill()
                h.wait()


if __name__ == "__main__":
    main()
