"""Average inference time per sample (AIT) of the baselines.

AIT as ChainHOI's Table 1 measures it: wall-clock seconds to generate one sample, averaged
over ``--samples`` samples after one warm-up sample. Diffusion baselines (ChainHOI, EJIM):
text and object encoding, 50 DDIM steps with classifier-free guidance (two network passes
per step), de-normalisation and decoding to joints. CATMO: text and object encoding,
``2 ceil(T / 4)`` autoregressive GPT passes (one position each, keys and values cached),
both VQ decoders, the object head and decoding to joints. Weights are random (AIT does not
depend on them).

    python benchmarks/baselines.py                       # tiny and paper, CPU, T = 120 frames
    python benchmarks/baselines.py --device cuda --samples 20
"""
from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np
import torch

from hoibench.baselines import joint_data as D
from hoibench.baselines.diffusion import GaussianDiffusion
from hoibench.baselines.registry import SPECS, get_spec
from hoibench.baselines.sampler import rows_to_sample
from hoibench.baselines.text import TextConditioner

CAPTION = "a person lifts the big box with both hands and puts it down"


def make_catmo_sampler(size: str, device: torch.device):
    from hoibench.baselines.catmo.config import preset
    from hoibench.baselines.catmo.model import CATMO
    from hoibench.representations import hoi269
    cfg = preset(size)
    vocab = D.build_vocab([CAPTION])
    text = TextConditioner(cfg.text.encoder, cfg.text.max_tokens, vocab)
    torch.manual_seed(0)
    model = CATMO(cfg, len(vocab), text.width, with_object=True).to(device).eval()
    verts = np.array([[0, 0, 0], [0.4, 0, 0], [0, 0.4, 0], [0, 0, 0.4]], float)
    faces = np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]])
    points = torch.from_numpy(D.surface_points(verts, faces, cfg.gpt.object_points, "box")[None]).to(device)

    @torch.no_grad()
    def one(length: int, seed: int, steps: int | None = None) -> None:
        units = -(-length // cfg.vq.unit) if steps is None else 2
        tt, pad = text([CAPTION], device)
        feat = model.object_feature(points)
        mi, ci = model.gpt.sample(model.condition(model.text(tt, pad), feat), units, torch.Generator().manual_seed(seed))
        motion = model.motion_vq.decode(mi)[:, :length]
        prob = torch.sigmoid(model.contact_vq.decode(ci)[:, :length])
        obj = model.object_head(motion, prob, feat)
        if device.type == "cuda":
            torch.cuda.synchronize()
        hoi269.decode(torch.cat([motion, obj], -1).float().cpu().numpy())

    return one, sum(p.numel() for p in model.parameters())


def make_sampler(name: str, size: str, device: torch.device):
    spec = get_spec(name)
    if spec.kind == "tokens":
        return make_catmo_sampler(size, device)
    cfg = spec.preset(size)
    vocab = D.build_vocab([CAPTION])
    text = TextConditioner(cfg.model.text_encoder, cfg.model.text_max_tokens, vocab)
    torch.manual_seed(0)
    model = spec.build_model(cfg, len(vocab), text.width).to(device).eval()
    diffusion = GaussianDiffusion(cfg.diffusion)
    stats = D.JointStats(np.zeros((24, 12), np.float32), np.ones((24, 12), np.float32))
    verts = np.array([[0, 0, 0], [0.4, 0, 0], [0, 0.4, 0], [0, 0, 0.4]], float)
    faces = np.array([[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]])
    points = D.surface_points(verts, faces, cfg.model.object_points, "box")

    @torch.no_grad()
    def one(length: int, seed: int, steps: int | None = None) -> None:
        tt, pad = text([CAPTION], device)
        tokens = model.encode_text(tt, pad)
        obj = model.encode_object(torch.from_numpy(points[None]).to(device))

        def x0(x, t, keep):
            n = x.shape[0]
            return model(x, t, keep, tokens.expand(n, -1, -1), pad.expand(n, -1), obj.expand(n, -1, -1))

        out = diffusion.ddim_sample(x0, (1, length, 24, 12), generator=torch.Generator().manual_seed(seed),
                                    device=device, steps=steps)
        if device.type == "cuda":
            torch.cuda.synchronize()
        rows_to_sample(stats.denormalize(out.float().cpu().numpy()))

    params = sum(p.numel() for p in model.parameters())
    return one, params


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--models", nargs="+", default=list(SPECS))
    ap.add_argument("--sizes", nargs="+", default=["tiny", "paper"])
    ap.add_argument("--frames", type=int, default=120, help="sample length (frames); BEHAVE clips average ~6 s")
    ap.add_argument("--samples", type=int, default=3, help="timed samples per model (tiny sizes)")
    ap.add_argument("--paper-samples", type=int, default=1, help="timed samples per model at paper size")
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--threads", type=int, default=None)
    args = ap.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    dev = torch.device(args.device)
    print(f"# AIT (diffusion: 50 DDIM steps with guidance; CATMO: autoregressive tokens), T = {args.frames}, "
          f"device {dev}, torch {torch.__version__}, "
          f"{torch.get_num_threads()} threads, {platform.processor() or platform.machine()}, "
          f"load {os.getloadavg()[0]:.2f}")
    print("| model | size | parameters (M) | AIT (s/sample) | samples |")
    print("|---|---|---:|---:|---:|")
    rows = {}
    for name in args.models:
        for size in args.sizes:
            one, params = make_sampler(name, size, dev)
            n = args.paper_samples if size == "paper" else args.samples
            one(args.frames, 999, steps=2)                   # warm-up
            t0 = time.perf_counter()
            for s in range(n):
                one(args.frames, s)
            ait = (time.perf_counter() - t0) / n
            rows[(name, size)] = ait
            print(f"| {name} | {size} | {params / 1e6:.2f} | {ait:.3f} | {n} |", flush=True)
    names = sorted({n for n, _ in rows})
    if len(names) > 1:
        for size in args.sizes:
            base = rows.get((names[0], size))
            for n in names[1:]:
                if base and (n, size) in rows:
                    print(f"ratio {n}/{names[0]} ({size}): {rows[(n, size)] / base:.3f}")


if __name__ == "__main__":
    main()
