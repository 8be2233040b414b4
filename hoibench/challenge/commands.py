"""``hoibench challenge ACTION`` (wired by :mod:`hoibench.cli`)."""
from __future__ import annotations

import json
import zipfile


def main_challenge(args) -> int:
    """Run one ``hoibench challenge`` action; return the exit status."""
    if args.action == "bundle":
        from .bundle import build_bundle, check_bundle
        phases = tuple(p.strip() for p in args.phases.split(",") if p.strip())
        path = build_bundle(args.data, args.evaluator, args.out, protocol=args.protocol, title=args.title,
                            phases=phases, docker_image=args.docker_image)
        probs = check_bundle(path)
        print(f"wrote {path} (Codabench bundle, YAML version 2; {len(probs)} problems); build the scoring image "
              f"with docker/Dockerfile inside it (docs/hosting.md)")
        return 0 if not probs else 1
    if args.action == "public":
        from .public import write_public
        out = write_public(args.data, args.out, args.title)
        print(f"wrote {out}: store/ (train split), prompts.jsonl (test prompts), README.md")
        return 0
    if args.action == "check":
        from .bundle import check_bundle
        probs = check_bundle(args.bundle)
        for p in probs:
            print(f"{args.bundle}: {p}")
        print(f"{args.bundle}: {'OK' if not probs else f'{len(probs)} problem(s)'}")
        return 0 if not probs else 1
    from ..publish.leaderboard import track_folder
    from ..publish.leaderboard_commands import resolve_root
    from .engine_results import add_hosted_rows
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
