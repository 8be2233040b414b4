"""A benchmark track: the declarative record (:class:`Track`) and the table the catalog
registers its entries in (:func:`register_track`); lookups are in
:mod:`hoibench.tracks.registry`."""
from __future__ import annotations

from dataclasses import dataclass, field

from ..core.registry import Registry

#: the kinds of store a track may read
STORE_KINDS = ("hoi", "human", "multibody")
#: the metrics a single-body track's page plots (a track may name others)
DEFAULT_HEADLINE = ("fid", "r_precision_top1", "cd", "fsr")


@dataclass(frozen=True)
class Track:
    """One benchmark track.

    ``datasets``: the store datasets (``manifest["dataset"]``) it scores; ``store_kind``:
    ``hoi`` (one human, one object), ``human`` (human-only clips: object metrics are not
    applicable) or ``multibody``; ``representation``: the store representation submissions are
    encoded with; ``submission``: the submission schema (``hoi``: hml263/hoi269 features or
    joints per sample; ``multibody``: per-body joints or poses); ``evaluator_kind``: the
    evaluator backend it needs; ``columns``: leaderboard columns in order; ``headline``: the
    metrics its page plots; ``protocols``: its shipped protocol ids, the default first. What
    it may score is its scorer's metrics in the catalogue (:attr:`metrics`); a protocol lists
    which of them it computes."""

    name: str
    datasets: tuple[str, ...]
    store_kind: str
    representation: str
    submission: str
    evaluator_kind: str
    columns: tuple[str, ...]
    protocols: tuple[str, ...]
    scorer: str
    renderer: str
    description: str = ""
    headline: tuple[str, ...] = DEFAULT_HEADLINE
    extras: dict = field(default_factory=dict, compare=False)

    @property
    def protocol_kind(self) -> str:
        """The kind of protocol this track's YAML files hold: its ``protocol_kind`` extra
        (``interact-task``), else ``hoi`` or ``multibody`` by its store kind."""
        return self.extras.get("protocol_kind") or ("multibody" if self.store_kind == "multibody" else "hoi")

    @property
    def by_protocol(self) -> bool:
        """Whether the track is chosen only by naming one of its protocols: a second task on a
        dataset another track scores by default (:func:`hoibench.tracks.registry.track_for`)."""
        return bool(self.extras.get("by_protocol"))

    @property
    def metrics(self) -> tuple[str, ...]:
        """What its scorer can compute (:func:`hoibench.metrics.catalog.metrics_for`)."""
        from ..metrics.catalog import metrics_for
        return metrics_for(self.scorer)

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
