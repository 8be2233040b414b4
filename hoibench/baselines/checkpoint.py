"""Baseline run folders: weights, card and id, like an evaluator folder.

Layout::

    RUN/weights.safetensors   EMA weights of the model and its normalisation statistics
    RUN/card.json             baseline, config, dataset (store manifest sha256, split, clip count,
                              statistics hashes, representation, fps), text encoder (vocabulary
                              or weights hash), training curve and summary, seed, toolkit
                              version, integrity hashes, checkpoint_id
    RUN/curve.png             loss curve                          (not covered by the id)
    RUN/train_log.json        wall-clock times, device and hardware, resumes  (not covered by the id)
    RUN/checkpoint/last.pt    training state for resuming (removed when training ends)

Checkpoint id = ``sha256(weights bytes || canonical card without checkpoint_id and the
provenance fields)``, as the evaluator id (:func:`hoibench.evaluator.card.compute_id`): the
same store content, config and seed give the same id on the same machine type, whatever the
folders' paths.
"""
from __future__ import annotations

import json
from pathlib import Path

from ..core.errors import HoibenchError
# the same file names, size limits and id scheme as an evaluator folder
from ..evaluator.card import (CARD, CURVE_PNG, MAX_CARD_BYTES, MAX_WEIGHTS_BYTES, TRAIN_LOG, WEIGHTS,  # noqa: F401
                              changed_parts, check_safetensors, compute_id, id_matches, integrity_block,
                              weights_bytes)
from ..evaluator.errors import CorruptEvaluatorFile
from ..core.io import atomic_write_bytes, atomic_write_text, load_json_bytes, read_regular_file

FORMAT = "hoibench-baseline-1"
CHECKPOINT_DIR = "checkpoint"
ID_KEY = "checkpoint_id"


class RunFolderError(HoibenchError, ValueError):
    """A baseline run folder that is missing, incomplete, modified or of another kind."""


def write_run(out: str | Path, state_dict: dict, card: dict) -> str:
    """Write weights and card (card last: it marks a complete folder); return the id."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    data = weights_bytes(state_dict)
    card = {k: v for k, v in card.items() if k not in (ID_KEY, "integrity")}
    card["format"] = FORMAT
    card["integrity"] = integrity_block(data, card, ID_KEY)
    card[ID_KEY] = compute_id(data, card, ID_KEY)
    atomic_write_bytes(out / WEIGHTS, data)
    atomic_write_text(out / CARD, json.dumps(card, indent=1, sort_keys=True, allow_nan=False) + "\n")
    return card[ID_KEY]


def verify_run(folder: str | Path, baseline: str | None = None) -> tuple[dict, bytes]:
    """(card, weights bytes) of a complete, unmodified run folder; :class:`RunFolderError`
    naming the file and field otherwise."""
    folder = Path(folder)
    cpath = folder / CARD
    if not cpath.exists():
        hint = " (training was interrupted: run `hoibench baseline train` again to resume)" \
            if (folder / CHECKPOINT_DIR).exists() else ""
        raise RunFolderError(f"{folder}: not a baseline run folder (no {CARD}){hint}")
    try:
        card = load_json_bytes(read_regular_file(cpath, MAX_CARD_BYTES, "baseline card"), cpath)
    except ValueError as exc:
        raise RunFolderError(str(exc)) from None
    if not isinstance(card, dict) or card.get("format") != FORMAT:
        got = card.get("format") if isinstance(card, dict) else type(card).__name__
        raise RunFolderError(f"{cpath}: field format: {got!r} is not {FORMAT!r} (an evaluator folder, or written "
                             f"by another hoibench version?)")
    for key, t in (("baseline", str), ("config", dict), ("dataset", dict), (ID_KEY, str)):
        if not isinstance(card.get(key), t):
            raise RunFolderError(f"{cpath}: field {key}: expected a {t.__name__}, got {type(card.get(key)).__name__}")
    if baseline is not None and card["baseline"] != baseline:
        raise RunFolderError(f"{cpath}: field baseline: this run is {card['baseline']!r}, not {baseline!r}")
    wpath = folder / WEIGHTS
    if not wpath.exists():
        raise RunFolderError(f"{folder}: {WEIGHTS} is missing (incomplete copy?)")
    try:
        data = read_regular_file(wpath, MAX_WEIGHTS_BYTES, "baseline weights")
        check_safetensors(data, wpath)
    except (ValueError, CorruptEvaluatorFile) as exc:
        raise RunFolderError(str(exc)) from None
    ok, actual = id_matches(data, card, ID_KEY)
    if not ok:
        detail = "; ".join(changed_parts(card, data, WEIGHTS, CARD, ID_KEY)) or \
            f"{CARD} field {ID_KEY} or integrity was modified"
        raise RunFolderError(f"{folder}: checkpoint id mismatch: {CARD} says {card[ID_KEY][:12]}... but the files hash "
                             f"to {actual[:12]}...: {detail} after training; retrain or restore the folder")
    return card, data


def hardware(device) -> str:
    """What a run trains on: the GPU's name, or the CPU's model and torch's thread count."""
    import torch
    dev = torch.device(device)
    if dev.type == "cuda":
        return f"{torch.cuda.get_device_name(dev)} (cuda)"
    model = ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():  # read-ok: the CPU name, a kernel file
            if line.lower().startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    if not model:
        import platform
        model = platform.processor() or platform.machine()
    return f"CPU {model}, {torch.get_num_threads()} thread(s)".replace("CPU , ", "CPU, ")


def training_budget(folder: str | Path, card: dict) -> dict:
    """A run's training budget, for its submissions and leaderboard rows: optimiser steps and
    parameter count (the card), wall-clock seconds, hardware and the step it resumed from
    (``train_log.json``; None when the file is absent) and the text encoder the generator is
    conditioned on (``tokens``: a trainable word-level encoder; ``minilm``: the frozen sentence
    encoder with its weights' sha256)."""
    from ..core.io import read_json_file
    summary = card.get("summary") if isinstance(card.get("summary"), dict) else {}
    log: dict = {}
    path = Path(folder) / TRAIN_LOG
    if path.is_file():
        try:
            got = read_json_file(path, 1 << 20, "train log")
            log = got if isinstance(got, dict) else {}
        except ValueError:
            log = {}
    text = card.get("text") if isinstance(card.get("text"), dict) else {}
    encoder = {"encoder": text.get("encoder")}
    if text.get("weights_sha256"):
        encoder["weights_sha256"] = text["weights_sha256"]
    return {"steps": summary.get("steps"), "parameters": summary.get("parameters"),
            "wall_seconds": log.get("seconds"), "hardware": log.get("hardware") or log.get("device"),
            "resumed_from": log.get("resumed_from", 0),
            "wall_seconds_from": log.get("seconds_from_step", log.get("resumed_from", 0)), "text_encoder": encoder}
