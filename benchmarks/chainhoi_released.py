"""ChainHOI ``released``: the full-size check against the public code's values, the padding
leak of the released arithmetic, and a short training run through the CLI.

    python benchmarks/chainhoi_released.py reference     # full-size outputs vs tests/data (max |diff|)
    python benchmarks/chainhoi_released.py padding       # leak of padding="reference" at initialisation
    python benchmarks/chainhoi_released.py train [--data DATA] [--steps 2] [--batch 2] [--frames 32]

``reference`` draws the 46 M seeded weights of tests/chainhoi_seeded_weights.py (``fill``) into
the BEHAVE-size denoiser and compares its output with ``full_out`` of
tests/data/chainhoi_released_reference.npz (computed with the public code, see
tests/data/README.md). ``train`` builds a 24-clip synthetic store when no ``--data`` is given
and runs ``hoibench baseline train chainhoi --config released`` for a few steps, printing
the seconds per step.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from chainhoi_seeded_weights import fill  # noqa: E402

from hoibench.baselines.chainhoi.released import ReleasedDenoiser  # noqa: E402
from hoibench.baselines.chainhoi.released_config import ReleasedConfig  # noqa: E402


def reference() -> None:
    with np.load(ROOT / "tests" / "data" / "chainhoi_released_reference.npz") as z:
        ref = dict(z)
    m = ReleasedDenoiser(ReleasedConfig(padding="reference")).eval()
    fill(m)
    rs = np.random.RandomState(7)
    B, L = ref["full_valid"].shape
    x = torch.from_numpy(rs.standard_normal((B, L, 24, 12)).astype(np.float32))
    text = torch.from_numpy(rs.standard_normal((B, 5, 512)).astype(np.float32))
    obj = torch.from_numpy(rs.standard_normal((B, 16, 512)).astype(np.float32))
    with torch.no_grad():
        out = m(x, torch.from_numpy(ref["full_valid"]), torch.from_numpy(ref["full_t"]), text,
                torch.from_numpy(ref["full_text_valid"]), obj).numpy()
    n = sum(p.numel() for p in m.parameters())
    print(f"parameters {n:,}; max |output| {np.abs(ref['full_out']).max():.3f}; "
          f"max |hoibench - public| {np.abs(out - ref['full_out']).max():.2e}")


def padding() -> None:
    torch.manual_seed(0)
    cfg = ReleasedConfig()
    for mode in ("reference", "masked"):
        torch.manual_seed(0)
        m = ReleasedDenoiser(ReleasedConfig(padding=mode)).eval()
        g = torch.Generator().manual_seed(0)
        x = torch.randn(2, 60, 24, 12, generator=g)
        valid = torch.arange(60)[None] < torch.tensor([60, 40])[:, None]
        text, obj = torch.randn(2, 8, cfg.cond_dim, generator=g), torch.randn(2, 16, cfg.cond_dim, generator=g)
        tv = torch.ones(2, 8, dtype=torch.bool)
        t = torch.tensor([500, 500])
        with torch.no_grad():
            batch = m(x, valid, t, text, tv, obj)
            alone = m(x[1:, :40], valid[1:, :40], t[1:], text[1:], tv[1:], obj[1:])
        d = (batch[1, :40] - alone[0]).abs()
        print(f"padding={mode}: max |padded - unpadded| {float(d.max()):.2e} (last 5 valid frames "
              f"{float(d[-5:].max()):.2e}, first 5 {float(d[:5].max()):.2e})")


def train(args) -> None:
    from hoibench.cli import main
    data = args.data
    if data is None:
        from hoibench.datasets.synthetic_store import build_synthetic_store, write_template_texts
        _, data, _ = build_synthetic_store(Path(tempfile.mkdtemp()) / "store", 24, seed=0)
        write_template_texts(data)
    out = Path(tempfile.mkdtemp()) / "run"
    t0 = time.perf_counter()
    rc = main(["baseline", "train", "chainhoi", str(data), "--out", str(out), "--config", "released",
               "--steps", str(args.steps), "--set", f"train.batch_size={args.batch}",
               "--set", f"train.max_frames={args.frames}", "--set", "train.log_every=1",
               "--set", 'model.text_encoder="tokens"', "--device", args.device])
    dt = time.perf_counter() - t0
    print(f"rc {rc}; {args.steps} steps of {args.batch} x {args.frames} frames in {dt:.0f} s "
          f"(including model construction and the final save) -> {out}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("what", choices=["reference", "padding", "train"])
    ap.add_argument("--data", type=Path, default=None)
    ap.add_argument("--steps", type=int, default=2)
    ap.add_argument("--batch", type=int, default=2)
    ap.add_argument("--frames", type=int, default=32)
    ap.add_argument("--device", default="cpu")
    a = ap.parse_args()
    {"reference": lambda: reference(), "padding": lambda: padding(), "train": lambda: train(a)}[a.what]()
    sys.exit(0)
