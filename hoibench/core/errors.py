"""Exceptions that the ``hoibench`` command reports as one line (no traceback)."""
from __future__ import annotations


def printable(text: str) -> str:
    """``text`` safe for a terminal: every control or other non-printable character (ESC of
    an escape sequence, a carriage return, a bidirectional override) written as its Python
    escape (``\x1b``), the rest unchanged."""
    text = str(text)
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else repr(c)[1:-1] if c not in "'\"" else c for c in text)


class HoibenchError(Exception):
    """An expected failure with a complete message: the CLI prints
    ``hoibench <command>: error: <message>`` and exits with ``exit_code``."""
    exit_code: int = 2


class StrictStop(HoibenchError, RuntimeError):
    """``--strict`` stopped a run at its first failing unit (already recorded in the
    command's errors.jsonl). A ``RuntimeError`` too, as it was before it had its own class."""
    exit_code = 1
