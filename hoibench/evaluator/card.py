"""Evaluator folders: write, verify, load, show.

Layout::

    EVAL/weights.safetensors   model tensors; of the pretrained text transformer only the
                               fine-tuned parameters (the rest is named by hash in the card)
    EVAL/card.json             config, dataset (manifest sha256, splits, texts sha256),
                               normalisation statistics and their sha256, text encoder
                               (name, weights sha256, pooling, fine-tuned or not), training
                               curve and its summary, GT retrieval scores, sanity gate,
                               toolkit and library versions, seed, evaluator_id
    EVAL/curve.png             training curve plot       (not covered by the id)
    EVAL/train_log.json        wall-clock times, resumes (not covered by the id)

Evaluator id = ``sha256(bytes of weights.safetensors || canonical card)``, where the
canonical card is ``json.dumps(card without "evaluator_id", sort_keys=True,
separators=(",", ":"), ensure_ascii=True)``. Nothing time- or machine-dependent enters the
card, so the same data, config and seed give the same id. :func:`verify_folder` recomputes
it; :func:`load_evaluator` additionally checks the normalisation statistics against their
hash, the local text encoder against the card's hash, the tensor names and shapes against
the config, and the sanity gate.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

from ..io import atomic_write_bytes, atomic_write_text

FORMAT = "hoibench-evaluator-1"
WEIGHTS = "weights.safetensors"
CARD = "card.json"
CURVE_PNG = "curve.png"
TRAIN_LOG = "train_log.json"


class EvaluatorIntegrityError(ValueError):
    """An evaluator folder that is incomplete, tampered with, or does not match its card."""


def canonical_card_bytes(card: dict) -> bytes:
    body = {k: v for k, v in card.items() if k != "evaluator_id"}
    return json.dumps(body, sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False).encode()


def compute_id(weights: bytes, card: dict) -> str:
    h = hashlib.sha256()
    h.update(weights)
    h.update(canonical_card_bytes(card))
    return h.hexdigest()


def weights_bytes(state_dict: dict) -> bytes:
    """safetensors bytes. One metadata key only: safetensors serialises its metadata map in
    hash order, so several keys would make the bytes (and the id) vary between runs."""
    from safetensors.torch import save
    return save(state_dict, metadata={"format": "pt"})


def write_folder(out: str | Path, state_dict: dict, card: dict) -> str:
    """Write weights and card (card last: its presence marks a complete folder); return the id."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    data = weights_bytes(state_dict)
    card = dict(card)
    card.pop("evaluator_id", None)
    card["format"] = FORMAT
    eid = compute_id(data, card)
    card["evaluator_id"] = eid
    atomic_write_bytes(out / WEIGHTS, data)
    atomic_write_text(out / CARD, json.dumps(card, indent=1, sort_keys=True, allow_nan=False) + "\n")
    return eid


def read_card(folder: str | Path) -> dict:
    path = Path(folder) / CARD
    if not path.exists():
        raise EvaluatorIntegrityError(f"{folder}: not an evaluator folder (no {CARD}); "
                                      f"train one with `hoibench train-evaluator`")
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise EvaluatorIntegrityError(f"{path}: not valid JSON ({exc})") from None


def verify_folder(folder: str | Path) -> tuple[dict, bytes]:
    """(card, weights bytes) of a folder whose id checks out; raises
    :class:`EvaluatorIntegrityError` naming what is wrong otherwise."""
    folder = Path(folder)
    card = read_card(folder)
    wpath = folder / WEIGHTS
    if not wpath.exists():
        raise EvaluatorIntegrityError(f"{folder}: {WEIGHTS} is missing (incomplete copy?)")
    if card.get("format") != FORMAT:
        raise EvaluatorIntegrityError(f"{folder}: card format {card.get('format')!r} is not {FORMAT!r} "
                                      f"(written by another hoibench version?)")
    recorded = card.get("evaluator_id")
    if not recorded:
        raise EvaluatorIntegrityError(f"{folder}: {CARD} has no evaluator_id")
    data = wpath.read_bytes()
    actual = compute_id(data, card)
    if actual != recorded:
        raise EvaluatorIntegrityError(
            f"{folder}: evaluator id mismatch: card.json says {recorded[:12]}... but weights.safetensors + "
            f"card.json hash to {actual[:12]}...; the folder was modified after training or mixes files of "
            f"different evaluators. Restore the original folder (or retrain); scores computed with it "
            f"would not be comparable")
    return card, data


def load_evaluator(folder: str | Path, *, allow_failed_gate: bool = False, text_encoder: str | None = None,
                   threads: int | None = None, device: str = "cpu"):
    """A verified :class:`~hoibench.evaluator.embed.Evaluator` from ``folder``.

    ``text_encoder``: where the pretrained sentence encoder is when it is not the packaged
    all-MiniLM-L6-v2 (a local folder); its weights must hash to the card's value.
    ``threads``/``device``: see :class:`~hoibench.evaluator.embed.Evaluator`.
    """
    import torch
    from safetensors.torch import load as load_tensors

    from . import text as text_mod
    from .config import EvaluatorConfig
    from .embed import Evaluator
    from .features import FeatureStats
    from .gate import check_card_gate
    from .model import TextMotionModel

    card, data = verify_folder(folder)
    if not allow_failed_gate:
        check_card_gate(card)
    try:
        config = EvaluatorConfig.from_dict(card["config"])
        stats = FeatureStats.from_card(card["normalization"])
    except (KeyError, TypeError, ValueError) as exc:
        raise EvaluatorIntegrityError(f"{folder}: card.json is inconsistent: {exc}") from None
    te = card["text_encoder"]
    name, path = text_mod.resolve_text_encoder(text_encoder or te["name"])
    sha = text_mod.weights_sha256(path)
    if sha != te["weights_sha256"]:
        raise EvaluatorIntegrityError(
            f"{folder}: text encoder mismatch: the card names {te['name']} with weights sha256 "
            f"{te['weights_sha256'][:12]}..., but {path} hashes to {sha[:12]}...; pass text_encoder=<folder of "
            f"the same pretrained model>")
    tok, transformer = text_mod.load_pretrained(path)
    model = TextMotionModel(config.model, transformer, te["pooling"])
    tensors = load_tensors(data)
    expected = model.own_state_dict(config.train.text_finetune_layers if te["fine_tuned"] else None)
    missing = sorted(set(expected) - set(tensors))
    extra = sorted(set(tensors) - set(expected))
    bad = sorted(k for k in set(expected) & set(tensors) if tuple(expected[k].shape) != tuple(tensors[k].shape))
    if missing or extra or bad:
        raise EvaluatorIntegrityError(
            f"{folder}: weights do not match the card's config (missing {missing[:3]}, unexpected {extra[:3]}, "
            f"wrong shape {bad[:3]})")
    with torch.no_grad():
        model.load_state_dict(tensors, strict=False)
    return Evaluator(config, model, tok, stats, card, threads=threads, device=device)


def summary(card: dict, verified: bool | None = None) -> str:
    """Human-readable card summary (what ``hoibench show EVAL`` prints)."""
    cfg = card.get("config", {})
    m, t = cfg.get("model", {}), cfg.get("train", {})
    ds = card.get("dataset", {})
    te = card.get("text_encoder", {})
    g = card.get("gt_retrieval", {})
    gate = card.get("gate", {})
    curve = card.get("curve", {}).get("summary", {})
    lines = [f"evaluator {card.get('evaluator_id', '?')}" + ("" if verified is None else
                                                            ("  (id verified)" if verified else "  (ID MISMATCH)")),
             f"  hoibench {card.get('toolkit_version', '?')}, format {card.get('format', '?')}, "
             f"seed {card.get('seed')}",
             f"  model: size {cfg.get('size')}, variant {m.get('variant')}, width {m.get('width')}, layers "
             f"{m.get('layers')}, heads {m.get('heads')}, dropout {m.get('dropout')}, output {m.get('embed_dim')}",
             f"  training: {t.get('epochs')} epochs, batch {t.get('batch_size')}, lr {t.get('lr')}, text frozen "
             f"until epoch {t.get('text_unfreeze_epoch')}, control {t.get('control')}",
             f"  dataset: {ds.get('name')} manifest {str(ds.get('manifest_sha256', ''))[:12]}, train "
             f"{ds.get('train_items')} items / test {ds.get('test_items')} items, {ds.get('representation')}",
             f"  normalisation: {card.get('normalization', {}).get('source')} sha256 "
             f"{str(card.get('normalization', {}).get('sha256', ''))[:12]}",
             f"  text encoder: {te.get('name')} sha256 {str(te.get('weights_sha256', ''))[:12]}, "
             f"{'fine-tuned' if te.get('fine_tuned') else 'frozen'}"]
    if curve:
        lines.append(f"  curve: loss {curve.get('first_loss', float('nan')):.3f} -> "
                     f"{curve.get('final_loss', float('nan')):.3f}, "
                     f"in-batch top-1 {curve.get('final_batch_top1', float('nan')):.3f}, "
                     f"temperature {curve.get('final_temperature', float('nan')):.4f}")
    if g:
        lines.append(f"  GT retrieval ({g.get('split')}, {g.get('items')} items, pool {g.get('pool_size')}, "
                     f"{g.get('replications')} replications): top-1 {g['top1']['mean']:.3f} "
                     f"+- {g['top1']['ci95']:.3f}, top-2 {g['top2']['mean']:.3f}, top-3 {g['top3']['mean']:.3f}, "
                     f"MM-Dist {g['mm_dist']['mean']:.3f}, "
                     f"chance {g.get('chance_top1', float('nan')):.3f}")
        lines.append(f"  GT-vs-GT FID (halves of {g.get('half_size')}): {g.get('fid_gt_halves', float('nan')):.4f} "
                     f"(relative {_fmt(g.get('fid_gt_relative'))})")
        if g.get("pool_size") != g.get("requested_pool_size"):
            lines.append(f"  note: {g.get('pool_rule')}")
    if gate:
        lines.append(f"  sanity gate: {'passed' if gate.get('passed') else 'FAILED'}"
                     + ("" if gate.get("passed") else ": " + "; ".join(gate.get("reasons", []))))
    return "\n".join(lines)


def _fmt(x, spec: str = ".3f") -> str:
    return "n/a" if x is None else format(x, spec)


def show(folder: str | Path) -> str:
    card = read_card(folder)
    try:
        verify_folder(folder)
        ok = True
    except EvaluatorIntegrityError:
        ok = False
    return summary(card, ok)
