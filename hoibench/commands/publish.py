"""Comparing results: ``hoibench compare``."""
from __future__ import annotations

from pathlib import Path


def _cmd_compare(args) -> int:
    from ..scoring.compare import compare, plot
    names = [n.strip() for n in args.names.split(",")] if args.names else None
    if names is not None and len(names) != len(args.results):
        raise ValueError(f"--names: {len(names)} names for {len(args.results)} results")
    print(compare(args.results, names))
    if args.plot:
        plot(args.results, args.plot, names)
        print(f"wrote {args.plot}")
    return 0


def register(sub) -> None:
    """compare."""
    s = sub.add_parser("compare", help="results side by side, with which differences are outside the CIs",
                       epilog="example: hoibench compare gt.json mine.json baseline.json --plot compare.png")
    s.add_argument("results", type=Path, nargs="+",
                   help="result JSONs (hoibench evaluate --out) or leaderboard entries; the first is the reference")
    s.add_argument("--names", default=None, help="comma-separated row names (default: the submissions' methods)")
    s.add_argument("--plot", type=Path, default=None, help="also draw bars with CI error bars to this PNG")
    s.set_defaults(func=_cmd_compare)
