"""SyncDiff's training data: multi-body clips as padded high-order representations plus
their conditions (paper 004, sections 3.2 and 3.4).

* Motion: :func:`hoibench.representations.multibody.encode` (individual motions, then every
  body's motion relative to each rigid body), normalised per column with statistics of the
  train clips of the same body layout (signature), padded to the widest layout's ``D`` with
  a 0/1 column mask and to the batch's longest clip with a 0/1 frame mask.
* Conditions: the action label and the object labels as text (the offline text encoder,
  standing in for CLIP), each object's BPS feature (:mod:`.bps`, one slot per object in body
  order), the skeletons' shape (each skeleton's mean bone lengths: hoibench's proxies have
  no shape coefficients, and bone lengths are what the shape fixes), plus the masks.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...bodies.multibody import Body, MultiBodyClip
from ...core.skeleton import PARENTS as HUMAN_PARENTS
from ...bodies.proxy_hand import MANO_PARENTS
from ...datasets.store import Store
from ...representations import multibody as R
from .. import joint_data as D
from . import bps

#: hoibench's hand joints: MANO's 16, then the tips (thumb, index, middle, ring, pinky)
HAND_PARENTS = tuple(MANO_PARENTS) + (15, 3, 6, 12, 9)
SHAPE_WIDTH = 21                              # bones of the widest skeleton (the human)
STD_FLOOR = 1e-2


def bone_lengths(b: Body) -> np.ndarray:
    """(21,) mean bone lengths (metres) of a skeleton, zero-padded (hands have 20)."""
    parents = HUMAN_PARENTS if b.kind == "human" else HAND_PARENTS
    J = np.asarray(b.joints, np.float64)
    out = np.zeros(SHAPE_WIDTH)
    lens = [np.linalg.norm(J[:, c] - J[:, p], axis=-1).mean() for c, p in enumerate(parents) if p >= 0]
    out[:len(lens)] = lens
    return out


def action_text(clip: MultiBodyClip) -> str:
    if clip.action:
        return clip.action
    if clip.texts:
        return str(clip.texts[0].get("text", ""))
    raise ValueError(f"{clip.name}: no action label and no text to condition on")


def object_text(clip: MultiBodyClip) -> str:
    return " ".join(b.template or b.name for b in clip.bodies if b.is_rigid) or "none"


@dataclass
class Item:
    """One clip: raw representation (T, D), its layout signature and conditions."""
    cid: str
    signature: str
    x: np.ndarray
    action: str
    objects: str
    templates: tuple[str, ...]
    shapes: np.ndarray            # (n_skeletons, 21)


@dataclass
class Stats:
    """Per-signature column mean and std (std floored at :data:`STD_FLOOR`)."""
    mean: dict[str, np.ndarray]
    std: dict[str, np.ndarray]

    @classmethod
    def from_items(cls, items: list[Item]) -> "Stats":
        mean, std = {}, {}
        for sig in sorted({it.signature for it in items}):
            rows = np.concatenate([it.x for it in items if it.signature == sig])
            mean[sig] = rows.mean(0).astype(np.float32)
            std[sig] = np.maximum(rows.std(0), STD_FLOOR).astype(np.float32)
        return cls(mean, std)

    def tensors(self, signatures: list[str]) -> dict:
        import torch
        out = {}
        for i, sig in enumerate(signatures):
            out[f"stats.{i}.mean"] = torch.from_numpy(self.mean[sig])
            out[f"stats.{i}.std"] = torch.from_numpy(self.std[sig])
        return out

    def sha256(self) -> str:
        h = hashlib.sha256()
        for sig in sorted(self.mean):
            h.update(sig.encode())
            h.update(self.mean[sig].tobytes())
            h.update(self.std[sig].tobytes())
        return h.hexdigest()


def item(clip: MultiBodyClip) -> Item:
    x, _ = R.encode(clip)
    shapes = np.stack([bone_lengths(b) for b in clip.bodies if not b.is_rigid]) if any(
        not b.is_rigid for b in clip.bodies) else np.zeros((0, SHAPE_WIDTH))
    return Item(clip.name, clip.signature(), x.astype(np.float32), action_text(clip), object_text(clip),
                tuple(b.template for b in clip.bodies if b.is_rigid), shapes.astype(np.float32))


def load_clip(store: Store, cid: str) -> MultiBodyClip:
    return MultiBodyClip.from_arrays(store.load(cid), store.object_template)


@dataclass
class TrainingSet:
    store: Store
    items: list[Item]
    stats: Stats
    signatures: list[str]                   # sorted; index = the layout id
    widths: list[int]                       # D per signature
    max_objects: int
    max_skeletons: int
    bps_features: dict[str, np.ndarray]     # template -> (bps_points,)
    vocab: list[str]
    layouts: list[list[R.Block]]            # block layout per signature

    @property
    def width(self) -> int:
        return max(self.widths)


def object_bps(store: Store, names, cfg) -> dict[str, np.ndarray]:
    """BPS feature per template name (surface samples seeded by the name)."""
    basis = bps.basis(cfg.bps_points, cfg.bps_radius, cfg.bps_seed)
    out = {}
    for name in sorted(names):
        v, f = store.object_template(name)
        out[name] = bps.encode(D.surface_points(v, f, cfg.surface_points, name), basis)
    return out


def training_set(data: str | Path, cfg) -> TrainingSet:
    store = Store(data)
    if not store.is_multibody:
        raise ValueError(f"{data}: not a multi-body store (SyncDiff trains on multi-body clips: "
                         f"`hoibench prepare multibody`)")
    items, layouts = [], {}
    for cid in store.clip_ids("train"):
        clip = load_clip(store, cid)
        it = item(clip)
        if len(it.x) >= cfg.train.min_frames:
            items.append(it)
            layouts.setdefault(it.signature, R.layout(clip))
    if not items:
        raise ValueError(f"{data}: no train clips with >= {cfg.train.min_frames} frames")
    sigs = sorted({it.signature for it in items})
    widths = [next(len(it.x[0]) for it in items if it.signature == s) for s in sigs]
    templates = {t for it in items for t in it.templates}
    vocab = D.build_vocab([it.action for it in items] + [it.objects for it in items])
    return TrainingSet(store, items, Stats.from_items(items), sigs, widths,
                       max(len(it.templates) for it in items), max(len(it.shapes) for it in items),
                       object_bps(store, templates, cfg.model), vocab, [layouts[s] for s in sigs])


def condition_arrays(it: Item, bps_features: dict[str, np.ndarray], max_objects: int, max_skeletons: int,
                     bps_points: int) -> tuple[np.ndarray, np.ndarray]:
    """(geometry (max_objects, bps_points + 1): BPS then a present flag; shapes
    (max_skeletons, 22): bone lengths then a present flag) of one clip."""
    if len(it.templates) > max_objects or len(it.shapes) > max_skeletons:
        raise ValueError(f"{it.cid}: {len(it.templates)} objects and {len(it.shapes)} skeletons; the run knows at "
                         f"most {max_objects} and {max_skeletons}")
    geo = np.zeros((max_objects, bps_points + 1), np.float32)
    for i, t in enumerate(it.templates):
        geo[i, :-1], geo[i, -1] = bps_features[t], 1.0
    shp = np.zeros((max_skeletons, SHAPE_WIDTH + 1), np.float32)
    shp[:len(it.shapes), :-1], shp[:len(it.shapes), -1] = it.shapes, 1.0
    return geo, shp
