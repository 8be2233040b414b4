"""The one id rule: every id that becomes a file name passes :func:`check_id`.

Clip ids (from BEHAVE folder names, OMOMO ``seq_name``, RICH sequence/subject names),
object names (``objects/<name>.npz``), split-file entries, submission sample ids and
exported file names all become path components. An id is accepted only when it is

    letters, digits, ``_``, ``-`` and ``.``; 1-200 characters; not starting with a dot

so it can never hold a separator (``/``, ``\\``), a traversal (``..`` as a component needs
a leading dot), a drive letter (``C:``), a NUL byte, whitespace or a hidden name. Anything
else is refused with :class:`InvalidIdError`, naming where the id came from.
"""
from __future__ import annotations

import re

ID_RULE = "letters, digits, '_', '-', '.'; 1-200 characters; no leading dot, no separator"
ID_PATTERN = re.compile(r"[A-Za-z0-9_\-][A-Za-z0-9_.\-]{0,199}")


class InvalidIdError(ValueError):
    """An id that would not be a safe, plain file name."""


def is_valid_id(value: object) -> bool:
    """True when ``value`` is a ``str`` that satisfies the id rule."""
    return isinstance(value, str) and ID_PATTERN.fullmatch(value) is not None


def check_id(value: object, what: str = "id", source: object = None) -> str:
    """Return ``value`` when it satisfies the id rule, else raise :class:`InvalidIdError`
    naming ``what`` (e.g. ``"sequence"``, ``"object name"``) and ``source`` (the file or
    field it came from)."""
    if is_valid_id(value):
        return value  # type: ignore[return-value]
    where = f" (from {source})" if source is not None else ""
    shown = repr(value) if len(repr(value)) <= 120 else repr(value)[:117] + "..."
    raise InvalidIdError(f"{what} {shown}{where} is not a valid id ({ID_RULE}): refused, nothing written")


__all__ = ["ID_RULE", "ID_PATTERN", "InvalidIdError", "is_valid_id", "check_id"]
