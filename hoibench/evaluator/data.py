"""Text-motion items of a store split: the unit the evaluator trains and retrieves on.

An item is a motion segment with its captions. A clip's whole-clip captions (``start = end =
0``) form one item over all its rows; a caption with its own ``[start, end]`` seconds becomes
its own item over rows ``[int(start * fps), int(end * fps))`` (HumanML3D's rule). Segments
shorter than ``min_frames`` rows are skipped. Items are ordered by clip id, then segment.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..datasets.store import Store
from .text import read_captions


@dataclass
class Item:
    clip_id: str
    start: int                      # first row
    end: int                        # one past the last row
    features: np.ndarray            # raw (rows, 263) hml263 or (rows, 269) hoi269
    captions: list[str] = field(default_factory=list)
    segment: bool = False           # True: a caption's own [start, end] window of the clip

    @property
    def key(self) -> str:
        return f"{self.clip_id}[{self.start}:{self.end}]" if self.segment else self.clip_id


@dataclass
class SplitItems:
    split: str
    items: list[Item]
    clip_ids: list[str]             # clips with at least one item
    missing_texts: list[str]        # clips without DATA/texts/<id>.txt
    skipped_segments: int           # captions whose segment is shorter than min_frames


def feature_key(variant: str) -> str:
    return "hoi269" if variant == "hoi" else "hml263"


def load_items(store: Store | str | Path, split: str, variant: str = "human", min_frames: int = 8) -> SplitItems:
    """Items of ``split``; captions from ``DATA/texts/<id>.txt``."""
    store = store if isinstance(store, Store) else Store(store)
    key = feature_key(variant)
    clips = store.manifest.get("clips") or []
    if variant == "hoi" and clips and not any(c.get("object") for c in clips):
        raise ValueError(f"{store.root}: the 'hoi' evaluator encodes the object's motion, and this store is "
                         f"human-only (no clip has an object, e.g. RICH): use the 'human' variant (--variant human)")
    items, with_items, missing, skipped = [], [], [], 0
    for cid in store.clip_ids(split):
        caps = read_captions(store.root, cid)
        if not caps:
            missing.append(cid)
            continue
        clip = store.load(cid)
        if key not in clip:
            raise ValueError(f"{cid}: the {variant!r} evaluator needs {key!r} rows, which this clip lacks "
                             f"(no object pose?)")
        feats = clip[key]
        fps = float(clip["fps"])
        whole = [c.text for c in caps if c.whole_clip]
        segs: dict[tuple[int, int], list[str]] = {}
        for c in caps:
            if c.whole_clip:
                continue
            a, b = int(c.start_s * fps), min(int(c.end_s * fps), len(feats))
            if b - a < min_frames:
                skipped += 1
                continue
            segs.setdefault((a, b), []).append(c.text)
        n0 = len(items)
        if whole and len(feats) >= min_frames:
            items.append(Item(cid, 0, len(feats), feats, whole))
        elif whole:
            skipped += len(whole)
        for (a, b), texts in sorted(segs.items()):
            items.append(Item(cid, a, b, feats[a:b], texts, segment=True))
        if len(items) > n0:
            with_items.append(cid)
    return SplitItems(split, items, with_items, missing, skipped)


def store_protocol(store: Store):
    """The protocol ``hoibench evaluate`` uses by default for this store
    (:func:`hoibench.tracks.protocol.default_protocol_id`: ``<dataset>-<mode>``, ``rich-cat-clean``
    for a ``rich`` store), or None when none is shipped: GT scores then use the trainer's own pools."""
    from ..tracks.protocol import default_protocol_id, get_protocol
    try:
        return get_protocol(default_protocol_id(store.manifest))
    except KeyError:
        return None
