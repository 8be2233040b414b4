"""The track registry: what each benchmark track scores and with what.

A :class:`Track` is declarative (as a task config in lm-evaluation-harness): it names the
kind of store it reads, the representation and submission schema it expects, the metrics it
scores, the kind of evaluator it needs, its leaderboard columns and its protocols. The code
that acts on a track is found by name in the stage that owns it:

=================  ==========================================  ==============================
field              resolved by                                 entries today
=================  ==========================================  ==============================
``scorer``         :func:`hoibench.scoring.pipeline.get_scorer`  ``hoi``, ``multibody``, ``interact-task``
``evaluator_kind`` :func:`hoibench.evaluator.backends.get_backend` ``contrastive``, ``recognizer`` (``none``: no evaluator)
``submission``     :data:`hoibench.scoring.reference_rows.REFERENCE_WRITERS` ``hoi``, ``multibody``, ``interact-task``
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
        if dataset in t.datasets and not t.by_protocol:
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


def track_for(store, protocol=None) -> Track:
    """The track that scores ``store`` under ``protocol`` (a
    :class:`~hoibench.tracks.protocol.Protocol`, or None for the store's default): the track
    the protocol names when that track scores the store's dataset (a dataset with several
    tracks, e.g. ``interact``, ``interact-o2h`` and ``interact-h2o``), else
    :func:`track_for_store` (whose protocol-kind check then refuses a protocol of another
    dataset's track)."""
    default = track_for_store(store)
    name = getattr(protocol, "track", "") if protocol is not None else ""
    if not name or name == default.name:
        return default
    try:
        named = get_track(name)
    except KeyError:
        return default
    return named if str(store.manifest.get("dataset", "")) in named.datasets else default


def protocol_misfit(store, protocol, track: Track | None = None) -> str | None:
    """Why ``protocol`` cannot score ``store`` (its track, :func:`track_for`, takes protocols
    of another kind: a protocol made for another dataset's track), or None when it fits."""
    track = track or track_for(store, protocol)
    if protocol is None or protocol.kind == track.protocol_kind:
        return None
    return (f"protocol {protocol.ref} is a {protocol.kind} protocol; {store.root} is a store of the {track.name} "
            f"track, scored under {track.protocol_kind} protocols ({', '.join(track.protocols)})")


def fitting_track(store, protocol=None) -> Track:
    """:func:`track_for`, refusing in one line (ValueError: :func:`protocol_misfit`'s) a
    protocol made for another dataset's track."""
    track = track_for(store, protocol)
    misfit = protocol_misfit(store, protocol, track)
    if misfit:
        raise ValueError(misfit)
    return track


__all__ = ["track_for", "track_for_store", "protocol_misfit", "fitting_track", "Track", "STORE_KINDS", "register_track", "list_tracks", "get_track", "headline_of",
           "track_for_dataset"]
