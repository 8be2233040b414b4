"""What the command modules share: help texts, the ``--executor`` argument type and choices
read from a registry on use."""
from __future__ import annotations

import argparse
from pathlib import Path
from typing import Iterator, Sequence


def executor_arg(spec: str) -> str:
    """``--executor``: its syntax is checked while the arguments are parsed, before any work."""
    from ..core.parallel import parse_executor
    try:
        parse_executor(spec)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("--executor: ")) from None
    return spec


H_EXECUTOR = "where per-clip work runs: serial (default), processes[:N] (N local processes) or dask://ADDRESS"
H_STORE = "the processed store (a folder written by hoibench prepare)"
H_SEED = "random seed (default 0)"
H_ZIP = "write the submission as one .zip file instead of a folder"
H_THREADS = ("torch threads (default: $HOIBENCH_THREADS, else $OMP_NUM_THREADS, else the cores not already busy "
             "by the load average; docs/benchmarks.md)")
H_ROOT = ("the leaderboards folder (default: the nearest leaderboards/ with track folders, in the current folder "
          "or above; the command says which)")
H_ACTION = "what to do: ls lists, show prints one (named next)"


class LazyChoices(Sequence[str]):
    """An argument's choices read from a registry (``"module:attr"``, an iterable of names) on
    first use, when the argument is parsed or its help shown: building the parser imports
    nothing heavy. Set it on the action after ``add_argument`` (which would read it at once)."""

    def __init__(self, reference: str):
        self.reference = reference
        self._items: tuple[str, ...] | None = None

    def _names(self) -> tuple[str, ...]:
        if self._items is None:
            from ..core.registry import load_object
            self._items = tuple(load_object(self.reference))
        return self._items

    def __getitem__(self, index):
        return self._names()[index]

    def __len__(self) -> int:
        return len(self._names())

    def __contains__(self, value: object) -> bool:
        return value in self._names()

    def __iter__(self) -> Iterator[str]:
        return iter(self._names())


def action_command(sub, name: str, help: str, examples: Sequence[str], actions: Sequence[str]):
    """The action subparsers of a new command ``hoibench NAME ACTION``: ``examples`` listed in
    its epilog, one a line; the chosen action lands in ``args.action``."""
    s = sub.add_parser(name, help=help, epilog="examples:\n" + "\n".join("  " + e for e in examples),
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    return s.add_subparsers(dest="action", required=True, metavar="{" + ",".join(actions) + "}")


def add_submission_args(s) -> None:
    """The submission and the store it is for (``evaluate``, ``validate``)."""
    s.add_argument("submission", type=Path, help="the submission folder or .zip")
    s.add_argument("--data", type=Path, required=True, help="the store the submission is for (" + H_STORE + ")")
