"""Reading published PyTorch checkpoints without running code from them.

:func:`load_checkpoint` reads a ``torch.save`` file with ``torch.load(weights_only=True)``:
torch's restricted unpickler builds tensors, containers and plain values and refuses any
other global. A PyTorch Lightning ``.ckpt`` usually carries more than weights: its
``hyper_parameters`` may hold ``functools.partial`` optimisers or OmegaConf containers,
its ``callbacks`` state Lightning classes. Those globals are refused by ``weights_only``;
for them, and only for the names torch's own scan of the file lists
(``torch.serialization.get_unsafe_globals_in_checkpoint``), the load is retried with each
such name bound to :class:`Inert`: a stand-in that accepts any arguments and state and
does nothing with them. No function or class named by the file is ever imported or called;
modules torch blocks (``os``, ``sys``, ``subprocess``, ...) stay refused. What comes back is
the same dictionary with every non-weight object replaced by an :class:`Inert` (names kept
in ``Inert.global_name`` of each class, for messages), which is all an importer needs: it
reads tensors only.

Every failure is one line naming the file: not a checkpoint, truncated (torch's zip
reader finds no central directory), a global in a blocked module.
"""
from __future__ import annotations

import re
from pathlib import Path

from .errors import EvaluatorError

__all__ = ["CheckpointReadError", "Inert", "load_checkpoint"]


class CheckpointReadError(EvaluatorError):
    """A published checkpoint that cannot be read safely (missing, truncated, not torch.save)."""


class Inert:
    """Stand-in for a global that ``weights_only`` refuses: constructed, called, given
    state or items, it stores nothing and runs nothing."""

    global_name = "?"

    def __new__(cls, *args, **kwargs):
        return object.__new__(cls)

    def __init__(self, *args, **kwargs) -> None:
        pass

    def __setstate__(self, state) -> None:
        pass

    def __repr__(self) -> str:
        return f"<inert {self.global_name}>"


def _stand_in(name: str) -> type:
    """A fresh :class:`Inert` subclass that remembers the global it replaces."""
    return type("Inert", (Inert,), {"global_name": name, "__module__": __name__})


def _one_line(exc: BaseException) -> str:
    """The informative part of torch's (long, multi-paragraph) message, on one line."""
    text = " ".join(str(exc).split())
    m = re.search(r"(Unsupported global: GLOBAL \S+|unsupported GLOBAL \S+ whose module \S+ is blocked|"
                  r"Trying to call reduce for unrecognized function \S+|Can only \w+ [^.]+|"
                  r"PytorchStreamReader failed [^.]+)", text)
    return (m.group(1) if m else text)[:240]


def not_a_checkpoint(head: bytes) -> str | None:
    """Why the first bytes of a file are not a ``torch.save`` file (a zip archive, ``PK\\x03\\x04``,
    or a legacy pickle, ``\\x80``), or None when they may be one: an HTML page (a failed
    download saved under the checkpoint's name), other text, or an unknown format."""
    if head.startswith(b"PK\x03\x04") or head.startswith(b"\x80"):
        return None
    text = head.lstrip(b"\xef\xbb\xbf \t\r\n").lower()
    if text.startswith((b"<!doctype html", b"<html", b"<head", b"<?xml", b"<!--")) or b"<html" in text[:512]:
        return "not a PyTorch checkpoint (looks like an HTML page: the download failed?)"
    if not head:
        return "not a PyTorch checkpoint (the file is empty)"
    printable = sum(32 <= b < 127 or b in (9, 10, 13) for b in head[:512])
    if printable >= 0.95 * len(head[:512]):
        return "not a PyTorch checkpoint (looks like a text file: the download failed?)"
    return None


def load_checkpoint(path: str | Path, what: str = "checkpoint") -> dict:
    """The dictionary stored in the ``torch.save`` file ``path`` (tensors on the CPU).

    Raises :class:`CheckpointReadError` (one line naming ``path``) when the file is missing,
    is not a regular file, is truncated or is not a torch checkpoint, does not hold a
    dictionary, or names a global in a module torch blocks."""
    import pickle

    import torch

    path = Path(path)
    if not path.exists():
        raise CheckpointReadError(f"{what} {path}: no such file")
    if not path.is_file():
        raise CheckpointReadError(f"{what} {path}: not a regular file")
    try:
        with open(path, "rb") as f:  # read-ok: its first 4 KiB, to tell a page or text from an archive
            why = not_a_checkpoint(f.read(4096))
    except OSError as exc:
        raise CheckpointReadError(f"{what} {path}: cannot be read ({exc.strerror or exc})") from None
    if why:
        raise CheckpointReadError(f"{what} {path}: {why}")
    try:
        obj = torch.load(path, map_location="cpu", weights_only=True)  # read-ok: weights-only unpickler (tensors, plain containers)
    except pickle.UnpicklingError as exc:
        if "Unsupported global" not in str(exc) and "unrecognized function" not in str(exc):
            raise CheckpointReadError(f"{what} {path}: refused by torch's weights-only loader "
                                      f"({_one_line(exc)})") from None
        obj = _load_with_stand_ins(path, what)
    except Exception as exc:                 # RuntimeError from the zip reader, EOFError, ...
        raise CheckpointReadError(f"{what} {path}: not a complete torch checkpoint (truncated or another "
                                  f"format: {_one_line(exc)})") from None
    if not isinstance(obj, dict):
        raise CheckpointReadError(f"{what} {path}: holds a {type(obj).__name__}, expected a dictionary")
    return obj


def _load_with_stand_ins(path: Path, what: str) -> dict:
    """``torch.load(weights_only=True)`` with every global torch's scan lists bound to an
    :class:`Inert` stand-in (the file's own classes and functions are never imported)."""
    import torch
    from torch.serialization import get_unsafe_globals_in_checkpoint, safe_globals
    try:
        names = get_unsafe_globals_in_checkpoint(path)
    except Exception as exc:
        raise CheckpointReadError(f"{what} {path}: not a complete torch checkpoint ({_one_line(exc)})") from None
    try:
        with safe_globals([(_stand_in(n), n) for n in names]):
            return torch.load(path, map_location="cpu", weights_only=True)  # read-ok: weights-only, inert stand-ins
    except Exception as exc:
        raise CheckpointReadError(f"{what} {path}: cannot be read with weights only, even with its "
                                  f"{len(names)} non-weight global(s) ({', '.join(names[:3])}) made inert: "
                                  f"{_one_line(exc)}") from None
