"""Training an evaluator on a store's train split, with checkpoints and exact resume.

Reproducibility: everything random is a function of ``(seed, epoch)``: the model is
initialised after ``torch.manual_seed(seed)``; at the start of epoch ``e`` torch's generator
is reseeded from ``(seed, e)`` (dropout) and ``numpy.random.default_rng([seed, e])`` draws the
item order, the caption of each item and the crop window of motions longer than
``max_frames``. A checkpoint (``OUT/checkpoint/last.pt``: model, AdamW and scheduler
state, curve, torch RNG state) is written atomically every ``checkpoint_every`` epochs and
after the last one, so a run interrupted at any point and restarted with the same arguments
ends with the same weights, card and evaluator id as an uninterrupted run (tested).
Training runs under ``torch.use_deterministic_algorithms(True, warn_only=True)`` with
``threads`` CPU threads.

While the sentence encoder is frozen (epochs < ``text_unfreeze_epoch``), its pooled outputs
for every caption are computed once in eval mode and reused (exactly what it would compute,
as a frozen encoder runs without dropout); from ``text_unfreeze_epoch`` on it is fine-tuned
with ``text_lr`` after its own linear warm-up. The learning rate warms up linearly for
``warmup_epochs`` and then follows a cosine to 10 % of its peak.

At the end: GT retrieval on the test split (:mod:`hoibench.evaluator.retrieval`), the sanity
gate (:mod:`hoibench.evaluator.gate`), and the evaluator folder (:mod:`hoibench.evaluator.card`).
"""
from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import torch

from .. import __version__
from ..core.io import (atomic_save_figure, atomic_torch_save, atomic_write_text, check_regular_file, clean_stale_tmp,
                       finished_output)
from ..datasets.store import Store, legacy_manifest_sha256, manifest_sha256
from . import card as card_mod
from . import text as text_mod
from .config import EvaluatorConfig, preset
from .data import SplitItems, feature_key, load_items, store_protocol
from .embed import Evaluator, deterministic
from .features import FeatureStats, object_relative, object_stats
from .errors import CheckpointError, EvaluatorFolderExists, EvaluatorIntegrityError
from .gate import GateResult, sanity_gate
from .model import TextMotionModel, contrastive_loss
from .retrieval import gt_scores

CHECKPOINT_DIR = "checkpoint"
CHECKPOINT = "last.pt"
CHECKPOINT_FORMAT = "hoibench-evaluator-checkpoint-1"
_CONTROL_SEED_TAG = 777


@dataclass
class TrainResult:
    out: Path
    status: str                      # "trained" | "already_trained" | "interrupted"
    evaluator_id: str | None
    card: dict | None
    gate: GateResult | None
    epochs_run: int                  # epochs run by this call


def _epoch_seed(seed: int, epoch: int) -> int:
    return int(np.random.SeedSequence([int(seed), int(epoch), 31337]).generate_state(1)[0])


def feature_stats(store: Store, variant: str, train_clip_ids: list[str]) -> FeatureStats:
    """The store's train-split hml263 statistics, plus object-relative ones for ``hoi``."""
    ns = store.stats("hml263")
    if variant == "human":
        return FeatureStats(ns.mean, ns.std)
    om, os_ = object_stats([object_relative(store.load(cid)["hoi269"]) for cid in sorted(train_clip_ids)])
    return FeatureStats(ns.mean, ns.std, om, os_)


def build_untrained(config: EvaluatorConfig, stats: FeatureStats, text_encoder: str | None = None,
                    seed: int = 0) -> Evaluator:
    """An evaluator with random motion/projection weights (for tests and the sanity gate)."""
    name, path = text_mod.resolve_text_encoder(text_encoder)
    tok, transformer = text_mod.load_pretrained(path)
    torch.manual_seed(seed)
    model = TextMotionModel(config.model, transformer, text_mod.pooling_mode(path))
    card = {"text_encoder": {"name": name, "weights_sha256": text_mod.weights_sha256(path)}}
    return Evaluator(config, model, tok, stats, card)


def _lr_lambdas(cfg: EvaluatorConfig, steps_per_epoch: int):
    t = cfg.train
    total = t.epochs * steps_per_epoch
    warm = max(1, t.warmup_epochs * steps_per_epoch)

    def cosine(step: int) -> float:
        p = min(1.0, max(0.0, (step - warm) / max(1, total - warm)))
        return 0.1 + 0.9 * 0.5 * (1.0 + math.cos(math.pi * p))

    def main(step: int) -> float:
        return (step + 1) / warm if step < warm else cosine(step)

    start = t.text_unfreeze_epoch * steps_per_epoch

    def text(step: int) -> float:
        if step < start:
            return 0.0
        k = step - start
        return min(1.0, (k + 1) / warm) * cosine(step)

    return main, text


def _param_groups(model: TextMotionModel, cfg: EvaluatorConfig) -> list[dict]:
    decay, no_decay = [], []
    for name, p in model.named_parameters():
        if name.startswith("text.transformer."):
            continue
        (decay if p.ndim >= 2 else no_decay).append(p)
    t = cfg.train
    return [{"params": decay, "lr": t.lr, "weight_decay": t.weight_decay},
            {"params": no_decay, "lr": t.lr, "weight_decay": 0.0},
            {"params": list(model.text.transformer.parameters()), "lr": t.text_lr, "weight_decay": t.weight_decay}]


def _batches(perm: np.ndarray, batch_size: int) -> list[np.ndarray]:
    out = [perm[i:i + batch_size] for i in range(0, len(perm), batch_size)]
    return [b for b in out if len(b) >= 2]


def _curve_summary(curve: list[dict]) -> dict:
    if not curve:
        return {}
    return {"epochs": len(curve), "first_loss": curve[0]["loss"], "final_loss": curve[-1]["loss"],
            "min_loss": min(c["loss"] for c in curve), "final_batch_top1": curve[-1]["batch_top1"],
            "final_temperature": curve[-1]["temperature"]}


def plot_curve(curve: list[dict], path: Path, unfreeze_epoch: int | None = None, title: str = "") -> None:
    """Loss, in-batch top-1 and temperature per epoch, as a PNG (matplotlib, Agg)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ep = [c["epoch"] for c in curve]
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.4))
    for ax, key, label in zip(axes, ("loss", "batch_top1", "temperature"),
                              ("symmetric InfoNCE loss", "in-batch top-1 (text -> motion)", "temperature")):
        ax.plot(ep, [c[key] for c in curve], lw=1.5)
        ax.set_xlabel("epoch")
        ax.set_title(label, fontsize=10)
        if unfreeze_epoch is not None and 0 < unfreeze_epoch < (ep[-1] if ep else 0):
            ax.axvline(unfreeze_epoch, color="gray", ls="--", lw=1)
        ax.grid(alpha=0.3)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    atomic_save_figure(fig, path)


#: what an evaluator output folder may hold before training (an interrupted run's leftovers)
_OUTPUT_ENTRIES = {CHECKPOINT_DIR, card_mod.WEIGHTS, card_mod.CURVE_PNG, card_mod.TRAIN_LOG}


def existing_output(out: Path, cfg: EvaluatorConfig, msha: str, legacy_msha: str | None = None) -> dict | None:
    """The card when ``out`` already holds this evaluator (same config and store manifest:
    ``msha``, or ``legacy_msha`` for a folder written before ids came from content only);
    None when ``out`` is free (missing, empty, or an interrupted run: checkpoint, partial
    files). :class:`EvaluatorFolderExists` otherwise, saying what is there."""
    if not finished_output(out, card_mod.CARD, _OUTPUT_ENTRIES, {CHECKPOINT_DIR}, "an evaluator folder",
                           EvaluatorFolderExists):
        return None
    try:
        card, _ = card_mod.verify_folder(out)
    except EvaluatorIntegrityError as exc:
        raise EvaluatorFolderExists(f"{out}: holds an evaluator folder that does not verify ({exc}); delete it or "
                                    f"choose another --out") from None
    diff = card_mod.dict_diff(card.get("config"), cfg.to_dict(), "config")
    if card.get("dataset", {}).get("manifest_sha256") not in (msha, legacy_msha or msha):
        diff.append("dataset.manifest_sha256 (another store)")
    if not diff:
        return card
    raise EvaluatorFolderExists(f"{out}: already holds evaluator {str(card.get('evaluator_id', '?'))[:12]}, trained "
                                f"with another recipe or store (differs in {', '.join(diff[:4])}"
                                f"{'...' if len(diff) > 4 else ''}); choose another --out or delete the folder")


def _read_checkpoint(path: Path, device) -> dict:
    """``torch.load(..., weights_only=True)`` of ``path``; :class:`CheckpointError` naming
    the file when it is not a readable checkpoint (truncated, garbage, pickled objects)."""
    try:
        check_regular_file(path, "training checkpoint")
        ck = torch.load(path, map_location=device, weights_only=True)  # read-ok: weights_only, regular file checked
    except Exception as exc:                  # torch raises many types for a bad file
        raise CheckpointError(f"{path}: not a readable training checkpoint ({type(exc).__name__}: "
                              f"{' '.join(str(exc).split())[:200]}); delete it to restart training from epoch 0 "
                              f"(same seed, same evaluator; only the time is lost)") from None
    if not isinstance(ck, dict):
        raise CheckpointError(f"{path}: not a hoibench training checkpoint (holds a {type(ck).__name__}); "
                              f"delete it to restart training from epoch 0")
    return ck


def resume_checkpoint(path: Path, ident: dict, epochs: int, model, opt, sched, device) -> list[dict]:
    """Load ``path`` into model, optimiser and scheduler; return the training curve so far
    (its length is the epoch to resume from). :class:`CheckpointError` when the file is
    unreadable, of another recipe, store, caption set or text encoder, or inconsistent."""
    ck = _read_checkpoint(path, device)
    other = sorted(k for k in ident if ck.get(k) != ident[k])
    if other:
        raise CheckpointError(f"{path}: checkpoint of another config, dataset, texts or text encoder (differs in "
                              f"{', '.join(other)}); delete it to start over or use another output folder")
    try:
        epoch = ck["epoch"]
        curve = json.loads(ck["curve"])  # read-ok: a string inside the checkpoint read above
        if not isinstance(epoch, int) or not 1 <= epoch <= epochs or not isinstance(curve, list) \
                or len(curve) != epoch:
            raise ValueError(f"epoch {epoch!r} with {len(curve) if isinstance(curve, list) else '?'} curve entries "
                             f"(training has {epochs} epochs)")
        missing, unexpected = model.load_state_dict(ck["model"], strict=False)
        if unexpected or any(not k.startswith("text.transformer.") for k in missing):
            raise ValueError(f"tensors do not match the model (unexpected {unexpected[:2]}, missing "
                             f"{[k for k in missing if not k.startswith('text.transformer.')][:2]})")
        opt.load_state_dict(ck["optimizer"])
        sched.load_state_dict(ck["scheduler"])
        torch.set_rng_state(ck["torch_rng"].cpu())   # (each epoch reseeds anyway)
    except Exception as exc:                  # KeyError, TypeError, size mismatches, bad JSON ...
        raise CheckpointError(f"{path}: inconsistent training checkpoint ({type(exc).__name__}: "
                              f"{' '.join(str(exc).split())[:200]}); delete it to restart training from epoch 0"
                              ) from None
    return curve


def _load_splits(store: Store, cfg: EvaluatorConfig, log: Callable[[str], None]) -> tuple[SplitItems, SplitItems]:
    """The captioned train and test items, checked (the ``shuffled_texts`` control applied)."""
    variant, tc = cfg.model.variant, cfg.train
    rep = store.manifest.get("representations", {}).get("hoi269", "")
    if variant == "hoi" and "clean" not in rep:
        raise ValueError(f"{store.root}: the hoi variant needs clean hoi269 rows (object rotation in the body's "
                         f"canonical frame); this store has {rep!r}: prepare it with --mode clean")
    train = load_items(store, "train", variant, tc.min_frames)
    test = load_items(store, "test", variant, tc.min_frames)
    if not train.items and not test.items:
        raise FileNotFoundError(f"{store.root / 'texts'}: no caption files (<clip id>.txt, HumanML3D lines "
                                f"'caption#tokens#start#end'); run `hoibench annotate` on the store first")
    if len(train.items) < 2:
        raise ValueError(f"train split: {len(train.items)} captioned items; at least 2 are needed "
                         f"({len(train.missing_texts)} train clips have no text file)")
    if len(test.items) < 4:
        raise ValueError(f"test split: {len(test.items)} captioned items; at least 4 are needed for GT "
                         f"retrieval and the GT-vs-GT FID")
    for s in (train, test):
        if s.missing_texts:
            log(f"[train-evaluator] {len(s.missing_texts)} {s.split} clips have no caption file and are left out "
                f"(e.g. {s.missing_texts[0]})")
    if tc.control == "shuffled_texts":
        perm = np.random.default_rng([tc.seed, _CONTROL_SEED_TAG]).permutation(len(train.items))
        caps = [train.items[j].captions for j in perm]
        for it, c in zip(train.items, caps):
            it.captions = c
    return train, test


@dataclass
class _Setup:
    """What a training call fixed before the first epoch: data, statistics, text encoder, checkpoint."""
    cfg: EvaluatorConfig
    out: Path
    store: Store
    msha: str
    train: SplitItems
    test: SplitItems
    stats: FeatureStats
    te_name: str
    te_sha: str
    pooling: str
    tok: object
    transformer: object
    tsha: str
    ckpt_path: Path
    ident: dict
    log: Callable[[str], None]


def _setup(store: Store, out: Path, cfg: EvaluatorConfig, msha: str, text_encoder: str | None,
           log: Callable[[str], None]) -> _Setup:
    """Items, statistics (checked against the manifest), the text encoder and the checkpoint identity."""
    train, test = _load_splits(store, cfg, log)
    stats = feature_stats(store, cfg.model.variant, train.clip_ids)
    recorded = store.manifest.get("stats", {}).get("hml263", {}).get("sha256")
    if recorded and recorded != stats.sha256():
        raise ValueError(f"{store.root}: stats/hml263.npz does not match the manifest's sha256 (store modified?)")
    te_name, te_path = text_mod.resolve_text_encoder(text_encoder)
    te_sha = text_mod.weights_sha256(te_path)
    pooling = text_mod.pooling_mode(te_path)
    tok, transformer = text_mod.load_pretrained(te_path)
    tsha = text_mod.texts_sha256(store.root, sorted(set(train.clip_ids) | set(test.clip_ids)))
    ident = {"format": CHECKPOINT_FORMAT, "config_sha256": cfg.sha256(), "manifest_sha256": msha,
             "texts_sha256": tsha, "text_encoder_sha256": te_sha}
    return _Setup(cfg, out, store, msha, train, test, stats, te_name, te_sha, pooling, tok, transformer, tsha,
                  out / CHECKPOINT_DIR / CHECKPOINT, ident, log)


@dataclass
class _Fit:
    """The outcome of the epoch loop: the model, its curve and (unless interrupted) its GT scores."""
    model: TextMotionModel
    curve: list[dict]
    vocab: list[str]
    epochs_run: int
    resumed_from: int | None
    interrupted: bool = False
    gt: dict | None = None
    tr: dict | None = None


def _run_epoch(e: int, su: _Setup, model: TextMotionModel, ev: Evaluator, opt, sched, params: list,
               prepared: list, cap_idx: list[list[int]], vocab: list[str], cache) -> dict:
    """One epoch's optimiser steps (order, captions and crops drawn from ``(seed, e)``); its curve row."""
    mc, tc = su.cfg.model, su.cfg.train
    dev = ev.device
    n = len(prepared)
    torch.manual_seed(_epoch_seed(tc.seed, e))
    rng = np.random.default_rng([tc.seed, e])
    perm = rng.permutation(n)
    pick = rng.integers(0, 1 << 30, size=n)
    crop_u = rng.random(n)
    frozen = e < tc.text_unfreeze_epoch
    model.text.set_frozen(frozen, tc.text_finetune_layers)
    model.train()
    tot_loss = tot_acc = 0.0
    count = 0
    for b in _batches(perm, tc.batch_size):
        caps = torch.tensor([cap_idx[i][pick[i] % len(cap_idx[i])] for i in b])
        crops = [int(crop_u[i] * (len(prepared[i][0]) - mc.max_frames + 1))
                 if len(prepared[i][0]) > mc.max_frames else 0 for i in b]
        body, lens, obj = ev._motion_batch([prepared[i] for i in b], crops)
        m_emb = model.motion(body, lens, obj)
        if frozen:
            pooled = cache[caps.to(dev)]
        else:
            pooled = model.text.pooled(ev.tokenize([vocab[c] for c in caps.tolist()]))
        t_emb = model.text.project(pooled)
        same = (caps[:, None] == caps[None, :]).to(dev) if tc.negatives == "mask_same_caption" else None
        loss, acc = contrastive_loss(t_emb, m_emb, model.scale(), same)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_([p for p in params if p.grad is not None], 1.0)
        opt.step()
        sched.step()
        tot_loss += float(loss.detach()) * len(b)
        tot_acc += float(acc.detach()) * len(b)
        count += len(b)
    if not math.isfinite(tot_loss):
        raise FloatingPointError(f"training diverged at epoch {e + 1} (loss {tot_loss}); lower lr "
                                 f"(now {tc.lr}) or check the features for outliers")
    return {"epoch": e + 1, "loss": tot_loss / count, "batch_top1": tot_acc / count,
            "temperature": float(1.0 / model.scale().detach()), "lr": opt.param_groups[0]["lr"],
            "text_lr": opt.param_groups[2]["lr"], "text_frozen": frozen}


def _fit(su: _Setup, resume: bool, checkpoint_every: int, interrupt_after_epoch: int | None,
         pool_size: int, replications: int, device: str) -> _Fit:
    """Model, optimiser and schedule (resumed from the checkpoint), the epochs, then GT scores on CPU."""
    cfg, log, ckpt_path = su.cfg, su.log, su.ckpt_path
    mc, tc = cfg.model, cfg.train
    with deterministic(tc.threads):
        torch.manual_seed(tc.seed)
        model = TextMotionModel(mc, su.transformer, su.pooling)
        ev = Evaluator(cfg, model, su.tok, su.stats, device=device)
        prepared = ev.prepare_motion([it.features for it in su.train.items], crop=False)
        vocab = sorted({c for it in su.train.items for c in it.captions})
        index = {c: i for i, c in enumerate(vocab)}
        cap_idx = [[index[c] for c in it.captions] for it in su.train.items]
        n = len(su.train.items)
        steps = len(_batches(np.arange(n), tc.batch_size))
        opt = torch.optim.AdamW(_param_groups(model, cfg), betas=(0.9, 0.98), eps=1e-6)
        main_lr, text_lr = _lr_lambdas(cfg, steps)
        sched = torch.optim.lr_scheduler.LambdaLR(opt, [main_lr, main_lr, text_lr])   # one per param group
        curve: list[dict] = []
        start = 0
        resumed_from = None
        if resume and ckpt_path.exists():
            curve = resume_checkpoint(ckpt_path, su.ident, tc.epochs, model, opt, sched, ev.device)
            start = resumed_from = len(curve)
            log(f"[train-evaluator] resuming from epoch {start} ({ckpt_path})")

        cache = None
        if start < tc.text_unfreeze_epoch:
            with torch.inference_mode():
                model.text.set_frozen(True)
                cache = torch.cat([model.text.pooled(ev.tokenize(vocab[s:s + 128])) for s in range(0, len(vocab), 128)])
            cache = cache.clone()
        epochs_run = 0
        params = [p for g in opt.param_groups for p in g["params"]]
        for e in range(start, tc.epochs):
            curve.append(_run_epoch(e, su, model, ev, opt, sched, params, prepared, cap_idx, vocab, cache))
            frozen = curve[-1]["text_frozen"]
            epochs_run += 1
            c = curve[-1]
            log(f"[train-evaluator] epoch {e + 1}/{tc.epochs} loss {c['loss']:.4f} batch top-1 "
                f"{c['batch_top1']:.3f} temperature {c['temperature']:.4f}{' (text frozen)' if frozen else ''}")
            stop = interrupt_after_epoch is not None and e + 1 >= interrupt_after_epoch and e + 1 < tc.epochs
            if (e + 1) % max(1, checkpoint_every) == 0 or e + 1 == tc.epochs or stop:
                atomic_torch_save({**su.ident, "epoch": e + 1,
                                    "model": model.own_state_dict(None if frozen else tc.text_finetune_layers),
                                    "optimizer": opt.state_dict(), "scheduler": sched.state_dict(),
                                    "torch_rng": torch.get_rng_state(), "curve": json.dumps(curve)}, ckpt_path)
            if stop:
                log(f"[train-evaluator] interrupted after epoch {e + 1} (checkpoint {ckpt_path})")
                return _Fit(model, curve, vocab, epochs_run, resumed_from, interrupted=True)

        model.eval()
        model.to("cpu")        # GT scores as a loaded evaluator computes them (CPU, EMBED_THREADS)
        ev = Evaluator(cfg, model, su.tok, su.stats)
        proto = store_protocol(su.store)
        gt = gt_scores(ev, su.test.items, pool_size, replications, tc.seed, protocol=proto)
        tr = gt_scores(ev, su.train.items, pool_size, replications, tc.seed)
    return _Fit(model, curve, vocab, epochs_run, resumed_from, gt=gt, tr=tr)


def _card(su: _Setup, fit: _Fit, gate: GateResult) -> dict:
    """The evaluator card (before its id is added by :func:`card.write_folder`)."""
    cfg, store, train, test, model, curve, gt, tr = su.cfg, su.store, su.train, su.test, fit.model, fit.curve, \
        fit.gt, fit.tr
    mc, tc = cfg.model, cfg.train
    variant = mc.variant
    fine_tune = tc.text_unfreeze_epoch < tc.epochs
    key = feature_key(variant)
    return {
        "toolkit": "hoibench", "toolkit_version": __version__, "seed": tc.seed,
        "config": cfg.to_dict(), "config_sha256": cfg.sha256(),
        "dataset": {"name": store.manifest.get("dataset"), "manifest_sha256": su.msha,
                    "representation": store.manifest.get("representations", {}).get(key), "features": key,
                    **card_mod.store_fingerprint(store.manifest),
                    "train_split": "train", "test_split": "test",
                    "train_clips": len(train.clip_ids), "train_items": len(train.items),
                    "test_clips": len(test.clip_ids), "test_items": len(test.items),
                    "clips_without_texts": {"train": len(train.missing_texts), "test": len(test.missing_texts)},
                    "skipped_segments": train.skipped_segments + test.skipped_segments,
                    "train_captions": len(fit.vocab), "texts_sha256": su.tsha},
        "normalization": su.stats.to_card("store stats/hml263.npz (train split)" + (
            "; object-relative statistics computed on the train split" if variant == "hoi" else "")),
        "text_encoder": {"name": su.te_name, "weights_sha256": su.te_sha, "pooling": su.pooling,
                         "hidden_size": model.text.hidden, "max_tokens": mc.text_max_tokens,
                         "fine_tuned": fine_tune, "fine_tuned_layers": tc.text_finetune_layers if fine_tune else 0,
                         "stored_in_weights": ("all fine-tuned transformer parameters" if fine_tune else
                                               "none (the pretrained encoder, named by its weights_sha256)")},
        "curve": {"summary": _curve_summary(curve), "epochs": curve},
        "gt_retrieval": {"split": "test", **gt},
        "train_retrieval": {"split": "train", "top1": tr["top1"], "top3": tr["top3"], "items": tr["items"],
                            "pool_size": tr["pool_size"]},
        "gate": gate.to_card(),
        "libraries": text_mod.package_versions(),
    }


def _write_output(su: _Setup, fit: _Fit, gate: GateResult, keep_checkpoint: bool, t_start: float) -> TrainResult:
    """The evaluator folder (weights, card), its curve plot and train log; the checkpoint removed."""
    cfg, out, log, ckpt_path = su.cfg, su.out, su.log, su.ckpt_path
    tc = cfg.train
    text_layers = tc.text_finetune_layers if tc.text_unfreeze_epoch < tc.epochs else None
    eid = card_mod.write_folder(out, fit.model.own_state_dict(text_layers), _card(su, fit, gate))
    card = card_mod.read_card(out)
    try:
        plot_curve(fit.curve, out / card_mod.CURVE_PNG, tc.text_unfreeze_epoch,
                   f"evaluator {eid[:12]} ({cfg.size}, {cfg.model.variant})")
    except Exception as exc:  # a plot must never lose a trained evaluator
        log(f"[train-evaluator] could not plot the curve: {exc}")
    atomic_write_text(out / card_mod.TRAIN_LOG, json.dumps(
        {"evaluator_id": eid, "wall_s_this_call": time.time() - t_start, "epochs_this_call": fit.epochs_run,
         "resumed_from_epoch": fit.resumed_from, "threads": tc.threads}, indent=1) + "\n")
    if not keep_checkpoint and ckpt_path.exists():
        ckpt_path.unlink()
        try:
            ckpt_path.parent.rmdir()
        except OSError:
            pass
    log(f"[train-evaluator] wrote evaluator {eid} to {out}; {gate.diagnostic()}")
    return TrainResult(out, "trained", eid, card, gate, fit.epochs_run)


def train_evaluator(data: str | Path, out: str | Path, config: EvaluatorConfig | None = None, *,
                    text_encoder: str | None = None, resume: bool = True, checkpoint_every: int = 1,
                    keep_checkpoint: bool = False, interrupt_after_epoch: int | None = None,
                    pool_size: int = 32, replications: int = 20, device: str = "cpu",
                    log: Callable[[str], None] | None = None) -> TrainResult:
    """Train an evaluator on ``data`` (a store with ``DATA/texts/``) into the folder ``out``.

    Args:
        config: :func:`~hoibench.evaluator.config.preset` ``("tiny", "human")`` by default.
        text_encoder: a local Hugging Face model folder; default the packaged all-MiniLM-L6-v2.
        resume: continue from ``OUT/checkpoint/last.pt`` when it exists (else start over).
        checkpoint_every: epochs between checkpoints (the last epoch is always saved).
        keep_checkpoint: keep the checkpoint after the evaluator folder is written.
        interrupt_after_epoch: stop after this many epochs, checkpoint written, no folder
            (simulates an interruption; used by the resume test).
        pool_size, replications: GT retrieval pools and replications (32 and 20 as in DESIGN
            section 8) for the train-split scores, and for the test split when no protocol
            ships for the store (``<dataset>-<mode>``); otherwise the test split is scored
            with that protocol's pools and caption draws, exactly as ``hoibench evaluate``
            scores the ground-truth submission.
        device: ``"cpu"`` or a torch device such as ``"cuda"`` (the card records neither the
            device nor the machine; CUDA results are reproducible on the same GPU type when
            ``CUBLAS_WORKSPACE_CONFIG=:4096:8`` is set before torch initialises CUDA).

    Returns a :class:`TrainResult`. ``out`` may be new, empty, or an interrupted run of the
    same recipe (resumed from its checkpoint). A folder that already holds this evaluator
    (same config and dataset) is verified and returned as ``already_trained``; one that holds
    another evaluator, an evaluator that does not verify, or files that are not an
    evaluator's raises :class:`~hoibench.evaluator.errors.EvaluatorFolderExists` (also a
    ``FileExistsError``) saying what differs. An unreadable or foreign checkpoint raises
    :class:`~hoibench.evaluator.errors.CheckpointError` (it is never silently discarded:
    delete it to restart from epoch 0, which gives the same evaluator).
    """
    cfg = config or preset()
    log = log or (lambda s: print(s, file=sys.stderr, flush=True))
    out = Path(out)
    store = Store(data)
    msha = manifest_sha256(store.manifest)
    clean_stale_tmp(out, out / CHECKPOINT_DIR)         # an interrupted write's leftovers

    done = existing_output(out, cfg, msha, legacy_manifest_sha256(store.manifest))
    if done is not None:
        log(f"[train-evaluator] {out} already holds evaluator {done['evaluator_id'][:12]} for this config")
        return TrainResult(out, "already_trained", done["evaluator_id"], done, None, 0)

    su = _setup(store, out, cfg, msha, text_encoder, log)
    t_start = time.time()
    fit = _fit(su, resume, checkpoint_every, interrupt_after_epoch, pool_size, replications, device)
    if fit.interrupted:
        return TrainResult(out, "interrupted", None, None, None, fit.epochs_run)
    gate = sanity_gate(fit.gt, cfg.model.embed_dim)
    return _write_output(su, fit, gate, keep_checkpoint, t_start)
