"""Where does a SyncDiff run's x0 prediction err: in the low band, the high band, or above the cutoff?

For each run and each test clip of one family (default the TACO-like ``hands``), the clip is
normalised with the run's statistics, noised at a few diffusion steps (seeded), denoised once,
and the error ``x0_pred - x0`` is split with :mod:`hoibench.baselines.syncdiff.frequency` into
the low part (k <= low), the high part (low < k <= cutoff) and the rest (k > cutoff); each
band's mean squared error per frame and column (normalised units) is printed, with the
ground truth's own energy in that band for scale. A model that denoises the high band worse
than another model at the same noise level is the one whose strokes come out wrong.

    python benchmarks/syncdiff_bands.py --data MB_DATA RUN [RUN ...] [--family hands]
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

T_STEPS = (50, 200, 500)


def band_energy(x: torch.Tensor, low: int, cutoff: int) -> tuple[float, float, float]:
    """Mean squared value per frame and column of ``x`` (n, D) in the low band (mean
    included), the high band and above the cutoff (the three add up to the whole)."""
    from hoibench.baselines.syncdiff import frequency as F
    x = x.double()
    lo, coef = F.split(x, low, cutoff)
    hi = F.high_frames(coef, len(x), low)
    rest = x - lo - hi
    return tuple(float((p ** 2).mean()) for p in (lo, hi, rest))


def run_bands(run: Path, data: Path, family: str, seed: int = 0) -> dict[int, np.ndarray]:
    from hoibench.baselines.syncdiff import data as SD
    from hoibench.baselines.syncdiff.sampler import LoadedSyncDiff
    from hoibench.baselines.syncdiff.trainer import condition_inputs, pad_batch
    from hoibench.datasets.store import Store
    loaded = LoadedSyncDiff(run)
    store = Store(data)
    sync = loaded.config.syncdiff
    ids = [c for c in store.clip_ids("test") if f"_{family}_" in c]
    bps = {}
    out: dict[int, list] = {t: [] for t in T_STEPS}
    gen = torch.Generator().manual_seed(seed)
    for cid in ids:
        it = SD.item(SD.load_clip(store, cid))
        lid = loaded.signatures.index(it.signature)
        x = (it.x - loaded.mean[lid].numpy()) / loaded.std[lid].numpy()
        for t in it.templates:
            if t not in bps:
                bps.update(SD.object_bps(store, {t}, loaded.config.model))
        batch = pad_batch([x.astype(np.float32)], [lid], max(loaded.widths), "cpu")
        inputs = condition_inputs([it], bps, loaded.max_objects, loaded.max_skeletons,
                                  loaded.config.model.bps_points, loaded.text, "cpu")
        with torch.no_grad():
            cond = loaded.model.condition(cols=batch["cols"], **inputs)
            for t in T_STEPS:
                tt = torch.tensor([t])
                noise = torch.randn(batch["x0"].shape, generator=gen)
                x_t = loaded.diffusion.q_sample(batch["x0"], tt, noise)
                pred = loaded.model(x_t, tt, batch["frames"], batch["cols"], cond)["x0"]
                D = x.shape[1]
                err = band_energy(pred[0, :, :D] - batch["x0"][0, :, :D], sync.low, sync.cutoff)
                ref = band_energy(batch["x0"][0, :, :D], sync.low, sync.cutoff)
                out[t].append(err + ref)
    return {t: np.mean(v, axis=0) for t, v in out.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("runs", type=Path, nargs="+")
    ap.add_argument("--data", type=Path, required=True)
    ap.add_argument("--family", default="hands")
    args = ap.parse_args()
    torch.set_num_threads(1)
    print(f"family {args.family}: mean squared x0 error per frame and column (normalised units) by band; "
          "GT = the clip's own energy in the band")
    print(f"{'run':28s} {'t':>4s} {'low err':>8s} {'high err':>9s} {'>cut err':>9s} {'GT low':>7s} {'GT high':>8s}")
    for run in args.runs:
        for t, v in run_bands(run, args.data, args.family).items():
            print(f"{run.name:28s} {t:4d} {v[0]:8.4f} {v[1]:9.4f} {v[2]:9.4f} {v[3]:7.4f} {v[4]:8.4f}")


if __name__ == "__main__":
    main()
