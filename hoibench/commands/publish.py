"""Comparing results: ``hoibench compare`` (side by side, or ``--paired``: a paired bootstrap
over the shared test clips)."""
from __future__ import annotations

from pathlib import Path


def _cmd_compare(args) -> int:
    from ..scoring.compare import compare, plot
    names = [n.strip() for n in args.names.split(",")] if args.names else None
    if names is not None and len(names) != len(args.results):
        raise ValueError(f"--names: {len(names)} names for {len(args.results)} results")
    if args.plot is not None and args.plot.is_dir():
        raise ValueError(f"--plot {args.plot}: is a folder; give the PNG file to write")
    if args.paired:
        return _paired(args)
    if args.out is not None:
        raise ValueError("--out: the comparison file is written by --paired only")
    print(compare(args.results, names))
    if args.plot:
        plot(args.results, args.plot, names)
        print(f"wrote {args.plot}")
    return 0


def _paired(args) -> int:
    from ..core.io import atomic_write_json
    from ..scoring.evaluate import check_result_free
    from ..scoring.paired import format_paired, paired_compare
    from ..scoring.slices import slice_gaps
    if args.out is not None:
        check_result_free(args.out, overwrite=args.overwrite)
    cmp = paired_compare(args.results, resamples=args.resamples, seed=args.seed, executor=args.executor,
                         extra=slice_gaps)
    print(format_paired(cmp))
    if args.out is not None:
        atomic_write_json(args.out, cmp)
        print(f"wrote {args.out}")
    return 0


def register(sub) -> None:
    """compare."""
    from .common import executor_arg
    s = sub.add_parser("compare", help="results side by side, with which differences are outside the CIs; "
                                       "--paired: a paired bootstrap test of every metric",
                       epilog="examples: hoibench compare gt.json mine.json baseline.json --plot compare.png; "
                              "hoibench compare a.json b.json --paired --out cmp.json")
    s.add_argument("results", type=Path, nargs="+",
                   help="result JSONs (hoibench evaluate --out) or leaderboard entries; the first is the reference")
    s.add_argument("--names", default=None, help="comma-separated row names (default: the submissions' methods)")
    s.add_argument("--plot", type=Path, default=None, help="also draw bars with CI error bars to this PNG")
    s.add_argument("--paired", action="store_true",
                   help="paired bootstrap over the test clips every result scored (needs each result's "
                        "per-clip data file, written beside it by evaluate --out): diff = B - A, 95%% interval, "
                        "Holm-adjusted p and a verdict per metric")
    s.add_argument("--resamples", type=int, default=2000, help="bootstrap resamples with --paired (at least 2000)")
    s.add_argument("--seed", type=int, default=0, help="seed of the resamples with --paired")
    s.add_argument("--executor", type=executor_arg, default="serial", help="where --paired's resamples run")
    s.add_argument("--out", type=Path, default=None, help="with --paired: write the comparison JSON here")
    s.add_argument("--overwrite", action="store_true", help="with --out: replace an existing file")
    s.set_defaults(func=_cmd_compare)
