"""Exceptions of the evaluator package: each message is one complete line naming the file
(and, where known, the field) that is wrong. All are ``ValueError`` subclasses and
:class:`hoibench.core.errors.HoibenchError`, so ``hoibench`` prints them as one line (exit 2)."""
from __future__ import annotations

from ..core.errors import HoibenchError


class EvaluatorError(HoibenchError, ValueError):
    """Base class: an evaluator folder, checkpoint or gate problem with a complete message."""


class EvaluatorIntegrityError(EvaluatorError):
    """An evaluator folder that is incomplete, tampered with, or does not match its card."""


class CorruptEvaluatorFile(EvaluatorIntegrityError):
    """A file of an evaluator folder that cannot be read: ``weights.safetensors`` that is not
    safetensors (truncated, garbage), ``card.json`` that is not JSON, nested too deeply, or
    has fields of the wrong type."""


class CheckpointError(EvaluatorError):
    """``OUT/checkpoint/last.pt`` cannot be resumed from (unreadable, or another recipe's)."""


class EvaluatorFolderExists(EvaluatorError, FileExistsError):
    """``train-evaluator --out`` names a folder that holds something else (another evaluator,
    or files that are not an evaluator's). Also a ``FileExistsError``."""


class SanityGateError(EvaluatorError):
    """An evaluator whose ground-truth scores do not show that it works."""


class StoreMismatchError(EvaluatorError):
    """An evaluator trained on another dataset, representation, normalisation or split."""


def read_evaluator_file(path, max_bytes: int, what: str, error: type[EvaluatorError] = EvaluatorError) -> bytes:
    """The bytes of the regular file ``path`` (at most ``max_bytes``,
    :func:`hoibench.core.io.read_regular_file`); its refusal raised as ``error``."""
    from ..core.io import read_regular_file
    try:
        return read_regular_file(path, max_bytes, what)
    except ValueError as exc:
        raise error(str(exc)) from None
