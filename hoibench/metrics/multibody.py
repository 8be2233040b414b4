"""Contact, penetration and diversity metrics of multi-body interaction (N hands or humans
with M rigid objects), as SyncDiff reports them: CSR, CRR, CSIoU, IV, ID, SD and OD.

Reference: SyncDiff (He et al., ICCV 2025, arXiv 2412.20104), section 4.2 and appendix C.5;
IV, ID, SD and OD follow DiffH2O (Christen et al., 2024), whose evaluation code fixes what
the SyncDiff text leaves out (``docs/multibody_metrics.md`` has the formulas, the sources of
every default and what the paper's text copy lost).

Conventions: metres, y-up (no metric here depends on the up axis), one clip of T frames.
A body is a posed mesh: vertices (T, V, 3) float, one per frame, and faces (F, 3) int shared
by all frames (:class:`PosedMesh`, or a ``(vertices, faces)`` pair). Hands/roots and objects
of one clip must have the same T; a generated clip and its ground truth must too (trim
explicitly; nothing here truncates silently).

Geometry is open3d's ``RaycastingScene`` (imported lazily), built per frame from the posed
vertices, in float32 after moving the frame's origin to the bodies' centre:

* distances (CSR, CRR): ``compute_distance``, the exact unsigned distance from a point to the
  nearest triangle, so meshes need not be closed (``distance="vertex"``: to the nearest
  object vertex instead, the reading of appendix C.5's vertex-only inputs);
* inside tests (IV, ID): ``compute_occupancy`` / ``compute_signed_distance`` (ray parity,
  ``nsamples`` rays, majority), exact only for closed, consistently oriented meshes without
  self-intersections -- :func:`check_closed` enforces the first two (a MANO hand must have
  its wrist sealed).

Two layers, as in :mod:`hoibench.metrics`: array-level functions (one clip or one frame),
then :class:`~hoibench.metrics.state.Metric` classes that accumulate per-clip values keyed by
clip id and reduce them in sorted key order, so serial and sharded runs are bit-identical.
Every input is validated; a bad one raises ``ValueError`` naming the argument.
"""
from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations
from typing import Any, Hashable, Sequence

import numpy as np

from .state import Metric, sorted_items

#: CSR contact threshold, metres. SyncDiff section 4.2 gives it in mm but the number is lost
#: in the text copy; 5 mm is DiffH2O's ``in_contact_threshold`` (its contact ratio).
CSR_THRESHOLD_M = 0.005
#: CRR threshold, metres: both hand roots (wrists) within it of an object. SyncDiff gives it
#: in cm, number lost; 5 cm is a documented default (DiffH2O's second-hand threshold).
CRR_THRESHOLD_M = 0.05
#: IV voxel edge, metres: DiffH2O's voxelisation pitch.
IV_VOXEL_M = 0.005
#: DiffH2O evaluates SD/OD on 15 frames taken at a stride of ``T // 15``.
DIFFH2O_FRAMES = 15
#: odd number of rays of the open3d inside test
NSAMPLES = 3
M3_TO_CM3 = 1e6
M_TO_MM = 1e3
PAIR_REDUCTIONS: tuple[str, ...] = ("sum", "max", "mean")
#: ``surface``: exact point-to-triangle distance; ``vertex``: to the nearest object vertex
#: (what appendix C.5's vertex-only inputs suggest; never smaller than ``surface``)
DISTANCES: tuple[str, ...] = ("surface", "vertex")
DIVERSITY_MODES: tuple[str, ...] = ("diffh2o", "per_frame")
_MAX_GRID_POINTS = 1_000_000          # voxel centres queried per open3d call (memory bound)


# ===================================================================== validation
@dataclass(frozen=True, eq=False)
class PosedMesh:
    """A body over one clip: ``vertices`` (T, V, 3) float64 metres, ``faces`` (F, 3) int64."""

    vertices: np.ndarray
    faces: np.ndarray

    @property
    def frames(self) -> int:
        return int(self.vertices.shape[0])


def _array(x, field: str) -> np.ndarray:
    try:
        return np.asarray(x, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{field}: expected a numeric array ({e})") from None


def _finite(a: np.ndarray, field: str) -> np.ndarray:
    if a.size == 0:
        raise ValueError(f"{field}: empty array of shape {a.shape}")
    bad = ~np.isfinite(a)
    if bad.any():
        raise ValueError(f"{field}: {int(bad.sum())} non-finite value(s) (NaN or inf)")
    return a


def _points(x, field: str, ndim: int, shape_text: str) -> np.ndarray:
    """A float64 array of ``ndim`` dims ending in 3, non-empty and finite."""
    a = _array(x, field)
    if a.ndim != ndim or a.shape[-1] != 3:
        raise ValueError(f"{field}: expected shape {shape_text}, got {a.shape}")
    return _finite(a, field)


def _faces(x, n_vertices: int, field: str) -> np.ndarray:
    a = np.asarray(x)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{field}: expected shape (F, 3), got {a.shape}")
    if a.size == 0:
        raise ValueError(f"{field}: empty array of shape {a.shape}")
    if not np.issubdtype(a.dtype, np.integer):
        raise ValueError(f"{field}: expected integer vertex indices, got dtype {a.dtype}")
    if a.min() < 0 or a.max() >= n_vertices:
        raise ValueError(f"{field}: indices must lie in [0, {n_vertices}), got [{a.min()}, {a.max()}]")
    return a.astype(np.int64)


def _posed_mesh(mesh, field: str, frames: int | None = None) -> PosedMesh:
    if isinstance(mesh, PosedMesh):
        v, f = mesh.vertices, mesh.faces
    else:
        try:
            v, f = mesh
        except (TypeError, ValueError):
            raise ValueError(f"{field}: expected a PosedMesh or a (vertices, faces) pair") from None
    v = _points(v, f"{field}.vertices", 3, "(T, V, 3)")
    if frames is not None and len(v) != frames:
        raise ValueError(f"{field}.vertices: expected {frames} frames, got {len(v)}")
    return PosedMesh(v, _faces(f, v.shape[1], f"{field}.faces"))


def _sequence(x, field: str) -> list:
    """A non-empty list of entries (a list, tuple or an array split along its first axis)."""
    if isinstance(x, np.ndarray) and x.ndim > 0:
        x = list(x)
    if isinstance(x, (str, bytes)) or not isinstance(x, Sequence):
        raise ValueError(f"{field}: expected a list (one entry per body), got {type(x).__name__}")
    if len(x) == 0:
        raise ValueError(f"{field}: empty list")
    return list(x)


def _meshes(meshes, field: str, frames: int | None = None) -> list[PosedMesh]:
    items = _sequence(meshes, field)
    out = [_posed_mesh(m, f"{field}[{i}]", frames) for i, m in enumerate(items)]
    if frames is None and len({m.frames for m in out}) > 1:
        raise ValueError(f"{field}: bodies have different frame counts {[m.frames for m in out]}")
    return out


def _positive(x, field: str) -> float:
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise ValueError(f"{field}: expected a positive number, got {x!r}") from None
    if not np.isfinite(v) or v <= 0:
        raise ValueError(f"{field}: expected a positive finite number, got {x!r}")
    return v


def _nsamples(n) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1 or n % 2 == 0:
        raise ValueError(f"nsamples: expected a positive odd integer, got {n!r}")
    return int(n)


def _distance_kind(x) -> str:
    if x not in DISTANCES:
        raise ValueError(f"distance: expected one of {DISTANCES}, got {x!r}")
    return x


def _pair_reduction(x) -> str:
    if x not in PAIR_REDUCTIONS:
        raise ValueError(f"pair_reduction: expected one of {PAIR_REDUCTIONS}, got {x!r}")
    return x


def _num_frames(n) -> int | None:
    if n is None:
        return None
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"num_frames: expected a positive integer or None, got {n!r}")
    return int(n)


def _mode(x) -> str:
    if x not in DIVERSITY_MODES:
        raise ValueError(f"mode: expected one of {DIVERSITY_MODES}, got {x!r}")
    return x


def _frames(x, field: str) -> np.ndarray:
    """Per-frame contact labels (T,) as bool; accepts bool or 0/1 numbers."""
    a = np.asarray(x)
    if a.ndim != 1:
        raise ValueError(f"{field}: expected shape (T,), got {a.shape}")
    if a.size == 0:
        raise ValueError(f"{field}: empty array of shape {a.shape}")
    if a.dtype != bool:
        v = _finite(_array(a, field), field)
        if not np.isin(v, (0.0, 1.0)).all():
            raise ValueError(f"{field}: expected booleans or 0/1 values")
        a = v.astype(bool)
    return a


def _frame_sets(x, field: str) -> list[np.ndarray]:
    out = [_frames(f, f"{field}[{i}]") for i, f in enumerate(_sequence(x, field))]
    lengths = {len(f) for f in out}
    if len(lengths) > 1:
        raise ValueError(f"{field}: bodies have different frame counts {[len(f) for f in out]}")
    return out


def check_closed(faces, field: str = "faces") -> None:
    """Raise ``ValueError`` unless the triangle mesh is closed and consistently oriented:
    every directed edge occurs once and its reverse occurs too (each undirected edge is
    shared by exactly two faces with opposite winding). Open meshes (MANO's wrist) make the
    inside tests of IV and ID meaningless."""
    f = np.asarray(faces, dtype=np.int64)
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    n = int(f.max()) + 1
    key = e[:, 0] * n + e[:, 1]
    uniq, counts = np.unique(key, return_counts=True)
    if (counts > 1).any():
        raise ValueError(f"{field}: {int((counts > 1).sum())} directed edge(s) used twice "
                         "(non-manifold or inconsistently oriented mesh)")
    open_edges = ~np.isin(e[:, 1] * n + e[:, 0], uniq)
    if open_edges.any():
        raise ValueError(f"{field}: mesh is not closed ({int(open_edges.sum())} boundary edge(s)); "
                         "IV and ID need watertight bodies (seal a MANO hand's wrist first)")


# ===================================================================== open3d helpers
def _scene(parts: Sequence[tuple[np.ndarray, np.ndarray]]):
    """One open3d raycasting scene holding the triangle meshes ``parts`` ((V, 3), (F, 3))."""
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    for v, f in parts:
        scene.add_triangles(o3d.core.Tensor(np.ascontiguousarray(v, dtype=np.float32)),
                            o3d.core.Tensor(np.ascontiguousarray(f, dtype=np.uint32)))
    return scene


def _tensor(points: np.ndarray):
    import open3d as o3d

    return o3d.core.Tensor(np.ascontiguousarray(points, dtype=np.float32))


def _unsigned(scene, points: np.ndarray) -> np.ndarray:
    return scene.compute_distance(_tensor(points)).numpy().astype(np.float64)


def _occupied(scene, points: np.ndarray, nsamples: int) -> np.ndarray:
    return scene.compute_occupancy(_tensor(points), nsamples=nsamples).numpy() > 0.5


def _signed(scene, points: np.ndarray, nsamples: int) -> np.ndarray:
    return scene.compute_signed_distance(_tensor(points), nsamples=nsamples).numpy().astype(np.float64)


def _nearest(points: np.ndarray, parts: Sequence[tuple[np.ndarray, np.ndarray]], distance: str) -> np.ndarray:
    """Distance (N,) from each point to the nearest of the meshes ``parts`` (one frame)."""
    if distance == "vertex":
        from scipy.spatial import cKDTree

        return cKDTree(np.concatenate([v for v, _ in parts])).query(points)[0]
    return _unsigned(_scene(parts), points)


def _frame_origin(*arrays: np.ndarray) -> np.ndarray:
    """Centre of the frame's bounding box: subtracted before the float32 cast so that
    precision does not depend on how far the scene is from the world origin."""
    lo = np.min([a.min(axis=0) for a in arrays], axis=0)
    hi = np.max([a.max(axis=0) for a in arrays], axis=0)
    return (lo + hi) / 2


# ===================================================================== contact (CSR, CRR)
def hand_object_distance(hand_vertices, object_meshes, distance: str = "surface") -> np.ndarray:
    """Per-frame distance (T,) m from a hand mesh to the nearest object:
    ``d_t = min_{v in hand vertices} min_{o} dist(v, surface_o(t))``, exact point-to-triangle
    distance (open3d ``compute_distance``), unsigned -- a vertex inside an object counts by
    its distance to that object's surface. ``distance="vertex"``: to the nearest object
    vertex instead (see :data:`DISTANCES`)."""
    return _hand_object_distance(hand_vertices, object_meshes, "hand_vertices", "object_meshes", distance)


def _hand_object_distance(hand_vertices, object_meshes, hand_field: str, obj_field: str,
                          distance: str = "surface") -> np.ndarray:
    distance = _distance_kind(distance)
    hand = _points(hand_vertices, hand_field, 3, "(T, V, 3)")
    objs = _meshes(object_meshes, obj_field, len(hand))
    out = np.empty(len(hand))
    for t in range(len(hand)):
        c = _frame_origin(hand[t], *(o.vertices[t] for o in objs))
        out[t] = _nearest(hand[t] - c, [(o.vertices[t] - c, o.faces) for o in objs], distance).min()
    return out


def contact_frames_hand(hand_vertices, object_meshes, threshold_m: float = CSR_THRESHOLD_M,
                        distance: str = "surface") -> np.ndarray:
    """Surface contact frames (T,) bool of one hand (SyncDiff's CSR contact, appendix C.5):
    ``c_t = [hand_object_distance_t <= threshold_m]`` -- some hand vertex within
    ``threshold_m`` of the surface of at least one object (see :func:`hand_object_distance`).
    ``hand_vertices`` (T, V, 3); ``object_meshes``: list of :class:`PosedMesh` or
    ``(vertices (T, V_o, 3), faces (F_o, 3))``."""
    thr = _positive(threshold_m, "threshold_m")
    return hand_object_distance(hand_vertices, object_meshes, distance) <= thr


def root_object_distances(points, object_meshes, distance: str = "surface") -> np.ndarray:
    """Distances (T, K, M) m from K points per frame (T, K, 3) -- hand roots -- to the surface
    (exact, unsigned; or nearest vertex, ``distance="vertex"``) of each of the M objects."""
    return _root_object_distances(points, object_meshes, "points", distance)


def _root_object_distances(points, object_meshes, field: str, distance: str = "surface") -> np.ndarray:
    distance = _distance_kind(distance)
    p = _points(points, field, 3, "(T, K, 3)")
    objs = _meshes(object_meshes, "object_meshes", len(p))
    out = np.empty((len(p), p.shape[1], len(objs)))
    for t in range(len(p)):
        c = _frame_origin(p[t], *(o.vertices[t] for o in objs))
        for m, o in enumerate(objs):
            out[t, :, m] = _nearest(p[t] - c, [(o.vertices[t] - c, o.faces)], distance)
    return out


def contact_frames_human_roots(left_root, right_root, object_meshes, threshold_m: float = CRR_THRESHOLD_M,
                               same_object: bool = True, distance: str = "surface") -> np.ndarray:
    """Root contact frames (T,) bool of one human (SyncDiff's CRR contact, appendix C.5):
    both hand roots (wrists, (T, 3) each) within ``threshold_m`` of an object's surface.
    ``same_object=True``: ``c_t = OR_o [d(l_t, o) <= thr AND d(r_t, o) <= thr]`` (one object
    held by both hands); ``False``: each root near any object, possibly different ones."""
    thr = _positive(threshold_m, "threshold_m")
    left = _points(left_root, "left_root", 2, "(T, 3)")
    right = _points(right_root, "right_root", 2, "(T, 3)")
    if len(left) != len(right):
        raise ValueError(f"right_root: expected {len(left)} frames like left_root, got {len(right)}")
    near = _root_object_distances(np.stack([left, right], axis=1), object_meshes, "roots", distance) <= thr
    if same_object:
        return (near[:, 0, :] & near[:, 1, :]).any(axis=1)
    return near[:, 0, :].any(axis=1) & near[:, 1, :].any(axis=1)


def contact_ratio(frames) -> float:
    """Fraction of frames in contact, ``sum_t c_t / T``."""
    return float(_frames(frames, "frames").mean())


def contact_surface_ratio(frames_per_hand) -> float:
    """CSR of one clip: the contact ratio of each hand, averaged over the hands (fraction;
    SyncDiff's tables print %)."""
    return float(np.mean([f.mean() for f in _frame_sets(frames_per_hand, "frames_per_hand")]))


def contact_root_ratio(frames_per_human) -> float:
    """CRR of one clip: the root-contact ratio of each human, averaged over the humans."""
    return float(np.mean([f.mean() for f in _frame_sets(frames_per_human, "frames_per_human")]))


def frame_iou(frames, gt_frames, empty_union: float | None = 1.0) -> float:
    """IoU of two contact-frame sets of equal length: ``|P & G| / |P | G|``. When neither has
    a contact frame the union is empty: ``empty_union`` (default 1.0: both agree there is
    no contact), or ``nan`` when ``empty_union`` is None (the body is left out of means)."""
    p, g = _frames(frames, "frames"), _frames(gt_frames, "gt_frames")
    if len(p) != len(g):
        raise ValueError(f"gt_frames: expected {len(p)} frames like frames, got {len(g)}")
    union = int((p | g).sum())
    if union == 0:
        return float("nan") if empty_union is None else float(empty_union)
    return int((p & g).sum()) / union


def contact_surface_iou(frames_per_hand, gt_frames_per_hand, empty_union: float | None = 1.0) -> float:
    """CSIoU of one clip: :func:`frame_iou` of each hand's generated vs ground-truth contact
    frames, averaged over the hands whose IoU is defined (``nan`` if none is)."""
    gen = _frame_sets(frames_per_hand, "frames_per_hand")
    gt = _frame_sets(gt_frames_per_hand, "gt_frames_per_hand")
    if len(gen) != len(gt):
        raise ValueError(f"gt_frames_per_hand: expected {len(gen)} hands like frames_per_hand, got {len(gt)}")
    if len(gen[0]) != len(gt[0]):
        raise ValueError(f"gt_frames_per_hand: expected {len(gen[0])} frames like frames_per_hand, "
                         f"got {len(gt[0])}")
    ious = np.array([frame_iou(p, g, empty_union) for p, g in zip(gen, gt)])
    ious = ious[~np.isnan(ious)]
    return float(ious.mean()) if len(ious) else float("nan")


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


# ===================================================================== diversity (SD, OD)
def downsample_indices(frames: int, num_frames: int | None = DIFFH2O_FRAMES) -> np.ndarray:
    """DiffH2O's frame subset: ``arange(0, T, T // n)[:n]`` (all frames when ``n`` is None).
    Needs ``T >= n``."""
    num_frames = _num_frames(num_frames)
    if num_frames is None:
        return np.arange(frames)
    if frames < num_frames:
        raise ValueError(f"frames: {frames}, fewer than num_frames={num_frames}")
    return np.arange(0, frames, frames // num_frames)[:num_frames]


def wrist_trajectory(x, num_frames: int | None = DIFFH2O_FRAMES, field: str = "trajectory") -> np.ndarray:
    """A validated wrist trajectory (T', J, 3): input (T, 3) (one wrist) or (T, J, 3) (e.g.
    J = 2 hands), subsampled with :func:`downsample_indices`."""
    a = _array(x, field)
    if a.ndim == 2:
        a = a[:, None, :]
    if a.ndim != 3 or a.shape[-1] != 3:
        raise ValueError(f"{field}: expected shape (T, 3) or (T, J, 3), got {np.shape(x)}")
    _finite(a, field)
    n = _num_frames(num_frames)
    if n is not None and len(a) < n:
        raise ValueError(f"{field}: {len(a)} frames, fewer than num_frames={n}")
    return a[downsample_indices(len(a), n)]


def mean_pairwise_distance(trajectories, mode: str = "diffh2o", field: str = "trajectories") -> float:
    """Mean over all unordered pairs (i < j) of the distance between trajectories
    (N, T, J, 3), N >= 2, all pairs exactly (no sampling):

    * ``diffh2o``: ``|x_i - x_j|_2 / T`` on the flattened (T*J*3) vectors -- DiffH2O's
      ``mean(pdist(x.reshape(N, -1))) / num_downsampled_frames``;
    * ``per_frame``: ``mean_{t, j} |x_i(t, j) - x_j(t, j)|``, the mean Euclidean distance
      between corresponding wrist positions (metres, independent of T).
    """
    mode = _mode(mode)
    x = _array(trajectories, field)
    if x.ndim != 4 or x.shape[-1] != 3:
        raise ValueError(f"{field}: expected shape (N, T, J, 3), got {x.shape}")
    _finite(x, field)
    if len(x) < 2:
        raise ValueError(f"{field}: need at least 2 trajectories, got {len(x)}")
    if mode == "diffh2o":
        from scipy.spatial.distance import pdist

        return float(pdist(x.reshape(len(x), -1), metric="euclidean").mean() / x.shape[1])
    d = np.concatenate([np.linalg.norm(x[i + 1:] - x[i], axis=-1).mean(axis=(1, 2)) for i in range(len(x) - 1)])
    return float(d.mean())


def _stack(trajs: Sequence[np.ndarray], field: str) -> np.ndarray:
    shapes = {t.shape for t in trajs}
    if len(shapes) > 1:
        raise ValueError(f"{field}: trajectories differ in shape {sorted(shapes)} (set num_frames, "
                         "or give equal lengths and wrist counts)")
    return np.stack(trajs)


def sample_diversity(samples_per_prompt, num_frames: int | None = DIFFH2O_FRAMES, mode: str = "diffh2o") -> float:
    """SD: for each prompt, :func:`mean_pairwise_distance` of its S >= 2 generated wrist
    trajectories; the mean over prompts."""
    prompts = _sequence(samples_per_prompt, "samples_per_prompt")
    return float(np.mean([_prompt_diversity(s, num_frames, mode, f"samples_per_prompt[{p}]")
                          for p, s in enumerate(prompts)]))


def _prompt_diversity(samples, num_frames, mode: str, field: str) -> float:
    trajs = [wrist_trajectory(s, num_frames, f"{field}[{i}]") for i, s in enumerate(_sequence(samples, field))]
    return mean_pairwise_distance(_stack(trajs, field), mode, field)


def overall_diversity(trajectories, num_frames: int | None = DIFFH2O_FRAMES, mode: str = "diffh2o") -> float:
    """OD: :func:`mean_pairwise_distance` over every generated wrist trajectory of a split
    (all samples of all prompts)."""
    trajs = [wrist_trajectory(s, num_frames, f"trajectories[{i}]")
             for i, s in enumerate(_sequence(trajectories, "trajectories"))]
    return mean_pairwise_distance(_stack(trajs, "trajectories"), mode)


# ===================================================================== mergeable metrics
def _clip_key(clip_id, field: str = "clip_id") -> Hashable:
    if clip_id is None:
        raise ValueError(f"{field}: expected a str, int or tuple id, got None")
    try:
        hash(clip_id)
    except TypeError:
        raise ValueError(f"{field}: expected a hashable id, got {type(clip_id).__name__}") from None
    return clip_id


class _PerClipMean(Metric):
    """Keyed per-clip values (``reduce="keyed"``); ``compute()`` is their mean in sorted key
    order, ``nan`` values (undefined clips) left out."""

    def __init__(self) -> None:
        super().__init__()
        self.add_state("clips", {}, "keyed")

    def _new_key(self, clip_id, field: str = "clip_id") -> Hashable:
        """Validate a clip id not added yet (checked before any geometry is computed)."""
        key = _clip_key(clip_id, field)
        if key in self.clips:
            raise ValueError(f"{field}: clip {key!r} was already added")
        return key

    def _put(self, clip_id, value: float, field: str = "clip_id") -> None:
        self.clips[self._new_key(clip_id, field)] = float(value)

    def per_clip(self) -> dict:
        """Per-clip values ``{clip_id: value}`` in sorted key order."""
        return dict(sorted_items(self.clips))

    def compute(self) -> float:
        if not self.clips:
            raise ValueError(f"{type(self).__name__}: no clips were added")
        v = np.array([x for _, x in sorted_items(self.clips)], dtype=np.float64)
        v = v[~np.isnan(v)]
        return float(v.mean()) if len(v) else float("nan")


class CSR(_PerClipMean):
    """Contact Surface Ratio (SyncDiff, hand-object settings): per clip the fraction of frames
    with a hand vertex within ``threshold_m`` of an object, averaged over hands; the mean over
    clips (fraction; the paper prints %)."""

    name = "csr"
    higher_is_better = True
    units = "fraction"
    paper_column = "CSR (SyncDiff)"

    def __init__(self, threshold_m: float = CSR_THRESHOLD_M, distance: str = "surface"):
        super().__init__()
        self.threshold_m = _positive(threshold_m, "threshold_m")
        self.distance = _distance_kind(distance)

    def config(self) -> dict:
        return {"threshold_m": self.threshold_m, "distance": self.distance}

    def update(self, clip_id, hand_vertices, object_meshes) -> None:
        """``hand_vertices``: list of (T, V, 3), one per hand; ``object_meshes``: list of
        posed meshes (see :func:`contact_frames_hand`)."""
        self._new_key(clip_id)
        hands = _sequence(hand_vertices, "hand_vertices")
        frames = [_hand_object_distance(h, object_meshes, f"hand_vertices[{i}]", "object_meshes", self.distance)
                  <= self.threshold_m for i, h in enumerate(hands)]
        self.update_frames(clip_id, frames)

    def update_frames(self, clip_id, frames_per_hand) -> None:
        """Add a clip from precomputed contact frames, one (T,) bool array per hand."""
        self._new_key(clip_id)
        self._put(clip_id, contact_surface_ratio(frames_per_hand))


class CRR(_PerClipMean):
    """Contact Root Ratio (SyncDiff, human-object settings): per clip the fraction of frames
    with both hand roots of a human within ``threshold_m`` of an object, averaged over humans;
    the mean over clips (fraction)."""

    name = "crr"
    higher_is_better = True
    units = "fraction"
    paper_column = "CRR (SyncDiff)"

    def __init__(self, threshold_m: float = CRR_THRESHOLD_M, same_object: bool = True, distance: str = "surface"):
        super().__init__()
        self.threshold_m = _positive(threshold_m, "threshold_m")
        self.same_object = bool(same_object)
        self.distance = _distance_kind(distance)

    def config(self) -> dict:
        return {"threshold_m": self.threshold_m, "same_object": self.same_object, "distance": self.distance}

    def update(self, clip_id, roots, object_meshes) -> None:
        """``roots``: list of ``(left_root (T, 3), right_root (T, 3))``, one per human."""
        self._new_key(clip_id)
        frames = []
        for i, r in enumerate(_sequence(roots, "roots")):
            try:
                left, right = r
            except (TypeError, ValueError):
                raise ValueError(f"roots[{i}]: expected a (left_root, right_root) pair") from None
            try:
                frames.append(contact_frames_human_roots(left, right, object_meshes, self.threshold_m,
                                                         self.same_object, self.distance))
            except ValueError as e:
                raise ValueError(f"roots[{i}]: {e}") from None
        self.update_frames(clip_id, frames)

    def update_frames(self, clip_id, frames_per_human) -> None:
        self._new_key(clip_id)
        self._put(clip_id, contact_root_ratio(frames_per_human))


class CSIoU(_PerClipMean):
    """Contact-frame IoU between generated and ground-truth motion (SyncDiff): per clip
    :func:`contact_surface_iou` (per hand, averaged over hands), then the mean over clips
    (fraction). ``empty_union``: the IoU of a hand with no contact frame in either (1.0, or
    None to leave that hand out)."""

    name = "csiou"
    higher_is_better = True
    units = "fraction"
    paper_column = "CSIoU (SyncDiff)"

    def __init__(self, threshold_m: float = CSR_THRESHOLD_M, empty_union: float | None = 1.0,
                 distance: str = "surface"):
        super().__init__()
        self.threshold_m = _positive(threshold_m, "threshold_m")
        self.distance = _distance_kind(distance)
        if empty_union is not None and not (0.0 <= float(empty_union) <= 1.0):
            raise ValueError(f"empty_union: expected a value in [0, 1] or None, got {empty_union!r}")
        self.empty_union = None if empty_union is None else float(empty_union)

    def config(self) -> dict:
        return {"threshold_m": self.threshold_m, "empty_union": self.empty_union, "distance": self.distance}

    def update(self, clip_id, hand_vertices, object_meshes, gt_hand_vertices, gt_object_meshes=None) -> None:
        """Generated and ground-truth hands (lists of (T, V, 3), same hands in the same order)
        against their own objects; ``gt_object_meshes`` None: the generated objects."""
        self._new_key(clip_id)
        gt_objects = object_meshes if gt_object_meshes is None else gt_object_meshes
        gt_field = "object_meshes" if gt_object_meshes is None else "gt_object_meshes"
        gen = [_hand_object_distance(h, object_meshes, f"hand_vertices[{i}]", "object_meshes", self.distance)
               <= self.threshold_m for i, h in enumerate(_sequence(hand_vertices, "hand_vertices"))]
        gt = [_hand_object_distance(h, gt_objects, f"gt_hand_vertices[{i}]", gt_field, self.distance)
              <= self.threshold_m for i, h in enumerate(_sequence(gt_hand_vertices, "gt_hand_vertices"))]
        self.update_frames(clip_id, gen, gt)

    def update_frames(self, clip_id, frames_per_hand, gt_frames_per_hand) -> None:
        self._new_key(clip_id)
        self._put(clip_id, contact_surface_iou(frames_per_hand, gt_frames_per_hand, self.empty_union))


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
    higher_is_better = False
    units = "cm^3"
    paper_column = "IV (SyncDiff / DiffH2O)"

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
    higher_is_better = False
    units = "mm"
    paper_column = "ID (SyncDiff / DiffH2O)"

    def update(self, clip_id, bodies, pairs=None) -> None:
        self._new_key(clip_id)
        p = pairwise_penetration(bodies, pairs, volume=False, depth=True, nsamples=self.nsamples,
                                 check_closed_meshes=self.check_closed_meshes)
        self.update_pairs(clip_id, p.depth_m)

    def update_pairs(self, clip_id, depth_m) -> None:
        """Add a clip from precomputed per-frame, per-pair depths (T, P), m."""
        self._new_key(clip_id)
        self._put(clip_id, reduce_pairs(depth_m, self.pair_reduction, "depth_m").mean() * M_TO_MM)


class SampleDiversity(_PerClipMean):
    """SD (DiffH2O, as SyncDiff reports it): keyed by prompt id, each prompt's mean pairwise
    distance between its generated wrist trajectories; the mean over prompts (metres, see
    :func:`mean_pairwise_distance` for ``mode``)."""

    name = "sd"
    higher_is_better = True
    units = "m (diffh2o: flattened distance / frames)"
    paper_column = "SD (SyncDiff / DiffH2O)"

    def __init__(self, num_frames: int | None = DIFFH2O_FRAMES, mode: str = "diffh2o"):
        super().__init__()
        self.num_frames, self.mode = _num_frames(num_frames), _mode(mode)

    def config(self) -> dict:
        return {"num_frames": self.num_frames, "mode": self.mode}

    def update(self, prompt_id, trajectories) -> None:
        """``trajectories``: the S >= 2 samples of one prompt, each (T, 3) or (T, J, 3)."""
        self._new_key(prompt_id, "prompt_id")
        self._put(prompt_id, _prompt_diversity(trajectories, self.num_frames, self.mode, "trajectories"), "prompt_id")


class OverallDiversity(Metric):
    """OD (DiffH2O, as SyncDiff reports it): every generated wrist trajectory of a split,
    keyed by id (e.g. ``(prompt id, sample)``); ``compute()`` stacks them in sorted key
    order and returns their mean pairwise distance (metres, see
    :func:`mean_pairwise_distance`)."""

    name = "od"
    higher_is_better = True
    units = "m (diffh2o: flattened distance / frames)"
    paper_column = "OD (SyncDiff / DiffH2O)"

    def __init__(self, num_frames: int | None = DIFFH2O_FRAMES, mode: str = "diffh2o"):
        super().__init__()
        self.num_frames, self.mode = _num_frames(num_frames), _mode(mode)
        self.add_state("trajectories", {}, "keyed")

    def config(self) -> dict:
        return {"num_frames": self.num_frames, "mode": self.mode}

    def update(self, clip_id, trajectory) -> None:
        """One generated wrist trajectory (T, 3) or (T, J, 3)."""
        key = _clip_key(clip_id)
        if key in self.trajectories:
            raise ValueError(f"clip_id: trajectory {key!r} was already added")
        self.trajectories[key] = wrist_trajectory(trajectory, self.num_frames)

    def compute(self) -> float:
        items = sorted_items(self.trajectories)
        if len(items) < 2:
            raise ValueError(f"OverallDiversity: need at least 2 trajectories, got {len(items)}")
        return mean_pairwise_distance(_stack([v for _, v in items], "trajectories"), self.mode)


__all__ = [
    "CSR_THRESHOLD_M", "CRR_THRESHOLD_M", "IV_VOXEL_M", "DIFFH2O_FRAMES", "NSAMPLES", "DISTANCES",
    "PosedMesh", "check_closed", "hand_object_distance", "contact_frames_hand", "root_object_distances",
    "contact_frames_human_roots", "contact_ratio", "contact_surface_ratio", "contact_root_ratio", "frame_iou",
    "contact_surface_iou", "interpenetration_volume", "interpenetration_depth", "PairwisePenetration",
    "pairwise_penetration", "reduce_pairs", "clip_interpenetration_volume", "clip_interpenetration_depth",
    "downsample_indices", "wrist_trajectory", "mean_pairwise_distance", "sample_diversity", "overall_diversity",
    "CSR", "CRR", "CSIoU", "InterpenetrationVolume", "InterpenetrationDepth", "SampleDiversity", "OverallDiversity",
]
