"""Sampling a SyncDiff run into a multi-body submission (``hoibench baseline sample syncdiff``).

For each clip of the split (test by default), conditioned on its action label, object
labels and geometry and its skeletons' shapes, ``K`` samples of the ground truth's length
and body layout are drawn by ancestral (DDPM) sampling over ``diffusion.ddim_steps`` evenly
spaced timesteps (the posterior ``q(x_{s} | x_t, x0)`` between visited steps ``t > s``),
from noise seeded by ``(seed, clip id)``. With ``explicit_sync`` on, every
``sync_every``-th visited step (the last one included) fuses the de-normalised x0 prediction
(:func:`.sync.explicit_sync`), and that step's noise scale per column is divided by
``sqrt(1 + w n)`` (the fused Gaussian's; the paper's noise-scale rule). The individual blocks
of the result are decoded into bodies and written as a standard multi-body submission.
"""
from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path
from typing import Callable

import numpy as np
import torch

from ...core.interrupts import check_interrupted
from ...datasets.store import Store
from ...representations import multibody as R
from .. import checkpoint as ckpt
from ..diffusion import GaussianDiffusion
from ..sampler import StoreMismatch, load_model_tensors, run_text_conditioner, submission_meta, write_logged
from ..registry import get_spec
from ..trainer import _seed
from . import data as SD
from .config import ModelConfig, SyncRunConfig
from .sync import explicit_sync
from .trainer import build_model, condition_inputs, pad_batch


#: the settings that act at sampling only (``hoibench baseline sample syncdiff --set``)
INFERENCE_FIELDS = ("syncdiff.explicit_sync", "syncdiff.sync_every", "syncdiff.sync_weight")


def posterior(abar_t: float, abar_s: float) -> tuple[float, float, float]:
    """(c0, ct, sigma) of ``q(x_s | x_t, x0) = N(c0 x0 + ct x_t, sigma^2)`` for ``s < t``."""
    beta = 1.0 - abar_t / abar_s
    c0 = abar_s ** 0.5 * beta / (1.0 - abar_t)
    ct = (abar_t / abar_s) ** 0.5 * (1.0 - abar_s) / (1.0 - abar_t)
    return c0, ct, (beta * (1.0 - abar_s) / (1.0 - abar_t)) ** 0.5


class LoadedSyncDiff:
    """A verified SyncDiff run: config, model (EMA weights, eval mode), statistics."""

    requires_object = False

    def __init__(self, folder: str | Path, device: str = "cpu", verified: tuple[dict, bytes] | None = None):
        from safetensors.torch import load as load_tensors
        self.folder = Path(folder)
        self.card, data = verified or ckpt.verify_run(self.folder, "syncdiff")
        self.id = self.card[ckpt.ID_KEY]
        self.spec = get_spec("syncdiff")
        self.config = SyncRunConfig.from_dict(self.card["config"], ModelConfig, f"{self.folder / ckpt.CARD}: config")
        ds = self.card["dataset"]
        self.signatures, self.widths = list(ds["signatures"]), [int(w) for w in ds["widths"]]
        self.max_objects, self.max_skeletons = int(ds["max_objects"]), int(ds["max_skeletons"])
        tensors = load_tensors(data)
        self.mean = [tensors.pop(f"stats.{i}.mean") for i in range(len(self.signatures))]
        self.std = [tensors.pop(f"stats.{i}.std") for i in range(len(self.signatures))]
        m = self.config.model
        self.text, vocab = run_text_conditioner(self.card, m.text_encoder, m.text_max_tokens, self.folder)
        self.device = torch.device(device)
        self.model = build_model(self.config, max(self.widths), len(vocab or []), self.text.width,
                                 self.max_objects, self.max_skeletons, 0)
        load_model_tensors(self.model, tensors, self.folder)
        self.model.to(self.device).eval()
        self.diffusion = GaussianDiffusion(self.config.diffusion)
        self._bps: dict[str, np.ndarray] = {}

    def check_store(self, store: Store) -> None:
        ds = self.card["dataset"]
        fps = float(store.manifest.get("config", {}).get("fps", 0.0))
        if not store.is_multibody:
            raise StoreMismatch(f"{store.root}: not a multi-body store; SyncDiff writes multi-body submissions")
        if fps != ds.get("fps"):
            raise StoreMismatch(f"{store.root}: fps {fps}, the run {self.id[:12]} was trained at {ds.get('fps')}")

    def options(self, steps: int | None = None) -> dict:
        n = self.config.diffusion.ddim_steps if steps is None else int(steps)
        if not 1 <= n <= self.config.diffusion.steps:
            raise ValueError(f"--ddim-steps: expected an integer in [1, {self.config.diffusion.steps}], got {steps!r}")
        return {"sampling_steps": n}

    def _bps_of(self, store: Store, names) -> dict[str, np.ndarray]:
        missing = [n for n in names if n not in self._bps]
        if missing:
            self._bps.update(SD.object_bps(store, missing, self.config.model))
        return self._bps

    @torch.no_grad()
    def generate(self, store: Store, gt, k: int, seed_parts: tuple, steps: int | None = None) -> list:
        """``k`` generated clips shaped like ``gt`` (a :class:`MultiBodyClip`)."""
        it = SD.item(gt)
        if it.signature not in self.signatures:
            raise ValueError(f"{gt.name}: body layout {it.signature!r} is not one the run was trained on "
                             f"({'; '.join(self.signatures)})")
        lid = self.signatures.index(it.signature)
        mean, std = self.mean[lid].to(self.device), self.std[lid].to(self.device)
        T, D, W = len(it.x), self.widths[lid], max(self.widths)
        batch = pad_batch([np.zeros((T, D), np.float32)] * k, [lid] * k, W, self.device)
        inputs = condition_inputs([it] * k, self._bps_of(store, it.templates), self.max_objects, self.max_skeletons,
                                  self.config.model.bps_points, self.text, self.device)
        cond = self.model.condition(cols=batch["cols"], **inputs)
        x0 = self.sample_loop(cond, batch["frames"], batch["cols"], R.layout(gt), mean, std, seed_parts, steps)
        raw = (x0[..., :D] * std + mean).double().cpu().numpy()
        return [replace(gt, bodies=R.decode(r, gt)) for r in raw]

    def sample_loop(self, cond, frames, cols, blocks, mean, std, seed_parts: tuple, steps: int | None = None
                    ) -> torch.Tensor:
        """Normalised x0 (K, T, W) by ancestral sampling with explicit synchronization."""
        sd = self.config.syncdiff
        gen = torch.Generator().manual_seed(_seed(*seed_parts))
        K, T, W, D = frames.shape[0], frames.shape[1], cols.shape[1], mean.shape[0]
        pad = frames.float()[..., None] * cols[:, None]
        x = torch.randn((K, T, W), generator=gen).to(self.device) * pad
        ts = self.diffusion.ddim_timesteps(steps)
        abar = self.diffusion.alphas_cumprod
        x0 = x
        for i, t in enumerate(ts):
            tt = torch.full((K,), t, dtype=torch.long, device=self.device)
            x0 = self.model(x, tt, frames, cols, cond)["x0"] * pad
            scale = torch.ones(W, device=self.device)
            if sd.explicit_sync and (i + 1) % sd.sync_every == 0:
                raw, gain = explicit_sync(x0[..., :D] * std + mean, blocks, sd.sync_weight)
                x0 = x0.clone()
                x0[..., :D] = ((raw - mean) / std) * frames[..., None]
                scale[:D] = gain.rsqrt().float()
            z = torch.randn((K, T, W), generator=gen).to(self.device)
            if i == len(ts) - 1:
                break
            c0, ct, sigma = posterior(float(abar[t]), float(abar[ts[i + 1]]))
            x = (c0 * x0 + ct * x + sigma * scale * z) * pad
        return x0

    def write_store_submission(self, data, out, *, samples: int = 1, seed: int = 0, split: str = "test",
                               steps: int | None = None, as_zip: bool = False, limit: int | None = None,
                               log: Callable[[str], None] | None = print, inference: dict | None = None) -> Path:
        """A multi-body submission of ``samples`` samples per clip of ``split``; ``inference``
        overrides the inference-time fields :data:`INFERENCE_FIELDS` (e.g. the "w/o exp sync"
        ablation of a run trained with it: explicit synchronization acts at sampling only)."""
        from ...scoring.multibody_samples import sample_arrays
        log = log or (lambda s: None)
        if inference:
            bad = sorted(set(inference) - set(INFERENCE_FIELDS))
            if bad:
                raise ValueError(f"--set {bad[0]}: not an inference-time setting (those are "
                                 f"{', '.join(INFERENCE_FIELDS)})")
            self.config = self.config.replace(**inference)
        store = Store(data)
        self.check_store(store)
        ids = store.clip_ids(split)[:limit]
        if not ids:
            raise ValueError(f"{data}: split {split!r} has no clips")
        opts = self.options(steps)
        sd = self.config.syncdiff
        meta = submission_meta("SyncDiff", "syncdiff", self, store, samples=samples, seed=seed, split=split,
                               representation="multibody-joints", selection="last (EMA)",
                               settings={**opts, "decompose": sd.decompose, "align_loss": sd.align_loss,
                                         "explicit_sync": sd.explicit_sync, "sync_every": sd.sync_every,
                                         "sync_weight": sd.sync_weight, "inference_overrides": dict(inference or {}),
                                         "condition": "action label, object labels, BPS, shapes"})
        t0 = time.perf_counter()

        def gen():
            for i, cid in enumerate(ids):
                check_interrupted()
                gt = SD.load_clip(store, cid)
                clips = self.generate(store, gt, samples, (seed, "sample", cid), opts["sampling_steps"])
                log(f"[syncdiff] sampled {i + 1}/{len(ids)} {cid} (K={samples}, T={gt.num_frames}) "
                    f"{time.perf_counter() - t0:.1f} s")
                yield cid, sample_arrays(clips)

        return write_logged(out, meta, gen(), clips=len(ids), samples=samples, tag="[syncdiff]", t0=t0,
                            as_zip=as_zip, log=log)
