"""The controlled corruptions of a metric validity audit: the registry :data:`FAMILIES`
(name -> :class:`FamilySpec`) and :func:`apply`, which corrupts a whole test split.

A family corrupts ``motion`` (a clip's arrays ``joints`` (..., T, 22, 3) m, ``obj_rot``
(..., T, 3, 3), ``obj_trans`` (..., T, 3), ``object_name``) or ``text`` (its caption lines).
Its ``severities`` increase from the identity (0; speed: factor 1) in the stated unit;
``magnitude(severity)`` orders them (the severity itself; ``|log2 c|`` for speed). A
``clip``-scope function is ``fn(arrays, severity, rng, ctx)``; a ``split``-scope one (a
fraction of the clips) is ``fn(items, severity, seed, ctx, severity_index)``. Every function
is pure and deterministic given its rng or seed, keeps the clip length and raises
``ValueError`` naming the argument it refuses.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

from ..evaluator.text import Caption
from . import captions as tx, motion as mo, objects as ob
from .checks import Context, check_clips, unchanged
from .streams import check_seed, clip_stream


@dataclass(frozen=True)
class FamilySpec:
    """One corruption family: its function, severities (the first is the identity) and their
    unit, what it corrupts (``motion`` | ``text``), its scope (``clip`` | ``split``) and a
    one-line description."""

    name: str
    fn: Callable
    severities: tuple[float, ...]
    unit: str
    corrupts: str
    scope: str
    description: str

    #: how far a severity is from the identity (default: the severity itself)
    distance: Callable[[float], float] | None = None

    def magnitude(self, severity: float) -> float:
        """How far ``severity`` is from the identity (``|log2 c|`` for a speed factor)."""
        return float(severity) if self.distance is None else float(self.distance(severity))

    @property
    def identity(self) -> float:
        return self.severities[0]


_FRACTIONS = (0.0, 0.1, 0.25, 0.5, 0.75, 1.0)


def _fraction_family(name: str, fn: Callable, corrupts: str, scope: str, description: str) -> tuple:
    """The spec of a family whose severities are :data:`_FRACTIONS`: of the clip's frames
    (``clip`` scope) or of the split's clips (``split``)."""
    unit = "fraction of the clip" if scope == "clip" else "fraction of clips"
    return (name, fn, _FRACTIONS, unit, corrupts, scope, description)


def octaves(factor: float) -> float:
    """``|log2 c|``: how far a speed factor is from 1 (0.5 and 2.0 are both 1)."""
    return abs(math.log2(factor))


_SPECS = (
    ("joint_noise", mo.joint_noise, (0.0, 0.005, 0.01, 0.02, 0.05, 0.1), "m (sigma)", "motion", "clip",
     "Gaussian noise on every joint coordinate"),
    ("jitter", mo.jitter, (0.0, 0.0025, 0.005, 0.01, 0.02, 0.04), "m (amplitude)", "motion", "clip",
     "every joint oscillates +-a along a fixed random direction at fps/2"),
    ("foot_sliding", mo.foot_sliding, (0.0, 0.05, 0.1, 0.2, 0.5, 1.0), "m/s", "motion", "clip",
     "horizontal drift of body and object while a foot is planted"),
    _fraction_family("freeze", mo.freeze, "motion", "clip",
                     "the last fraction of the clip holds one frame (1: all of it at frame 0)"),
    _fraction_family("reverse", mo.reverse, "motion", "clip", "the last fraction of the clip played backwards"),
    ("speed", mo.speed, (1.0, 0.8, 1.25, 0.625, 1.6, 0.5, 2.0, 0.4, 2.5), "factor (magnitude |log2 c|)",
     "motion", "clip", "played c times as fast, resampled to the same length", octaves),
    _fraction_family("mirror", mo.mirror, "motion", "split",
                     "left-right mirror (x -> -x, left/right joints swapped, object mirrored)"),
    ("object_float", ob.object_float, (0.0, 0.02, 0.05, 0.1, 0.2, 0.5), "m", "motion", "clip",
     "the object lifted by h on every frame"),
    _fraction_family("object_detach", ob.object_detach, "motion", "clip",
                     "the object keeps its pose from a frame on while the body moves on"),
    ("grasp_offset", ob.grasp_offset, (0.0, 0.02, 0.05, 0.1, 0.2, 0.5), "m", "motion", "clip",
     "the object moved d away from the body, horizontally"),
    ("object_penetrate", ob.object_penetrate, (0.0, 0.02, 0.05, 0.1, 0.2, 0.3), "m", "motion", "clip",
     "the object pushed d towards and into the body, horizontally"),
    _fraction_family("object_swap", ob.object_swap, "motion", "split",
                     "the object's template swapped for another object's"),
    _fraction_family("caption_swap", tx.caption_swap, "text", "split",
                     "captions passed round a cycle of clips (the multiset is kept)"),
    _fraction_family("noun_swap", tx.noun_swap, "text", "split", "the object noun replaced by another object's"),
    _fraction_family("verb_swap", tx.verb_swap, "text", "split", "the main verb replaced by another verb of the split"),
)
FAMILIES: dict[str, FamilySpec] = {s[0]: FamilySpec(*s) for s in _SPECS}


def spec_object_nouns(spec) -> tuple[dict[str, tuple[tuple[str, ...], ...]], dict[str, str]]:
    """``(object nouns, object categories)`` of an annotator spec
    (:func:`hoibench.text.spec.load_spec`), in :class:`Context`'s form."""
    nouns = {name: tuple(tuple(t.hml() for t in phrase) for phrase in e["nouns"]) for name, e in spec.objects.items()}
    return nouns, {name: str(e["category"]) for name, e in spec.objects.items()}


def split_context(clips: Mapping[str, Mapping[str, np.ndarray]], captions: Mapping[str, Sequence[Caption]],
                  fps: float = 20.0, spec=None) -> Context:
    """The :class:`Context` of a split: ``clip_objects`` and ``objects`` from each clip's
    ``object_name``, ``verbs`` from the captions (:func:`~hoibench.audit.captions.split_verbs`),
    nouns and categories from ``spec`` (an annotator spec; without one an object is named by
    its name)."""
    clip_objects = {cid: str(a["object_name"]) for cid, a in clips.items() if "object_name" in a}
    nouns, cats = spec_object_nouns(spec) if spec is not None else ({}, {})
    return Context(fps=float(fps), objects=tuple(sorted(set(clip_objects.values()))), clip_objects=clip_objects,
                   object_nouns=nouns, object_categories=cats, verbs=tx.split_verbs(captions))


def apply(family: str, severity: float, clips: Mapping[str, Mapping[str, np.ndarray]],
          captions: Mapping[str, Sequence[Caption]], seed: int, ctx: Context | None = None,
          ) -> tuple[dict[str, dict[str, np.ndarray]], dict[str, list[Caption]]]:
    """Corrupt a whole split: ``(clips', captions')`` with every clip id of ``clips`` (and of
    ``captions``). ``severity`` must be one of the family's severities; clip ``c`` draws from
    ``clip_stream(seed, family, index of severity, c)`` (numpy ``SeedSequence`` of the seed,
    the family name's key, the severity index and the clip id's key), so a clip's result does
    not depend on the order of the clips or on how they are split between workers. The side a
    family does not corrupt is returned as copies. ``ctx``: :func:`split_context` when None."""
    if family not in FAMILIES:
        raise ValueError(f"family: unknown corruption {family!r} (known: {', '.join(FAMILIES)})")
    spec = FAMILIES[family]
    if severity not in spec.severities:
        raise ValueError(f"severity: {severity!r} is not one of {family}'s severities {spec.severities}")
    index = spec.severities.index(severity)
    seed = check_seed(seed)
    check_clips(clips)
    if not isinstance(captions, Mapping):
        raise ValueError(f"captions: expected a mapping of clip id -> caption lines, got {type(captions).__name__}")
    ctx = split_context(clips, captions) if ctx is None else ctx
    new_clips = {cid: unchanged(a) for cid, a in clips.items()}
    new_caps = {cid: list(lines) for cid, lines in captions.items()}
    if spec.corrupts == "text":
        new_caps = spec.fn(captions, severity, seed, ctx, severity_index=index)
    elif spec.scope == "split":
        new_clips = spec.fn(clips, severity, seed, ctx, severity_index=index)
    else:
        new_clips = {cid: spec.fn(a, severity, clip_stream(seed, family, index, cid), ctx) for cid, a in clips.items()}
    return new_clips, new_caps
