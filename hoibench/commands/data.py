"""Representations, raw data, stores and texts: ``hoibench representations``, ``represent``,
``synth``, ``prepare``, ``datasets`` (``ls``, ``leak-check``), ``splits``, ``export``, ``annotate``.

``synth`` and ``prepare`` run what the registries say (:mod:`hoibench.datasets.synth_registry`,
:mod:`hoibench.datasets.catalog`): no branch names a layout or a dataset."""
from __future__ import annotations

import json
import sys
from pathlib import Path

from .common import H_ACTION, H_EXECUTOR, H_SEED, H_STORE, executor_arg


def _cmd_representations(args) -> int:
    from ..representations import hml263, hoi269
    rows = [("hml263", hml263.DIM, mode, hml263.VERSION[mode]) for mode in hml263.MODES]
    rows += [("hoi269", hoi269.DIM, mode, hoi269.VERSION[mode]) for mode in hoi269.BODY_MODE]
    rows += [("joint_level", "24x12", "-", "joint_level-1.0 (from hoi269)")]
    print(f"{'name':12s} {'dims':>6s}  {'mode':15s} version")
    for name, dim, mode, version in rows:
        print(f"{name:12s} {str(dim):>6s}  {mode:15s} {version}")
    return 0


def _cmd_represent(args) -> int:
    import io as _io

    import numpy as np

    from ..core.io import atomic_save_npy, read_regular_file
    from ..representations import hml263, joint_level
    from ..scoring.submission import MAX_ARRAY_BYTES
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
    atomic_save_npy(args.out, feats)
    print(f"wrote {args.out}: {feats.shape} {feats.dtype}")
    return 0


def parse_defects(items: list[str]) -> dict:
    """['3:foot_skating=1.0', 'Date01_Sub01_boxsmall_lift:penetration=0.02'] -> {clip: [Defect]}."""
    from ..datasets.synthetic import Defect
    out: dict = {}
    for item in items or []:
        clip, _, spec = item.rpartition(":")
        kind, _, mag = spec.partition("=")
        if not clip or not mag:
            raise ValueError(f"--defect: expected CLIP:KIND=MAGNITUDE, got {item!r}")
        key = int(clip) if clip.isdigit() else clip
        out.setdefault(key, []).append(Defect(kind, float(mag)))
    return out


def _cmd_synth(args) -> int:
    from ..datasets.synth_registry import SYNTH_LAYOUTS, layouts_with
    layout = SYNTH_LAYOUTS.get(args.layout)
    options: dict = {}
    if layout.takes_defects:
        options["defects"] = parse_defects(args.defect)
    elif args.defect:
        raise ValueError(f"--defect: defects are injected in the {', '.join(layouts_with('takes_defects'))} "
                         f"layout only")
    if layout.takes_executor:
        options["executor"] = args.executor
    layout.load()(args.out, args.clips, seed=args.seed, **options)
    models = f"; body models in {Path(args.out) / 'body_models'}" if layout.writes_body_models else ""
    print(f"wrote {args.clips} synthetic {layout.what} to {args.out} {layout.where}{models}")
    return 0


#: the loader-specific ``prepare`` options: the option (its dest) and its help, for the loaders that read it
PREPARE_OPTIONS = {
    "sources": dict(default=None, help="comma-separated source datasets (default: every one present), e.g. "
                                       "behave,grab"),
    "split": dict(choices=["object", "sequence"], default=None,
                  help="InterAct's sequence split (test_seq.txt, default: what its evaluation script uses) or object "
                       "split (test.txt)"),
}


def _cmd_prepare(args) -> int:
    from ..datasets.catalog import get_loader, loader_names
    from ..datasets.store import PrepareConfig, prepare, summary_table
    loader = get_loader(args.dataset)
    name = loader.name_for(args.root)
    if loader.needs_body_models and args.body_models is None:
        raise ValueError(f"prepare {args.dataset}: --body-models is required (the folder with smplh/ or smplx/)")
    cfg = PrepareConfig(name, fps=args.fps, mode=args.mode, body_model_type=loader.body_model_type)
    given = [k for k in PREPARE_OPTIONS if getattr(args, k, None) is not None]
    foreign = [k for k in given if k not in loader.options]
    if foreign:
        readers = [n for n in loader_names() if foreign[0] in get_loader(n).options]
        raise ValueError(f"prepare {args.dataset}: --{foreign[0]} is read by "
                         f"{' and '.join(f'`prepare {n}`' for n in readers)} only")
    extra = {k: getattr(args, k) for k in given}
    jobs = loader.load().prepare_jobs(args.root, args.body_models, args.out, cfg, split_file=args.split_file,
                                      **extra)
    warnings = loader.warnings_for(args.root, args.body_models)
    manifest = prepare(jobs, args.out, cfg, executor=args.executor, strict=args.strict,
                       source={"root": str(Path(args.root).resolve()), "body_models": cfg.body_model_type},
                       warnings=warnings)
    loader.write_texts(args.out, manifest)
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


def _cmd_datasets(args) -> int:
    """``hoibench datasets ls``: one block per registered loader."""
    from ..datasets.catalog import get_loader, loader_names
    if args.action != "ls":
        raise ValueError(f"datasets: unknown action {args.action!r} (expected ls)")
    for x in (get_loader(n) for n in loader_names()):
        print(f"{x.name}\n  source:   {x.source}\n  licence:  {x.licence}\n  split:    {x.split}\n"
              f"  verified: {x.verified}")
    print("no loader was run on real files in hoibench's tests (the data is licensed); "
          "see docs/datasets.md for what could not be established")
    return 0


def _cmd_splits(args) -> int:
    from ..datasets import splits
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
    from ..datasets.export import export
    report = export(args.data, args.out, args.format, args.overwrite)
    print(f"exported {report['clips']} clips to {args.out} ({args.format}); "
          f"{len(report['missing_texts'])} without texts")
    return 0


def _cmd_annotate(args) -> int:
    from ..text.annotate import main_annotate
    return main_annotate(args.data, preview=args.preview, executor=args.executor, strict=args.strict,
                         seed=args.seed, spec_dir=args.spec_dir, labels=args.labels)


def _synth_layout_help() -> str:
    """``--layout``'s help from the registry: layouts with the same help text share a line."""
    from ..datasets.synth_registry import SYNTH_LAYOUTS, layout_names
    groups: dict[str, list[str]] = {}
    for name in layout_names():
        text = SYNTH_LAYOUTS.get(name).help
        if text:
            groups.setdefault(text, []).append(name)
    return "; ".join(f"{' / '.join(group)}: {text}" for text, group in groups.items())


def _add_represent(sub) -> None:
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


def _add_raw(sub) -> None:
    """``synth``, ``prepare``, ``datasets``: choices and per-loader notes from the registries."""
    from ..datasets.catalog import get_loader, loader_names
    from ..datasets.synth_registry import layout_names
    s = sub.add_parser("synth", help="write the deterministic synthetic HOI dataset",
                       epilog="example: hoibench synth --out raw --clips 120 --seed 0 "
                              "--defect 3:foot_skating=1.0 --defect 5:penetration=0.02")
    s.add_argument("--out", type=Path, required=True, help="the raw-layout folder to write")
    s.add_argument("--clips", type=int, default=24, help="how many clips (default 24; 120 for the evaluator gate)")
    s.add_argument("--seed", type=int, default=0, help=H_SEED)
    s.add_argument("--layout", choices=layout_names(), default="behave", help=_synth_layout_help())
    s.add_argument("--defect", action="append", default=[],
                   help="CLIP:KIND=MAGNITUDE, KIND in foot_skating (m/s), penetration (m), lost_contact (m)")
    s.add_argument("--executor", default="serial", type=executor_arg, help=H_EXECUTOR)
    s.set_defaults(func=_cmd_synth)

    loaders = [get_loader(n) for n in loader_names()]
    s = sub.add_parser("prepare", help="raw dataset (hoibench datasets ls) -> processed store",
                       epilog="example: hoibench prepare behave --root RAW --body-models MODELS "
                              "--out DATA --fps 20 --executor processes:2")
    s.add_argument("dataset", choices=loader_names(),
                   help="the raw layout to read (hoibench datasets ls; interact: InterAct's processed data/ folder)")
    s.add_argument("--root", type=Path, required=True, help="raw dataset folder")
    s.add_argument("--body-models", type=Path, default=None,
                   help="folder with smplh/ (BEHAVE) or smplx/ (OMOMO, RICH) model files: yours or the proxy "
                        f"(not needed for {', '.join(x.name for x in loaders if not x.needs_body_models)})")
    s.add_argument("--out", type=Path, required=True, help="the store folder to write (rerunning resumes)")
    s.add_argument("--fps", type=float, default=20.0, help="resample to this rate, by time")
    s.add_argument("--mode", choices=["clean", "legacy", "legacy-hoidiff"], default="clean",
                   help="representation mode (legacy-hoidiff: HOI-Diff's features, for behave-legacy/omomo-legacy)")
    s.add_argument("--split-file", type=Path, default=None, help="JSON {train: [...], test: [...]}")
    for option, spec in PREPARE_OPTIONS.items():
        readers = ", ".join(x.name for x in loaders if option in x.options)
        s.add_argument("--" + option, **{**spec, "help": f"{readers}: {spec['help']}"})
    s.add_argument("--executor", default="serial", type=executor_arg, help=H_EXECUTOR)
    s.add_argument("--strict", action="store_true", help="stop at the first failing sequence")
    s.set_defaults(func=_cmd_prepare)

    s = sub.add_parser("datasets", help="list the raw-data loaders; check a store for train/test leakage",
                       epilog="examples: hoibench datasets ls; hoibench datasets leak-check data/interact --out leak")
    actions = s.add_subparsers(dest="action", required=True, metavar="{ls,leak-check}")
    a = actions.add_parser("ls", help="one block per loader: source, licence, split, verification",
                           epilog="example: hoibench datasets ls")
    a.set_defaults(func=_cmd_datasets)
    _add_leak_check(actions)


def _cmd_leak_check(args) -> int:
    """``hoibench datasets leak-check``: motion, caption, object and subject overlap of test and train."""
    from ..core.parallel import LineProgress, _progress_bar
    from ..datasets.leak_check import leak_check, markdown, write_report
    bars: list = []

    def progress(name: str, total: int):
        bar = _progress_bar(name, total)
        if bar is None:
            return None
        bars.append(bar)
        return bar.update

    try:
        report = leak_check(args.store, against=args.against, split=args.split, train_split=args.train_split,
                            threshold_m=args.threshold, jaccard=args.jaccard, progress=progress)
    except BaseException:
        for bar in bars:              # a terminal bar is closed; a line log says nothing more
            if not isinstance(bar, LineProgress):
                bar.close()
        raise
    for bar in bars:
        bar.close()
    print(markdown(report), end="")
    if args.out is not None:
        j, m = write_report(report, args.out)
        print(f"wrote {j} and {m}")
    return 1 if args.fail_on_leak and report["summary"]["motion_duplicates"] else 0


def _add_leak_check(actions) -> None:
    import argparse
    from ..datasets import leak_settings as ls
    a = actions.add_parser(
        "leak-check", help="near-duplicate motions and captions between a store's test and train splits",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
               "  hoibench datasets leak-check data/interact --out leak        # test against train\n"
               "  hoibench datasets leak-check data/interact --against data/behave --out leak-behave\n"
               "motion: MPJPE of the best-aligned overlap (least-squares turn about the vertical and floor shift;\n"
               f"  same or mirrored, any time offset, overlap >= {ls.MIN_COVERAGE:g} of the shorter clip);\n"
               f"  a duplicate is at <= {1000 * ls.THRESHOLD_M:g} mm\n"
               f"captions: exact, normalised, word {ls.NGRAM}-gram Jaccard >= {ls.JACCARD_THRESHOLD:g}\n"
               "see docs/datasets.md, 'Leak check'")
    a.add_argument("store", type=Path, help=H_STORE)
    a.add_argument("--against", type=Path, default=None,
                   help="compare with every clip of this store instead of STORE's train split")
    a.add_argument("--split", default="test", help="the split checked (default test)")
    a.add_argument("--train-split", default="train", help="the split compared with, without --against (default train)")
    a.add_argument("--threshold", type=float, default=ls.THRESHOLD_M,
                   help=f"motion duplicate threshold, metres of MPJPE (default {ls.THRESHOLD_M:g})")
    a.add_argument("--jaccard", type=float, default=ls.JACCARD_THRESHOLD,
                   help=f"caption word 3-gram Jaccard threshold (default {ls.JACCARD_THRESHOLD:g})")
    a.add_argument("--out", type=Path, default=None, help="write OUT/leak_check.json and OUT/leak_check.md")
    a.add_argument("--fail-on-leak", action="store_true", help="exit status 1 when a motion duplicate is found")
    a.set_defaults(func=_cmd_leak_check)


def _add_stores(sub) -> None:
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
    s.add_argument("--executor", default="serial", type=executor_arg, help=H_EXECUTOR)
    s.add_argument("--strict", action="store_true", help="stop at the first clip that fails")
    s.set_defaults(func=_cmd_annotate)


def register(sub) -> None:
    """representations, represent, synth, prepare, datasets, splits, export, annotate."""
    for add in (_add_represent, _add_raw, _add_stores):
        add(sub)
