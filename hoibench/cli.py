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
import sys

from .datasets.synth_registry import SYNTH_LAYOUTS  # noqa: F401  (hoibench.cli.SYNTH_LAYOUTS, the --layout registry)


def _cmd_version(args) -> int:
    from . import __version__
    print(__version__)
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


def build_parser() -> argparse.ArgumentParser:
    """The ``hoibench`` parser: ``version``, then the commands of every module of
    :mod:`hoibench.commands` (:data:`~hoibench.commands.MODULES`, each adding its parsers and
    handlers with ``register``); :func:`main` runs the chosen handler."""
    from .commands import MODULES
    p = _Parser(prog="hoibench", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    sub.add_parser("version", help="print the toolkit version").set_defaults(func=_cmd_version)
    for module in MODULES:
        module.register(sub)
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


def _say(line: str) -> None:
    """``line`` on stderr, flushed now; a closed stderr is not an error."""
    try:
        print(line, file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass


def _quiet_stdout() -> None:
    """Point stdout at the null device: the interpreter flushes stdout when it exits, and a
    pipe whose reader has gone would answer that with "Exception ignored ... BrokenPipeError"."""
    import os
    try:
        null = os.open(os.devnull, os.O_WRONLY)  # read-ok: the null device, opened for writing
        os.dup2(null, sys.stdout.fileno())
        os.close(null)
    except (OSError, ValueError, AttributeError):
        pass


def main(argv: list[str] | None = None) -> int:
    """Run one command. Bad input ends in one line ``hoibench <command>: error: ...`` and
    exit status 2 (1 for a ``--strict`` stop, 130 for an interrupt), never a traceback;
    ``HOIBENCH_DEBUG=1`` re-raises for debugging."""
    import os

    from .core.threads import set_wait_policy
    set_wait_policy()                # before anything loads torch (OpenMP reads it then)
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
        _say(interrupt_message(f"hoibench {args.command}"))
        return EXIT_INTERRUPTED
    except BrokenPipeError:          # output piped into a command that stopped reading
        _quiet_stdout()
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
