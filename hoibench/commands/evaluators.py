"""Evaluators and scoring with them: ``hoibench train-evaluator``, ``train-recognizer``,
``evaluator``, ``evaluate``. The backend names in ``evaluator``'s help come from the backend
registry (:mod:`hoibench.evaluator.backends`)."""
from __future__ import annotations

from pathlib import Path

from .common import H_EXECUTOR, H_SEED, H_STORE, add_submission_args, executor_arg


def _cmd_train_evaluator(args) -> int:
    from ..evaluator import main_train_evaluator
    return main_train_evaluator(args.data, args.out, size=args.size, variant=args.variant,
                                epochs=args.epochs, seed=args.seed)


def import_evaluator_folder(kind: str | None, out, files: dict) -> int:
    """``hoibench evaluator import KIND ... --out EV``: write the folder, print its summary."""
    from ..evaluator.backends import import_evaluator
    if not kind:
        raise ValueError("evaluator import: name the backend (hoibench evaluator ls lists them)")
    if out is None:
        raise ValueError(f"evaluator import {kind}: --out is required (the evaluator folder to write)")
    if Path(out).exists() and (not Path(out).is_dir() or any(Path(out).iterdir())):
        raise ValueError(f"--out {out}: exists and is not an empty folder; choose a new folder")
    eid = import_evaluator(kind, out, **files)
    print(f"wrote {kind} evaluator {eid} to {out}")
    return 0


def _cmd_evaluator(args) -> int:
    from ..evaluator import main_show
    from ..evaluator.backends import import_options, list_backends
    if args.action == "ls":
        for b in list_backends():
            how = "hoibench evaluator import " + b.name if b.importer else "made by its own command"
            print(f"{b.name:12s} {b.kind:12s} {b.description} ({how})")
        return 0
    if args.action == "import":
        return import_evaluator_folder(args.dir, args.out, {k: getattr(args, k) for k in import_options()})
    if args.dir is None:
        raise ValueError("evaluator show: give the evaluator folder (hoibench evaluator show EV)")
    return main_show(args.dir, as_json=args.json)


def _cmd_train_recognizer(args) -> int:
    from ..evaluator.recognizer import train_recognizer
    if args.out.exists() and any(args.out.iterdir()):
        raise ValueError(f"--out {args.out}: not empty; choose a new folder")
    card = train_recognizer(args.data, args.out, split=args.split, steps=args.steps, seed=args.seed)
    acc = ", ".join(f"{k} {v:.3f}" for k, v in card["gt_accuracy"].items())
    print(f"wrote {args.out}: recognizer {card['recognizer_id']} trained on {card['trained_on_split']} "
          f"({card['train_clips']} clips, {len(card['classes'])} actions); ground-truth accuracy {acc} "
          f"(chance {card['chance_accuracy']:.3f})")
    return 0


def _cmd_evaluate(args) -> int:
    from ..scoring.evaluate import main_evaluate
    return main_evaluate(args.submission, args.data, args.evaluator, out=args.out,
                         protocol=args.protocol, executor=args.executor, allow_failed_gate=args.allow_failed_gate,
                         allow_protocol_mismatch=args.allow_protocol_mismatch,
                         allow_evaluator_mismatch=args.allow_evaluator_mismatch, overwrite=args.overwrite)


def _add_training(sub) -> None:
    s = sub.add_parser("train-evaluator", help="train the contrastive text-motion evaluator on a store",
                       epilog="example: hoibench train-evaluator data --out evaluators/synthetic-tiny --size tiny")
    s.add_argument("data", type=Path, help=H_STORE + ", annotated")
    s.add_argument("--out", type=Path, required=True, help="the evaluator folder to write")
    s.add_argument("--size", choices=["tiny", "paper"], default="tiny", help="tiny (default; CPU minutes) or paper")
    s.add_argument("--variant", choices=["human", "hoi"], default="human",
                   help="human (default: the body's 263 features) or hoi (with the object's)")
    s.add_argument("--epochs", type=int, default=None, help="training epochs (default: the size's)")
    s.add_argument("--seed", type=int, default=0, help=H_SEED)
    s.set_defaults(func=_cmd_train_evaluator)

    s = sub.add_parser("train-recognizer", help="train the multi-body action recognizer (RA, FID) on a store",
                       epilog="example: hoibench train-recognizer data --out recognizers/mb --split train")
    s.add_argument("data", type=Path, help="a multi-body store (" + H_STORE + ")")
    s.add_argument("--out", type=Path, required=True, help="the recognizer folder to write (new or empty)")
    s.add_argument("--split", choices=["train", "all"], default="train",
                   help="train (hoibench's protocols) or all (every split, as the SyncDiff paper)")
    s.add_argument("--steps", type=int, default=400, help="optimiser steps (default 400)")
    s.add_argument("--seed", type=int, default=0, help=H_SEED)
    s.set_defaults(func=_cmd_train_recognizer)


def _add_evaluator(sub) -> None:
    from ..evaluator.backends import import_options, list_backends
    importable = ", ".join(b.name for b in list_backends() if b.importer)
    s = sub.add_parser("evaluator", help="show an evaluator card, list backends, import a published evaluator",
                       epilog="examples: hoibench evaluator show evaluators/synthetic-tiny; hoibench evaluator ls; "
                              "hoibench evaluator import t2m --checkpoint finest.tar --glove glove --meta meta --out ev")
    s.add_argument("action", choices=["show", "ls", "import"],
                   help="show: print the card after verifying the folder; ls: the evaluator backends; "
                        "import KIND: write an evaluator folder from a published evaluator's files")
    s.add_argument("dir", nargs="?", default=None,
                   help=f"show: the evaluator folder; import: the backend ({importable}; hoibench evaluator ls)")
    s.add_argument("--json", action="store_true", help="print the card as JSON")
    s.add_argument("--out", type=Path, help="import: the evaluator folder to write (must not exist)")
    for option, text in import_options().items():
        s.add_argument("--" + option.replace("_", "-"), dest=option, type=Path, default=None, help="import: " + text)
    s.set_defaults(func=_cmd_evaluator)


def _add_evaluate(sub) -> None:
    s = sub.add_parser("evaluate", help="score a submission under a protocol (writes a result JSON with --out)",
                       epilog="example: hoibench evaluate sub.zip --data data --evaluator ev --out result.json")
    add_submission_args(s)
    s.add_argument("--evaluator", type=Path, default=None,
                   help="the evaluator folder (hoibench train-evaluator; train-recognizer for multi-body stores); "
                        "not read by InterAct's o2h/h2o protocols (--protocol interact-o2h-clean)")
    s.add_argument("--protocol", default=None, help="protocol id (default: <dataset>-<mode> of the store)")
    s.add_argument("--executor", default="serial", type=executor_arg, help=H_EXECUTOR)
    s.add_argument("--out", type=Path, default=None,
                   help="write the result JSON here (a new file; without --out nothing is written)")
    s.add_argument("--overwrite", action="store_true", help="replace an existing --out file")
    s.add_argument("--allow-failed-gate", action="store_true",
                   help="score with an evaluator that fails its sanity gate on this store (the result is marked)")
    s.add_argument("--allow-protocol-mismatch", action="store_true",
                   help="score under a protocol for another dataset, mode or fps (the result records it)")
    s.add_argument("--allow-evaluator-mismatch", action="store_true",
                   help="score with an evaluator trained on another dataset or representation (recorded)")
    s.set_defaults(func=_cmd_evaluate)


def register(sub) -> None:
    """train-evaluator, train-recognizer, evaluator, evaluate."""
    for add in (_add_training, _add_evaluator, _add_evaluate):
        add(sub)
