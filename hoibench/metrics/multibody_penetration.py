"""Penetration metrics of multi-body interaction (SyncDiff, following DiffH2O): IV (voxel
intersection volume) and ID (deepest penetrating vertex) per pair of bodies and frame, as
functions and as mergeable metrics.
"""
from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations
from typing import Any

import numpy as np

from .multibody_common import (IV_VOXEL_M, M3_TO_CM3, M_TO_MM, NSAMPLES, _MAX_GRID_POINTS, _array, _faces, _finite,
                               _frame_origin, _meshes, _nsamples, _occupied, _pair_reduction, _PerClipMean, _points,
                               _positive, _scene, _sequence, _signed, check_closed)

# ===================================================================== penetration (IV, ID)
def _aabb_overlap(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    lo, hi = np.maximum(a.min(axis=0), b.min(axis=0)), np.minimum(a.max(axis=0), b.max(axis=0))
    return None if (hi <= lo).any() else (lo, hi)


def _volume(va, sa, vb, sb, voxel_m: float, nsamples: int) -> float:
    """Voxel estimate (m^3) of the volume inside both meshes; see
    :func:`interpenetration_volume`."""
    box = _aabb_overlap(va, vb)
    if box is None:
        return 0.0
    lo, hi = box
    n = np.maximum(np.ceil((hi - lo) / voxel_m).astype(np.int64), 1)
    axes = [lo[k] + (np.arange(n[k]) + 0.5) * voxel_m for k in range(3)]
    rows = max(1, _MAX_GRID_POINTS // int(n[1] * n[2]))
    inside = 0
    for s in range(0, int(n[0]), rows):
        g = np.stack(np.meshgrid(axes[0][s:s + rows], axes[1], axes[2], indexing="ij"), axis=-1).reshape(-1, 3)
        g = g[_occupied(sa, g, nsamples)]
        if len(g):
            inside += int(_occupied(sb, g, nsamples).sum())
    return inside * voxel_m ** 3


def _depth(va, sa, vb, sb, nsamples: int) -> float:
    """Deepest vertex of either mesh inside the other (m); see :func:`interpenetration_depth`."""
    box = _aabb_overlap(va, vb)
    if box is None:
        return 0.0
    lo, hi = box
    deepest = 0.0
    for pts, scene in ((va, sb), (vb, sa)):
        q = pts[((pts >= lo) & (pts <= hi)).all(axis=1)]      # only these can be inside the other
        if len(q):
            deepest = max(deepest, float(-_signed(scene, q, nsamples).min()))
    return deepest


def _frame_pair(vertices_a, faces_a, vertices_b, faces_b, closed: bool):
    va = _points(vertices_a, "vertices_a", 2, "(V, 3)")
    vb = _points(vertices_b, "vertices_b", 2, "(V, 3)")
    fa = _faces(faces_a, len(va), "faces_a")
    fb = _faces(faces_b, len(vb), "faces_b")
    if closed:
        check_closed(fa, "faces_a")
        check_closed(fb, "faces_b")
    c = _frame_origin(va, vb)
    va, vb = va - c, vb - c
    return va, _scene([(va, fa)]), vb, _scene([(vb, fb)])


def interpenetration_volume(vertices_a, faces_a, vertices_b, faces_b, voxel_m: float = IV_VOXEL_M,
                            nsamples: int = NSAMPLES, check_closed_meshes: bool = True) -> float:
    """IV of two closed meshes in one frame, m^3 (multiply by 1e6 for SyncDiff's cm^3).

    ``IV = h^3 * #{voxel centres inside A and inside B}``: a grid of edge ``h = voxel_m``
    anchored at the lower corner of the intersection of the two bounding boxes, centres at
    ``lo + (i + 1/2) h``; inside = open3d ray parity (``nsamples`` rays). For a box-shaped
    intersection of sides ``L_k`` the count per axis is ``L_k / h`` rounded to nearest, so
    the error per side is at most ``h / 2``. DiffH2O instead counts the *surface* voxels of
    the object (trimesh ``voxelized``) inside the hand, pitch 5 mm; see the docs.
    """
    h = _positive(voxel_m, "voxel_m")
    va, sa, vb, sb = _frame_pair(vertices_a, faces_a, vertices_b, faces_b, check_closed_meshes)
    return _volume(va, sa, vb, sb, h, _nsamples(nsamples))


def interpenetration_depth(vertices_a, faces_a, vertices_b, faces_b, nsamples: int = NSAMPLES,
                           check_closed_meshes: bool = True) -> float:
    """ID of two closed meshes in one frame, m (multiply by 1e3 for SyncDiff's mm).

    ``ID = max(0, max_{v in A} -sd_B(v), max_{w in B} -sd_A(w))``: the deepest vertex of
    either body inside the other, depth = its distance to the other's surface (open3d
    ``compute_signed_distance``, negative inside). DiffH2O measures hand vertices inside the
    object only; two bodies of a multi-body scene have no such order, so both directions.
    """
    va, sa, vb, sb = _frame_pair(vertices_a, faces_a, vertices_b, faces_b, check_closed_meshes)
    return _depth(va, sa, vb, sb, _nsamples(nsamples))


@dataclass(frozen=True)
class PairwisePenetration:
    """Per-frame, per-pair penetration of a clip: ``pairs`` [(i, j)] body indices,
    ``volume_m3`` and ``depth_m`` (T, P) (None when not asked for)."""

    pairs: tuple[tuple[int, int], ...]
    volume_m3: np.ndarray | None
    depth_m: np.ndarray | None


def _pairs(pairs, n: int) -> tuple[tuple[int, int], ...]:
    if pairs is None:
        if n < 2:
            raise ValueError(f"bodies: need at least two bodies for pairwise penetration, got {n}")
        return tuple(combinations(range(n), 2))
    items = _sequence(pairs, "pairs")
    out = []
    for k, p in enumerate(items):
        try:
            i, j = (int(x) for x in p)
        except (TypeError, ValueError):
            raise ValueError(f"pairs[{k}]: expected two body indices, got {p!r}") from None
        if not (0 <= i < n and 0 <= j < n) or i == j:
            raise ValueError(f"pairs[{k}]: expected two different indices in [0, {n}), got {p!r}")
        out.append((i, j))
    return tuple(out)


def pairwise_penetration(bodies, pairs=None, volume: bool = True, depth: bool = True,
                         voxel_m: float = IV_VOXEL_M, nsamples: int = NSAMPLES,
                         check_closed_meshes: bool = True) -> PairwisePenetration:
    """IV and/or ID of every pair of bodies in every frame of a clip.

    ``bodies``: list of :class:`PosedMesh` or ``(vertices (T, V, 3), faces)``, hands, humans
    and objects alike; ``pairs``: body-index pairs to measure (default: every unordered pair,
    hand-hand and object-object included). One raycasting scene per body per frame serves
    all its pairs.
    """
    h = _positive(voxel_m, "voxel_m")
    ns = _nsamples(nsamples)
    meshes = _meshes(bodies, "bodies")
    if check_closed_meshes:
        for i, m in enumerate(meshes):
            check_closed(m.faces, f"bodies[{i}].faces")
    pr = _pairs(pairs, len(meshes))
    T = meshes[0].frames
    vol = np.zeros((T, len(pr))) if volume else None
    dep = np.zeros((T, len(pr))) if depth else None
    for t in range(T):
        c = _frame_origin(*(m.vertices[t] for m in meshes))
        verts = [m.vertices[t] - c for m in meshes]
        scenes: dict[int, Any] = {}

        def scene(i):
            if i not in scenes:
                scenes[i] = _scene([(verts[i], meshes[i].faces)])
            return scenes[i]

        for k, (i, j) in enumerate(pr):
            if _aabb_overlap(verts[i], verts[j]) is None:
                continue
            if volume:
                vol[t, k] = _volume(verts[i], scene(i), verts[j], scene(j), h, ns)
            if depth:
                dep[t, k] = _depth(verts[i], scene(i), verts[j], scene(j), ns)
    return PairwisePenetration(pr, vol, dep)


def reduce_pairs(values, pair_reduction: str = "sum", field: str = "values") -> np.ndarray:
    """Per-frame value (T,) from per-pair values (T, P): ``sum`` (DiffH2O adds the left and
    right hands' values), ``max`` or ``mean`` over the pairs."""
    pair_reduction = _pair_reduction(pair_reduction)
    v = _array(values, field)
    if v.ndim != 2:
        raise ValueError(f"{field}: expected shape (T, P), got {v.shape}")
    _finite(v, field)
    if (v < 0).any():
        raise ValueError(f"{field}: penetration values must be >= 0")
    return getattr(v, pair_reduction)(axis=1)


def clip_interpenetration_volume(bodies, pairs=None, voxel_m: float = IV_VOXEL_M,
                                 pair_reduction: str = "sum", nsamples: int = NSAMPLES,
                                 check_closed_meshes: bool = True) -> float:
    """IV of one clip, cm^3: ``mean_t reduce_pairs(IV_t(i, j))`` (every frame counts, frames
    without penetration as 0, as DiffH2O's ``inter_volume_mean``)."""
    _pair_reduction(pair_reduction)                                # validate before the work
    p = pairwise_penetration(bodies, pairs, volume=True, depth=False, voxel_m=voxel_m, nsamples=nsamples,
                             check_closed_meshes=check_closed_meshes)
    return float(reduce_pairs(p.volume_m3, pair_reduction).mean() * M3_TO_CM3)


def clip_interpenetration_depth(bodies, pairs=None, pair_reduction: str = "sum", nsamples: int = NSAMPLES,
                                check_closed_meshes: bool = True) -> float:
    """ID of one clip, mm: ``mean_t reduce_pairs(ID_t(i, j))`` (DiffH2O's
    ``inter_depth_mean``, summed over hands)."""
    _pair_reduction(pair_reduction)
    p = pairwise_penetration(bodies, pairs, volume=False, depth=True, nsamples=nsamples,
                             check_closed_meshes=check_closed_meshes)
    return float(reduce_pairs(p.depth_m, pair_reduction).mean() * M_TO_MM)


# ===================================================================== mergeable metrics
class _Penetration(_PerClipMean):
    def __init__(self, pair_reduction: str = "sum", nsamples: int = NSAMPLES, check_closed_meshes: bool = True):
        super().__init__()
        self.pair_reduction = _pair_reduction(pair_reduction)
        self.nsamples = _nsamples(nsamples)
        self.check_closed_meshes = bool(check_closed_meshes)

    def config(self) -> dict:
        return {"pair_reduction": self.pair_reduction, "nsamples": self.nsamples,
                "check_closed_meshes": self.check_closed_meshes}


class InterpenetrationVolume(_Penetration):
    """IV (SyncDiff, following DiffH2O), cm^3: per frame the voxel intersection volume of each
    pair of bodies (:func:`interpenetration_volume`), reduced over pairs (``sum`` default),
    averaged over the clip's frames; the mean over clips."""

    name = "iv"

    def __init__(self, voxel_m: float = IV_VOXEL_M, pair_reduction: str = "sum", nsamples: int = NSAMPLES,
                 check_closed_meshes: bool = True):
        super().__init__(pair_reduction, nsamples, check_closed_meshes)
        self.voxel_m = _positive(voxel_m, "voxel_m")

    def config(self) -> dict:
        return {"voxel_m": self.voxel_m, **super().config()}

    def update(self, clip_id, bodies, pairs=None) -> None:
        """``bodies``: list of posed meshes (hands, humans, objects); ``pairs``: see
        :func:`pairwise_penetration`."""
        self._new_key(clip_id)
        p = pairwise_penetration(bodies, pairs, volume=True, depth=False, voxel_m=self.voxel_m,
                                 nsamples=self.nsamples, check_closed_meshes=self.check_closed_meshes)
        self.update_pairs(clip_id, p.volume_m3)

    def update_pairs(self, clip_id, volume_m3) -> None:
        """Add a clip from precomputed per-frame, per-pair volumes (T, P), m^3."""
        self._new_key(clip_id)
        self._put(clip_id, reduce_pairs(volume_m3, self.pair_reduction, "volume_m3").mean() * M3_TO_CM3)


class InterpenetrationDepth(_Penetration):
    """ID (SyncDiff, following DiffH2O), mm: per frame the deepest vertex of either body of
    each pair inside the other (:func:`interpenetration_depth`), reduced over pairs, averaged
    over the clip's frames; the mean over clips."""

    name = "id"

    def update(self, clip_id, bodies, pairs=None) -> None:
        self._new_key(clip_id)
        p = pairwise_penetration(bodies, pairs, volume=False, depth=True, nsamples=self.nsamples,
                                 check_closed_meshes=self.check_closed_meshes)
        self.update_pairs(clip_id, p.depth_m)

    def update_pairs(self, clip_id, depth_m) -> None:
        """Add a clip from precomputed per-frame, per-pair depths (T, P), m."""
        self._new_key(clip_id)
        self._put(clip_id, reduce_pairs(depth_m, self.pair_reduction, "depth_m").mean() * M_TO_MM)
