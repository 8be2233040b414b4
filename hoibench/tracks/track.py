"""A benchmark track: the declarative record (:class:`Track`) and the table the catalog
registers its entries in (:func:`register_track`); lookups are in
:mod:`hoibench.tracks.registry`."""
from __future__ import annotations

from dataclasses import dataclass, field

from ..core.registry import Registry

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


_TRACKS: Registry[Track] = Registry("track")


def register_track(track: Track) -> Track:
    """Add ``track`` to the registry (a name registered twice is an error)."""
    if track.store_kind not in STORE_KINDS:
        raise ValueError(f"track {track.name!r}: store_kind must be one of {STORE_KINDS}, got {track.store_kind!r}")
    return _TRACKS.add(track.name, track)


__all__ = ["Track", "STORE_KINDS", "register_track"]
