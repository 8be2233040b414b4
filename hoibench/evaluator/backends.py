"""The evaluator registry: every kind of evaluator folder hoibench can score with.

A :class:`Backend` names the kind of evaluator a track asks for (``contrastive``: a
text-motion embedding model for R-precision, FID, MM-Dist, Diversity and MultiModality;
``recognizer``: an action classifier for RA and FID on multi-body tracks), the file that
marks a folder as its own, and its loader (``"module:function"``, imported on use). Every
loaded evaluator has an ``id`` (content hash of its weights and card), a ``card`` (dict) and
an embedding method (``embed_motion`` for contrastive evaluators, ``features`` for
recognizers). :func:`load_evaluator` is the one entry point: it recognises the folder and
returns the backend's object.

Adding a backend (for example one that imports a published evaluator) is one
:func:`register_backend` call here with its loader module.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..core.registry import Registry, load_object


@dataclass(frozen=True)
class Backend:
    """An evaluator kind: ``marker`` is the file whose presence identifies its folders."""

    name: str
    kind: str
    marker: str
    loader: str
    description: str

    def load(self, folder: str | Path, **options) -> Any:
        return load_object(self.loader, __package__)(folder, **options)


_BACKENDS: Registry[Backend] = Registry("evaluator backend")


def register_backend(backend: Backend) -> Backend:
    """Add ``backend`` to the registry (a name registered twice is an error)."""
    return _BACKENDS.add(backend.name, backend)


register_backend(Backend("contrastive", "contrastive", "card.json", ".card:load_evaluator",
                         "hoibench's contrastive text-motion evaluator (hoibench train-evaluator)"))
register_backend(Backend("recognizer", "recognizer", "recognizer.json", ".recognizer:load_recognizer",
                         "the multi-body action recognizer (hoibench train-recognizer)"))


def list_backends() -> list[Backend]:
    return _BACKENDS.values()


def get_backend(name: str) -> Backend:
    return _BACKENDS.get(name)


def backend_of(folder: str | Path) -> Backend | None:
    """The backend whose marker file ``folder`` holds (None when none does)."""
    folder = Path(folder)
    for b in _BACKENDS.values():
        if (folder / b.marker).is_file():
            return b
    return None


def peek_card(folder: str | Path, kind: str | None = None) -> dict:
    """The card of ``folder`` (its marker file's JSON) read without loading any weights, for
    checks that can refuse before the slow load; ``{}`` when the folder has no marker of
    ``kind`` or it cannot be read (:func:`load_evaluator` then names the problem)."""
    from ..core.io import read_json_file
    backend = backend_of(folder)
    if backend is None or (kind is not None and backend.kind != kind):
        return {}
    try:
        card = read_json_file(Path(folder) / backend.marker, 8 << 20, backend.marker)
    except (ValueError, OSError, RecursionError):
        return {}
    return card if isinstance(card, dict) else {}


def load_evaluator(folder: str | Path, kind: str | None = None, **options) -> Any:
    """The evaluator in ``folder``, loaded and verified by its backend.

    ``kind``: the evaluator kind the caller needs (a track's ``evaluator_kind``); a folder of
    another kind is refused with a one-line error saying which command makes the right one.
    ``options`` go to the backend's loader (contrastive: ``allow_failed_gate``,
    ``text_encoder``, ``threads``, ``device``)."""
    backend = backend_of(folder)
    if backend is None:
        backend = get_backend(kind or "contrastive")     # its loader names the missing file
    elif kind is not None and backend.kind != kind:
        make = {"contrastive": "hoibench train-evaluator DATA --out EV",
                "recognizer": "hoibench train-recognizer DATA --out EV"}.get(kind, f"a {kind} evaluator")
        raise ValueError(f"{folder}: a {backend.kind} evaluator ({backend.marker}), this track needs a {kind} one "
                         f"(make it with `{make}`)")
    return backend.load(folder, **options)


__all__ = ["Backend", "register_backend", "list_backends", "get_backend", "backend_of", "peek_card", "load_evaluator"]
