"""Average inference time per generated sample (AIT) of ChainHOI, CATMO and EJIM, tiny and
paper configs, on CPU with 1 and 2 threads, in one run.

Each model is an untrained run folder (``hoibench baseline train NAME DATA --config SIZE
--steps 0``, written once under ``--work``; AIT does not depend on the weights) sampled
through the path ``hoibench baseline sample`` takes: ``load_run`` (the card and weights
verified), the run's own sampling options (``options()``: the config's DDIM steps and
guidance, or CATMO's temperature) and ``generate_sample`` (text and object encoding, the
DDIM loop with classifier-free guidance or CATMO's autoregressive tokens, de-normalisation,
decoding to joints and object pose). Prompt and object: the first test clip of ``--data``;
length ``--frames``. Threads wait passively (``OMP_WAIT_POLICY=PASSIVE`` unless set, as the
``hoibench`` command sets it). One warm-up sample (2 DDIM steps) per model and thread count, then
``--samples`` timed samples (``--paper-samples`` at paper size). The load average is
printed beside every row (the figures are only comparable within one run), and the
process's CPU seconds per sample beside the wall time (all threads together; on a shared
machine the steadier figure at one thread).

    python benchmarks/ait.py --data STORE [--work W] [--frames 120] [--threads 1 2] [--paper-threads 1]

With two threads on a 2-core machine that other jobs share, torch's threads wait for each
other (a 10-80x slowdown was measured): ``--paper-threads 1`` keeps the run to minutes there.
"""
from __future__ import annotations

import argparse
import contextlib
import io
import os
import platform
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")   # as the hoibench command: waiting threads sleep

import torch  # noqa: E402

from hoibench.baselines import joint_data as D  # noqa: E402
from hoibench.baselines.sampler import load_run  # noqa: E402
from hoibench.commands.baselines import train_baseline  # noqa: E402
from hoibench.datasets.store import Store  # noqa: E402
from hoibench.evaluator.text import read_captions  # noqa: E402


def run_folder(work: Path, name: str, size: str, data: str) -> Path:
    """The untrained run of ``name`` at ``size`` (written on first use)."""
    out = work / f"{name}-{size}"
    if not (out / "card.json").exists():
        with contextlib.redirect_stdout(io.StringIO()):
            train_baseline(name, data, out, config=size, steps=0)
    return out


def prompt(data: str) -> tuple[str, str]:
    """(caption, object name) of the store's first test clip."""
    store = Store(data)
    cid = store.clip_ids("test")[0]
    return read_captions(store.root, cid)[0].text, str(store.load(cid)["object_name"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", required=True, help="a prepared, annotated store (the README store)")
    ap.add_argument("--work", default=None, help="folder for the untrained run folders (default: a temporary one)")
    ap.add_argument("--models", nargs="+", default=["chainhoi", "catmo", "ejim"])
    ap.add_argument("--sizes", nargs="+", default=["tiny", "paper"])
    ap.add_argument("--threads", nargs="+", type=int, default=[1, 2])
    ap.add_argument("--paper-threads", nargs="+", type=int, default=None,
                    help="thread counts at paper size (default: --threads)")
    ap.add_argument("--frames", type=int, default=120, help="sample length in frames")
    ap.add_argument("--samples", type=int, default=3, help="timed samples per model at tiny size")
    ap.add_argument("--paper-samples", type=int, default=1, help="timed samples per model at paper size")
    args = ap.parse_args()
    tmp = tempfile.TemporaryDirectory() if args.work is None else None
    work = Path(args.work or tmp.name)
    caption, obj = prompt(args.data)
    v, f = Store(args.data).object_template(obj)
    print(f"# AIT on CPU ({platform.processor() or platform.machine()}, {os.cpu_count()} cores), torch "
          f"{torch.__version__}, T = {args.frames} frames, untrained weights; prompt {caption!r} ({obj})")
    print("| model | size | parameters (M) | sampling | threads | AIT (s/sample) | CPU s/sample | samples | load |")
    print("|---|---|---:|---|---:|---:|---:|---:|---:|")
    for name in args.models:
        for size in args.sizes:
            try:
                loaded = load_run(run_folder(work, name, size, args.data))
            except Exception as exc:                      # report the row, time the others
                print(f"| {name} | {size} | | | | not measured: {type(exc).__name__}: {exc} | | | |", flush=True)
                continue
            opts = loaded.options()
            points = (D.input_points(v, f, loaded.object_points, obj, getattr(loaded, "object_source", "surface"))
                      if loaded.requires_object else None)
            params = sum(p.numel() for p in loaded.model.parameters())
            n = args.paper_samples if size == "paper" else args.samples
            for threads in (args.paper_threads or args.threads) if size == "paper" else args.threads:
                torch.set_num_threads(threads)
                warm = {**opts, "ddim_steps": 2} if "ddim_steps" in opts else opts
                loaded.generate_sample(caption, points, args.frames, 1, (0, "warm-up"), **warm)
                t0, c0 = time.perf_counter(), time.process_time()
                for s in range(n):
                    loaded.generate_sample(caption, points, args.frames, 1, (0, "ait", s), **opts)
                ait, cpu = (time.perf_counter() - t0) / n, (time.process_time() - c0) / n
                how = ", ".join(f"{k} {v:g}" for k, v in opts.items())
                print(f"| {name} | {size} | {params / 1e6:.2f} | {how} | {threads} | {ait:.3f} | {cpu:.3f} | {n} | "
                      f"{os.getloadavg()[0]:.2f} |", flush=True)
    if tmp is not None:
        tmp.cleanup()


if __name__ == "__main__":
    main()
