"""Hosted challenges: ``hoibench challenge bundle|public|check|import-results``."""
from __future__ import annotations

import json
import zipfile
from datetime import date
from pathlib import Path

from .common import H_ROOT, H_STORE, action_command


def iso_date(option: str, text: str | None) -> date | None:
    """``--start 2027-01-31`` -> a date; anything but an ISO date YYYY-MM-DD is refused naming ``option``."""
    if text is None:
        return None
    try:
        return date.fromisoformat(text)
    except ValueError:
        raise ValueError(f"{option}: expected an ISO date YYYY-MM-DD, got {text!r}") from None


def _cmd_bundle(args) -> int:
    from ..challenge.bundle import build_bundle, inspect_bundle
    phases = tuple(p.strip() for p in args.phases.split(",") if p.strip())
    start, end = iso_date("--start", args.start), iso_date("--end", args.end)
    path = build_bundle(args.data, args.evaluator, args.out, protocol=args.protocol, title=args.title,
                        phases=phases, docker_image=args.docker_image, start=start, end=end)
    probs, warns = inspect_bundle(path)
    for w in warns:
        print(f"{path}: warning: {w}")
    print(f"wrote {path} (Codabench bundle, YAML version 2; {len(probs)} problems); build the scoring image "
          f"with docker/Dockerfile inside it (docs/hosting.md)")
    return 0 if not probs else 1


def _cmd_check(args) -> int:
    from ..challenge.bundle import inspect_bundle
    probs, warns = inspect_bundle(args.bundle)
    for p in probs:
        print(f"{args.bundle}: {p}")
    for w in warns:
        print(f"{args.bundle}: warning: {w}")
    print(f"{args.bundle}: {'OK' if not probs else f'{len(probs)} problem(s)'}")
    return 0 if not probs else 1


def _cmd_public(args) -> int:
    from ..challenge.public import write_public
    out = write_public(args.data, args.out, args.title)
    print(f"wrote {out}: store/ (train split), prompts.jsonl (test prompts), README.md")
    return 0


def _cmd_import_results(args) -> int:
    from ..challenge.engine_results import add_hosted_rows
    from ..publish.leaderboard import track_folder
    from ..publish.leaderboard_commands import resolve_root
    try:
        with zipfile.ZipFile(args.bundle) as z:  # read-ok: only challenge.json is read, capped at 1 MiB
            if z.getinfo("challenge.json").file_size > 1 << 20:
                raise ValueError(f"{args.bundle}: challenge.json over 1 MiB")
            info = json.loads(z.read("challenge.json"))  # read-ok: the capped member above
    except (KeyError, zipfile.BadZipFile, json.JSONDecodeError) as exc:
        raise ValueError(f"{args.bundle}: not a hoibench challenge bundle (challenge.json: {exc})") from None
    written, refused = add_hosted_rows(args.export, info, track_folder(resolve_root(args.root), args.track),
                                       engine=args.engine, replace=args.replace)
    for r in refused:
        print(f"refused: {r}")
    print(f"added {len(written)} row(s) to {args.track}; {len(refused)} refused")
    return 0 if not refused else 1


def register(sub) -> None:
    """challenge."""
    csub = action_command(
        sub, "challenge", "host a challenge on Codabench or EvalAI: bundle, public data, results",
        ["hoibench challenge bundle --data data --evaluator ev --out bundle.zip",
         "hoibench challenge public --data data --out public",
         "hoibench challenge import-results results.json --bundle bundle.zip --track synthetic"],
        ["bundle", "public", "check", "import-results"])
    b = csub.add_parser("bundle", help="a Codabench competition bundle with the hidden test split")
    b.add_argument("--data", type=Path, required=True, help="the store (" + H_STORE + ")")
    b.add_argument("--evaluator", type=Path, required=True, help="the evaluator folder the challenge scores with")
    b.add_argument("--protocol", default=None, help="protocol id (default: the store's)")
    b.add_argument("--out", type=Path, required=True, help="the bundle .zip to write (must not exist)")
    b.add_argument("--title", default=None, help="the competition's title")
    b.add_argument("--phases", default="dev,test", help="comma-separated phase names (default dev,test)")
    b.add_argument("--start", default=None, metavar="DATE",
                   help="the first phase's first day, YYYY-MM-DD (default: today)")
    b.add_argument("--end", default=None, metavar="DATE",
                   help="the last phase's last day, YYYY-MM-DD (default: 90 days per phase); the phases split "
                        "the days from --start to --end into consecutive equal parts")
    b.add_argument("--docker-image", default=None, help="the scoring image's name (default hoibench/scorer:VERSION)")
    b.set_defaults(func=_cmd_bundle)
    b = csub.add_parser("public", help="what participants may have: the train split and the test prompts")
    b.add_argument("--data", type=Path, required=True, help="the store (" + H_STORE + ")")
    b.add_argument("--out", type=Path, required=True, help="the folder to write (new or empty)")
    b.add_argument("--title", default="hoibench challenge", help="the title in its README.md")
    b.set_defaults(func=_cmd_public)
    b = csub.add_parser("check", help="check a bundle against Codabench's v2 bundle structure (and warn of phases "
                                      "that have ended or never start)")
    b.add_argument("bundle", type=Path, help="the bundle .zip")
    b.set_defaults(func=_cmd_check)
    b = csub.add_parser("import-results", help="an engine's exported leaderboard -> entries of a track")
    b.add_argument("export", type=Path, help="the exported leaderboard JSON (Codabench results.json)")
    b.add_argument("--bundle", type=Path, required=True, help="the challenge's bundle .zip (its challenge.json)")
    b.add_argument("--track", required=True, help="the track folder's name under the root")
    b.add_argument("--root", type=Path, default=None, help=H_ROOT)
    b.add_argument("--engine", default="codabench", help="the engine's name recorded with the rows")
    b.add_argument("--replace", action="store_true", help="replace entries of the same name")
    b.set_defaults(func=_cmd_import_results)
