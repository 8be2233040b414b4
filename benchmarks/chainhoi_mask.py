"""What the Kinematic-aware Decoder's mask does: the paper's boolean mask vs the released code's.

The released ChainHOI code passes the float ``1 - mask`` as ``attn_mask``; PyTorch adds a
float mask to the attention scores, so nodes outside a chain get +1 and nodes inside +0:
nothing is masked and out-of-chain nodes are even favoured. For each run folder given, on
the test split's first clips (text and object of each, noise at t = 500, seed 0), this prints

- the attention mass each chain token puts outside its chain (mean over blocks, heads,
  chain tokens and frames): exactly 0 for the paper's mask;
- the same weights run with the other mask mode: mean |x0 difference| (normalised units)
  relative to the mean |x0|.

    python benchmarks/chainhoi_mask.py --data demo-out/data RUN_PAPER RUN_RELEASED
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from hoibench.baselines import joint_data as D
from hoibench.baselines.chainhoi.graph import chain_mask
from hoibench.baselines.sampler import LoadedRun
from hoibench.evaluator.text import read_captions
from hoibench.datasets.store import Store


def set_mask(model, mode: str) -> None:
    m = torch.from_numpy(chain_mask())
    for blk in model.blocks:
        blk.kim.kinematic.mask = m if mode == "paper" else m.float()


@torch.no_grad()
def measure(run: LoadedRun, store: Store, clips: int) -> dict:
    outside = torch.from_numpy(chain_mask())
    masses, diffs, norms = [], [], []
    mode = run.config.model.mask
    other = "released" if mode == "paper" else "paper"
    for cid in store.clip_ids("test")[:clips]:
        clip = store.load(cid)
        rows = clip["joint_level"]
        x0 = torch.from_numpy(run.stats.normalize(rows))[None]
        g = torch.Generator().manual_seed(0)
        t = torch.tensor([500])
        xt = run.diffusion.q_sample(x0, t, torch.randn(x0.shape, generator=g))
        tt, pad = run.text([read_captions(store.root, cid)[0].text], "cpu")
        v, f = store.object_template(str(clip["object_name"]))
        pts = torch.from_numpy(D.surface_points(v, f, run.config.model.object_points, str(clip["object_name"])))[None]
        text, obj = run.model.encode_text(tt, pad), run.model.encode_object(pts)
        keep = torch.ones(1, dtype=torch.bool)
        for blk in run.model.blocks:
            blk.kim.kinematic.keep_attention = True
        a = run.model(xt, t, keep, text, pad, obj)
        for blk in run.model.blocks:
            w = blk.kim.kinematic.last_attention                 # (L, heads, 6, 24)
            masses.append(float((w * outside).sum(-1).mean()))
            blk.kim.kinematic.keep_attention = False
        set_mask(run.model, other)
        b = run.model(xt, t, keep, text, pad, obj)
        set_mask(run.model, mode)
        diffs.append(float((a - b).abs().mean()))
        norms.append(float(a.abs().mean()))
    return {"mask": mode, "outside_mass": float(np.mean(masses)), "swap_rel_diff": float(np.mean(diffs) / np.mean(norms))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("runs", nargs="+", type=Path)
    ap.add_argument("--data", type=Path, default=Path("demo-out/data"))
    ap.add_argument("--clips", type=int, default=8)
    args = ap.parse_args()
    store = Store(args.data)
    print("| run | trained with mask | attention mass outside the chain | x0 change when the mask is swapped |")
    print("|---|---|---:|---:|")
    for r in args.runs:
        run = LoadedRun(r)
        m = measure(run, store, args.clips)
        print(f"| {r.name} ({run.id[:12]}) | {m['mask']} | {m['outside_mass']:.3f} | {100 * m['swap_rel_diff']:.1f}% |")
    # chance level: a uniform token over 24 nodes puts (24 - chain size) / 24 outside
    sizes = (~chain_mask()).sum(1)
    print(f"uniform attention would put {float(np.mean((24 - sizes) / 24)):.3f} outside the chain")


if __name__ == "__main__":
    main()
