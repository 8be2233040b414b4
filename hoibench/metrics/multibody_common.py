"""What the multi-body metrics share: their units and defaults, input validation
(:class:`PosedMesh`, :func:`check_closed`), the open3d raycasting helpers and the
per-clip-mean metric base. Conventions: :mod:`hoibench.metrics.multibody`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Hashable, Sequence

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


def _choice(x, options: tuple, field: str) -> str:
    """``x`` when it is one of ``options``; ``ValueError`` naming ``field`` otherwise."""
    if x not in options:
        raise ValueError(f"{field}: expected one of {options}, got {x!r}")
    return x


def _distance_kind(x) -> str:
    return _choice(x, DISTANCES, "distance")


def _pair_reduction(x) -> str:
    return _choice(x, PAIR_REDUCTIONS, "pair_reduction")


def _num_frames(n) -> int | None:
    if n is None:
        return None
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"num_frames: expected a positive integer or None, got {n!r}")
    return int(n)


def _mode(x) -> str:
    return _choice(x, DIVERSITY_MODES, "mode")


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


def recognition_accuracy(predicted, actions) -> float:
    """RA: the fraction of generated clips whose recognised action equals the prompt's
    action label (SyncDiff, section 4.2), ``mean(predicted[i] == actions[i])``."""
    predicted, actions = list(predicted), list(actions)
    if len(predicted) != len(actions) or not predicted:
        raise ValueError(f"predicted, actions: expected two non-empty lists of one length, got "
                         f"{len(predicted)} and {len(actions)}")
    return float(np.mean([p == a for p, a in zip(predicted, actions)]))
