"""Training a joint-level diffusion baseline on a prepared store (``hoibench baseline train``).

Shared by every :class:`~hoibench.baselines.registry.Spec` (ChainHOI, EJIM): the spec gives
the model and its losses; this module draws batches, steps the optimiser, keeps the EMA of
the weights, checkpoints, resumes and writes the run folder.

Every step draws its batch, windows, captions, timesteps, noise and condition drops from
generators seeded by ``(seed, step)``, and reseeds dropout, so a resumed run equals an
uninterrupted one (same checkpoint id). Checkpoints (``RUN/checkpoint/last.pt``) are written
atomically every ``checkpoint_every`` steps; the final folder holds the EMA weights.
"""
from __future__ import annotations

import hashlib
import json
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np
import torch

from .. import __version__
from ..core.errors import HoibenchError
from .config import check_parameter_count, sizing
from ..core.interrupts import check_interrupted, hold_sigint
from ..core.threads import set_torch_threads
from ..core.io import (MAX_SMALL_JSON_BYTES, atomic_save_figure, atomic_torch_save, atomic_write_json, check_regular_file,
                       clean_stale_tmp, finished_output, read_json_file)
from ..datasets.store import Store, legacy_manifest_sha256
from . import checkpoint as ckpt
from . import joint_data as D
from .kernels import describe as describe_kernels
from .config import RunConfig
from .diffusion import EMA, GaussianDiffusion
from .registry import Spec, get_spec
from .text import TextConditioner


class TrainingDiverged(HoibenchError, FloatingPointError):
    """A loss became NaN or infinite (the checkpoint before it is kept)."""


def _seed(*parts) -> int:
    return int.from_bytes(hashlib.sha256(repr(parts).encode()).digest()[:8], "little") & ((1 << 63) - 1)


# ------------------------------------------------------------------------------ data
@dataclass
class TrainingSet:
    store: Store
    items: list[D.ClipItem]
    stats: D.JointStats
    points: dict[str, np.ndarray]           # object -> (object_points, 3)
    contact_points: dict[str, np.ndarray]   # object -> (contact_points, 3)
    vocab: list[str]
    missing_texts: list[str]
    meshes: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)   # object -> (vertices, faces)
    contact_mesh: dict[str, np.ndarray] = field(default_factory=dict)   # object -> (F, 3, 3) ("exact" L_h)


def training_set(data: str | Path, cfg: RunConfig) -> TrainingSet:
    store, items, missing = D.read_split(data, "train")
    items = [it for it in items if len(it.rows) >= cfg.train.min_frames]
    if not items:
        raise ValueError(f"{data}: no train clips with captions and >= {cfg.train.min_frames} rows; annotate the store "
                         f"first (`hoibench annotate {data}`)")
    source = getattr(cfg.model, "object_source", "surface")      # "vertices": ChainHOI released
    rows = [it.rows for it in items]
    stats = D.grouped_stats(rows) if source == "vertices" else D.JointStats.from_rows(rows)
    names = {it.object_name for it in items}
    vocab = D.build_vocab([c for it in items for c in it.captions])
    meshes = {n: store.object_template(n) for n in sorted(names)} if source == "vertices" else {}
    mesh = D.object_triangles(store, names) if getattr(cfg.train, "contact_distance", "samples") == "exact" else {}
    return TrainingSet(store, items, stats, D.object_points(store, names, cfg.model.object_points, source),
                       D.object_points(store, names, cfg.train.contact_points), vocab, missing, meshes, mesh)


def make_batch(ts: TrainingSet, cfg: RunConfig, step: int, text: TextConditioner, device) -> dict:
    """The batch of ``step``: clips, windows and captions drawn from ``(seed, step)``."""
    rng = np.random.default_rng(_seed(cfg.train.seed, "batch", step))
    B, W = cfg.train.batch_size, cfg.train.max_frames
    pick = rng.integers(0, len(ts.items), B)
    wins, conts, caps, pts, cpts, starts = [], [], [], [], [], []
    for i in pick:
        it = ts.items[i]
        L = len(it.rows)
        a = int(rng.integers(0, L - W + 1)) if L > W else 0
        n = min(L, W)
        wins.append(ts.stats.normalize(D.recentre_window(it.rows, a, n)))
        starts.append(a)
        conts.append(it.contacts[a:a + n])
        caps.append(it.captions[int(rng.integers(0, len(it.captions)))])
        pts.append(ts.points[it.object_name])
        cpts.append(ts.contact_points[it.object_name])
    Lmax = max(len(w) for w in wins)
    x0 = np.zeros((B, Lmax, 24, 12), np.float32)
    valid = np.zeros((B, Lmax), bool)
    contacts = np.zeros((B, Lmax, len(D.INTERACTION_JOINTS)), bool)
    for b, (w, c) in enumerate(zip(wins, conts)):
        x0[b, :len(w)], valid[b, :len(w)], contacts[b, :len(c)] = w, True, c
    tt, tpad = text(caps, device)
    f = lambda a: torch.from_numpy(np.ascontiguousarray(a)).to(device)   # noqa: E731
    batch = {"x0": f(x0), "valid": f(valid), "contacts": f(contacts), "text": tt, "text_pad": tpad,
             "points": f(np.stack(pts)), "contact_points": f(np.stack(cpts))}
    if ts.meshes:
        batch.update({k: f(v) for k, v in mesh_batch(ts, [ts.items[i] for i in pick], wins, starts, Lmax).items()})
    if ts.contact_mesh:
        batch["contact_mesh"] = f(D.stack_meshes([ts.contact_mesh[ts.items[i].object_name] for i in pick]))
    return batch


def mesh_batch(ts: TrainingSet, items: list, wins: list, starts: list[int], Lmax: int) -> dict[str, np.ndarray]:
    """Template meshes (vertices padded by repeating vertex 0, faces by repeating face 0) and
    per-joint contact labels (B, Lmax, 22) of the batch's windows."""
    meshes = [ts.meshes[it.object_name] for it in items]
    nv, nf = max(len(v) for v, _ in meshes), max(len(fc) for _, fc in meshes)
    B = len(items)
    verts, vvalid = np.zeros((B, nv, 3), np.float32), np.zeros((B, nv), bool)
    faces = np.zeros((B, nf, 3), np.int64)
    joint_contacts = np.zeros((B, Lmax, 22), bool)
    for b, ((v, fc), it, w, a) in enumerate(zip(meshes, items, wins, starts)):
        verts[b] = v[0]
        verts[b, :len(v)], vvalid[b, :len(v)] = v, True
        faces[b] = fc[0]
        faces[b, :len(fc)] = fc
        if it.joint_contacts is not None:
            joint_contacts[b, :len(w)] = it.joint_contacts[a:a + len(w)]
    return {"mesh_vertices": verts, "mesh_vertex_valid": vvalid, "mesh_faces": faces, "joint_contacts": joint_contacts}


def build_model(spec: Spec, cfg: RunConfig, text: TextConditioner, seed: int):
    vocab = len(text.vocab or [])
    check_parameter_count(lambda c: spec.build_model(c, *sizing(c, vocab, text.width)), cfg, spec.preset("paper"),
                          "config")
    torch.manual_seed(_seed(seed, "init"))
    return spec.build_model(cfg, vocab, text.width)


# ------------------------------------------------------------------------------ training
@dataclass
class TrainResult:
    out: Path
    checkpoint_id: str
    card: dict
    seconds: float
    resumed_from: int = 0
    already_trained: bool = False


def _identity(cfg: RunConfig, dataset: dict) -> dict:
    """What a checkpoint must share with the run that resumes it (``dataset``: :func:`_store_block`)."""
    return {"config": json.dumps(cfg.to_dict(), sort_keys=True), "store": dataset["manifest_sha256"],
            "stats": dataset["joint_stats_sha256"], "store_stats": dataset["store_hoi269_stats_sha256"]}


def _store_block(store: Store, ts: TrainingSet) -> dict:
    """The card's ``dataset`` block: which store, split and statistics the run was trained on."""
    m = store.manifest
    return {"name": m.get("dataset", ""), "manifest_sha256": store.manifest_sha256(), "split": "train",
            "clips": len(ts.items), "clips_without_texts": len(ts.missing_texts),
            "fps": float(m.get("config", {}).get("fps", 0.0)), "mode": m.get("config", {}).get("mode", ""),
            "representation": m.get("representations", {}).get("hoi269", ""),
            "store_hoi269_stats_sha256": store.stats_sha256("hoi269"), "joint_stats_sha256": ts.stats.sha256()}


def plot_panels(panels: dict[str, tuple[list, list]], path: Path, title: str) -> None:
    """One log-scale panel per ``title -> (steps, values)``, saved atomically as PNG."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(panels), figsize=(3.4 * len(panels), 3.1), squeeze=False)
    for ax, (name, (steps, values)) in zip(axes[0], panels.items()):
        ax.plot(steps, [max(v, 1e-12) for v in values], lw=1.3)
        ax.set_title(name, fontsize=10)
        ax.set_xlabel("step")
        ax.set_yscale("log")
        ax.grid(alpha=0.3)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    atomic_save_figure(fig, path)


def _plot_curve(curve: list[dict], path: Path, title: str) -> None:
    steps = [c["step"] for c in curve]
    plot_panels({(k if k != "loss" else "total loss"): (steps, [c[k] for c in curve])
                 for k in curve[0] if k != "step"}, path, title)


def _save_checkpoint(path: Path, step: int, curve: list[dict], model, ema: EMA, opt, ident: dict,
                     window: dict | None = None) -> None:
    """``window``: the loss values since the last curve row (an interrupt between log steps)."""
    atomic_torch_save({"step": step, "curve": json.dumps(curve), "window": json.dumps(window or {}),
                       "model": model.state_dict(), "ema": ema.state_dict(), "optimizer": opt.state_dict(),
                       **ident}, path)


def read_checkpoint(path: Path, ident: dict, device, restore: Callable[[dict], Any]) -> Any:
    """``restore(checkpoint)`` of the training checkpoint at ``path`` once its identity
    fields equal ``ident``; :class:`RunFolderError` naming the file for an unreadable
    checkpoint, another run's, or one ``restore`` cannot apply."""
    try:
        check_regular_file(path, "training checkpoint")
        ck = torch.load(path, map_location=device, weights_only=True)  # read-ok: weights_only, regular file checked
    except Exception as exc:                  # torch raises many types for a bad file
        raise ckpt.RunFolderError(f"{path}: not a readable training checkpoint ({type(exc).__name__}); delete it to "
                                  f"restart training") from None
    other = sorted(k for k in ident if not isinstance(ck, dict) or ck.get(k) != ident[k])
    if other:
        raise ckpt.RunFolderError(f"{path}: checkpoint of another {', '.join(other)}; delete it or choose another "
                                  f"--out")
    try:
        return restore(ck)
    except Exception as exc:
        raise ckpt.RunFolderError(f"{path}: inconsistent training checkpoint ({type(exc).__name__}: "
                                  f"{' '.join(str(exc).split())[:160]}); delete it to restart training") from None


#: the wall time of each process's steps, beside the checkpoint (a resumed run sums them)
SEGMENTS_FILE = "segments.json"


def record_segment(cpath: Path, start: int, step: int, seconds: float) -> None:
    """Record that this process ran steps ``start..step`` in ``seconds`` of wall time (one
    entry per start step, rewritten at each checkpoint)."""
    path = cpath.parent / SEGMENTS_FILE
    segments = [s for s in read_segments(cpath) if s["from"] != start]
    segments.append({"from": int(start), "to": int(step), "seconds": round(float(seconds), 1)})
    atomic_write_json(path, {"segments": sorted(segments, key=lambda s: s["from"])})


def read_segments(cpath: Path) -> list[dict]:
    """The recorded segments of a run's earlier processes ([] when none or unreadable)."""
    path = cpath.parent / SEGMENTS_FILE
    if not path.is_file():
        return []
    try:
        got = read_json_file(path, MAX_SMALL_JSON_BYTES, "training segments")
    except ValueError:
        return []
    rows = got.get("segments") if isinstance(got, dict) else None
    return [s for s in rows or [] if isinstance(s, dict) and {"from", "to", "seconds"} <= set(s)]


def total_wall_seconds(cpath: Path, start: int, seconds: float) -> tuple[float, int]:
    """(wall seconds, first step they cover): this process's ``seconds`` from ``start`` plus the
    recorded segments that chain back to it (each ending where the next began)."""
    by_end = {int(s["to"]): s for s in read_segments(cpath) if int(s["from"]) < int(s["to"])}
    first, total = int(start), float(seconds)
    while first in by_end and first > 0:
        seg = by_end[first]
        total, first = total + float(seg["seconds"]), int(seg["from"])
    return total, first


def drop_checkpoint(cpath: Path) -> None:
    """Remove a finished run's checkpoint, its segments and its folder (when empty)."""
    (cpath.parent / SEGMENTS_FILE).unlink(missing_ok=True)
    if cpath.exists():
        cpath.unlink()
        try:
            cpath.parent.rmdir()
        except OSError:
            pass


def _load_checkpoint(path: Path, ident: dict, steps: int, model, ema: EMA, opt, device
                     ) -> tuple[int, list[dict], dict]:
    def restore(ck: dict) -> tuple[int, list[dict], dict]:
        step, curve, window = int(ck["step"]), json.loads(ck["curve"]), json.loads(ck.get("window", "{}"))  # read-ok: checkpoint strings
        if not 0 < step <= steps:
            raise ValueError(f"step {step} outside 1..{steps}")
        model.load_state_dict(ck["model"])
        ema.load_state_dict(ck["ema"])
        opt.load_state_dict(ck["optimizer"])
        return step, curve, window
    return read_checkpoint(path, ident, device, restore)


def _existing(out: Path, name: str, config: dict, dataset: dict,
              keys: tuple[str, ...] = ("manifest_sha256", "store_hoi269_stats_sha256"),
              aliases: dict | None = None) -> dict | None:
    """The card of a finished run folder ``out`` trained with this baseline, ``config`` and
    store (the ``dataset`` fields ``keys``); None for an absent or unfinished folder;
    :class:`RunFolderError` naming the differing fields otherwise."""
    leftovers = {ckpt.CHECKPOINT_DIR, ckpt.WEIGHTS, ckpt.CURVE_PNG, ckpt.TRAIN_LOG}
    if not finished_output(out, ckpt.CARD, leftovers, {ckpt.CHECKPOINT_DIR}, "a baseline run", ckpt.RunFolderError):
        return None
    card, _ = ckpt.verify_run(out)
    from ..evaluator.card import dict_diff
    diff = [] if card.get("baseline") == name else [f"baseline ({card.get('baseline')!r})"]
    diff += dict_diff(card.get("config"), config, "config")
    ds = card.get("dataset", {})
    for key in keys:
        if ds.get(key) != dataset[key] and ds.get(key) != (aliases or {}).get(key, dataset[key]):
            diff.append(f"dataset.{key} (another store)")
    if not diff:
        return card
    raise ckpt.RunFolderError(f"{out}: already holds run {card.get(ckpt.ID_KEY, '?')[:12]}, trained with another "
                              f"recipe or store (differs in {', '.join(diff[:4])}{'...' if len(diff) > 4 else ''}); "
                              f"choose another --out or delete the folder")


def train(baseline: str, data: str | Path, out: str | Path, config: RunConfig | str = "tiny", *,
          device: str = "cpu", resume: bool = True, stop_after: int | None = None, threads: int | None = None,
          log: Callable[[str], None] | None = print) -> TrainResult:
    """Train ``baseline`` (``chainhoi``, ``ejim``, ``catmo``) on ``data``'s train split into the
    run folder ``out``, with the train entry point its registry spec names
    (:func:`train_joint` for the diffusion baselines).

    ``config``: a run config or a preset name (``tiny``, ``paper``). ``resume``: continue from
    ``OUT/checkpoint/last.pt``. ``stop_after``: stop after this many steps with the checkpoint
    written and no final folder (an interruption, for tests). ``steps = 0`` writes the
    untrained model (the "untrained" reference row).
    """
    spec = get_spec(baseline)
    return spec.entry_point("train")(spec, data, out, config, device=device, resume=resume, stop_after=stop_after,
                                     threads=threads, log=log)


def finished_run(out: Path, name: str, config: dict, dataset: dict, tag: str, log: Callable[[str], None],
                 keys: tuple[str, ...] | None = None, store=None) -> "TrainResult | None":
    """The finished run already in ``out`` for this config and store (its leftover
    checkpoints removed), or None after making ``out`` ready for training (stale temporary
    files removed). With ``store``, a run written before ids came from content only (its card
    records the whole manifest's sha256) counts as this store's too."""
    aliases = {"manifest_sha256": legacy_manifest_sha256(store.manifest)} if store is not None else None
    done = _existing(out, name, config, dataset, keys or ("manifest_sha256", "store_hoi269_stats_sha256"), aliases)
    if done is not None:
        if (out / ckpt.CHECKPOINT_DIR).is_dir():        # interrupted after the folder was written
            shutil.rmtree(out / ckpt.CHECKPOINT_DIR, ignore_errors=True)
        log(f"{tag} {out} already holds this run ({done[ckpt.ID_KEY][:12]}); nothing to do")
        return TrainResult(out, done[ckpt.ID_KEY], done, 0.0, already_trained=True)
    out.mkdir(parents=True, exist_ok=True)
    clean_stale_tmp(out)
    clean_stale_tmp(out / ckpt.CHECKPOINT_DIR)
    return None


def start_run(out: str | Path, device: str, threads: int | None, log: Callable[[str], None] | None
              ) -> tuple[Callable[[str], None], Path, "torch.device", float]:
    """What every baseline's training starts with: the log function (None: silent), the run
    folder, the torch device, the thread count set (``threads``, else the machine's free
    cores: :func:`hoibench.core.threads.set_torch_threads`), and the start time."""
    set_torch_threads(threads)
    return log or (lambda s: None), Path(out), torch.device(device), time.perf_counter()



def collect_losses(window: dict[str, list[float]], losses: dict[str, torch.Tensor]) -> None:
    """Add one step's loss values to ``window``, the losses since the last curve row."""
    for k, v in losses.items():
        window.setdefault(k, []).append(float(v.detach()))


def close_window(window: dict[str, list[float]], curve: list, step: int, start: int, t_start: float) -> str:
    """Append the curve row of ``window`` (each loss's mean at ``step``) to ``curve``; return
    the log line's tail: the losses and the steps per second since ``start`` (at ``t_start``)."""
    row = {"step": step, **{k: float(np.mean(v)) for k, v in window.items()}}
    curve.append(row)
    rate = (step - start) / max(time.perf_counter() - t_start, 1e-9)
    parts = " ".join(f"{k} {v:.4g}" for k, v in row.items() if k not in ("step", "loss"))
    return f"loss {row['loss']:.4f} ({parts}) {rate:.2f} steps/s"


def run_steps(model, ema, opt, train, step_losses: Callable[[int], dict], *, step: int, curve: list, window: dict,
              cpath: Path, ident: dict, out: Path, t0: float, tag: str, log: Callable[[str], None],
              stop_after: int | None = None) -> TrainResult | None:
    """The optimiser loop every diffusion baseline shares, from ``step`` to ``train.steps``:
    ``step_losses(step)`` gives the step's losses (``loss`` is optimised); a non-finite loss
    stops the run (:class:`TrainingDiverged`); gradients are clipped to ``train.grad_clip``
    (0: none); the EMA follows; the mean of each loss over ``train.log_every`` steps goes into
    ``curve`` (appended in place) and the log; a checkpoint is written every
    ``train.checkpoint_every`` steps, at the end, and on an interrupt. Returns the partial
    :class:`TrainResult` when ``stop_after`` steps have run before the end, else None."""
    start = saved = step
    tl = time.perf_counter()

    def save() -> None:                                  # the checkpoint, and this process's wall time
        _save_checkpoint(cpath, step, curve, model, ema, opt, ident, window)
        record_segment(cpath, start, step, time.perf_counter() - t0)

    model.train()
    while step < train.steps:
        try:
            check_interrupted()
            losses = step_losses(step)
            if not torch.isfinite(losses["loss"]):
                raise TrainingDiverged(f"{tag} step {step}: non-finite loss "
                                       f"({ {k: float(v.detach()) for k, v in losses.items()} }); lower train.lr")
            opt.zero_grad(set_to_none=True)
            losses["loss"].backward()
            if train.grad_clip > 0:                      # 0: no clipping (ChainHOI released)
                torch.nn.utils.clip_grad_norm_(model.parameters(), train.grad_clip)
            with hold_sigint():                          # the update is whole or not at all
                opt.step()
                ema.update(model)
                step += 1
                collect_losses(window, losses)
        except KeyboardInterrupt:                        # between steps or inside one (its update not made)
            if step > saved:                             # keep the work done since the last checkpoint
                save()
            raise
        if step % train.log_every == 0 or step == train.steps:
            progress = close_window(window, curve, step, start, tl)
            window = {}
            log(f"{tag} step {step}/{train.steps} {progress}")
        if step % train.checkpoint_every == 0 or step == train.steps:
            save()
            saved = step
        if stop_after is not None and step - start >= stop_after and step < train.steps:
            if step > saved:
                save()
            return TrainResult(out, "", {}, time.perf_counter() - t0, resumed_from=start)
    return None


def train_joint(spec: Spec, data: str | Path, out: str | Path, config: RunConfig | str = "tiny", *,
                device: str = "cpu", resume: bool = True, stop_after: int | None = None, threads: int | None = None,
                log: Callable[[str], None] | None = print) -> TrainResult:
    """Train the joint-level diffusion baseline ``spec`` (ChainHOI, EJIM): :func:`train`'s
    registry entry point for ``kind = "diffusion"``."""
    cfg = spec.preset(config) if isinstance(config, str) else config
    tag = f"[{spec.name}]"
    log, out, dev, t0 = start_run(out, device, threads, log)
    ts = training_set(data, cfg)
    dataset = _store_block(ts.store, ts)
    finished = finished_run(out, spec.name, cfg.to_dict(), dataset, tag, log, store=ts.store)
    if finished is not None:
        return finished
    text = TextConditioner(cfg.model.text_encoder, cfg.model.text_max_tokens, ts.vocab)
    model = build_model(spec, cfg, text, cfg.train.seed).to(dev)
    ema = EMA(model, cfg.train.ema_decay)
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.train.lr, weight_decay=cfg.train.weight_decay)
    diffusion = GaussianDiffusion(cfg.diffusion)
    mean = torch.from_numpy(ts.stats.mean).to(dev)
    std = torch.from_numpy(ts.stats.std).to(dev)
    ident = {**_identity(cfg, dataset), "baseline": spec.name}
    cpath, step, curve, window = resume_point(out, resume, ident, cfg.train.steps, model, ema, opt, dev, log, tag)
    start = step
    n_params = sum(p.numel() for p in model.parameters())
    log(f"{tag} training {cfg.name}: {n_params / 1e6:.2f} M parameters, {len(ts.items)} train clips, "
        f"{cfg.train.steps} steps of {cfg.train.batch_size}, device {dev}")

    def step_losses(step: int) -> dict:
        torch.manual_seed(_seed(cfg.train.seed, "dropout", step))
        gen = torch.Generator().manual_seed(_seed(cfg.train.seed, "noise", step))
        return spec.losses(model, diffusion, make_batch(ts, cfg, step, text, dev), cfg, mean, std, gen)

    tl = time.perf_counter()
    stopped = run_steps(model, ema, opt, cfg.train, step_losses, step=step, curve=curve, window=window, cpath=cpath,
                        ident=ident, out=out, t0=t0, tag=tag, log=log, stop_after=stop_after)
    if stopped is not None:
        return stopped
    state = {"model." + k: v.detach().cpu().contiguous().clone() for k, v in ema.state_dict().items()}
    state.update({k: torch.from_numpy(v) for k, v in ts.stats.tensors().items()})
    return finish_run(spec, cfg, state, dataset, text, curve, n_params, out, dev, t0, tl, start, cpath, log, tag,
                      ts.store.manifest.get("dataset", ""))


def resume_point(out: Path, resume: bool, ident: dict, steps: int, model, ema: EMA, opt, device,
                 log: Callable[[str], None], tag: str) -> tuple[Path, int, list[dict], dict]:
    """(checkpoint path, step, curve, window) a diffusion run starts from: ``OUT/checkpoint/last.pt``
    restored when ``resume`` and it exists (model, EMA and optimiser loaded), else step 0."""
    cpath = out / ckpt.CHECKPOINT_DIR / "last.pt"
    if not (resume and cpath.exists()):
        return cpath, 0, [], {}
    step, curve, window = _load_checkpoint(cpath, ident, steps, model, ema, opt, device)
    log(f"{tag} resuming at step {step}/{steps}")
    return cpath, step, curve, window


def finish_run(spec, cfg, state: dict, dataset: dict, text: TextConditioner, curve: list[dict], n_params: int,
               out: Path, dev, t0: float, tl: float, start: int, cpath: Path, log: Callable[[str], None], tag: str,
               dataset_name: str) -> TrainResult:
    """Write a finished diffusion run: ``state`` (EMA weights and statistics) and its card as the
    run folder, the loss curve, ``train_log.json`` (seconds: the wall time of every process
    of the run whose segments chain back from this one, from step ``seconds_from_step``; this
    process's ``segment_seconds``; device, hardware, resumed step, steps/s); then drop the
    checkpoint."""
    card = {"baseline": spec.name, "config": cfg.to_dict(), "dataset": dataset,
            "text": text.describe(), "curve": curve,
            "summary": {"steps": cfg.train.steps, "parameters": n_params,
                        "final_loss": curve[-1]["loss"] if curve else None},
            "seed": cfg.train.seed, "toolkit_version": __version__, "torch_version": torch.__version__.split("+")[0]}
    cid = ckpt.write_run(out, state, card)
    seconds = time.perf_counter() - t0
    total, first = total_wall_seconds(cpath, start, seconds)
    if curve:
        try:
            _plot_curve(curve, out / ckpt.CURVE_PNG, f"{spec.title} {cfg.name} on {dataset_name} ({cid[:12]})")
        except ImportError:              # a GPU machine with only torch, numpy and safetensors
            log(f"{tag} matplotlib is not installed: {ckpt.CURVE_PNG} not drawn (the curve is in the card)")
    atomic_write_json(out / ckpt.TRAIN_LOG, {"seconds": round(total, 1), "seconds_from_step": first,
                                            "segment_seconds": round(seconds, 1), "device": str(dev),
                                            "hardware": ckpt.hardware(dev), "resumed_from": start,
                                            "kernels": describe_kernels(dev),
                                            "steps_per_second": round((cfg.train.steps - start) /
                                                                      max(time.perf_counter() - tl, 1e-9), 3)})
    drop_checkpoint(cpath)
    card = read_json_file(out / ckpt.CARD, MAX_SMALL_JSON_BYTES, "run card")
    log(f"{tag} wrote {out} (checkpoint id {cid[:12]}) in {seconds:.0f} s")
    return TrainResult(out, cid, card, seconds, resumed_from=start)
