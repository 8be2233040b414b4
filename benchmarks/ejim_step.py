"""One training step of EJIM tiny before and after the fused selective scan, and ChainHOI tiny's.

A step is what the trainer's loop does (``hoibench/baselines/trainer.py``): draw the step's
batch from the store (``make_batch``), the baseline's losses (noising, text and object
encoding, the denoiser, the loss terms), backward, gradient clipping, the AdamW step and the
EMA update. Three models, each with its config's own batch (EJIM 8, ChainHOI 16 clips of up
to 96 frames):

- ``EJIM tiny, before``: the frozen reference implementation (``tests/_ejim_reference.py``:
  the Blelloch scan over materialised (sequences, frames, width, state) tensors);
- ``EJIM tiny, after (torch loop)``: ``hoibench.baselines.ejim`` with the fused time-major scan
  as a PyTorch loop (``HOIBENCH_SCAN=torch``);
- ``EJIM tiny, after (compiled scan)``: the same model with the scan's compiled loops
  (``hoibench.baselines.kernels``; needs ``pip install hoibench[fast]``, else the row is left out);
- ``ChainHOI tiny``.

The models take turns step by step (the same step indices, so the same batches), so a change
in the machine's load hits all three alike; the load average is printed beside every round,
and the thread's CPU time beside the wall time (on a shared machine the CPU time is the
steadier figure).

    python benchmarks/ejim_step.py --data STORE [--steps 3] [--threads 1]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from _ejim_reference import EJIM as ReferenceEJIM  # noqa: E402

from hoibench.baselines import kernels  # noqa: E402
from hoibench.baselines.diffusion import EMA, GaussianDiffusion  # noqa: E402
from hoibench.baselines.registry import get_spec  # noqa: E402
from hoibench.baselines.text import TextConditioner  # noqa: E402
from hoibench.baselines.trainer import build_model, make_batch, training_set  # noqa: E402


def stepper(name: str, data: str, reference: bool = False, scan: str = ""):
    """(parameter count, step(i) -> seconds) for ``name``'s tiny config on ``data``."""
    spec = get_spec(name)
    cfg = spec.preset("tiny")
    ts = training_set(data, cfg)
    text = TextConditioner(cfg.model.text_encoder, cfg.model.text_max_tokens, ts.vocab)
    model = build_model(spec, cfg, text, cfg.train.seed)
    if reference:
        ref = ReferenceEJIM(cfg.model, vocab=len(text.vocab or []), text_width=text.width)
        ref.load_state_dict(model.state_dict())
        model = ref
    model.train()
    ema = EMA(model, cfg.train.ema_decay)
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.train.lr, weight_decay=cfg.train.weight_decay)
    diffusion = GaussianDiffusion(cfg.diffusion)
    mean, std = torch.from_numpy(ts.stats.mean), torch.from_numpy(ts.stats.std)

    def step(i: int) -> tuple[float, float]:
        os.environ[kernels.ENV] = scan
        t0, c0 = time.perf_counter(), time.thread_time()
        torch.manual_seed(i)
        batch = make_batch(ts, cfg, i, text, "cpu")
        losses = spec.losses(model, diffusion, batch, cfg, mean, std, torch.Generator().manual_seed(i))
        opt.zero_grad(set_to_none=True)
        losses["loss"].backward()
        if cfg.train.grad_clip > 0:
            torch.nn.utils.clip_grad_norm_(model.parameters(), cfg.train.grad_clip)
        opt.step()
        ema.update(model)
        return time.perf_counter() - t0, time.thread_time() - c0

    return sum(p.numel() for p in model.parameters()), step


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", required=True, help="a prepared, annotated store (the README store)")
    ap.add_argument("--steps", type=int, default=3, help="timed steps per model, after one warm-up step")
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    models = {"EJIM tiny, before": stepper("ejim", args.data, reference=True, scan="torch"),
              "EJIM tiny, after (torch loop)": stepper("ejim", args.data, scan="torch")}
    if kernels.numba is not None:
        models["EJIM tiny, after (compiled scan)"] = stepper("ejim", args.data, scan="numba")
    models["ChainHOI tiny"] = stepper("chainhoi", args.data)
    print(f"# {args.threads} thread(s), torch {torch.__version__}, {os.cpu_count()} CPUs; "
          f"load average at start {os.getloadavg()[0]:.2f}")
    times: dict[str, list[float]] = {k: [] for k in models}
    cpu: dict[str, list[float]] = {k: [] for k in models}
    for i in range(args.steps + 1):
        row = []
        for name, (_, step) in models.items():
            s, c = step(1000 + i)
            if i:
                times[name].append(s)
                cpu[name].append(c)
            row.append(f"{name} {s:.2f} s (CPU {c:.2f} s)")
        print(f"round {i}{' (warm-up)' if not i else ''}: " + ", ".join(row) +
              f"; load {os.getloadavg()[0]:.2f}", flush=True)
    print("\n| model | parameters (M) | step s (median wall) | min | CPU s (median) | steps/s |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, (n, _) in models.items():
        med = statistics.median(times[name])
        print(f"| {name} | {n / 1e6:.2f} | {med:.2f} | {min(times[name]):.2f} | {statistics.median(cpu[name]):.2f} | "
              f"{1 / med:.2f} |")
    for label, t in (("wall", times), ("CPU", cpu)):
        before, chain = statistics.median(t["EJIM tiny, before"]), statistics.median(t["ChainHOI tiny"])
        for name in [k for k in models if k.startswith("EJIM tiny, after")]:
            after = statistics.median(t[name])
            print(f"{label}: {name}: before / after {before / after:.2f}x; EJIM tiny / ChainHOI tiny step "
                  f"{before / chain:.2f} before, {after / chain:.2f} after")
    print(f"load average at end {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
