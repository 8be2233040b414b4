"""Tracks, protocols and submissions: ``hoibench tracks``, ``protocols``, ``validate``,
``submission``. The track and protocol names in their help come from the track registry and
the protocol files."""
from __future__ import annotations

import argparse
from pathlib import Path

from .common import H_ACTION, H_STORE, H_ZIP, add_submission_args


def _cmd_tracks(args) -> int:
    """``hoibench tracks ls`` (one line per track) or ``hoibench tracks show NAME`` (its
    registry entry as JSON)."""
    import json

    from ..tracks.registry import get_track, list_tracks
    if args.action == "show":
        if not args.name:
            raise ValueError("tracks show: name a track, e.g. hoibench tracks show rich-cat")
        print(json.dumps(get_track(args.name).to_dict(), indent=1))
        return 0
    print(f"{'track':20s} {'store':9s} {'evaluator':11s} {'scorer':13s} protocols")
    for t in list_tracks():
        print(f"{t.name:20s} {t.store_kind:9s} {t.evaluator_kind:11s} {t.scorer:13s} {', '.join(t.protocols)}")
    return 0


def _cmd_protocols(args) -> int:
    from ..tracks.protocol import main_protocols
    return main_protocols(args.action, args.name)


def _cmd_validate(args) -> int:
    from ..scoring.submission import main_validate
    return main_validate(args.submission, args.data, protocol=args.protocol)


def _cmd_submission(args) -> int:
    if args.action == "prompts":
        from ..scoring.prompts import write_prompts
        text = write_prompts(args.data, args.out, protocol=args.protocol)
        if args.out is None:
            print(text, end="")
        else:
            print(f"wrote {args.out}: {text.count(chr(10))} prompts")
        return 0
    if args.out is None:
        raise ValueError(f"submission {args.action}: --out is required")
    from ..scoring.reference_rows import main_reference
    return main_reference(args.action, args.data, args.out, args.kind, as_zip=args.zip, samples=args.samples,
                          sigma=args.sigma, seed=args.seed, protocol=args.protocol)


def track_names() -> list[str]:
    """The registered tracks' names, sorted."""
    from ..tracks.registry import list_tracks
    return [t.name for t in list_tracks()]


def protocol_ids() -> list[str]:
    """The shipped protocols' ids, sorted: the stems of ``hoibench/tracks/protocols/*.yaml``
    less a later version's ``-<version>`` suffix (read without loading the files, so that
    building the parser stays fast)."""
    import re

    from .. import tracks
    return sorted({re.sub(r"-\d+(\.\d+)+$", "", p.stem)
                   for p in (Path(tracks.__file__).parent / "protocols").glob("*.yaml")})


def _add_tracks_protocols(sub) -> None:
    s = sub.add_parser("tracks", help="list or show the benchmark tracks (store kind, evaluator, metrics, protocols)",
                       epilog="examples: hoibench tracks ls; hoibench tracks show rich-cat")
    s.add_argument("action", choices=["ls", "show"], help=H_ACTION)
    s.add_argument("name", nargs="?", help=f"show: the track ({', '.join(track_names())})")
    s.set_defaults(func=_cmd_tracks)

    s = sub.add_parser("protocols", help="list or show evaluation protocols",
                       epilog="examples: hoibench protocols ls; hoibench protocols show behave-clean")
    s.add_argument("action", choices=["ls", "show"], help=H_ACTION)
    s.add_argument("name", nargs="?", help=f"show: the protocol id ({', '.join(protocol_ids())})")
    s.set_defaults(func=_cmd_protocols)


def _add_submissions(sub) -> None:
    s = sub.add_parser("validate", help="check a submission against a store's test split",
                       epilog="example: hoibench validate my_method.zip --data data/behave")
    add_submission_args(s)
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
                              "  hoibench submission prompts data --out prompts.jsonl   # what a generator needs\n"
                              "  hoibench submission prompts data --protocol interact-o2h-clean --out o2h/prompts.jsonl"
                              "   # + conditions/",
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
    s.add_argument("--protocol", default=None,
                   help="the protocol whose track the rows are for (default: the store's); InterAct's "
                        "interact-o2h-clean / interact-h2o-clean: prompts carry the conditions, reference kinds "
                        "gt and static-first-pose")
    s.add_argument("--zip", action="store_true", help=H_ZIP)
    s.set_defaults(func=_cmd_submission)


def register(sub) -> None:
    """tracks, protocols, validate, submission."""
    _add_tracks_protocols(sub)
    _add_submissions(sub)
