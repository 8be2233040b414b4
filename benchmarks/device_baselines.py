"""Train and sample the reference baselines on one device, side by side: optimiser steps
per second and the average inference time per sample (AIT), on the same store.

    python benchmarks/device_baselines.py --data STORE --device cuda [--steps 1000] [--out DIR]

Each job trains with ``hoibench baseline train`` (the same code as on CPU, ``--device``),
then samples the first ``--clips`` test clips twice (one clip to warm up, then the timed
ones) with the config's sampling settings (DDIM 50 steps and guidance 2 for the diffusion
baselines; CATMO's autoregressive decoding). Text conditioning is the trainable word-token
encoder for every job (``model.text_encoder="tokens"``; the MiniLM path needs the
sentence-encoder files), so the timings exclude a frozen text encoder. Training runs on the
store's clips as they are: the step rate is the figure, not the samples' quality. A job that
fails prints its error and the others go on. Prints one table (markdown).
"""
from __future__ import annotations

import argparse
import contextlib
import io
import shutil
import tempfile
import time
from pathlib import Path

JOBS = {
    "chainhoi-released": ("chainhoi", "released", ['model.text_encoder="tokens"']),
    "chainhoi-paper": ("chainhoi", "paper", ['model.text_encoder="tokens"']),
    "ejim-paper": ("ejim", "paper", ['model.text_encoder="tokens"']),
    "catmo-paper": ("catmo", "paper", []),
}


def _train(name: str, config: str, sets: list[str], data: Path, out: Path, steps: int, device: str) -> float:
    from hoibench.cli import main
    argv = ["baseline", "train", name, str(data), "--out", str(out), "--config", config, "--device", device]
    if name == "catmo":
        per = max(1, steps // 6)
        sets = sets + [f"train.vq_steps={per}", f"train.contact_steps={per}", f"text.movement_ae_steps={per}",
                       f"text.match_steps={per}", f"train.gpt_steps={per}", f"object.steps={per}"]
    else:
        argv += ["--steps", str(steps)]
    for s in sets:
        argv += ["--set", s]
    t0 = time.perf_counter()
    rc = main(argv)
    if rc != 0:
        raise RuntimeError(f"train exited {rc}")
    return time.perf_counter() - t0


def _ait(run: Path, data: Path, tmp: Path, clips: int, device: str) -> float:
    from hoibench.baselines.sampler import sample
    sample(run, data, tmp / "warm", device=device, limit=1, log=None)
    t0 = time.perf_counter()
    sample(run, data, tmp / "timed", device=device, limit=clips, log=None)
    return (time.perf_counter() - t0) / clips


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, required=True)
    ap.add_argument("--device", default="cuda")
    ap.add_argument("--steps", type=int, default=1000)
    ap.add_argument("--clips", type=int, default=4)
    ap.add_argument("--jobs", default=",".join(JOBS))
    ap.add_argument("--out", type=Path, default=None, help="keep the runs here (default: a temporary folder)")
    ap.add_argument("--set", action="append", default=[], help="an override for every job (a dry run: "
                    "--set train.batch_size=2 --set train.max_frames=32)")
    a = ap.parse_args()
    import torch
    dev = torch.cuda.get_device_name(0) if a.device == "cuda" and torch.cuda.is_available() else a.device
    root = a.out or Path(tempfile.mkdtemp())
    rows = []
    for job in a.jobs.split(","):
        name, config, sets = JOBS[job]
        sets = sets + list(a.set)
        run = root / job
        shutil.rmtree(run, ignore_errors=True)
        log = io.StringIO()
        try:
            with contextlib.redirect_stdout(log), contextlib.redirect_stderr(log):
                secs = _train(name, config, sets, a.data, run, a.steps, a.device)
            n = sum(p.numel() for p in torch.load(next(run.glob("*.pt")), map_location="cpu",
                                                  weights_only=True).values()) if list(run.glob("*.pt")) else None
            ait = _ait(run, a.data, root / f"{job}-samples", a.clips, a.device)
            rows.append((job, f"{a.steps}", f"{secs:.0f}", f"{a.steps / secs:.2f}", f"{ait:.2f}",
                         f"{n / 1e6:.2f} M" if n else "-"))
        except Exception as exc:          # one failing job does not stop the others
            tail = (log.getvalue().strip().splitlines() or [""])[-1]
            rows.append((job, f"{a.steps}", "-", "-", "-", f"failed: {type(exc).__name__}: {exc}; {tail}"[:300]))
        print(rows[-1], flush=True)
    print(f"\ndevice: {dev}; torch {torch.__version__}")
    print("| job | steps | train s | steps/s | AIT s/sample | notes |\n|---|---:|---:|---:|---:|---|")
    for r in rows:
        print("| " + " | ".join(r) + " |")


if __name__ == "__main__":
    main()
