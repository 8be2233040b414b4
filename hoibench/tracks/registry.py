"""The track registry: what each benchmark track scores and with what.

A :class:`Track` is declarative (as a task config in lm-evaluation-harness): it names the
kind of store it reads, the representation and submission schema it expects, the metrics it
scores, the kind of evaluator it needs, its leaderboard columns and its protocols. The code
that acts on a track is found by name in the stage that owns it:

=================  ==========================================  ==============================
field              resolved by                                 entries today
=================  ==========================================  ==============================
``scorer``         :func:`hoibench.scoring.pipeline.get_scorer`  ``hoi``, ``multibody``
``evaluator_kind`` :func:`hoibench.evaluator.backends.get_backend` ``contrastive``, ``recognizer``
``submission``     :data:`hoibench.scoring.reference_rows.REFERENCE_WRITERS` ``hoi``, ``multibody``
``renderer``       :data:`hoibench.publish.renderers.RENDERERS`      ``hoi``, ``multibody``
=================  ==========================================  ==============================

Adding a track is one :func:`register_track` call in :mod:`hoibench.tracks.catalog` plus a
protocol YAML file naming it (docs/architecture.md has the worked example).
"""
from __future__ import annotations

from dataclasses import dataclass, field

#: the kinds of store a track may read
STORE_KINDS = ("hoi", "human", "multibody")


@dataclass(frozen=True)
class Track:
    """One benchmark track.

    ``datasets``: the store datasets (``manifest["dataset"]``) it scores; ``store_kind``:
    ``hoi`` (one human, one object), ``human`` (human-only clips: object metrics are not
    applicable) or ``multibody``; ``representation``: the store representation submissions are
    encoded with; ``submission``: the submission schema (``hoi``: hml263/hoi269 features or
    joints per sample; ``multibody``: per-body joints or poses); ``metrics``: what it scores
    (the protocol may list fewer); ``evaluator_kind``: the evaluator backend it needs;
    ``columns``: leaderboard columns in order; ``protocols``: its shipped protocol ids, the
    default first."""

    name: str
    datasets: tuple[str, ...]
    store_kind: str
    representation: str
    submission: str
    metrics: tuple[str, ...]
    evaluator_kind: str
    columns: tuple[str, ...]
    protocols: tuple[str, ...]
    scorer: str
    renderer: str
    description: str = ""
    extras: dict = field(default_factory=dict, compare=False)

    @property
    def protocol_kind(self) -> str:
        """The kind of protocol this track's YAML files hold (``hoi`` or ``multibody``)."""
        return "multibody" if self.store_kind == "multibody" else "hoi"

    def to_dict(self) -> dict:
        return {"name": self.name, "datasets": list(self.datasets), "store_kind": self.store_kind,
                "representation": self.representation, "submission": self.submission,
                "metrics": list(self.metrics), "evaluator_kind": self.evaluator_kind, "columns": list(self.columns),
                "protocols": list(self.protocols), "scorer": self.scorer, "renderer": self.renderer,
                "description": self.description}


_TRACKS: dict[str, Track] = {}


def register_track(track: Track) -> Track:
    """Add ``track`` to the registry (a name registered twice is an error)."""
    if track.name in _TRACKS:
        raise ValueError(f"track {track.name!r} is registered twice")
    if track.store_kind not in STORE_KINDS:
        raise ValueError(f"track {track.name!r}: store_kind must be one of {STORE_KINDS}, got {track.store_kind!r}")
    _TRACKS[track.name] = track
    return track


def _load_catalog() -> None:
    if not _TRACKS:
        from . import catalog  # noqa: F401  (registers the shipped tracks)


def list_tracks() -> list[Track]:
    """Every registered track, sorted by name."""
    _load_catalog()
    return [_TRACKS[k] for k in sorted(_TRACKS)]


def get_track(name: str) -> Track:
    """A track by name; ``KeyError`` listing the known names otherwise."""
    _load_catalog()
    if name not in _TRACKS:
        raise KeyError(f"unknown track {name!r}; known: {', '.join(sorted(_TRACKS))}")
    return _TRACKS[name]


def track_for_dataset(dataset: str, multibody: bool = False) -> Track:
    """The track that scores stores of ``dataset``; a dataset no track lists falls back to the
    generic track of its kind (``multibody-synthetic`` settings are not assumed: the caller's
    protocol lookup then names what is missing)."""
    _load_catalog()
    for t in _TRACKS.values():
        if dataset in t.datasets:
            return t
    kind = "multibody" if multibody else "hoi"
    generic = [t for t in _TRACKS.values() if t.extras.get("generic_for") == kind]
    if not generic:
        raise KeyError(f"no track scores dataset {dataset!r}")
    return generic[0]


def track_for_store(store) -> Track:
    """The track that scores ``store`` (a :class:`hoibench.datasets.store.Store`): by its
    dataset, else the generic track of its kind."""
    return track_for_dataset(str(store.manifest.get("dataset", "")), multibody=store.is_multibody)


__all__ = ["track_for_store", "Track", "STORE_KINDS", "register_track", "list_tracks", "get_track", "track_for_dataset"]
