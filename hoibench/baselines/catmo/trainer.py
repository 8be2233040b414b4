"""Training CATMO on a prepared store (``hoibench baseline train catmo``), in stages.

==============  ===========================================  =====================================
stage           trains                                       loss
==============  ===========================================  =====================================
motion_vq       motion VQ-VAE (windows of normalised hml263)  smooth-L1(x^, x) + 0.5 smooth-L1 on
                                                             the joint-position channels + beta L_c
contact_vq      contact VQ-VAE (windows of 22 labels)        BCE(logits, C) + beta L_c
movement_ae     movement encoder part 1 + its decoder        smooth-L1 reconstruction
text_match      text encoder + movement encoder part 2       CATMO supp. eq. 1-3 (margin m)
gpt             intertwined GPT (+ point encoder, HOI)       CE over [m1, c1, ..., END] on corrupted
                                                             inputs + lambda_align alignment loss
object          object head (HOI stores only)                smooth-L1 on normalised object rows
==============  ===========================================  =====================================

The GPT trains on the token sequences of the frozen VQ-VAEs (computed once, after them); the
alignment loss decodes the GPT's expected motion codes with the frozen motion decoder and
embeds them with the frozen movement encoder (the paper does not say how the argmax indices
are made differentiable; the expectation under the predicted distribution is hoibench's
choice). The object head sees the VQ-VAE reconstructions of the motion and contacts, as it
sees decoded tokens at sampling.

Every step draws its batch, windows, captions, corruption and resets from generators
seeded by ``(seed, stage, step)`` and reseeds dropout, so a resumed run equals an
uninterrupted one (same checkpoint id). One checkpoint (``RUN/checkpoint/last.pt``: every
module, the current stage's optimiser, the curves) is written atomically every
``checkpoint_every`` steps, at the end of every stage and on interrupt.
"""
from __future__ import annotations

import json

from ...core.io import MAX_SMALL_JSON_BYTES, read_json_file
import shutil
import time
from pathlib import Path
from typing import Callable

import numpy as np
import torch
import torch.nn.functional as F

from ... import __version__
from ...core.interrupts import check_interrupted
from ...core.io import atomic_torch_save, atomic_write_json, clean_stale_tmp
from ...representations import hml263
from .. import checkpoint as ckpt
from ..text import TextConditioner
from ..trainer import (TrainingDiverged, TrainResult, _existing, _seed, close_window, collect_losses, drop_checkpoint,
                       finished_run, plot_panels, read_checkpoint, start_run)
from . import data as CD
from .config import CatmoConfig, preset
from .gpt import corrupt, interleave
from .model import CATMO
from .textmatch import matching_loss

NAME, TITLE = "catmo", "CATMO"
STAGES = ("motion_vq", "contact_vq", "movement_ae", "text_match", "gpt", "object")
RIC = slice(4, 4 + 21 * 3)          # hml263's root-relative joint positions (T2M-GPT's "velocity" term)


def stage_steps(cfg: CatmoConfig, with_object: bool) -> dict[str, int]:
    t = cfg.train
    return {"motion_vq": t.vq_steps, "contact_vq": t.contact_steps, "movement_ae": cfg.text.movement_ae_steps,
            "text_match": cfg.text.match_steps, "gpt": t.gpt_steps, "object": cfg.object.steps if with_object else 0}


def _masked_mean(x: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
    """Mean of (B, L, C) over the valid (B, L) rows and every channel."""
    w = valid.to(x.dtype)[..., None].expand_as(x)
    return (x * w).sum() / w.sum().clamp_min(1.0)


# ------------------------------------------------------------------------------ tokens
@torch.no_grad()
def clip_tokens(model: CATMO, data: CD.CatmoData, device) -> list[tuple[np.ndarray, np.ndarray]]:
    """(motion indices, contact indices) of every clip, whole clip floored to units."""
    unit = model.cfg.vq.unit
    out = []
    for it in data.items:
        n = len(it.motion) // unit * unit
        m = torch.from_numpy(it.motion[None, :n]).to(device)
        c = torch.from_numpy(it.contacts[None, :n]).to(device)
        out.append((model.motion_vq.encode(m)[0].cpu().numpy(), model.contact_vq.encode(c)[0].cpu().numpy()))
    return out


# ------------------------------------------------------------------------------ one step per stage
class Steps:
    """The loss of one step of each stage (``self.<stage>(step)``)."""

    def __init__(self, model: CATMO, data: CD.CatmoData, cfg: CatmoConfig, text: TextConditioner, device):
        self.model, self.data, self.cfg, self.text, self.dev = model, data, cfg, text, device
        self.tokens: list[tuple[np.ndarray, np.ndarray]] | None = None

    def _rng(self, stage: str, step: int) -> np.random.Generator:
        return np.random.default_rng(_seed(self.cfg.train.seed, stage, "batch", step))

    def _gen(self, stage: str, step: int) -> torch.Generator:
        return torch.Generator().manual_seed(_seed(self.cfg.train.seed, stage, "noise", step))

    def _t(self, a: np.ndarray) -> torch.Tensor:
        return torch.from_numpy(np.ascontiguousarray(a)).to(self.dev)

    def _pick(self, rng: np.random.Generator) -> np.ndarray:
        return rng.integers(0, len(self.data.items), self.cfg.train.batch_size)

    def _windows(self, stage: str, step: int):
        rng = self._rng(stage, step)
        m, c, valid = CD.window_batch(self.data.items, self._pick(rng), self.cfg.vq.window, self.cfg.vq.unit, rng)
        return self._t(m), self._t(c), self._t(valid)

    def _captions(self, pick: np.ndarray, rng: np.random.Generator) -> list[str]:
        caps = [self.data.items[i].captions for i in pick]
        return [c[int(rng.integers(0, len(c)))] for c in caps]

    def _text_embedding(self, captions: list[str]) -> torch.Tensor:
        tt, tpad = self.text(captions, self.dev)
        return self.model.text(tt, tpad)

    def motion_vq(self, step: int) -> dict:
        x, _, valid = self._windows("motion_vq", step)
        u = self.cfg.vq.unit
        o = self.model.motion_vq(x, valid[:, u - 1::u], self._gen("motion_vq", step))
        rec = _masked_mean(F.smooth_l1_loss(o["out"], x, reduction="none"), valid)
        vel = _masked_mean(F.smooth_l1_loss(o["out"][..., RIC], x[..., RIC], reduction="none"), valid)
        loss = rec + self.cfg.vq.lambda_velocity * vel + self.cfg.vq.beta * o["commit"]
        return {"loss": loss, "recon": rec, "position": vel, "commit": o["commit"], "perplexity": o["perplexity"]}

    def contact_vq(self, step: int) -> dict:
        _, c, valid = self._windows("contact_vq", step)
        u = self.cfg.vq.unit
        o = self.model.contact_vq(c, valid[:, u - 1::u], self._gen("contact_vq", step))
        bce = _masked_mean(F.binary_cross_entropy_with_logits(o["out"], c, reduction="none"), valid)
        acc = _masked_mean(((o["out"] > 0).float() == c).float(), valid)
        loss = bce + self.cfg.vq.beta * o["commit"]
        return {"loss": loss, "bce": bce, "commit": o["commit"], "accuracy": acc, "perplexity": o["perplexity"]}

    def movement_ae(self, step: int) -> dict:
        x, _, valid = self._windows("movement_ae", step)
        mv = self.model.movement
        rec = _masked_mean(F.smooth_l1_loss(mv.deconv(mv.conv(x, valid), valid), x, reduction="none"), valid)
        return {"loss": rec}

    def _clips(self, stage: str, step: int):
        rng = self._rng(stage, step)
        pick = self._pick(rng)
        g = self.cfg.gpt
        m, c, o, valid = CD.clip_batch(self.data.items, pick, g.max_units * self.cfg.vq.unit, self.cfg.vq.unit)
        return rng, pick, self._t(m), self._t(c), (None if o is None else self._t(o)), self._t(valid)

    def text_match(self, step: int) -> dict:
        rng, pick, x, _, _, valid = self._clips("text_match", step)
        zt = self._text_embedding(self._captions(pick, rng))
        zm = self.model.movement(x, valid)
        offset = int(rng.integers(1, max(2, len(pick))))
        loss = matching_loss(zt, zm, self.cfg.text.margin, offset)
        d = torch.cdist(zt.detach(), zm.detach())
        return {"loss": loss, "match_top1": (d.argmin(1) == torch.arange(len(pick), device=d.device)).float().mean()}

    def _object_feature(self, pick: np.ndarray) -> torch.Tensor | None:
        if not self.data.with_object:
            return None
        pts = np.stack([self.data.points[self.data.items[i].object_name] for i in pick])
        return self.model.object_feature(self._t(pts))

    def gpt(self, step: int) -> dict:
        if self.tokens is None:
            self.tokens = clip_tokens(self.model, self.data, self.dev)
        cfg, g = self.cfg, self.cfg.gpt
        rng = self._rng("gpt", step)
        pick = self._pick(rng)
        units = [min(len(self.tokens[i][0]), g.max_units) for i in pick]
        U = max(units)
        mi = np.zeros((len(pick), U), np.int64)
        ci = np.zeros((len(pick), U), np.int64)
        for b, (i, u) in enumerate(zip(pick, units)):
            m, c = self.tokens[i]
            a = int(rng.integers(0, len(m) - u + 1)) if len(m) > u else 0
            mi[b, :u], ci[b, :u] = m[a:a + u], c[a:a + u]
        captions = self._captions(pick, rng)
        gen = self._gen("gpt", step)
        Km, Kc = cfg.vq.motion_codes, cfg.vq.contact_codes
        n_units = self._t(np.array(units))
        target, valid = interleave(self._t(mi), self._t(ci), n_units, Km, Kc)
        inputs = corrupt(target[:, :-1], g.corrupt_rate, Km, Kc, g.corruption, gen)
        with torch.no_grad():
            zt = self._text_embedding(captions)
        cond = self.model.condition(zt, self._object_feature(pick))
        logits = self.model.gpt(cond, inputs)
        ce = F.cross_entropy(logits[valid], target[valid])
        acc = (logits[valid].argmax(-1) == target[valid]).float().mean()
        out = {"ce": ce, "accuracy": acc}
        loss = ce
        if g.lambda_align > 0:
            probs = F.softmax(logits[:, 0:2 * U:2, :Km], -1)                     # (B, U, Km)
            rows = torch.arange(U * cfg.vq.unit, device=self.dev)[None]
            vrows = rows < (n_units * cfg.vq.unit)[:, None]
            motion = self.model.motion_vq.decode_soft(probs, vrows[:, cfg.vq.unit - 1::cfg.vq.unit])
            zm = self.model.movement(motion, vrows)
            offset = int(rng.integers(1, max(2, len(pick))))
            align = matching_loss(zt, zm, cfg.text.margin, offset)
            out["align"] = align
            loss = loss + g.lambda_align * align
        return {"loss": loss, **out}

    def object(self, step: int) -> dict:
        rng, pick, x, c, o, valid = self._clips("object", step)
        with torch.no_grad():
            u = self.cfg.vq.unit
            xm = self.model.motion_vq(x, valid[:, u - 1::u])["out"]
            pc = torch.sigmoid(self.model.contact_vq(c, valid[:, u - 1::u])["out"])
            feat = self._object_feature(pick)
        pred = self.model.object_head(xm, pc, feat, valid)
        loss = _masked_mean(F.smooth_l1_loss(pred, o, reduction="none"), valid)
        return {"loss": loss}


# ------------------------------------------------------------------------------ reports
@torch.no_grad()
def vq_report(model: CATMO, data: CD.CatmoData, device) -> dict:
    """Reconstruction error and codebook usage of both VQ-VAEs on ``data``'s clips (whole
    clips floored to units, one at a time): motion MPJPE (m) of the decoded joints against
    the decoded ground-truth features, feature RMSE (normalised units), contact accuracy and
    F1, perplexity and used codes over every token."""
    unit = model.cfg.vq.unit
    err, sq, nfeat, hits, tp, fp, fn, n_lab = 0.0, 0.0, 0, 0, 0, 0, 0, 0
    frames = 0
    m_counts = np.zeros(model.cfg.vq.motion_codes)
    c_counts = np.zeros(model.cfg.vq.contact_codes)
    for it in data.items:
        n = len(it.motion) // unit * unit
        if n == 0:
            continue
        x = torch.from_numpy(it.motion[None, :n]).to(device)
        c = torch.from_numpy(it.contacts[None, :n]).to(device)
        mi = model.motion_vq.encode(x)
        ci = model.contact_vq.encode(c)
        xr = model.motion_vq.decode(mi)[0].cpu().numpy()
        cr = (model.contact_vq.decode(ci)[0] > 0).cpu().numpy()
        m_counts += np.bincount(mi[0].cpu().numpy(), minlength=len(m_counts))
        c_counts += np.bincount(ci[0].cpu().numpy(), minlength=len(c_counts))
        gt = it.motion[:n]
        sq += float(((xr - gt) ** 2).sum())
        nfeat += gt.size
        jr = hml263.decode(xr * data.std + data.mean)
        jg = hml263.decode(gt * data.std + data.mean)
        err += float(np.linalg.norm(jr - jg, axis=-1).mean(-1).sum())
        frames += n
        lab = it.contacts[:n] > 0.5
        hits += int((cr == lab).sum())
        n_lab += lab.size
        tp += int((cr & lab).sum())
        fp += int((cr & ~lab).sum())
        fn += int((~cr & lab).sum())

    def usage(counts: np.ndarray) -> dict:
        p = counts / max(counts.sum(), 1)
        nz = p[p > 0]
        return {"perplexity": float(np.exp(-(nz * np.log(nz)).sum())) if len(nz) else 0.0,
                "codes_used": int((counts > 0).sum()), "codebook": int(len(counts)), "tokens": int(counts.sum())}

    return {"clips": len(data.items), "frames": frames,
            "motion": {"mpjpe_m": err / max(frames, 1), "feature_rmse": float(np.sqrt(sq / max(nfeat, 1))),
                       **usage(m_counts)},
            "contact": {"accuracy": hits / max(n_lab, 1),
                        "f1": 2 * tp / max(2 * tp + fp + fn, 1), "positive_rate": (tp + fn) / max(n_lab, 1),
                        **usage(c_counts)}}


@torch.no_grad()
def match_report(model: CATMO, data: CD.CatmoData, text: TextConditioner, device) -> dict:
    """Top-1 text-to-motion retrieval of the matching model over ``data``'s clips (first caption)."""
    if len(data.items) < 2:
        return {}
    unit = model.cfg.vq.unit
    zt, zm = [], []
    for it in data.items:
        n = min(len(it.motion), model.cfg.gpt.max_units * unit) // unit * unit
        x = torch.from_numpy(it.motion[None, :n]).to(device)
        zm.append(model.movement(x, torch.ones(1, n, dtype=torch.bool, device=device)))
        tt, tpad = text([it.captions[0]], device)
        zt.append(model.text(tt, tpad))
    d = torch.cdist(torch.cat(zt), torch.cat(zm))
    top1 = (d.argmin(1) == torch.arange(len(zt), device=d.device)).float().mean()
    return {"clips": len(zt), "top1": float(top1), "chance": 1.0 / len(zt)}


# ------------------------------------------------------------------------------ training
def _store_block(data: CD.CatmoData) -> dict:
    store = data.store
    m = store.manifest
    reps = m.get("representations", {})
    return {"name": m.get("dataset", ""), "manifest_sha256": store.manifest_sha256(), "split": "train",
            "clips": len(data.items), "clips_without_texts": len(data.missing_texts),
            "fps": float(m.get("config", {}).get("fps", 0.0)), "mode": m.get("config", {}).get("mode", ""),
            "representation": reps.get("hml263", ""), "with_object": data.with_object,
            "store_hml263_stats_sha256": store.stats_sha256("hml263"),
            "store_hoi269_stats_sha256": store.stats_sha256("hoi269") if data.with_object else ""}


def _plot(curves: dict[str, list[dict]], path: Path, title: str) -> None:
    """Each stage's total loss, one panel per stage."""
    plot_panels({s: ([r["step"] for r in curves[s]], [r["loss"] for r in curves[s]])
                 for s in STAGES if curves.get(s)}, path, title)


def _set_trainable(model: CATMO, stage: str) -> list[torch.nn.Parameter]:
    model.eval()
    for p in model.parameters():
        p.requires_grad_(False)
    params = []
    for mod in model.stage_modules(stage):
        mod.train()
        for p in mod.parameters():
            p.requires_grad_(True)
            params.append(p)
    return params


def _save(path: Path, stage: int, step: int, model, opt, curves, window, ident) -> None:
    atomic_torch_save({"stage": stage, "step": step, "model": model.state_dict(),
                       "optimizer": opt.state_dict() if opt is not None else {},
                       "curves": json.dumps(curves), "window": json.dumps(window), **ident}, path)


def _load(path: Path, ident: dict, model, device) -> tuple[int, int, dict, dict, dict]:
    def restore(ck: dict) -> tuple[int, int, dict, dict, dict]:
        stage, step = int(ck["stage"]), int(ck["step"])
        if not 0 <= stage <= len(STAGES) or step < 0:
            raise ValueError(f"stage {stage} step {step} out of range")
        model.load_state_dict(ck["model"])
        return stage, step, ck["optimizer"], json.loads(ck["curves"]), json.loads(ck["window"])  # read-ok: strings inside a checkpoint read by read_checkpoint
    return read_checkpoint(path, ident, device, restore)


def _run_stages(model: CATMO, steps: Steps, cfg: CatmoConfig, steps_of: dict[str, int],
                resumed: tuple[int, int, dict, dict, dict], cpath: Path, ident: dict, stop_after: int | None,
                log: Callable[[str], None], tag: str) -> dict[str, float] | None:
    """Every stage's remaining steps from ``resumed`` (stage, step, optimiser state, curves,
    loss window; ``curves`` is filled in place), checkpointed; each stage's seconds, or None
    when ``stop_after`` stopped the run."""
    stage_i, step, opt_state, curves, window = resumed
    taken = 0
    stage_seconds: dict[str, float] = {}
    while stage_i < len(STAGES):
        stage = STAGES[stage_i]
        total = steps_of[stage]
        if step >= total:
            stage_i, step, opt_state = stage_i + 1, 0, {}
            continue
        params = _set_trainable(model, stage)
        opt = torch.optim.AdamW(params, lr=cfg.train.lr, weight_decay=cfg.train.weight_decay)
        if opt_state:
            opt.load_state_dict(opt_state)
        opt_state = {}
        curve = curves.setdefault(stage, [])
        saved, tl, start = step, time.perf_counter(), step
        while step < total:
            try:
                check_interrupted()
            except KeyboardInterrupt:
                if step > saved:
                    _save(cpath, stage_i, step, model, opt, curves, window, ident)
                raise
            torch.manual_seed(_seed(cfg.train.seed, stage, "dropout", step))
            losses = getattr(steps, stage)(step)
            if not torch.isfinite(losses["loss"]):
                raise TrainingDiverged(f"{tag} {stage} step {step}: non-finite loss "
                                       f"({ {k: float(v.detach()) for k, v in losses.items()} }); lower train.lr")
            opt.zero_grad(set_to_none=True)
            losses["loss"].backward()
            torch.nn.utils.clip_grad_norm_(params, cfg.train.grad_clip)
            opt.step()
            step += 1
            taken += 1
            collect_losses(window, losses)
            if step % cfg.train.log_every == 0 or step == total:
                progress = close_window(window, curve, step, start, tl)
                window = {}
                log(f"{tag} {stage} {step}/{total} {progress}")
            if step == total:
                _save(cpath, stage_i + 1, 0, model, None, curves, window, ident)
                saved = step
            elif step % cfg.train.checkpoint_every == 0:
                _save(cpath, stage_i, step, model, opt, curves, window, ident)
                saved = step
            if stop_after is not None and taken >= stop_after and not (step == total and stage_i == len(STAGES) - 1):
                if step > saved:
                    _save(cpath, stage_i, step, model, opt, curves, window, ident)
                return None
        stage_seconds[stage] = round(time.perf_counter() - tl, 1)
        stage_i, step = stage_i + 1, 0
    return stage_seconds


def _write_result(out: Path, model: CATMO, data_: CD.CatmoData, cfg: CatmoConfig, text: TextConditioner, dev,
                  dataset: dict, curves: dict[str, list[dict]], steps_of: dict[str, int], n_params: dict[str, int],
                  stage_seconds: dict[str, float], cpath: Path, t0: float, log: Callable[[str], None],
                  tag: str) -> TrainResult:
    """VQ and matching reports, the run folder (weights, card), its curves and train log; the checkpoint removed."""
    model.eval()
    reports = {"train": vq_report(model, data_, dev)}
    test = CD.read_data(data_.store, "test", cfg.gpt.object_points, 1,
                        stats=(data_.mean, data_.std, data_.obj_mean, data_.obj_std))
    if test.items:
        reports["test"] = vq_report(model, test, dev)
    match = {"train": match_report(model, data_, text, dev), "test": match_report(model, test, text, dev)}
    state = {"model." + k: v.detach().cpu().contiguous().clone() for k, v in model.state_dict().items()}
    state["stats.hml263_mean"] = torch.from_numpy(data_.mean)
    state["stats.hml263_std"] = torch.from_numpy(data_.std)
    if data_.with_object:
        state["stats.object_mean"] = torch.from_numpy(data_.obj_mean)
        state["stats.object_std"] = torch.from_numpy(data_.obj_std)
    card = {"baseline": NAME, "config": cfg.to_dict(), "dataset": dataset, "text": text.describe(),
            "curves": curves, "vq": reports, "text_match": match,
            "summary": {"steps": sum(steps_of.values()), "stage_steps": steps_of,
                        "parameters": sum(n_params.values()), "parameters_by_module": n_params,
                        "final_loss": {s: c[-1]["loss"] for s, c in curves.items() if c}},
            "seed": cfg.train.seed, "toolkit_version": __version__, "torch_version": torch.__version__.split("+")[0]}
    cid = ckpt.write_run(out, state, card)
    seconds = time.perf_counter() - t0
    if any(curves.values()):
        try:
            _plot(curves, out / ckpt.CURVE_PNG, f"{TITLE} {cfg.name} on {data_.store.manifest.get('dataset', '')} "
                                                f"({cid[:12]})")
        except ImportError:
            log(f"{tag} matplotlib is not installed: {ckpt.CURVE_PNG} not drawn (the curves are in the card)")
    atomic_write_json(out / ckpt.TRAIN_LOG, {"seconds": round(seconds, 1), "device": str(dev),
                                            "hardware": ckpt.hardware(dev), "stage_seconds": stage_seconds})
    drop_checkpoint(cpath)
    card = read_json_file(out / ckpt.CARD, MAX_SMALL_JSON_BYTES, "checkpoint card")
    mv, ct = reports.get("test", reports["train"])["motion"], reports.get("test", reports["train"])["contact"]
    log(f"{tag} VQ ({'test' if 'test' in reports else 'train'}): motion MPJPE {mv['mpjpe_m'] * 100:.2f} cm, "
        f"perplexity {mv['perplexity']:.1f} ({mv['codes_used']}/{mv['codebook']} codes); contacts accuracy "
        f"{ct['accuracy']:.3f}, F1 {ct['f1']:.3f}, perplexity {ct['perplexity']:.1f}")
    log(f"{tag} wrote {out} (checkpoint id {cid[:12]}) in {seconds:.0f} s")
    return TrainResult(out, cid, card, seconds)


def train(data: str | Path, out: str | Path, config: CatmoConfig | str = "tiny", *, device: str = "cpu",
          resume: bool = True, stop_after: int | None = None, threads: int | None = None,
          log: Callable[[str], None] | None = print) -> TrainResult:
    """Train CATMO on ``data``'s train split into the run folder ``out`` (stages above).

    ``stop_after``: stop after this many optimiser steps in total with the checkpoint
    written (an interruption, for tests). All steps 0 writes the untrained model.
    """
    cfg = preset(config) if isinstance(config, str) else config
    tag = f"[{NAME}]"
    log, out, dev, t0 = start_run(out, device, threads, log)
    data_ = CD.read_data(data, "train", cfg.gpt.object_points, cfg.train.min_frames)
    if not data_.items:
        raise ValueError(f"{data}: no train clips with captions and >= {cfg.train.min_frames} rows; annotate the store "
                         f"first (`hoibench annotate {data}`)")
    dataset = _store_block(data_)
    keys = ("manifest_sha256", "store_hml263_stats_sha256", "store_hoi269_stats_sha256")
    finished = finished_run(out, NAME, cfg.to_dict(), dataset, tag, log, keys, store=data_.store)
    if finished is not None:
        return finished
    text = TextConditioner(cfg.text.encoder, cfg.text.max_tokens, data_.vocab)
    torch.manual_seed(_seed(cfg.train.seed, "init"))
    from ..config import check_parameter_count, sizing
    from .config import preset as _preset
    check_parameter_count(lambda c: CATMO(c, *sizing(c, len(text.vocab or []), text.width), data_.with_object), cfg,
                          _preset("paper"), "config")
    model = CATMO(cfg, len(text.vocab or []), text.width, data_.with_object).to(dev)
    steps_of = stage_steps(cfg, data_.with_object)
    ident = {"config": json.dumps(cfg.to_dict(), sort_keys=True), "baseline": NAME,
             **{k: dataset[k] for k in keys}}
    cpath = out / ckpt.CHECKPOINT_DIR / "last.pt"
    resumed = (0, 0, {}, {}, {})                  # stage, step, optimiser state, curves, loss window
    if resume and cpath.exists():
        resumed = _load(cpath, ident, model, dev)
        if resumed[0] < len(STAGES):
            log(f"{tag} resuming at stage {STAGES[resumed[0]]} step {resumed[1]}/{steps_of[STAGES[resumed[0]]]}")
    n_params = {k: sum(p.numel() for p in m.parameters()) for k, m in model.named_children()}
    log(f"{tag} training {cfg.name}: {sum(n_params.values()) / 1e6:.2f} M parameters, {len(data_.items)} train clips, "
        f"{'human-object' if data_.with_object else 'human-only'} store, stages "
        + ", ".join(f"{s} {steps_of[s]}" for s in STAGES if steps_of[s]) + f", device {dev}")
    steps = Steps(model, data_, cfg, text, dev)
    stage_seconds = _run_stages(model, steps, cfg, steps_of, resumed, cpath, ident, stop_after, log, tag)
    if stage_seconds is None:
        return TrainResult(out, "", {}, time.perf_counter() - t0)
    return _write_result(out, model, data_, cfg, text, dev, dataset, resumed[3], steps_of, n_params, stage_seconds,
                         cpath, t0, log, tag)


def train_baseline(spec, data: str | Path, out: str | Path, config: CatmoConfig | str = "tiny", *,
                   device: str = "cpu", resume: bool = True, stop_after: int | None = None,
                   threads: int | None = None, log: Callable[[str], None] | None = print) -> TrainResult:
    """CATMO's train entry point in the baseline registry (``spec``: its
    :class:`~hoibench.baselines.registry.Spec`): :func:`train`."""
    return train(data, out, config, device=device, resume=resume, stop_after=stop_after, threads=threads, log=log)
