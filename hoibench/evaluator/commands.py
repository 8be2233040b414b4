"""Evaluator functions behind the command line (called by :mod:`hoibench.commands.evaluators`).

Examples::

    hoibench train-evaluator DATA --out EVAL --size tiny --variant human --epochs 60 --seed 0
    hoibench evaluator show EVAL

Errors are :class:`~hoibench.evaluator.errors.EvaluatorError` (``ValueError``) with one-line
messages naming the file: ``hoibench`` prints them without a traceback (exit 2).
"""
from __future__ import annotations

import json
import sys


def main_train_evaluator(data, out, size: str = "tiny", variant: str = "human", epochs: int | None = None,
                         seed: int = 0, *, text_encoder: str | None = None, batch_size: int | None = None,
                         control: str = "none", threads: int | None = None, text_unfreeze_epoch: int | None = None,
                         resume: bool = True,
                         checkpoint_every: int = 1, keep_checkpoint: bool = False) -> int:
    """Train an evaluator; print its card summary. Returns 0 when it passes the sanity gate,
    1 when it was written but failed the gate (the diagnostic is printed)."""
    from .card import summary
    from .config import preset
    from .gate import card_gate
    from .train import train_evaluator
    cfg = preset(size, variant, epochs, seed, batch_size=batch_size, control=control, threads=threads,
                 text_unfreeze_epoch=text_unfreeze_epoch)
    res = train_evaluator(data, out, cfg, text_encoder=text_encoder, resume=resume,
                          checkpoint_every=checkpoint_every, keep_checkpoint=keep_checkpoint)
    print(summary(res.card, verified=True))
    gate = card_gate(res.card)                   # this version's rule, not the card's own record
    if not gate.passed:
        small = (f"; the test split has only {gate.items} items, which makes the gate's thresholds high "
                 f"(more clips help: the synthetic data passes reliably with 120, docs/evaluator.md)"
                 if gate.items < 32 and control == "none" else "")
        print(f"evaluator written to {out} but it FAILED the sanity gate"
              + (" (expected: this is a shuffled-text control)" if control != "none" else "")
              + small + "; load_evaluator() will refuse it", file=sys.stderr)
    return 0 if gate.passed else 1


def main_show(dir, as_json: bool = False) -> int:
    """Print an evaluator's card (summary, or the raw card with ``as_json``). Returns 0 when
    the folder verifies; 1 when its id does not match (modified: the summary is printed with
    the error naming the file and field); 2, with one line and no summary, when it is not an
    evaluator folder or a file cannot be read (corrupt ``card.json`` or ``weights.safetensors``)."""
    from .backends import backend_of
    from .card import read_card, summary, verify_folder
    from .errors import CorruptEvaluatorFile, EvaluatorIntegrityError
    backend = backend_of(dir)
    if backend is not None and backend.show:       # imported evaluators have their own card
        from ..core.registry import load_object
        try:
            text, card = load_object(backend.show, __package__)(dir)
        except EvaluatorIntegrityError as exc:
            print(f"hoibench evaluator: error: {exc}", file=sys.stderr)
            return 2 if isinstance(exc, CorruptEvaluatorFile) else 1
        print(json.dumps(card, indent=1, sort_keys=True) if as_json else text)
        return 0
    if backend is not None and backend.importer is not None:
        return _show_imported(dir, backend, as_json)
    try:
        card = read_card(dir)
    except EvaluatorIntegrityError as exc:
        print(f"hoibench evaluator: error: {exc}", file=sys.stderr)
        return 2
    try:
        verify_folder(dir)
        ok, err = True, None
    except CorruptEvaluatorFile as exc:
        print(f"hoibench evaluator: error: {exc}", file=sys.stderr)
        return 2
    except EvaluatorIntegrityError as exc:
        ok, err = False, exc
    print(json.dumps(card, indent=1, sort_keys=True) if as_json else summary(card, ok))
    if not ok:
        print(f"hoibench evaluator: error: {err}", file=sys.stderr)
        return 1
    return 0


def _show_imported(dir, backend, as_json: bool) -> int:
    """``main_show`` for a folder written by an importer: its loader module's ``verify_folder``
    (-> card, weights bytes) and ``summary(card, verified)`` (the raw card without one)."""
    from importlib import import_module

    from .backends import peek_card
    from .errors import CorruptEvaluatorFile, EvaluatorIntegrityError
    mod = import_module(backend.loader.split(":")[0], __package__)
    try:
        card, _ = mod.verify_folder(dir)
        ok, err = True, None
    except CorruptEvaluatorFile as exc:
        print(f"hoibench evaluator: error: {exc}", file=sys.stderr)
        return 2
    except EvaluatorIntegrityError as exc:
        card, ok, err = peek_card(dir), False, exc
    show = getattr(mod, "summary", None)
    print(json.dumps(card, indent=1, sort_keys=True) if as_json or show is None else show(card, ok))
    if not ok:
        print(f"hoibench evaluator: error: {err}", file=sys.stderr)
        return 1
    return 0
