"""Training SyncDiff on a multi-body store (``hoibench baseline train syncdiff``): its
registry train entry point, on the shared run folder, card, EMA, checkpoint and resume
machinery of :mod:`hoibench.baselines.trainer`.

Every step draws its batch, windows, timesteps and noise from generators seeded by
``(seed, step)`` and reseeds dropout, so a resumed run equals an uninterrupted one (same
checkpoint id).
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Callable

import numpy as np
import torch

from ...representations import multibody as R
from ..diffusion import EMA, GaussianDiffusion
from ..text import TextConditioner
from ..trainer import TrainResult, _seed, finish_run, finished_run, resume_point, run_steps, start_run
from . import data as SD
from . import losses as L
from .config import SyncRunConfig, preset
from .data import SHAPE_WIDTH
from .model import SyncDiffNet


def build_model(cfg: SyncRunConfig, width: int, vocab: int, text_width: int, max_objects: int,
                max_skeletons: int, seed: int) -> SyncDiffNet:
    torch.manual_seed(_seed(seed, "init"))
    return SyncDiffNet(cfg.model, cfg.syncdiff, width, vocab, text_width, max_objects, max_skeletons,
                       SHAPE_WIDTH + 1)


def dataset_block(ts: SD.TrainingSet) -> dict:
    m = ts.store.manifest
    return {"name": m.get("dataset", ""), "manifest_sha256": ts.store.manifest_sha256(), "split": "train",
            "clips": len(ts.items), "fps": float(m.get("config", {}).get("fps", 0.0)),
            "representation": R.VERSION, "signatures": ts.signatures, "widths": ts.widths,
            "max_objects": ts.max_objects, "max_skeletons": ts.max_skeletons,
            "syncdiff_stats_sha256": ts.stats.sha256()}


def condition_inputs(items: list[SD.Item], bps_features: dict, max_objects: int, max_skeletons: int,
                     bps_points: int, text: TextConditioner, device) -> dict:
    """The condition inputs of ``items`` for :meth:`SyncDiffNet.condition` (less the column mask)."""
    geo, shp = zip(*(SD.condition_arrays(it, bps_features, max_objects, max_skeletons, bps_points) for it in items))
    return {"action": text([it.action for it in items], device), "objects": text([it.objects for it in items], device),
            "geo": torch.from_numpy(np.stack(geo)).to(device), "shapes": torch.from_numpy(np.stack(shp)).to(device)}


def pad_batch(xs: list[np.ndarray], lids: list[int], width: int, device) -> dict:
    """Normalised clips (T_i, D_i) -> padded ``x0`` (B, T, width), ``frames``, ``cols``, ``layout``."""
    T = max(len(x) for x in xs)
    x0 = np.zeros((len(xs), T, width), np.float32)
    frames = np.zeros((len(xs), T), bool)
    cols = np.zeros((len(xs), width), np.float32)
    for b, x in enumerate(xs):
        x0[b, :len(x), :x.shape[1]], frames[b, :len(x)], cols[b, :x.shape[1]] = x, True, 1.0
    f = lambda a: torch.from_numpy(a).to(device)   # noqa: E731
    return {"x0": f(x0), "frames": f(frames), "cols": f(cols), "layout": torch.tensor(lids, device=device)}


def make_batch(ts: SD.TrainingSet, cfg: SyncRunConfig, step: int, text: TextConditioner, device) -> dict:
    """The batch of ``step``: clips and windows drawn from ``(seed, step)``."""
    rng = np.random.default_rng(_seed(cfg.train.seed, "batch", step))
    W = cfg.train.max_frames
    picks = [ts.items[i] for i in rng.integers(0, len(ts.items), cfg.train.batch_size)]
    xs, lids = [], []
    for it in picks:
        a = int(rng.integers(0, len(it.x) - W + 1)) if len(it.x) > W else 0
        sig = it.signature
        xs.append((it.x[a:a + W] - ts.stats.mean[sig]) / ts.stats.std[sig])
        lids.append(ts.signatures.index(sig))
    batch = pad_batch(xs, lids, ts.width, device)
    batch["inputs"] = condition_inputs(picks, ts.bps_features, ts.max_objects, ts.max_skeletons,
                                       cfg.model.bps_points, text, device)
    return batch


def _one_step(model, diffusion, ts, cfg, step, text, dev, layouts, mean, std) -> dict:
    torch.manual_seed(_seed(cfg.train.seed, "dropout", step))
    gen = torch.Generator().manual_seed(_seed(cfg.train.seed, "noise", step))
    batch = make_batch(ts, cfg, step, text, dev)
    batch["cond"] = model.condition(cols=batch["cols"], **batch["inputs"])
    return L.compute(model, diffusion, batch, cfg.syncdiff, layouts, mean, std, gen)


def train_syncdiff(spec, data: str | Path, out: str | Path, config: SyncRunConfig | str = "tiny", *,
                   device: str = "cpu", resume: bool = True, stop_after: int | None = None,
                   threads: int | None = None, log: Callable[[str], None] | None = print) -> TrainResult:
    """Train SyncDiff on ``data``'s train split into the run folder ``out`` (``steps = 0``:
    the untrained model); see :func:`hoibench.baselines.trainer.train`."""
    cfg = preset(config) if isinstance(config, str) else config
    tag = f"[{spec.name}]"
    log, out, dev, t0 = start_run(out, device, threads, log)
    ts = SD.training_set(data, cfg)
    dataset = dataset_block(ts)
    finished = finished_run(out, spec.name, cfg.to_dict(), dataset, tag, log, keys=("manifest_sha256",))
    if finished is not None:
        return finished
    text = TextConditioner(cfg.model.text_encoder, cfg.model.text_max_tokens, ts.vocab)
    model = build_model(cfg, ts.width, len(text.vocab or []), text.width, ts.max_objects, ts.max_skeletons,
                        cfg.train.seed).to(dev)
    ema = EMA(model, cfg.train.ema_decay)
    opt = torch.optim.Adam(model.parameters(), lr=cfg.train.lr, weight_decay=cfg.train.weight_decay)
    diffusion = GaussianDiffusion(cfg.diffusion)
    mean = [torch.from_numpy(ts.stats.mean[s]).to(dev) for s in ts.signatures]
    std = [torch.from_numpy(ts.stats.std[s]).to(dev) for s in ts.signatures]
    ident = {"config": cfg.sha(), "store": dataset["manifest_sha256"], "stats": dataset["syncdiff_stats_sha256"],
             "baseline": spec.name}
    cpath, step, curve, window = resume_point(out, resume, ident, cfg.train.steps, model, ema, opt, dev, log, tag)
    start = step
    n_params = sum(p.numel() for p in model.parameters())
    log(f"{tag} training {cfg.name}: {n_params / 1e6:.2f} M parameters, {len(ts.items)} train clips, "
        f"{len(ts.signatures)} layouts, {cfg.train.steps} steps of {cfg.train.batch_size}, device {dev}")
    tl = time.perf_counter()
    stopped = run_steps(model, ema, opt, cfg.train,
                        lambda step: _one_step(model, diffusion, ts, cfg, step, text, dev, ts.layouts, mean, std),
                        step=step, curve=curve, window=window, cpath=cpath, ident=ident, out=out, t0=t0, tag=tag,
                        log=log, stop_after=stop_after)
    if stopped is not None:
        return stopped
    state = {"model." + k: v.detach().cpu().contiguous().clone() for k, v in ema.state_dict().items()}
    state.update(ts.stats.tensors(ts.signatures))
    return finish_run(spec, cfg, state, dataset, text, curve, n_params, out, dev, t0, tl, start, cpath, log, tag,
                      dataset["name"])
