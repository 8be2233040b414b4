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

Adding a track is one :func:`~hoibench.tracks.track.register_track` call in :mod:`hoibench.tracks.catalog` plus a
protocol YAML file naming it (docs/architecture.md has the worked example).
"""
from __future__ import annotations

from . import catalog  # noqa: F401  (registers the shipped tracks)
from .track import _TRACKS, STORE_KINDS, Track, register_track


def list_tracks() -> list[Track]:
    """Every registered track, sorted by name."""
    return _TRACKS.values()


def get_track(name: str) -> Track:
    """A track by name; ``KeyError`` listing the known names otherwise."""
    return _TRACKS.get(name)


def headline_of(name: str) -> tuple[str, ...]:
    """The metrics the pages and ``compare --plot`` draw for track ``name`` (its ``headline``;
    the single-body default for a track the registry does not know)."""
    from .track import DEFAULT_HEADLINE
    try:
        return get_track(name).headline
    except KeyError:
        return DEFAULT_HEADLINE


def track_for_dataset(dataset: str, multibody: bool = False) -> Track:
    """The track that scores stores of ``dataset``; a dataset no track lists falls back to the
    generic track of its kind (``multibody-synthetic`` settings are not assumed: the caller's
    protocol lookup then names what is missing)."""
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


__all__ = ["track_for_store", "Track", "STORE_KINDS", "register_track", "list_tracks", "get_track", "headline_of",
           "track_for_dataset"]
