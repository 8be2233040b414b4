"""Exceptions that the ``hoibench`` command reports as one line (no traceback)."""
from __future__ import annotations


class HoibenchError(Exception):
    """An expected failure with a complete message: the CLI prints
    ``hoibench <command>: error: <message>`` and exits with ``exit_code``."""
    exit_code: int = 2


class StrictStop(HoibenchError, RuntimeError):
    """``--strict`` stopped a run at its first failing unit (already recorded in the
    command's errors.jsonl). A ``RuntimeError`` too, as it was before it had its own class."""
    exit_code = 1
