"""The metric validity audit: ``hoibench audit``. The family names in its help come from the
corruption registry (:data:`hoibench.audit.corruptions.FAMILIES`) when the help is shown."""
from __future__ import annotations

from pathlib import Path

from .common import H_EXECUTOR, H_STORE, executor_arg


def _cmd_audit(args) -> int:
    from ..audit.document import run_audit
    families = [f.strip() for f in args.families.split(",") if f.strip()] if args.families else None
    run_audit(args.data, args.evaluator, args.out, protocol=args.protocol, families=families, seed=args.seed,
              resamples=args.resamples, executor=args.executor, allow_failed_gate=args.allow_failed_gate,
              overwrite=args.overwrite, allow_protocol_mismatch=args.allow_protocol_mismatch)
    return 0


class _FamiliesHelp(str):
    """The ``--families`` help, listing the registry's families when argparse formats it."""

    def __mod__(self, params):
        from ..audit.corruptions import FAMILIES
        return f"{str(self)} (default: all of {', '.join(FAMILIES)})"


def register(sub) -> None:
    """audit."""
    s = sub.add_parser("audit", help="metric validity audit: score controlled corruptions of the ground truth "
                                     "and report what each metric sees",
                       epilog="example: hoibench audit --data data --evaluator ev --out audit "
                              "(writes audit/audit.json, audit/heatmap.png, audit/cards/*.md, audit/README.md; "
                              "docs/audit.md explains them)")
    s.add_argument("--data", type=Path, required=True, help=H_STORE)
    s.add_argument("--evaluator", type=Path, required=True, help="the evaluator folder (hoibench train-evaluator)")
    s.add_argument("--protocol", default=None, help="protocol id (default: <dataset>-<mode> of the store)")
    s.add_argument("--out", type=Path, required=True, help="the folder to write the audit into")
    s.add_argument("--families", default=None, help=_FamiliesHelp("comma-separated corruption families"))
    s.add_argument("--seed", type=int, default=0, help="seed of the corruptions and the paired bootstrap (default 0)")
    s.add_argument("--resamples", type=int, default=None,
                   help="paired clip-bootstrap resamples per test (default: compare --paired's minimum, 2000)")
    s.add_argument("--executor", default="serial", type=executor_arg, help=H_EXECUTOR)
    s.add_argument("--overwrite", action="store_true", help="replace an audit already in --out")
    s.add_argument("--allow-failed-gate", action="store_true",
                   help="audit with an evaluator that fails its sanity gate on this store (audit.json records it)")
    s.add_argument("--allow-protocol-mismatch", action="store_true",
                   help="audit under a protocol of another mode or representation than the store's (e.g. a legacy "
                        "protocol on a clean store: its metric rules, the store's features; audit.json records it)")
    s.set_defaults(func=_cmd_audit)
