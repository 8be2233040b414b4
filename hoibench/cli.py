"""The ``hoibench`` command: a thin shell over library functions.

Examples::

    hoibench demo --out demo-out
    hoibench synth --out raw --clips 120
    hoibench prepare behave --root raw --body-models raw/body_models --split-file raw/split.json --out data
    hoibench annotate data
    hoibench train-evaluator data --out ev
    hoibench validate sub.zip --data data
    hoibench evaluate sub.zip --data data --evaluator ev --out result.json

Each subcommand's --help has its own example.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def _cmd_version(args) -> int:
    from . import __version__
    print(__version__)
    return 0


def _cmd_representations(args) -> int:
    from .representations import hml263, hoi269
    rows = [("hml263", hml263.DIM, mode, hml263.VERSION[mode]) for mode in hml263.MODES]
    rows += [("hoi269", hoi269.DIM, mode, hoi269.VERSION[mode]) for mode in hoi269.BODY_MODE]
    rows += [("joint_level", "24x12", "-", "joint_level-1.0 (from hoi269)")]
    print(f"{'name':12s} {'dims':>6s}  {'mode':15s} version")
    for name, dim, mode, version in rows:
        print(f"{name:12s} {str(dim):>6s}  {mode:15s} {version}")
    return 0


def _cmd_represent(args) -> int:
    import numpy as np

    from .core.io import read_regular_file
    from .representations import hml263, joint_level
    from .scoring.submission import MAX_ARRAY_BYTES
    import io as _io
    raw = read_regular_file(args.joints, MAX_ARRAY_BYTES, "joints file")
    try:
        joints = np.load(_io.BytesIO(raw), allow_pickle=False)
    except Exception as e:  # not an .npy, pickled objects, truncated
        raise ValueError(f"{args.joints}: not a plain .npy array ({type(e).__name__}: "
                         f"{str(e).split('.')[0]})") from None
    if not isinstance(joints, np.ndarray) or joints.dtype.kind != "f" or joints.shape[-2:] != (22, 3) \
            or joints.ndim not in (3, 4) or not np.isfinite(joints).all():
        raise ValueError(f"{args.joints}: joints: expected finite floats of shape (T, 22, 3) or (B, T, 22, 3), "
                         f"got {getattr(joints, 'dtype', '?')} {getattr(joints, 'shape', '?')}")
    feats = hml263.encode(joints, mode=args.mode, fps=args.fps)
    if args.format == "joint_level":
        feats = joint_level.from_hoi269(feats)
    from .core.io import atomic_save_npy
    atomic_save_npy(args.out, feats)
    print(f"wrote {args.out}: {feats.shape} {feats.dtype}")
    return 0


def _parse_defects(items: list[str]) -> dict:
    """['3:foot_skating=1.0', 'Date01_Sub01_boxsmall_lift:penetration=0.02'] -> {clip: [Defect]}."""
    from .datasets.synthetic import Defect
    out: dict = {}
    for item in items or []:
        clip, _, spec = item.rpartition(":")
        kind, _, mag = spec.partition("=")
        if not clip or not mag:
            raise ValueError(f"--defect: expected CLIP:KIND=MAGNITUDE, got {item!r}")
        key = int(clip) if clip.isdigit() else clip
        out.setdefault(key, []).append(Defect(kind, float(mag)))
    return out


#: ``hoibench synth --layout L``: the writer of each raw layout and what it writes
SYNTH_LAYOUTS = {
    "behave": (".datasets.synthetic", "write_behave_layout", "clips", "in the behave layout"),
    "omomo": (".datasets.synthetic_layouts", "write_omomo_layout", "clips", "in the omomo layout"),
    "rich": (".datasets.synthetic_layouts", "write_rich_layout", "clips", "in the rich layout"),
    "multibody": (".datasets.multibody", "write_synthetic_layout", "multi-body clips",
                  "(hoibench's multi-body layout)"),
    "grab": (".datasets.grab_layout", "write_grab_layout", "grab sequences", "in GRAB's layout"),
    "core4d": (".datasets.core4d_layout", "write_core4d_layout", "core4d sequences", "in CORE4D's layout"),
    "interact": (".datasets.interact_layout", "write_interact_layout", "interact sequences",
                 "in InterAct's processed layout"),
    "taco": (".datasets.taco_layout", "write_taco_layout", "taco sequences", "in TACO's layout"),
    "oakink2": (".datasets.oakink2_layout", "write_oakink2_layout", "oakink2 sequences", "in OAKINK2's layout"),
}


def _cmd_synth(args) -> int:
    import importlib
    module, function, what, where = SYNTH_LAYOUTS[args.layout]
    writer = getattr(importlib.import_module(module, __package__), function)
    if args.layout == "behave":
        writer(args.out, args.clips, seed=args.seed, defects=_parse_defects(args.defect), executor=args.executor)
    elif args.defect:
        raise ValueError("--defect: defects are injected in the behave layout only")
    else:
        writer(args.out, args.clips, seed=args.seed)
    models = "" if args.layout == "multibody" else f"; body models in {Path(args.out) / 'body_models'}"
    print(f"wrote {args.clips} synthetic {what} to {args.out} {where}{models}")
    return 0


def _cmd_prepare(args) -> int:
    from .datasets.store import PrepareConfig, prepare, summary_table
    import importlib
    loader = importlib.import_module(f".datasets.{args.dataset}", __package__)
    # hoibench's own synthetic data in a raw layout is named as such (its protocol differs)
    synthetic = args.dataset == "behave" and (Path(args.root) / "hoibench_synthetic.json").exists()
    name = "synthetic" if synthetic else args.dataset
    if hasattr(loader, "dataset_name"):           # the layout names its dataset (multi-body)
        name = loader.dataset_name(args.root)
    elif args.body_models is None:
        raise ValueError(f"prepare {args.dataset}: --body-models is required (the folder with smplh/ or smplx/)")
    cfg = PrepareConfig(name, fps=args.fps, mode=args.mode,
                        body_model_type="smplh" if args.dataset == "behave" else "smplx")
    extra = {k: getattr(args, k) for k in ("sources", "split") if getattr(args, k, None) is not None}
    if extra and args.dataset != "interact":
        raise ValueError(f"prepare {args.dataset}: --{next(iter(extra))} is read by `prepare interact` only")
    jobs = loader.prepare_jobs(args.root, args.body_models, args.out, cfg, split_file=args.split_file, **extra)
    warnings = getattr(loader, "prepare_warnings", lambda root, models: [])(args.root, args.body_models)
    manifest = prepare(jobs, args.out, cfg, executor=args.executor, strict=args.strict,
                       source={"root": str(Path(args.root).resolve()), "body_models": cfg.body_model_type},
                       warnings=warnings)
    finish = getattr(loader, "write_texts", None)     # sources whose texts come with the data (interact)
    if finish is not None:
        finish(args.out, manifest)
    print(summary_table(manifest))
    counts = manifest.get("counts", {})
    if not counts.get("clips") and counts.get("failed"):
        print(f"hoibench prepare: error: every sequence failed ({counts['failed']}; see "
              f"{Path(args.out) / 'errors.jsonl'}): nothing was prepared", file=sys.stderr)
        return 1
    missing = manifest.get("incomplete") or []
    if missing:
        print(f"hoibench prepare: error: the store is incomplete: {len(missing)} raw source(s) missing or "
              f"unreadable (see errors.jsonl): {missing[0]}", file=sys.stderr)
        return 1
    return 0


def _cmd_render(args) -> int:
    from .publish.renderers import main_render, main_render_worst
    if args.worst is not None:
        main_render_worst(args.clip, args.worst, args.by, args.data, args.submission, args.out)
        return 0
    if args.submission is not None:
        raise ValueError("render: --submission goes with RESULT --worst K (for one id: render SUB --id ID)")
    print(f"wrote {main_render(args.clip, args.data, args.id, args.out, sample=args.sample, body=args.body)}")
    return 0


def _cmd_datasets(args) -> int:
    from .datasets.catalog import main_datasets
    return main_datasets(args.action)


def _cmd_splits(args) -> int:
    from .datasets import splits
    if args.action == "ls":
        print("\n".join(splits.summary_lines()))
        print("(* = default)")
        return 0
    if not args.dataset:
        raise ValueError("splits show: name a dataset, e.g. hoibench splits show behave --split hoidiff-clips")
    sp = splits.get(args.dataset, args.split)
    print(json.dumps(sp if args.full else {k: (v if not isinstance(v, list) else f"{len(v)} ids: {v[:3]} ...")
                                           for k, v in sp.items()}, indent=2))
    return 0


def _cmd_export(args) -> int:
    from .datasets.export import main_export
    return main_export(args.data, args.out, args.format, overwrite=args.overwrite)


def _cmd_annotate(args) -> int:
    from .text.annotate import main_annotate
    return main_annotate(args.data, preview=args.preview, executor=args.executor, strict=args.strict,
                         seed=args.seed, spec_dir=args.spec_dir, labels=args.labels)


def _cmd_protocols(args) -> int:
    from .tracks.protocol import main_protocols
    return main_protocols(args.action, args.name)


def _cmd_tracks(args) -> int:
    from .tracks.registry import main_tracks
    return main_tracks(args.action, args.name)


def _cmd_validate(args) -> int:
    from .scoring.submission import main_validate
    return main_validate(args.submission, args.data, protocol=args.protocol)


def _cmd_submission(args) -> int:
    if args.action == "prompts":
        from .scoring.prompts import write_prompts
        text = write_prompts(args.data, args.out)
        if args.out is None:
            print(text, end="")
        else:
            print(f"wrote {args.out}: {text.count(chr(10))} prompts")
        return 0
    if args.out is None:
        raise ValueError(f"submission {args.action}: --out is required")
    from .scoring.reference_rows import main_reference
    return main_reference(args.action, args.data, args.out, args.kind, as_zip=args.zip, samples=args.samples,
                          sigma=args.sigma, seed=args.seed)


def _cmd_train_evaluator(args) -> int:
    from .evaluator import main_train_evaluator
    return main_train_evaluator(args.data, args.out, size=args.size, variant=args.variant,
                                epochs=args.epochs, seed=args.seed)


def _cmd_evaluator(args) -> int:
    from .evaluator import main_show
    from .evaluator.backends import import_options, list_backends
    if args.action == "ls":
        for b in list_backends():
            how = "hoibench evaluator import " + b.name if b.importer else "made by its own command"
            print(f"{b.name:12s} {b.kind:12s} {b.description} ({how})")
        return 0
    if args.action == "import":
        from .evaluator.commands import main_import
        files = {k: getattr(args, k) for k in import_options()}
        return main_import(args.dir, args.out, files)
    if args.dir is None:
        raise ValueError("evaluator show: give the evaluator folder (hoibench evaluator show EV)")
    return main_show(args.dir, as_json=args.json)


def _cmd_train_recognizer(args) -> int:
    from .evaluator.recognizer import train_recognizer
    if args.out.exists() and any(args.out.iterdir()):
        raise ValueError(f"--out {args.out}: not empty; choose a new folder")
    card = train_recognizer(args.data, args.out, split=args.split, steps=args.steps, seed=args.seed)
    acc = ", ".join(f"{k} {v:.3f}" for k, v in card["gt_accuracy"].items())
    print(f"wrote {args.out}: recognizer {card['recognizer_id']} trained on {card['trained_on_split']} "
          f"({card['train_clips']} clips, {len(card['classes'])} actions); ground-truth accuracy {acc} "
          f"(chance {card['chance_accuracy']:.3f})")
    return 0


def _cmd_evaluate(args) -> int:
    from .scoring.evaluate import main_evaluate
    return main_evaluate(args.submission, args.data, args.evaluator, out=args.out,
                         protocol=args.protocol, executor=args.executor, allow_failed_gate=args.allow_failed_gate,
                         allow_protocol_mismatch=args.allow_protocol_mismatch,
                         allow_evaluator_mismatch=args.allow_evaluator_mismatch, overwrite=args.overwrite)


def _cmd_baseline(args) -> int:
    from .baselines import commands
    if args.action == "train":
        return commands.main_train(args.name, args.data, args.out, config=args.config, device=args.device,
                                   steps=args.steps, seed=args.seed, mask=args.mask, threads=args.threads,
                                   overrides=args.set)
    if args.action == "sample":
        return commands.main_sample(args.name, args.run, args.data, args.out, samples=args.samples, seed=args.seed,
                                    device=args.device, guidance=args.guidance, ddim_steps=args.ddim_steps,
                                    temperature=args.temperature, as_zip=args.zip, threads=args.threads,
                                    overrides=args.set)
    return commands.main_show(args.run)


def _cmd_import(args) -> int:
    from .scoring.importers import import_results
    path, rep = import_results(args.format, args.results, args.data, args.out, match=args.match, mapping=args.map,
                               trust_pickle=args.trust_pickle, fps=args.fps, up=args.up, normalized=args.normalized,
                               method=args.method, as_zip=args.zip, body_models=args.body_models,
                               model_type=args.model_type, gender=args.gender)
    conv = rep["conversions"]
    print(f"wrote {path}: {rep['matched']}/{rep['test_ids']} test ids, K = {rep['samples_per_prompt'][0]} "
          f"(matched by {conv['match']}; {conv['source_fps']:g} -> {conv['store_fps']:g} fps; up {conv['up_axis']})")
    if rep["missing_ids"]:
        print(f"  missing: {len(rep['missing_ids'])} test ids without samples (e.g. {rep['missing_ids'][0]}): the "
              f"submission is incomplete")
    if rep.get("human_only"):
        print("  human-only: the results carry no object motion for this human-object store; submission.json has "
              "flags.human_only, so evaluate scores the embedding metrics, FSR and jitter on the human and "
              "reports the object metrics (CD, OCD, PS, penetration, ...) as not applicable; the leaderboard marks "
              "the row human-only (for object metrics import with --format hoidiff or chois)")
    if rep["unmatched_entries"]:
        print(f"  unmatched: {len(rep['unmatched_entries'])} entries (e.g. {rep['unmatched_entries'][0]!r})")
    if rep["ambiguous_texts"]:
        print(f"  ambiguous: {len(rep['ambiguous_texts'])} texts shared by several clips (assigned in id order)")
    return 0


def _cmd_compare(args) -> int:
    from .scoring.compare import compare, plot
    names = [n.strip() for n in args.names.split(",")] if args.names else None
    if names is not None and len(names) != len(args.results):
        raise ValueError(f"--names: {len(names)} names for {len(args.results)} results")
    print(compare(args.results, names))
    if args.plot:
        plot(args.results, args.plot, names)
        print(f"wrote {args.plot}")
    return 0


def _cmd_leaderboard(args) -> int:
    from .publish.leaderboard_commands import main_leaderboard
    return main_leaderboard(args.action, args.root, getattr(args, "track", None), result=getattr(args, "result", None),
                            method=getattr(args, "method", ""), role=getattr(args, "role", "method"),
                            notes=getattr(args, "notes", ""), allow_incomplete=getattr(args, "allow_incomplete", False),
                            replace=getattr(args, "replace", False), new_track=getattr(args, "new_track", False))


def _cmd_leaderboard_site(args) -> int:
    from .publish.leaderboard_commands import resolve_root
    from .publish.site import build_site
    paths = build_site(resolve_root(args.root), args.out)
    print(f"wrote {len(paths)} files to {args.out} (open {args.out / 'index.html'})")
    return 0


def _cmd_challenge(args) -> int:
    from .challenge.commands import main_challenge
    return main_challenge(args)


def _cmd_demo(args) -> int:
    from .demo import run_demo
    run_demo(Path(args.out), seed=args.seed, baselines=not args.no_baselines)
    return 0


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors and exit status 2: a misspelled command or choice gets
    its nearest spelling (difflib), any other usage error its message, both naming the command."""

    def _check_value(self, action, value) -> None:
        choices = action.choices
        if choices is None or value in choices:
            return
        import difflib
        names = [str(c) for c in choices]
        close = difflib.get_close_matches(str(value), names, n=1, cutoff=0.6)
        what = "command" if isinstance(action, argparse._SubParsersAction) else \
            ("choice for " + "/".join(action.option_strings) if action.option_strings else f"{action.dest}")
        hint = f": did you mean {close[0]!r}?" if close else f" (choose from {', '.join(names)})"
        self.exit(2, f"{self.prog}: error: unknown {what} {value!r}{hint}\n")

    def error(self, message: str):
        """One line, ``PROG: error: MESSAGE (see PROG --help)``, and exit status 2."""
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _executor_arg(spec: str) -> str:
    """``--executor``: its syntax is checked while the arguments are parsed, before any work."""
    from .core.parallel import parse_executor
    try:
        parse_executor(spec)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("--executor: ")) from None
    return spec


H_EXECUTOR = "where per-clip work runs: serial (default), processes[:N] (N local processes) or dask://ADDRESS"
H_STORE = "the processed store (a folder written by hoibench prepare)"
H_SEED = "random seed (default 0)"
H_ZIP = "write the submission as one .zip file instead of a folder"
H_THREADS = "torch threads (default: torch's own choice)"
H_ROOT = ("the leaderboards folder (default: the nearest leaderboards/ with track folders, in the current folder "
          "or above; the command says which)")
H_ACTION = "what to do: ls lists, show prints one (named next)"


def _add_data_commands(sub) -> None:
    from .datasets.catalog import loader_names
    """Representations, raw data, stores and texts: version, representations, represent, synth, prepare, splits, export, annotate."""
    s = sub.add_parser("version", help="print the toolkit version")
    s.set_defaults(func=_cmd_version)

    s = sub.add_parser("representations", help="list representations, modes and versions",
                       epilog="example: hoibench representations ls")
    s.add_argument("action", choices=["ls"], help="ls: one line per representation and mode")
    s.set_defaults(func=_cmd_representations)

    s = sub.add_parser("represent", help="encode a joints .npy (T,22,3) or (B,T,22,3)",
                       epilog="example: hoibench represent joints.npy --mode clean --out feats.npy")
    s.add_argument("joints", type=Path, help="a .npy of joints (T, 22, 3) or (B, T, 22, 3), metres, y-up")
    s.add_argument("--format", choices=["hml263", "joint_level"], default="hml263",
                   help="hml263 (default; 263 values per frame) or joint_level (24 x 12)")
    s.add_argument("--mode", choices=["clean", "legacy", "legacy-hoidiff"], default="clean",
                   help="clean (default) or the reference code's quirks (legacy, legacy-hoidiff)")
    s.add_argument("--fps", type=float, default=20.0, help="the joints' frame rate (default 20)")
    s.add_argument("--out", type=Path, required=True, help="the .npy to write")
    s.set_defaults(func=_cmd_represent)

    s = sub.add_parser("synth", help="write the deterministic synthetic HOI dataset",
                       epilog="example: hoibench synth --out raw --clips 120 --seed 0 "
                              "--defect 3:foot_skating=1.0 --defect 5:penetration=0.02")
    s.add_argument("--out", type=Path, required=True, help="the raw-layout folder to write")
    s.add_argument("--clips", type=int, default=24, help="how many clips (default 24; 120 for the evaluator gate)")
    s.add_argument("--seed", type=int, default=0, help=H_SEED)
    s.add_argument("--layout", choices=list(SYNTH_LAYOUTS), default="behave",
                   help="multibody: hands, people and objects in hoibench's multi-body layout; grab / core4d / "
                        "taco / oakink2: multi-body sequences in that release's layout; interact: InterAct's "
                        "processed layout (proxy body models)")
    s.add_argument("--defect", action="append", default=[],
                   help="CLIP:KIND=MAGNITUDE, KIND in foot_skating (m/s), penetration (m), lost_contact (m)")
    s.add_argument("--executor", default="serial", type=_executor_arg, help=H_EXECUTOR)
    s.set_defaults(func=_cmd_synth)

    s = sub.add_parser("prepare", help="raw dataset (hoibench datasets ls) -> processed store",
                       epilog="example: hoibench prepare behave --root RAW --body-models MODELS "
                              "--out DATA --fps 20 --executor processes:2")
    s.add_argument("dataset", choices=loader_names(),
                   help="the raw layout to read (hoibench datasets ls; interact: InterAct's processed data/ folder)")
    s.add_argument("--root", type=Path, required=True, help="raw dataset folder")
    s.add_argument("--body-models", type=Path, default=None,
                   help="folder with smplh/ (BEHAVE) or smplx/ (OMOMO, RICH) model files: yours or the proxy "
                        "(not needed for multibody)")
    s.add_argument("--out", type=Path, required=True, help="the store folder to write (rerunning resumes)")
    s.add_argument("--fps", type=float, default=20.0, help="resample to this rate, by time")
    s.add_argument("--mode", choices=["clean", "legacy", "legacy-hoidiff"], default="clean",
                   help="representation mode (legacy-hoidiff: HOI-Diff's features, for behave-legacy/omomo-legacy)")
    s.add_argument("--split-file", type=Path, default=None, help="JSON {train: [...], test: [...]}")
    s.add_argument("--sources", default=None,
                   help="interact: comma-separated source datasets (default: every one present), e.g. behave,grab")
    s.add_argument("--split", choices=["object", "sequence"], default=None,
                   help="interact: InterAct's sequence split (test_seq.txt, default: what its evaluation script "
                        "uses) or object split (test.txt)")
    s.add_argument("--executor", default="serial", type=_executor_arg, help=H_EXECUTOR)
    s.add_argument("--strict", action="store_true", help="stop at the first failing sequence")
    s.set_defaults(func=_cmd_prepare)

    s = sub.add_parser("datasets", help="list the raw-data loaders: source, licence, split, verification",
                       epilog="example: hoibench datasets ls")
    s.add_argument("action", choices=["ls"], help="ls: one block per loader")
    s.set_defaults(func=_cmd_datasets)

    s = sub.add_parser("splits", help="list or show the split files and their sources",
                       epilog="examples: hoibench splits ls; hoibench splits show omomo --split unseen-object")
    s.add_argument("action", choices=["ls", "show"], help=H_ACTION)
    s.add_argument("dataset", nargs="?", help="show: the dataset (behave, omomo, ...)")
    s.add_argument("--split", default=None, help="show: which split file (default: the dataset's default, * in ls)")
    s.add_argument("--full", action="store_true", help="print every id")
    s.set_defaults(func=_cmd_splits)

    s = sub.add_parser("export", help="write a store in the HumanML3D or HOI-Diff folder layout",
                       epilog="example: hoibench export --format humanml3d data/behave out/HumanML3D")
    s.add_argument("--format", choices=["humanml3d", "hoidiff"], default="humanml3d",
                   help="the folder layout to write (default humanml3d)")
    s.add_argument("data", type=Path, help=H_STORE)
    s.add_argument("out", type=Path, help="the folder to write: new, empty, or an earlier export")
    s.add_argument("--overwrite", action="store_true",
                   help="write into a non-empty folder that is not an earlier export (same-named files are replaced)")
    s.set_defaults(func=_cmd_export)

    s = sub.add_parser("annotate", help="contact-aware texts and semantic groups for a store",
                       epilog="examples: hoibench annotate data --preview 5; "
                              "hoibench annotate data --labels action_label.json --executor processes:2")
    s.add_argument("data", type=Path, help=H_STORE)
    s.add_argument("--preview", type=int, default=None, metavar="N",
                   help="print a table of N clips (timelines, texts) and write nothing")
    s.add_argument("--labels", type=Path, default=None, help="BEHAVE per-second action labels (json)")
    s.add_argument("--seed", type=int, default=0, help="paraphrase choice seed")
    s.add_argument("--spec-dir", type=Path, default=None, help="annotator spec folder (default annotators/)")
    s.add_argument("--executor", default="serial", type=_executor_arg, help=H_EXECUTOR)
    s.add_argument("--strict", action="store_true", help="stop at the first clip that fails")
    s.set_defaults(func=_cmd_annotate)


def _add_scoring_commands(sub) -> None:
    """Protocols, submissions, evaluators and scoring: protocols, validate, submission, train-evaluator, train-recognizer, evaluator, evaluate."""
    s = sub.add_parser("tracks", help="list or show the benchmark tracks (store kind, evaluator, metrics, protocols)",
                       epilog="examples: hoibench tracks ls; hoibench tracks show rich-cat")
    s.add_argument("action", choices=["ls", "show"], help=H_ACTION)
    s.add_argument("name", nargs="?", help="show: the track")
    s.set_defaults(func=_cmd_tracks)

    s = sub.add_parser("protocols", help="list or show evaluation protocols",
                       epilog="examples: hoibench protocols ls; hoibench protocols show behave-clean")
    s.add_argument("action", choices=["ls", "show"], help=H_ACTION)
    s.add_argument("name", nargs="?", help="show: the protocol id")
    s.set_defaults(func=_cmd_protocols)

    s = sub.add_parser("validate", help="check a submission against a store's test split",
                       epilog="example: hoibench validate my_method.zip --data data/behave")
    s.add_argument("submission", type=Path, help="the submission folder or .zip")
    s.add_argument("--data", type=Path, required=True, help="the store the submission is for (" + H_STORE + ")")
    s.add_argument("--protocol", default=None, help="protocol id (default: the store's)")
    s.set_defaults(func=_cmd_validate)

    s = sub.add_parser("submission", help="make submissions (from-store: the ground-truth 'real motion' row; "
                                          "reference: the rows that bracket every metric; prompts: what a "
                                          "generator needs)",
                       description="actions:\n"
                                   "  from-store  the store's own test clips as a submission: the ground-truth row\n"
                                   "  reference   a reference row that brackets the metrics (--kind: noisy GT, "
                                   "static or mean pose,\n              mismatched texts, ...)\n"
                                   "  prompts     every test id with its captions, length, fps and object: what "
                                   "your generator needs",
                       epilog="examples:\n  hoibench submission from-store data --out gt_submission\n"
                              "  hoibench submission reference data --kind gt-noise --sigma 0.03 --out gt3cm\n"
                              "  hoibench submission reference data --kind mismatched-texts --out mismatched\n"
                              "  hoibench submission prompts data --out prompts.jsonl   # what a generator needs",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    s.add_argument("action", choices=["from-store", "reference", "prompts"],
                   help="from-store, reference or prompts (see above)")
    s.add_argument("data", type=Path, help=H_STORE)
    s.add_argument("--out", type=Path, default=None,
                   help="from-store, reference: the submission folder (or .zip with --zip) to write; prompts: a "
                        ".jsonl file (default: print)")
    s.add_argument("--kind", default=None,
                   choices=["gt", "gt-noise", "static-first-pose", "mean-pose", "mismatched-texts",
                            "desync", "lost_contact", "interpenetration", "static"],
                   help="reference: which row (docs/leaderboards.md; multi-body stores: gt, gt-noise, desync, "
                        "lost_contact, interpenetration, static -- docs/multibody.md)")
    s.add_argument("--sigma", type=float, default=0.01, help="gt-noise: noise std in metres (default 0.01)")
    s.add_argument("--seed", type=int, default=0, help="reference: seed of the noise or the shuffle (default 0)")
    s.add_argument("--samples", "-k", type=int, default=1, help="multi-body gt-noise: samples per prompt")
    s.add_argument("--zip", action="store_true", help=H_ZIP)
    s.set_defaults(func=_cmd_submission)

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

    from .evaluator.backends import import_options
    s = sub.add_parser("evaluator", help="show an evaluator card, list backends, import a published evaluator",
                       epilog="examples: hoibench evaluator show evaluators/synthetic-tiny; hoibench evaluator ls; "
                              "hoibench evaluator import t2m --checkpoint finest.tar --glove glove --meta meta --out ev")
    s.add_argument("action", choices=["show", "ls", "import"],
                   help="show: print the card after verifying the folder; ls: the evaluator backends; "
                        "import KIND: write an evaluator folder from a published evaluator's files")
    s.add_argument("dir", nargs="?", default=None,
                   help="show: the evaluator folder; import: the backend (hoibench evaluator ls)")
    s.add_argument("--json", action="store_true", help="print the card as JSON")
    s.add_argument("--out", type=Path, help="import: the evaluator folder to write (must not exist)")
    for option, text in import_options().items():
        s.add_argument("--" + option.replace("_", "-"), dest=option, type=Path, default=None, help="import: " + text)
    s.set_defaults(func=_cmd_evaluator)

    s = sub.add_parser("evaluate", help="score a submission under a protocol (writes a result JSON with --out)",
                       epilog="example: hoibench evaluate sub.zip --data data --evaluator ev --out result.json")
    s.add_argument("submission", type=Path, help="the submission folder or .zip")
    s.add_argument("--data", type=Path, required=True, help="the store the submission is for (" + H_STORE + ")")
    s.add_argument("--evaluator", type=Path, required=True,
                   help="the evaluator folder (hoibench train-evaluator; train-recognizer for multi-body stores)")
    s.add_argument("--protocol", default=None, help="protocol id (default: <dataset>-<mode> of the store)")
    s.add_argument("--executor", default="serial", type=_executor_arg, help=H_EXECUTOR)
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


def _add_baseline_train(bsub, names: list[str]) -> None:
    """``hoibench baseline train``."""
    b = bsub.add_parser("train", help="train a baseline on a store's train split")
    b.add_argument("name", choices=names, help="the baseline")
    b.add_argument("data", type=Path, help=H_STORE + ", annotated")
    b.add_argument("--out", type=Path, required=True, help="the run folder to write")
    b.add_argument("--config", default="tiny",
                   help="a named config: tiny (default; CPU minutes), paper, or the baseline's own "
                        "(chainhoi: released, the public code's network; ejim: micro)")
    b.add_argument("--steps", type=int, default=None,
                   help="optimiser steps (0: the untrained model); catmo: every stage's steps (0: untrained)")
    b.add_argument("--set", action="append", default=[], metavar="SECTION.FIELD=VALUE",
                   help="override one config field (JSON value), e.g. train.lr=5e-4; repeatable")
    b.add_argument("--seed", type=int, default=None, help="random seed (default: the config's)")
    b.add_argument("--mask", choices=["paper", "released"], default=None,
                   help="chainhoi only: Kinematic-aware Decoder mask (released: the published code's additive "
                        "float mask)")
    b.add_argument("--device", default="cpu", help="cpu (default) or cuda")
    b.add_argument("--threads", type=int, default=None, help=H_THREADS)
    b.set_defaults(func=_cmd_baseline)


def _add_baseline_sample(bsub, names: list[str]) -> None:
    """``hoibench baseline sample``."""
    b = bsub.add_parser("sample", help="sample a baseline into a standard submission for the test split")
    b.add_argument("name", choices=names + ["mean-pose"], help="the baseline (mean-pose needs no run)")
    b.add_argument("run", type=Path, nargs="?", default=None,
                   help="run folder (chainhoi, ejim, catmo, syncdiff; none for mean-pose)")
    b.add_argument("--data", type=Path, required=True, help="the store to sample its test split for")
    b.add_argument("--out", type=Path, required=True, help="the submission folder (or .zip with --zip) to write")
    b.add_argument("--samples", "-k", type=int, default=1,
                   help="samples per prompt (K, at most the protocol's 30; MultiModality needs 30)")
    b.add_argument("--seed", type=int, default=0, help=H_SEED)
    b.add_argument("--guidance", type=float, default=None, help="classifier-free guidance scale (default: config, 2)")
    b.add_argument("--ddim-steps", type=int, default=None, help="DDIM steps (default: config, 50)")
    b.add_argument("--temperature", type=float, default=None, help="catmo: sampling temperature (default: config, 1)")
    b.add_argument("--set", action="append", default=[], metavar="SECTION.FIELD=VALUE",
                   help="syncdiff: inference-time settings (syncdiff.explicit_sync, syncdiff.sync_every, "
                        "syncdiff.sync_weight), recorded in the submission")
    b.add_argument("--device", default="cpu", help="cpu (default) or cuda")
    b.add_argument("--threads", type=int, default=None, help=H_THREADS)
    b.add_argument("--zip", action="store_true", help=H_ZIP)
    b.set_defaults(func=_cmd_baseline)


def _add_baseline_commands(sub) -> None:
    """Reference baselines and importers of other generators' outputs: baseline, import."""
    from .baselines.registry import SPECS as BASELINES
    s = sub.add_parser("baseline", help="train and sample reference baselines (chainhoi, ejim, catmo, mean-pose)",
                       epilog="examples:\n  hoibench baseline train chainhoi data --config tiny --out runs/chainhoi-tiny\n"
                              "  hoibench baseline sample chainhoi runs/chainhoi-tiny --data data --out sub\n"
                              "  hoibench baseline train catmo data --out runs/catmo-tiny --set train.gpt_steps=3000\n"
                              "  hoibench baseline sample catmo runs/catmo-tiny --data data --out sub-catmo -k 30\n"
                              "  hoibench baseline sample mean-pose --data data --out sub-mean\n"
                              "  hoibench baseline show runs/chainhoi-tiny",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    bsub = s.add_subparsers(dest="action", required=True, metavar="{train,sample,show}")
    _add_baseline_train(bsub, sorted(BASELINES))
    _add_baseline_sample(bsub, sorted(BASELINES))
    b = bsub.add_parser("show", help="show (and verify) a baseline run folder")
    b.add_argument("run", type=Path, help="the run folder")
    b.set_defaults(func=_cmd_baseline)

    s = sub.add_parser("import", help="turn existing generators' outputs (MDM, HOI-Diff, T2M-GPT/MoMask joints, "
                                      "CHOIS, feature folders) into a submission",
                       epilog="examples:\n  hoibench import mdm results.npy --data data --out sub --trust-pickle\n"
                              "  hoibench import joints t2mgpt_joints/ --data data --out sub --fps 20\n"
                              "  hoibench import features feats/ --data data --out sub --normalized",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    s.add_argument("format", choices=["mdm", "hoidiff", "joints", "chois", "features", "params"],
                   help="the outputs' format (params: per-frame SMPL/SMPL-H/SMPL-X parameters, posed with --body-models)")
    s.add_argument("results", type=Path, help="results.npy (mdm, hoidiff) or a folder of files")
    s.add_argument("--data", type=Path, required=True, help="the store the outputs are for (" + H_STORE + ")")
    s.add_argument("--out", type=Path, required=True, help="the submission folder (or .zip with --zip) to write")
    s.add_argument("--match", choices=["id", "text"], default=None,
                   help="map entries to test ids by file name (id) or caption (text); default: text for mdm/hoidiff")
    s.add_argument("--map", type=Path, default=None, help="JSON {entry index or file stem: test id}")
    s.add_argument("--trust-pickle", action="store_true",
                   help="read MDM/HOI-Diff results.npy, a pickle: only for files you produced yourself")
    s.add_argument("--fps", type=float, default=None, help="the source frame rate (default: the format's, or the store's)")
    s.add_argument("--up", choices=["y", "z"], default="y", help="joints, params: the source's up axis")
    s.add_argument("--normalized", action="store_true", help="features: de-normalise with the store's statistics")
    s.add_argument("--body-models", type=Path, default=None,
                   help="params: the folder with your smplh/, smplx/ or smpl/ model files")
    s.add_argument("--model-type", choices=["smplh", "smplx", "smpl"], default="smplh",
                   help="params: the body model the parameters are for (default smplh)")
    s.add_argument("--gender", choices=["neutral", "male", "female"], default="neutral",
                   help="params: the model gender when a file has no 'gender' field (default neutral)")
    s.add_argument("--method", default=None, help="the method name written to submission.json")
    s.add_argument("--zip", action="store_true", help=H_ZIP)
    s.set_defaults(func=_cmd_import)


def _add_leaderboard_commands(sub) -> None:
    """``hoibench leaderboard add|build|ls``."""
    s = sub.add_parser("leaderboard", help="add results to a track and build its README, CSV and HTML page",
                       epilog="examples:\n  hoibench leaderboard add result.json --track synthetic --method 'My method'\n"
                              "  hoibench leaderboard build            # every track under leaderboards/\n"
                              "  hoibench leaderboard ls",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    lsub = s.add_subparsers(dest="action", required=True, metavar="{add,build,ls,site}")
    b = lsub.add_parser("add", help="add a result of `hoibench evaluate` to a track")
    b.add_argument("result", type=Path, help="the result JSON (hoibench evaluate --out)")
    b.add_argument("--track", required=True, help="the track folder's name under the root (an id)")
    b.add_argument("--method", required=True, help="the row's name (its entry file is the name's slug)")
    b.add_argument("--role", default="method", choices=["ground-truth", "reference", "baseline", "method"],
                   help="how the row is shown (default method; the ground-truth row comes first)")
    b.add_argument("--notes", default="", help="a note shown with the row")
    b.add_argument("--allow-incomplete", action="store_true", help="add an incomplete result, marked as such")
    b.add_argument("--replace", action="store_true", help="replace an entry of the same name")
    b.add_argument("--new-track", action="store_true", help="start the track when it does not exist yet")
    b.add_argument("--root", type=Path, default=None, help=H_ROOT)
    b.set_defaults(func=_cmd_leaderboard)
    b = lsub.add_parser("build", help="render README.md, leaderboard.csv, index.html and plots of tracks")
    b.add_argument("--track", default=None, help="one track (default: every track under --root)")
    b.add_argument("--root", type=Path, default=None, help=H_ROOT)
    b.set_defaults(func=_cmd_leaderboard)
    b = lsub.add_parser("ls", help="list tracks and their entries")
    b.add_argument("--root", type=Path, default=None, help=H_ROOT)
    b.set_defaults(func=_cmd_leaderboard)
    b = lsub.add_parser("site", help="every track's page plus an index page, static files for GitHub Pages")
    b.add_argument("--out", type=Path, required=True, help="the site folder to write")
    b.add_argument("--root", type=Path, default=None, help=H_ROOT)
    b.set_defaults(func=_cmd_leaderboard_site)


def _add_publish_commands(sub) -> None:
    """Comparing, publishing and looking: compare, leaderboard, challenge, render, demo."""
    s = sub.add_parser("compare", help="results side by side, with which differences are outside the CIs",
                       epilog="example: hoibench compare gt.json mine.json baseline.json --plot compare.png")
    s.add_argument("results", type=Path, nargs="+",
                   help="result JSONs (hoibench evaluate --out) or leaderboard entries; the first is the reference")
    s.add_argument("--names", default=None, help="comma-separated row names (default: the submissions' methods)")
    s.add_argument("--plot", type=Path, default=None, help="also draw bars with CI error bars to this PNG")
    s.set_defaults(func=_cmd_compare)

    _add_leaderboard_commands(sub)
    from .challenge.commands import add_challenge_parser
    add_challenge_parser(sub, _cmd_challenge, H_STORE, H_ROOT)

    s = sub.add_parser("demo", help="run the main job on the embedded synthetic data",
                       epilog="example: hoibench demo --out demo-out")
    s.add_argument("--out", type=Path, default=Path("demo-out"), help="the folder to write (default demo-out)")
    s.add_argument("--seed", type=int, default=0, help=H_SEED)
    s.add_argument("--no-baselines", action="store_true",
                   help="skip training the tiny ChainHOI and CATMO (~9 of the demo's ~13 minutes)")
    s.set_defaults(func=_cmd_demo)

    s = sub.add_parser("render", help="render a processed clip to PNG, GIF or MP4 (off-screen)",
                       epilog="examples:\n  hoibench render data/clips/Date01_Sub01_boxsmall_lift.npz --out clip.gif\n"
                              "  hoibench render Date01_Sub01_boxsmall_lift --data data --out clip.gif\n"
                              "  hoibench render sub.zip --id Date03_Sub01_backpack_hold --data data --out cmp.gif\n"
                              "  hoibench render result.json --worst 5 --by mm_dist --data data --out worst/",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    s.add_argument("clip", help="DATA/clips/<id>.npz, or a clip id together with --data, or a submission with --id, "
                                "or a result of `hoibench evaluate` with --worst")
    s.add_argument("--data", type=Path, default=None, help="the store the clip id (or the submission) belongs to")
    s.add_argument("--id", default=None, help="with a submission: draw its sample for this id beside the ground truth")
    s.add_argument("--sample", type=int, default=0, help="with --id: which of the K samples (default 0)")
    s.add_argument("--out", type=Path, required=True,
                   help=".png (middle frame), .gif or .mp4; with --worst a folder (one GIF per clip)")
    s.add_argument("--worst", type=int, default=None, metavar="K",
                   help="with a result: draw the K test clips at the failure end of --by, each beside its ground truth")
    s.add_argument("--by", default="mm_dist",
                   help="with --worst: a column of the result's per-clip table (default mm_dist; also text_rank, "
                        "cd, ocd, ps, fsr, jitter_mps3, penetration_depth_max_m, contact_iou, ...)")
    s.add_argument("--submission", type=Path, default=None,
                   help="with --worst: the scored submission (default: the path the result records)")
    s.add_argument("--body", choices=["proxy", "skeleton"], default="proxy",
                   help="proxy (default: a body surface from the stored parameters) or skeleton")
    s.set_defaults(func=_cmd_render)


def build_parser() -> argparse.ArgumentParser:
    """The ``hoibench`` parser: every subcommand, every argument with its help."""
    p = _Parser(prog="hoibench", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add in (_add_data_commands, _add_scoring_commands, _add_baseline_commands, _add_publish_commands):
        add(sub)
    return p


#: exceptions that mean "bad input or environment": one line, exit status 2
_INPUT_ERRORS = (ValueError, KeyError, LookupError, OSError, RecursionError, MemoryError, EOFError,
                 UnicodeError, NotImplementedError)


def _one_line(exc: BaseException) -> str:
    """The message of ``exc`` on one line (a KeyError's message is its first argument)."""
    if isinstance(exc, KeyError) and exc.args:
        msg = str(exc.args[0])
    elif isinstance(exc, RecursionError):
        msg = f"input nested too deeply ({exc})"
    elif isinstance(exc, MemoryError):
        msg = "out of memory (an input larger than its budget? see docs/security.md)"
    elif isinstance(exc, OSError) and exc.filename is not None:
        msg = f"{exc.filename}: {exc.strerror or exc}"
    else:
        msg = str(exc) or type(exc).__name__
    from .core.errors import printable
    return printable(" ".join(msg.split()))


def main(argv: list[str] | None = None) -> int:
    """Run one command. Bad input ends in one line ``hoibench <command>: error: ...`` and
    exit status 2 (1 for a ``--strict`` stop, 130 for an interrupt), never a traceback;
    ``HOIBENCH_DEBUG=1`` re-raises for debugging."""
    import os

    from .core.errors import HoibenchError
    from .core.interrupts import EXIT_INTERRUPTED, interrupt_message, terminate_as_interrupt, was_interrupted
    args = build_parser().parse_args(argv)
    debug = os.environ.get("HOIBENCH_DEBUG") == "1"
    try:
        with terminate_as_interrupt():
            code = int(args.func(args) or 0)
            if was_interrupted():       # swallowed on the way (e.g. inside a finalizer)
                raise KeyboardInterrupt
            return code
    except KeyboardInterrupt:
        print(interrupt_message(f"hoibench {args.command}"), file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:          # output piped into a command that stopped reading
        return 0
    except HoibenchError as exc:
        if debug:
            raise
        print(f"hoibench {args.command}: error: {_one_line(exc)}", file=sys.stderr)
        return exc.exit_code
    except _INPUT_ERRORS as exc:
        if debug:
            raise
        print(f"hoibench {args.command}: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except Exception as exc:         # a defect, not bad input: still one line, and how to see more
        if debug:
            raise
        print(f"hoibench {args.command}: internal error: {type(exc).__name__}: {_one_line(exc)} "
              f"(rerun with HOIBENCH_DEBUG=1 for the traceback, and please report it)", file=sys.stderr)
        return 3


if __name__ == "__main__":
    sys.exit(main())
