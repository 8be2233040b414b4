"""Leaderboards: ``hoibench leaderboard add|build|ls|site``."""
from __future__ import annotations

from pathlib import Path

from .common import H_ROOT, action_command


def _cmd_leaderboard(args) -> int:
    from ..publish.leaderboard_commands import main_leaderboard
    return main_leaderboard(args.action, args.root, getattr(args, "track", None), result=getattr(args, "result", None),
                            method=getattr(args, "method", ""), role=getattr(args, "role", "method"),
                            notes=getattr(args, "notes", ""), allow_incomplete=getattr(args, "allow_incomplete", False),
                            replace=getattr(args, "replace", False), new_track=getattr(args, "new_track", False))


def _cmd_leaderboard_site(args) -> int:
    from ..publish.leaderboard_commands import resolve_root
    from ..publish.site import build_site
    paths = build_site(resolve_root(args.root), args.out)
    print(f"wrote {len(paths)} files to {args.out} (open {args.out / 'index.html'})")
    return 0


def register(sub) -> None:
    """leaderboard."""
    lsub = action_command(
        sub, "leaderboard", "add results to a track and build its README, CSV and HTML page",
        ["hoibench leaderboard add result.json --track synthetic --method 'My method'",
         "hoibench leaderboard build            # every track under leaderboards/",
         "hoibench leaderboard ls"],
        ["add", "build", "ls", "site"])
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
