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
:func:`register_backend` call here with its loader module. A backend that imports a
published evaluator also names an ``importer`` (``"module:function"``, called as
``importer(out, **files)`` and returning the new folder's evaluator id) and the files it
reads (:class:`ImportFile`: ``hoibench evaluator import KIND --checkpoint ... --out EV``).
Its folders carry ``card.json`` with ``"backend": NAME``; :func:`backend_of` dispatches on
that field before it looks at marker files.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..core.registry import Registry, load_object


@dataclass(frozen=True)
class ImportFile:
    """One input of an importer: ``option`` is its keyword (``--option`` on the command line)."""

    option: str
    help: str
    required: bool = True


@dataclass(frozen=True)
class Backend:
    """An evaluator kind: ``marker`` is the file whose presence identifies its folders
    (a ``card.json`` whose ``backend`` field names this backend also does)."""

    name: str
    kind: str
    marker: str
    loader: str
    description: str
    importer: str | None = None
    import_files: tuple[ImportFile, ...] = ()
    #: ``"module:function"`` giving ``(summary text, verified)`` of a folder for
    #: ``hoibench evaluator show`` (None: the contrastive card summary)
    show: str | None = None

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
register_backend(Backend("chainhoi", "contrastive", "card.json", ".published_chainhoi:load_chainhoi",
                         "ChainHOI's published MotionCLIP evaluator (RoBERTa + motion transformer)",
                         ".published_chainhoi:import_chainhoi", (
                             ImportFile("checkpoint", "the evaluator's Lightning .ckpt (ChainHOI: "
                                        "checkpoint/behave_t2m/epoch=24-step=325.ckpt or "
                                        "checkpoint/omomo/epoch=273-step=9590.ckpt)"),
                             ImportFile("text_model", "a local roberta-base folder (config.json, vocab.json, "
                                        "merges.txt)"),
                             ImportFile("stats", "ChainHOI's dataset folder holding Mean_local.npy and Std_local.npy "
                                        "(dataset/behave_t2m or dataset/omomo)"))))


register_backend(Backend(
    "interact", "interact", "card.json", ".interact:load_interact",
    "InterAct's published text-to-interaction evaluator (markers + object BPS, DistilBERT text branch)",
    importer=".interact_import:import_interact", show=".interact:show_interact",
    import_files=(ImportFile("checkpoint", "the evaluator checkpoint (InterAct: markersbps.ckpt)"),
                  ImportFile("distilbert", "local distilbert-base-uncased folder (config.json + tokenizer files)"),
                  ImportFile("mean", "InterAct: mean_train_markersbps.npy (615,)"),
                  ImportFile("std", "InterAct: std_train_markersbps.npy (615,)"),
                  ImportFile("bps_basis", "InterAct: bps_basis_set_128_1.npy (128, 3)"))))

#: the backends of Guo et al.'s matching architecture: name, loader, importer, description and
#: what each imported file (checkpoint, GloVe folder, meta statistics) is
_T2M_ARCHITECTURE = (
    ("t2m", ".published_t2m:load_t2m", ".published_t2m:import_t2m",
     "Guo et al.'s text-motion matching evaluator (text-to-motion's finest.tar, GloVe, meta)",
     ("text-to-motion's finest.tar", "the glove/ folder (our_vab_data.npy, our_vab_words.pkl, our_vab_idx.pkl)",
      "the evaluator's meta/ folder (mean.npy, std.npy)")),
    ("chois", ".chois_t2m:load_chois", ".chois_t2m:import_chois",
     "CHOIS's text-motion matching evaluator (t2m architecture on OMOMO joints24, 120 frames)",
     ("CHOIS: text_motion_features/model/finest.tar",
      "CHOIS: the glove_840B/ folder (our_vab_data.npy, our_vab_words.pkl, our_vab_idx.pkl)",
      "CHOIS: a folder with mean.npy and std.npy (72,) from t2m_mean_std_jpos.p (docs/evaluator.md)")),
)
for _name, _loader, _importer, _description, _files in _T2M_ARCHITECTURE:
    register_backend(Backend(_name, "contrastive", "card.json", _loader, _description, importer=_importer,
                             import_files=tuple(ImportFile(option, text)
                                                for option, text in zip(("checkpoint", "glove", "meta"), _files))))


def list_backends() -> list[Backend]:
    return _BACKENDS.values()


def get_backend(name: str) -> Backend:
    return _BACKENDS.get(name)


#: the last card files read: {(path, size, mtime_ns): parsed JSON or None}; one evaluation asks
#: for the same card from several checks, and reads it once
_CARDS: dict[tuple, Any] = {}


def _read_card(path: Path, what: str) -> Any:
    """The JSON of ``path`` (None when unreadable), read once per file version."""
    import copy

    from ..core.io import read_json_file
    try:
        st = path.stat()
    except OSError:
        return None
    key = (str(path.resolve()), st.st_size, st.st_mtime_ns)
    if key not in _CARDS:
        try:
            got = read_json_file(path, 8 << 20, what)
        except (ValueError, OSError, RecursionError):
            got = None
        if len(_CARDS) > 16:
            _CARDS.clear()
        _CARDS[key] = got
    return copy.deepcopy(_CARDS[key])


def _declared_backend(folder: Path) -> Backend | None:
    """The backend named by ``folder/card.json``'s ``backend`` field (None without one)."""
    card = _read_card(folder / "card.json", "card.json")
    name = card.get("backend") if isinstance(card, dict) else None
    if isinstance(name, str) and name in _BACKENDS:
        return _BACKENDS.get(name)
    return None


def baseline_run_refusal(folder: str | Path) -> str | None:
    """The one-line refusal of a baseline run folder given where an evaluator folder is needed
    (its ``card.json`` has ``checkpoint_id`` and ``baseline``, no ``evaluator_id``); None otherwise."""
    folder = Path(folder)
    if not (folder / "card.json").is_file():
        return None
    card = _read_card(folder / "card.json", "card.json")
    if not isinstance(card, dict) or "evaluator_id" in card or "checkpoint_id" not in card:
        return None
    name = str(card.get("baseline", "?"))[:40]
    return (f"{folder}: a baseline run folder (the trained {name} generator: card.json with checkpoint_id), not an "
            f"evaluator folder; --evaluator takes a folder whose card.json has evaluator_id (made by `hoibench "
            f"train-evaluator DATA --out EV` or `hoibench evaluator import ...`, or a track's "
            f"leaderboards/<track>/evaluator)")


def backend_of(folder: str | Path) -> Backend | None:
    """The backend of ``folder``: the one its ``card.json`` names in ``backend``, else the
    one whose marker file it holds (None when none does)."""
    folder = Path(folder)
    if (folder / "card.json").is_file():
        declared = _declared_backend(folder)
        if declared is not None:
            return declared
    for b in _BACKENDS.values():
        if b.importer is None and (folder / b.marker).is_file():   # imported folders name their backend
            return b
    return None


def peek_card(folder: str | Path, kind: str | None = None) -> dict:
    """The card of ``folder`` (its marker file's JSON) read without loading any weights, for
    checks that can refuse before the slow load; ``{}`` when the folder has no marker of
    ``kind`` or it cannot be read (:func:`load_evaluator` then names the problem)."""
    backend = backend_of(folder)
    if backend is None or (kind is not None and backend.kind != kind) or baseline_run_refusal(folder):
        return {}
    card = _read_card(Path(folder) / backend.marker, backend.marker)
    return card if isinstance(card, dict) else {}


def load_evaluator(folder: str | Path, kind: str | None = None, **options) -> Any:
    """The evaluator in ``folder``, loaded and verified by its backend.

    ``kind``: the evaluator kind the caller needs (a track's ``evaluator_kind``); a folder of
    another kind is refused with a one-line error saying which command makes the right one.
    ``options`` go to the backend's loader (contrastive: ``allow_failed_gate``,
    ``text_encoder``, ``threads``, ``device``)."""
    refusal = baseline_run_refusal(folder)
    if refusal:
        raise ValueError(refusal)
    backend = backend_of(folder)
    if backend is None:
        backend = get_backend(kind or "contrastive")     # its loader names the missing file
    elif kind is not None and backend.kind != kind:
        make = {"contrastive": "hoibench train-evaluator DATA --out EV",
                "recognizer": "hoibench train-recognizer DATA --out EV"}.get(
            kind, f"hoibench evaluator import {kind} ... --out EV" if kind in _BACKENDS and
            _BACKENDS.get(kind).importer else f"a {kind} evaluator")
        raise ValueError(f"{folder}: a {backend.kind} evaluator ({backend.marker}), this track needs a {kind} one "
                         f"(make it with `{make}`)")
    return backend.load(folder, **options)


def import_evaluator(name: str, out: str | Path, **files) -> str:
    """Write an evaluator folder at ``out`` from a published evaluator's files with backend
    ``name``'s importer; return its evaluator id. ``files``: the backend's
    :class:`ImportFile` options (paths); a missing required one is a one-line error."""
    if name not in _BACKENDS:
        raise ValueError(f"evaluator import: unknown backend {name!r}; known: {', '.join(_BACKENDS)}")
    backend = get_backend(name)
    if backend.importer is None:
        importable = [b.name for b in _BACKENDS.values() if b.importer]
        raise ValueError(f"evaluator import: {name!r} is made by its own command, not imported "
                         f"(importable: {', '.join(importable) or 'none'})")
    known = {f.option for f in backend.import_files}
    unknown = sorted(k for k, v in files.items() if v is not None and k not in known)
    if unknown:
        raise ValueError(f"evaluator import {name}: --{unknown[0].replace('_', '-')} is not read by this backend "
                         f"(it reads {', '.join('--' + f.option.replace('_', '-') for f in backend.import_files)})")
    missing = [f.option for f in backend.import_files if f.required and files.get(f.option) is None]
    if missing:
        raise ValueError(f"evaluator import {name}: --{missing[0].replace('_', '-')} is required "
                         f"({next(f.help for f in backend.import_files if f.option == missing[0])})")
    given = {k: Path(v) for k, v in files.items() if v is not None}
    return load_object(backend.importer, __package__)(Path(out), **given)


def import_options() -> dict[str, str]:
    """Every importer option of every registered backend -> its help (for the command line)."""
    out: dict[str, str] = {}
    for b in _BACKENDS.values():
        for f in b.import_files:
            out.setdefault(f.option, f"{f.help} [{b.name}]" if f.option not in out else out[f.option])
    return out


__all__ = ["Backend", "ImportFile", "import_evaluator", "import_options", "register_backend", "list_backends", "get_backend", "backend_of", "peek_card", "load_evaluator"]
