"""CATMO's training inputs from a prepared store (numpy only).

- **Motion**: a clip's hml263 rows (T-1, 263), normalised with the store's train statistics
  (``stats/hml263.npz``, HumanML3D's grouped std).
- **Contacts**: the stored per-joint labels (T, 22), rows 0..T-2 (one per motion row);
  clips without labels are all zero.
- **Object** (HOI stores): hoi269's object channels (axis-angle 3 + translation 3, canonical
  frame of frame 0) normalised with the store's hoi269 statistics, and the object's
  centred template sampled on its surface.
- **Text**: the clip's captions (``DATA/texts/<id>.txt``).

Windows for the VQ-VAEs and the movement encoder are ``vq.window`` rows at a random start,
zero-padded (with a validity mask) for shorter clips. The GPT and the object head see whole
clips from frame 0 (cropped at ``gpt.max_units`` units), because the object channels are
expressed in the clip's frame-0 canonical frame.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...representations import hml263, hoi269
from ...datasets.store import Store
from .. import joint_data as D


@dataclass
class CatmoItem:
    clip_id: str
    motion: np.ndarray                  # (L, 263) normalised
    contacts: np.ndarray                # (L, 22) float32 0/1
    obj: np.ndarray | None              # (L, 6) normalised, HOI stores
    object_name: str | None
    captions: list[str] = field(default_factory=list)


@dataclass
class CatmoData:
    store: Store
    items: list[CatmoItem]
    mean: np.ndarray                    # (263,) hml263 statistics
    std: np.ndarray
    obj_mean: np.ndarray | None         # (6,) hoi269 object-channel statistics
    obj_std: np.ndarray | None
    points: dict[str, np.ndarray]       # object -> (object_points, 3)
    vocab: list[str]
    missing_texts: list[str]

    @property
    def with_object(self) -> bool:
        return self.obj_mean is not None


def store_statistics(store: Store, with_object: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray | None,
                                                                np.ndarray | None]:
    """(mean, std) of hml263 and, for HOI stores, of hoi269's six object channels."""
    try:
        s = store.stats("hml263")
    except FileNotFoundError:
        raise ValueError(f"{store.root}/stats/hml263.npz: missing: CATMO normalises with the store's hml263 "
                         f"statistics (prepare the store again)") from None
    om = os_ = None
    if with_object:
        try:
            o = store.stats("hoi269")
        except FileNotFoundError:
            raise ValueError(f"{store.root}/stats/hoi269.npz: missing: the object head normalises with the store's "
                             f"hoi269 statistics") from None
        om, os_ = o.mean[hml263.DIM:].astype(np.float32), o.std[hml263.DIM:].astype(np.float32)
    return s.mean.astype(np.float32), s.std.astype(np.float32), om, os_


def has_objects(store: Store, ids: list[str]) -> bool:
    """True when the clips carry an object (an HOI store); all or none must."""
    flags = {cid: "obj_rot" in store.load(cid, keys=("obj_rot",)) for cid in ids}
    if len(set(flags.values())) > 1:
        some = sorted(c for c, f in flags.items() if not f)[:3]
        raise ValueError(f"{store.root}: clips {', '.join(some)} have no object while others do: CATMO trains on "
                         f"a human-only or a human-object store, not a mix")
    return bool(flags) and next(iter(flags.values()))


def load_item(store: Store, cid: str, captions: list[str], mean, std, obj_mean, obj_std) -> CatmoItem:
    clip = store.load(cid)
    if "hml263" not in clip:
        raise ValueError(f"{store.root}: clip {cid}: field hml263 missing")
    rows = np.asarray(clip["hml263"], np.float32)
    L = rows.shape[0]
    contacts = np.asarray(clip["contacts"], np.float32)[:L] if "contacts" in clip else np.zeros((L, 22), np.float32)
    obj = None
    if obj_mean is not None:
        if "hoi269" not in clip:
            raise ValueError(f"{store.root}: clip {cid}: field hoi269 missing (an HOI store needs it)")
        obj = ((np.asarray(clip["hoi269"], np.float32)[:, hml263.DIM:] - obj_mean) / obj_std).astype(np.float32)
    name = str(clip["object_name"]) if "object_name" in clip else None
    return CatmoItem(cid, ((rows - mean) / std).astype(np.float32), contacts, obj, name, captions)


def read_data(data: str | Path | Store, split: str, object_points: int, min_frames: int = 8,
              stats: tuple | None = None) -> CatmoData:
    """The clips of ``split`` with captions and >= ``min_frames`` rows (``stats``: the run's
    statistics, else the store's)."""
    store = data if isinstance(data, Store) else Store(data)
    with_object = has_objects(store, store.clip_ids(split))
    mean, std, om, os_ = stats if stats is not None else store_statistics(store, with_object)
    found, missing = D.captioned_ids(store, split)
    items = [it for it in (load_item(store, cid, texts, mean, std, om, os_) for cid, texts in found)
             if len(it.motion) >= min_frames]
    names = {it.object_name for it in items if it.object_name}
    points = D.object_points(store, names, object_points) if with_object else {}
    vocab = D.build_vocab([c for it in items for c in it.captions])
    return CatmoData(store, items, mean, std, om, os_, points, vocab, missing)


def window_batch(items: list[CatmoItem], pick: np.ndarray, window: int, unit: int, rng: np.random.Generator
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(motion (B, W, 263), contacts (B, W, 22), valid rows (B, W)): a random ``window``-row
    crop of each picked clip; shorter clips are zero-padded to ``window`` and keep their
    rows up to a multiple of ``unit``."""
    B = len(pick)
    m = np.zeros((B, window, hml263.DIM), np.float32)
    c = np.zeros((B, window, 22), np.float32)
    valid = np.zeros((B, window), bool)
    for b, i in enumerate(pick):
        it = items[i]
        L = len(it.motion)
        a = int(rng.integers(0, L - window + 1)) if L > window else 0
        n = min(L, window) // unit * unit
        m[b, :n], c[b, :n], valid[b, :n] = it.motion[a:a + n], it.contacts[a:a + n], True
    return m, c, valid


def clip_batch(items: list[CatmoItem], pick: np.ndarray, max_rows: int, unit: int
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]:
    """Whole clips from frame 0 (at most ``max_rows`` rows, a multiple of ``unit``), padded
    to the batch's longest: (motion, contacts, object rows or None, valid rows)."""
    lens = [min(len(items[i].motion), max_rows) // unit * unit for i in pick]
    W = max(lens)
    B = len(pick)
    m = np.zeros((B, W, hml263.DIM), np.float32)
    c = np.zeros((B, W, 22), np.float32)
    o = np.zeros((B, W, hoi269.DIM - hml263.DIM), np.float32) if items[pick[0]].obj is not None else None
    valid = np.zeros((B, W), bool)
    for b, (i, n) in enumerate(zip(pick, lens)):
        it = items[i]
        m[b, :n], c[b, :n], valid[b, :n] = it.motion[:n], it.contacts[:n], True
        if o is not None:
            o[b, :n] = it.obj[:n]
    return m, c, o, valid
