"""ChainHOI's released distance rules in numpy: what its evaluation measures, quirks included.

Sources: ChainHOI commit 4990160 (``src/models/metrics/compute.py``, cited ``compute.py:LINE``)
and TorchSDF (wrc042/TorchSDF 3f3f83d, ``torchsdf/csrc/unbatched_triangle_distance_cuda.cu``,
cited ``.cu:LINE``), the CUDA extension ChainHOI's PS calls. Units: metres.

**PS sign, the closest-face rule** (``PeneMetric.update``, compute.py:1186-1198, torchsdf
``compute_sdf``). Per point p and face f = (v1, v2, v3), the kernel finds the closest point
``c_f`` of the face (kaolin's region tests, .cu:203-231; exact geometry) and keeps the face of
smallest ``|p - c_f|^2`` -- stored as float32 (.cu:237), replaced only by a strictly smaller
value, so *the first face wins ties* (.cu:238, 245; faces in blocks of 512, a block whose
first face gives NaN is left out). The sign is that face's: ``+1`` (outside) when
``(p - c_f) . n_f >= 0`` with ``n_f = (v1 - v2) x (v1 - v3)`` (.cu:211, 236), else ``-1`` --
the side of the face's plane, as ``c_f`` lies in it. Float32 squares also tie faces whose
distances differ below float32 resolution: a point ~1 m away whose closest point is within
~0.2 mm of a vertex can take the sign of any face at that vertex, the first one.
ChainHOI multiplies the *squared* distance by the sign and counts ``< 0`` (compute.py:1192-1195):
a vertex penetrates when its sign is -1 and it is not on the surface. The mesh is used as loaded
(``trimesh.load``, hoidataset.py:103; no repair), so an inverted part flips every point whose
closest face it holds, and overlapping or touching parts sign points by whichever part's face
is nearest, not by "inside any part".

**Contact distance, the edge quirk** (CD/OCD; BEHAVE: ``ContactMetric`` compute.py:573 ->
``point_to_triangle_distance`` compute.py:428-482; OMOMO: ``ContactMetric2`` compute.py:997 ->
``point_to_triangle_distance3`` compute.py:722-818). Per face: the signed distance to the
plane where the projection's barycentric coordinates are all >= 0, else the distance to the
nearest of the three edges. Edge k has ``e = [v1 - v0, v2 - v0, v2 - v1][k]``, parameter
``t = clamp((p - s_k) . e / |e|^2, 0, 1)`` with ``s = [v0, v1, v1]`` (compute.py:418, 778)
and point ``b_k + t e`` with ``b = [v0, v0, v1]`` (compute.py:422, 794): for edge v0 -> v2
the projection is measured from v1, so the point lands at ``v0 + clamp(t - (v1 - v0).e/|e|^2)
e`` instead of the foot of the perpendicular. Every value is the distance to some point of the
triangle, so the result is never below the exact distance; it exceeds it where the nearest
feature of the mesh is the interior of an edge that is ``v0 -> v2`` in every face holding it.
Edge distances get the sign of the plane distance ``sign(d_plane + eps)``; over faces the
smallest ``|edge|`` and the smallest ``|plane|`` are taken (first on ties), then the smaller
of the two (the edge one on ties). Variants differ in their epsilons (:data:`CONTACT_VARIANTS`).
CD squares the value, so only its magnitude matters there.

Everything here is float64 (the reference runs float32 on a GPU): values agree to ~1e-7
relative; squared distances are compared as float32, as the kernel stores them, so exact ties
(faces sharing the closest point) are reproduced, and near-ties at float32 resolution are
reproduced in kind but not point for point (the kernel's own rounding decides them).

Entry points: :func:`closest_face_brute` (the kernel face by face, any mesh),
:class:`ClosestFaceField` (the same answer fast: open3d finds a closest face, its touching
faces settle ties), :func:`contact_distance_brute` (compute.py's function, signed) and
:class:`ContactDistanceField` (its magnitude, fast), :func:`exact_triangle_distance` (the exact
point-triangle distance, for comparison).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SOURCE = "ChainHOI 4990160 src/models/metrics/compute.py; wrc042/TorchSDF 3f3f83d unbatched_triangle_distance_cuda.cu"
#: faces per shared-memory block of the torchsdf kernel (.cu:287)
KERNEL_BLOCK = 512


@dataclass(frozen=True)
class ContactVariant:
    """Numerics of one of compute.py's point-to-triangle functions.

    ``normal_eps``: the unit normal is ``n / (|n| + normal_eps)``; ``sign_eps``: edge
    distances get ``sign(d_plane + sign_eps)``; ``edge_eps``: a zero ``|e|^2`` is replaced by it
    (None: left 0, the division gives inf/NaN); ``quirk``: edge v0 -> v2 measured from v1.
    """

    name: str
    normal_eps: float
    sign_eps: float
    edge_eps: float | None
    quirk: bool = True


#: ``reference``: ``point_to_triangle_distance`` (BEHAVE, compute.py:428-482);
#: ``reference-omomo``: ``point_to_triangle_distance3`` (OMOMO, compute.py:722-818);
#: ``exact-edges``: the BEHAVE numerics without the quirk (equals the exact distance)
CONTACT_VARIANTS: dict[str, ContactVariant] = {
    "reference": ContactVariant("reference", 0.0, 1e-9, None),
    "reference-omomo": ContactVariant("reference-omomo", 1e-8, 1e-7, 1e-7),
    "exact-edges": ContactVariant("exact-edges", 0.0, 1e-9, None, quirk=False),
}


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", a, b)


def _mesh(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise ValueError(f"vertices, faces: expected (V, 3) and (F >= 1, 3), got {v.shape} and {f.shape}")
    return v, f


def _points(points) -> np.ndarray:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"points: expected shape (N, 3), got {p.shape}")
    return p


def degenerate_faces(vertices, faces) -> np.ndarray:
    """Faces (F,) bool with a zero normal or a zero-length edge (the kernel and compute.py give
    NaN or inf on them; the fast paths fall back to the brute-force ones)."""
    v, f = _mesh(vertices, faces)
    t = v[f]
    zero_edge = np.zeros(len(f), bool)
    for i, j in ((0, 1), (1, 2), (2, 0)):
        zero_edge |= ~np.any(t[:, i] != t[:, j], axis=1)
    return zero_edge | ~np.any(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]) != 0, axis=1)


# ============================================================== exact distance
def exact_closest_point(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Closest point of triangle (a, b, c) to p, exactly (Ericson, *Real-Time Collision
    Detection* 5.1.5: Voronoi regions of vertices, edges, face); broadcasts over leading axes."""
    ab, ac, ap, bp, cp = b - a, c - a, p - a, p - b, p - c
    d1, d2, d3, d4, d5, d6 = _dot(ab, ap), _dot(ac, ap), _dot(ab, bp), _dot(ac, bp), _dot(ab, cp), _dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        s = 1.0 / (va + vb + vc)
        out = a + ab * (vb * s)[..., None] + ac * (vc * s)[..., None]              # face
        bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        out = np.where(((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0))[..., None], b + (c - b) * bc[..., None], out)
        out = np.where(((vb <= 0) & (d2 >= 0) & (d6 <= 0))[..., None], a + ac * (d2 / (d2 - d6))[..., None], out)
        out = np.where(((d6 >= 0) & (d5 <= d6))[..., None], np.broadcast_to(c, out.shape), out)
        out = np.where(((vc <= 0) & (d1 >= 0) & (d3 <= 0))[..., None], a + ab * (d1 / (d1 - d3))[..., None], out)
        out = np.where(((d3 >= 0) & (d4 <= d3))[..., None], np.broadcast_to(b, out.shape), out)
        out = np.where(((d1 <= 0) & (d2 <= 0))[..., None], np.broadcast_to(a, out.shape), out)
    return out


def exact_triangle_distance(points, vertices, faces, chunk_pairs: int = 400_000) -> np.ndarray:
    """Exact unsigned distance (N,) of points (N, 3) to a triangle mesh, m (brute force over
    faces, ``chunk_pairs`` point-face pairs at a time)."""
    p, (v, f) = _points(points), _mesh(vertices, faces)
    t = v[f]
    out = np.empty(len(p))
    step = max(1, chunk_pairs // len(f))
    for s in range(0, len(p), step):
        q = p[s:s + step, None, :]
        c = exact_closest_point(q, t[None, :, 0], t[None, :, 1], t[None, :, 2])
        out[s:s + step] = np.sqrt(np.square(q - c).sum(-1).min(1))
    return out


# ============================================================== torchsdf kernel (PS sign)
def _cdot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Dot products of (3, P) component arrays."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


class KernelFaces:
    """torchsdf's per-face step (.cu:203-237) over point-face pairs of one mesh.

    For a pair (p, face (v1, v2, v3)): ``u_ab = (p - v1).e12 / |e12|^2``, ``u_bc``, ``u_ca``
    likewise (``e12 = v2 - v1``, ``e23 = v3 - v2``, ``e31 = v1 - v3``), ``n = (v1 - v2) x
    (v1 - v3)``. The closest point, in the kernel's order: vertex v1 when ``u_ca > 1`` and
    ``u_ab < 0``, v2 when ``u_ab > 1, u_bc < 0``, v3 when ``u_bc > 1, u_ca < 0``; else edge 12,
    23, 31 when its parameter is in [0, 1] and p is not above it (``(n x e).(p - v) <= 0``);
    else the projection on the plane. ``sign = +1`` iff ``(p - c).n >= 0``. Per-face constants
    are computed once, so a pair costs a gather and component-wise products.
    """

    def __init__(self, tri: np.ndarray):
        v1, v2, v3 = tri[:, 0], tri[:, 1], tri[:, 2]
        e12, e23, e31 = v2 - v1, v3 - v2, v1 - v3
        n = np.cross(v1 - v2, e31)
        with np.errstate(divide="ignore", invalid="ignore"):
            nn = np.sqrt(_dot(n, n))
            len2 = [_dot(e, e) for e in (e12, e23, e31)]
            inv_h = [1.0 / (nn * np.sqrt(x)) for x in len2]     # in-plane distance to an edge line
            rows = [v1, v2, v3, e12, e23, e31, n, n / nn[:, None]] + [np.cross(n, e) for e in (e12, e23, e31)]
        self.table = np.concatenate([r.T for r in rows] + [np.stack(len2 + inv_h)])   # (39, F)

    #: region codes of :meth:`__call__`: the closest point is the plane projection farther than
    #: the margin inside every edge, vertex v1, v2, v3, on edge 12, 23, 31 farther than the
    #: margin from its ends, or near a boundary (a projection near an edge, an edge point near
    #: a vertex)
    PLANE, V1, V2, V3, E12, E23, E31, NEAR = range(8)

    def __call__(self, points: np.ndarray, face: np.ndarray, margin: float = 0.0, chunk: int = 131072
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(squared distance (P,), sign (P,) int8, region (P,) int8, closest point (P, 3))``
        of points (P, 3) to ``face`` (P,), ``chunk`` pairs at a time; ``region``: which feature
        holds the closest point (the class's codes; ``margin`` in m)."""
        p = np.asarray(points, dtype=np.float64)
        out = np.empty(len(p)), np.empty(len(p), np.int8), np.empty(len(p), np.int8), np.empty((len(p), 3))
        for s in range(0, len(p), chunk):
            for o, x in zip(out, self._pairs(p[s:s + chunk].T, self.table[:, face[s:s + chunk]], margin)):
                o[s:s + chunk] = x
        return out

    @staticmethod
    def _pairs(q: np.ndarray, g: np.ndarray, margin: float) -> tuple:
        v1, v2, v3, e12, e23, e31, n, un, m12, m23, m31 = (g[3 * i:3 * i + 3] for i in range(11))
        l12, l23, l31, h12, h23, h31 = g[33:39]
        d1, d2, d3 = q - v1, q - v2, q - v3
        with np.errstate(divide="ignore", invalid="ignore"):
            uab, ubc, uca = _cdot(d1, e12) / l12, _cdot(d2, e23) / l23, _cdot(d3, e31) / l31
            s12, s23, s31 = _cdot(m12, d1), _cdot(m23, d2), _cdot(m31, d3)     # > 0: inside the edge
            at1 = (uca > 1) & (uab < 0)
            at2 = ~at1 & (uab > 1) & (ubc < 0)
            at3 = ~at1 & ~at2 & (ubc > 1) & (uca < 0)
            rest = ~(at1 | at2 | at3)
            on12 = rest & (uab >= 0) & (uab <= 1) & (s12 <= 0)
            on23 = rest & ~on12 & (ubc >= 0) & (ubc <= 1) & (s23 <= 0)
            on31 = rest & ~on12 & ~on23 & (uca >= 0) & (uca <= 1) & (s31 <= 0)
            c = q - un * _cdot(d1, un)
            region = np.where(np.minimum(np.minimum(s12 * h12, s23 * h23), s31 * h31) > margin,
                              KernelFaces.PLANE, KernelFaces.NEAR).astype(np.int8)
            for code, mask, point, u, l2 in ((6, on31, v3 + e31 * uca, uca, l31), (5, on23, v2 + e23 * ubc, ubc, l23),
                                             (4, on12, v1 + e12 * uab, uab, l12)):
                c = np.where(mask, point, c)
                region[mask] = np.where(np.minimum(u, 1 - u)[mask] * np.sqrt(l2[mask]) > margin, code,
                                        KernelFaces.NEAR)
            for code, mask, point in ((3, at3, v3), (2, at2, v2), (1, at1, v1)):
                c = np.where(mask, point, c)
                region[mask] = code
            dv = q - c
        return _cdot(dv, dv), np.where(_cdot(dv, n) >= 0, 1, -1).astype(np.int8), region, c.T


def kernel_pairs(points, triangles) -> tuple[np.ndarray, np.ndarray]:
    """torchsdf's step for point i and triangle i: ``(squared distance (P,), sign (P,))`` of
    points (P, 3) and triangles (P, 3, 3) (:class:`KernelFaces`)."""
    p, t = _points(points), np.asarray(triangles, dtype=np.float64)
    sq, sign, _, _ = KernelFaces(t)(p, np.arange(len(p)))
    return sq, sign


@dataclass(frozen=True)
class ClosestFace:
    """The closest-face answer for N points: ``distance`` (N,) m (unsigned, float64), ``sign``
    (N,) int8 (+1 outside, -1 inside), ``face`` (N,) the winning face. ``signed`` = sign x
    distance; ``penetrating`` = ChainHOI's ``|p - c|^2 * sign < 0`` (float32 squares)."""

    distance: np.ndarray
    sign: np.ndarray
    face: np.ndarray

    @property
    def signed(self) -> np.ndarray:
        return self.sign * self.distance

    @property
    def penetrating(self) -> np.ndarray:
        return (self.sign < 0) & (np.square(self.distance).astype(np.float32) > 0)


def _block_first_min(sq32: np.ndarray) -> np.ndarray:
    """The kernel's winner per row of float32 squares (n, F): per block of 512 faces the first
    face, replaced by strictly smaller values (a NaN first face keeps its block); blocks merge
    the same way (.cu:188-249)."""
    rows = np.arange(len(sq32))
    best_i = best_v = None
    for s in range(0, sq32.shape[1], KERNEL_BLOCK):
        blk = sq32[:, s:s + KERNEL_BLOCK]
        filled = np.where(np.isnan(blk), np.inf, blk)
        j = filled.argmin(1)
        val = filled[rows, j]
        first_nan = np.isnan(blk[:, 0])
        j, val = np.where(first_nan, 0, j) + s, np.where(first_nan, np.nan, val)
        if best_i is None:
            best_i, best_v = j, val
        else:
            better = best_v > val                       # NaN compares False, as in the kernel
            best_i, best_v = np.where(better, j, best_i), np.where(better, val, best_v)
    return best_i


def closest_face_brute(points, vertices, faces, chunk_pairs: int = 200_000) -> ClosestFace:
    """The torchsdf closest-face rule, face by face (:class:`KernelFaces` for every point-face
    pair, float32 squares, the kernel's block order and tie rule). O(N F): 10k faces x 6,890
    points take ~15 s per frame; :class:`ClosestFaceField` answers the same faster."""
    p, (v, f) = _points(points), _mesh(vertices, faces)
    kernel = KernelFaces(v[f])
    dist, sign, face = np.empty(len(p)), np.empty(len(p), np.int8), np.empty(len(p), np.int64)
    step = max(1, chunk_pairs // len(f))
    for s in range(0, len(p), step):
        q = p[s:s + step]
        sq, sg, _, _ = kernel(np.repeat(q, len(f), axis=0), np.tile(np.arange(len(f)), len(q)))
        sq, sg = sq.reshape(len(q), len(f)), sg.reshape(len(q), len(f))
        i = _block_first_min(sq.astype(np.float32))
        r = np.arange(len(i))
        dist[s:s + step], sign[s:s + step], face[s:s + step] = np.sqrt(sq[r, i]), sg[r, i], i
    return ClosestFace(dist, sign, face)


@dataclass(frozen=True)
class Touching:
    """Faces that touch, CSR: face f's neighbours are ``nbrs[offsets[f]:offsets[f + 1]]`` (f
    not among them); ``inner`` (aligned with ``nbrs``): the pair may meet inside a face
    (coplanar, or sharing no vertex position: coincident or abutting parts), not only at
    shared vertices and edges."""

    offsets: np.ndarray
    nbrs: np.ndarray
    inner: np.ndarray


def touching_faces(vertices, faces, tol: float = 1e-6, chunk: int = 1024) -> Touching:
    """Pairs of faces that can share a closest point: a vertex of one within ``tol`` m of the
    other (shared vertices and edges, T-junctions), or coplanar within ``tol`` with
    overlapping bounding boxes (coincident parts). Candidates come from bounding boxes grown
    by ``tol``."""
    v, f = _mesh(vertices, faces)
    t = v[f]
    lo, hi = t.min(1) - tol, t.max(1) + tol
    with np.errstate(divide="ignore", invalid="ignore"):
        n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        n /= np.sqrt(_dot(n, n))[:, None]
    ii, jj = [], []
    for s in range(0, len(f), chunk):
        i, j = np.nonzero(np.all((lo[s:s + chunk, None] <= hi[None]) & (hi[s:s + chunk, None] >= lo[None]), axis=-1))
        ii.append(i[j > i + s] + s)
        jj.append(j[j > i + s])
    i, j = np.concatenate(ii), np.concatenate(jj)
    a, b = t[i], t[j]
    gap = np.full(len(i), np.inf)
    for x, y in ((a, b), (b, a)):
        for k in range(3):
            gap = np.minimum(gap, np.sqrt(np.square(x[:, k] - exact_closest_point(x[:, k], y[:, 0], y[:, 1], y[:, 2])).sum(-1)))
    coplanar = (np.abs(_dot(b - a[:, :1], n[i][:, None])).max(1) <= tol) & \
        (np.abs(_dot(a - b[:, :1], n[j][:, None])).max(1) <= tol)
    shared = (np.sqrt(np.square(a[:, :, None] - b[:, None]).sum(-1)) <= tol).any((1, 2))
    keep = (gap <= tol) | coplanar
    src, dst = np.concatenate([i[keep], j[keep]]), np.concatenate([j[keep], i[keep]])
    order = np.argsort(src, kind="stable")
    offsets = np.concatenate([[0], np.cumsum(np.bincount(src, minlength=len(f)))])
    inner = (coplanar | ~shared)[keep]
    return Touching(offsets, dst[order], np.concatenate([inner, inner])[order])


def _csr_pairs(point: np.ndarray, face: np.ndarray, offsets: np.ndarray, nbrs: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """``(point, neighbour)`` for every neighbour of ``face[i]`` (CSR), for each i."""
    deg = offsets[face + 1] - offsets[face]
    rep = np.repeat(np.arange(len(face)), deg)
    k = np.arange(len(rep)) - np.repeat(np.cumsum(deg) - deg, deg)
    return point[rep], nbrs[offsets[face[rep]] + k]


def _first_min_runs(point: np.ndarray, face: np.ndarray, key: np.ndarray) -> np.ndarray:
    """Per run of equal ``point`` (contiguous, faces distinct within a run), the position of the
    smallest ``key``, the lowest face on ties (the kernel's rule)."""
    new = np.r_[True, point[1:] != point[:-1]]
    starts, run = np.flatnonzero(new), np.cumsum(new) - 1
    low = np.minimum.reduceat(key, starts)[run]
    best = np.minimum.reduceat(np.where(key == low, face, np.iinfo(np.int64).max), starts)[run]
    return np.flatnonzero((face == best) & (key == low))


class ClosestFaceField:
    """The torchsdf closest-face rule for one mesh (as given: no repair), queried many times.

    The kernel's sign is the side of the winning face's plane: its closest point c lies in
    that plane, so ``(p - c).n = (p - v1).n``. Fast path (open3d): ``compute_closest_points``
    gives a closest face, the seed; the kernel on the seed says where c lies, and so which
    faces can tie with it (pass through c): the seed alone when c is inside it, farther than
    ``margin`` (m, times the mesh size when that exceeds 1 m) from its edges; every face at c's
    vertex position; every face holding c's edge when c is farther than the margin from its
    ends; all touching faces (:func:`touching_faces`) when c is within the margin of an edge
    or a vertex (:attr:`KernelFaces.NEAR`); plus, always, the faces that may meet the seed inside
    it (coplanar ones, other parts; :class:`Touching`). These also catch open3d's float32 choosing a neighbour of the true closest face.
    When the candidates' plane sides agree, that is the sign (distance: the seed's); else the
    kernel's winner among them decides. Not covered (the kernel's own float32 rounding decides
    them too): ties between faces whose closest points differ (measure zero, e.g. a point
    equidistant from two separate walls), near-ties below float32 resolution between faces
    that do not touch, faces sharing a vertex with the seed that also fold over its interior.
    Meshes with degenerate faces (:func:`degenerate_faces`) or ``method="brute"`` use
    :func:`closest_face_brute`.
    """

    def __init__(self, vertices, faces, method: str = "auto", margin: float = 1e-3, tol: float = 1e-6):
        if method not in ("auto", "brute"):
            raise ValueError(f"method: expected 'auto' or 'brute', got {method!r}")
        self.vertices, self.faces = v, f = _mesh(vertices, faces)
        self.brute = method == "brute" or bool(degenerate_faces(v, f).any())
        if self.brute:
            return
        import open3d as o3d
        self._scene = o3d.t.geometry.RaycastingScene()
        self._scene.add_triangles(o3d.core.Tensor(np.ascontiguousarray(v, np.float32)),
                                  o3d.core.Tensor(np.ascontiguousarray(f, np.uint32)))
        scale = max(float(np.ptp(v, axis=0).max()), 1.0)
        self.margin = margin * scale
        self.touch = t = touching_faces(v, f, tol * scale)
        self._inner = (np.r_[0, np.cumsum(t.inner)][t.offsets], t.nbrs[t.inner])   # CSR
        self.kernel = KernelFaces(v[f])
        self._lo, self._hi = v[f].min(1) - self.margin, v[f].max(1) + self.margin
        n = self.kernel.table[18:21]
        self._plane = np.vstack([n, _cdot(self.kernel.table[0:3], n)[None]])   # n, v1.n: sides
        _, pid = np.unique(v, axis=0, return_inverse=True)
        self._pos = pid.reshape(-1)[f]                                  # (F, 3) vertex positions
        order = np.argsort(self._pos.ravel(), kind="stable")            # star: faces at a position
        self._star = (np.r_[0, np.cumsum(np.bincount(self._pos.ravel()))], order // 3)

    def seeds(self, p: np.ndarray) -> np.ndarray:
        """open3d's closest face (N,) of points (N, 3)."""
        import open3d as o3d
        from .distance import _threads
        res = self._scene.compute_closest_points(o3d.core.Tensor(np.ascontiguousarray(p, np.float32)),
                                                 nthreads=_threads())
        return res["primitive_ids"].numpy().astype(np.int64)

    def _candidates(self, seed: np.ndarray, region: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(point, face)`` pairs, sorted by point and face, distinct (see the class); touching
        faces only where their bounding box, grown by the margin, holds c."""
        r, pos, K = np.arange(len(seed)), self._pos[seed], KernelFaces
        plane, near = region == K.PLANE, region == K.NEAR
        pieces = [(r[plane | near], seed[plane | near])]
        for pt, g in (_csr_pairs(r[near], seed[near], self.touch.offsets, self.touch.nbrs),
                      _csr_pairs(r[~near], seed[~near], *self._inner)):
            keep = np.all((c[pt] >= self._lo[g]) & (c[pt] <= self._hi[g]), axis=1)
            pieces.append((pt[keep], g[keep]))
        for code, k in ((K.V1, 0), (K.V2, 1), (K.V3, 2)):
            m = region == code
            pieces.append(_csr_pairs(r[m], pos[m, k], *self._star))
        for code, (i, j) in ((K.E12, (0, 1)), (K.E23, (1, 2)), (K.E31, (2, 0))):
            m = region == code
            pt, g = _csr_pairs(r[m], pos[m, i], *self._star)
            keep = (self._pos[g] == pos[pt, j][:, None]).any(1)         # faces holding the edge
            pieces.append((pt[keep], g[keep]))
        point, face = (np.concatenate(x) for x in zip(*pieces))
        key = np.sort(point * len(self.faces) + face)
        key = key[np.r_[True, key[1:] != key[:-1]]]
        return key // len(self.faces), key % len(self.faces)

    def __call__(self, points, chunk: int = 65536) -> ClosestFace:
        """:class:`ClosestFace` of points (N, 3) in the mesh's frame, ``chunk`` points at a time
        (``face``: the seed where the candidates agree, else the kernel's winner)."""
        p = _points(points)
        if self.brute or len(p) == 0:
            return closest_face_brute(p, self.vertices, self.faces)
        parts = [self._query(p[s:s + chunk]) for s in range(0, len(p), chunk)]
        return ClosestFace(*(np.concatenate(x) for x in zip(*((c.distance, c.sign, c.face) for c in parts))))

    def _query(self, p: np.ndarray) -> ClosestFace:
        face = self.seeds(p)
        sq, sign, region, c = self.kernel(p, face, self.margin)
        point, cand = self._candidates(face, region, c)
        g = self._plane[:, cand]
        q = p[point]
        side = q[:, 0] * g[0] + q[:, 1] * g[1] + q[:, 2] * g[2] >= g[3]     # (p - v1).n >= 0
        n_pos = np.bincount(point, side, len(p))
        n_all = np.bincount(point, minlength=len(p))
        sign = np.where(n_pos == n_all, 1, np.where(n_pos == 0, -1, sign)).astype(np.int8)
        split = (n_pos > 0) & (n_pos < n_all)
        redo = split[point]
        if redo.any():
            pt, cd = point[redo], cand[redo]
            sq2, sign2, _, _ = self.kernel(p[pt], cd)
            best = _first_min_runs(pt, cd, sq2.astype(np.float32))
            sq[pt[best]], sign[pt[best]], face[pt[best]] = sq2[best], sign2[best], cd[best]
        return ClosestFace(np.sqrt(sq), sign, face)


_CACHE: dict = {}


def _cached(cls, vertices, faces, arg: str):
    """One ``cls(vertices, faces, arg)`` per mesh and argument (the 8 most recent)."""
    v = np.ascontiguousarray(vertices, dtype=np.float64)
    f = np.ascontiguousarray(faces, dtype=np.int64)
    key = (cls.__name__, v.tobytes(), f.tobytes(), arg)
    field = _CACHE.pop(key, None) or cls(v, f, arg)
    _CACHE[key] = field
    while len(_CACHE) > 8:
        _CACHE.pop(next(iter(_CACHE)))
    return field


def closest_face_field(vertices, faces, method: str = "auto") -> ClosestFaceField:
    """A cached :class:`ClosestFaceField`."""
    return _cached(ClosestFaceField, vertices, faces, method)


# ============================================================== compute.py (contact distance)
def contact_pairs(p: np.ndarray, v0: np.ndarray, v1: np.ndarray, v2: np.ndarray,
                  variant: ContactVariant) -> tuple[np.ndarray, np.ndarray]:
    """compute.py's per-face values for broadcast point/face pairs: ``(edge, plane)`` with
    ``edge = min_k |p - (b_k + clamp(t_k) e_k)| * sign(d_plane + sign_eps)`` (see the module)
    and ``plane = d_plane`` where the projection is inside the triangle, else ``inf``."""
    edges = (v1 - v0, v2 - v0, v2 - v1)
    starts = (v0, v1 if variant.quirk else v0, v1)
    bases = (v0, v0, v1)
    with np.errstate(divide="ignore", invalid="ignore"):
        n = np.cross(v1 - v0, v2 - v0)
        n = n / (np.sqrt(_dot(n, n)) + variant.normal_eps)[..., None]
        plane = _dot(p - v0, n)
        proj = p - plane[..., None] * n
        e = None
        for edge, start, base in zip(edges, starts, bases):
            den = _dot(edge, edge)
            if variant.edge_eps is not None:
                den = np.where(den == 0, variant.edge_eps, den)
            t = np.clip(_dot(p - start, edge) / den, 0, 1)
            dk = np.sqrt(_dot(p - (t[..., None] * edge + base), p - (t[..., None] * edge + base)))
            e = dk if e is None else np.minimum(e, dk)         # NaN propagates, as torch.min
        a, b, c = v1 - v0, v2 - v0, proj - v0                  # barycentric, compute.py:450-463
        d00, d01, d11, d20, d21 = _dot(a, a), _dot(a, b), _dot(b, b), _dot(c, a), _dot(c, b)
        den = d00 * d11 - d01 * d01
        bv, bw = (d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den
        inside = (1 - bv - bw >= 0) & (bv >= 0) & (bw >= 0)
        return e * np.sign(plane + variant.sign_eps), np.where(inside, plane, np.inf)


def contact_distance_brute(points, vertices, faces, variant: str = "reference",
                           chunk_pairs: int = 200_000) -> np.ndarray:
    """compute.py's signed point-to-mesh distance (N,) of points (N, 3), m, as the reference
    returns it: over faces the smallest ``|edge|`` and the smallest ``|plane|`` (first face on
    ties, NaN first as ``argmin``), then the smaller of the two (edge on ties)."""
    var = CONTACT_VARIANTS[variant]
    p, (v, f) = _points(points), _mesh(vertices, faces)
    t = v[f]
    out = np.empty(len(p))
    step = max(1, chunk_pairs // len(f))
    for s in range(0, len(p), step):
        edge, plane = contact_pairs(p[s:s + step, None, :], t[None, :, 0], t[None, :, 1], t[None, :, 2], var)
        r = np.arange(edge.shape[0])
        d1, d2 = edge[r, np.abs(edge).argmin(1)], plane[r, np.abs(plane).argmin(1)]
        out[s:s + step] = np.where(np.abs(d2) < np.abs(d1), d2, d1)
    return out


class ContactDistanceField:
    """The magnitude of :func:`contact_distance_brute` for one mesh, fast (CD needs only
    ``d^2``).

    Every face's value is the distance to a point of the face (up to the ``normal_eps``
    shrink of plane distances), so it is at least ``(|p - m_f| - r_f) |n_f| / (|n_f| + eps)``
    with ``m_f``, ``r_f`` the face's centroid and radius. An upper bound (the value of
    open3d's closest face and its touching faces) then limits the faces to evaluate, found
    with a k-d tree of centroids: the result equals the brute force's magnitude. Meshes with
    degenerate faces use the brute force.
    """

    def __init__(self, vertices, faces, variant: str = "reference"):
        if variant not in CONTACT_VARIANTS:
            raise ValueError(f"variant: expected one of {sorted(CONTACT_VARIANTS)}, got {variant!r}")
        self.variant = CONTACT_VARIANTS[variant]
        self.vertices, self.faces = _mesh(vertices, faces)
        self._tri = self.vertices[self.faces]
        self.brute = bool(degenerate_faces(self.vertices, self.faces).any())
        if not self.brute:
            from scipy.spatial import cKDTree
            self._cf = closest_face_field(self.vertices, self.faces)
            self._centre = self._tri.mean(1)
            self._radius = np.sqrt(np.square(self._tri - self._centre[:, None]).sum(-1)).max(1)
            nn = np.sqrt(np.square(np.cross(self._tri[:, 1] - self._tri[:, 0], self._tri[:, 2] - self._tri[:, 0])).sum(-1))
            self._shrink = nn / (nn + self.variant.normal_eps)
            self._tree = cKDTree(self._centre)

    def _values(self, p: np.ndarray, point: np.ndarray, face: np.ndarray) -> np.ndarray:
        t = self._tri[face]
        edge, plane = contact_pairs(p[point], t[:, 0], t[:, 1], t[:, 2], self.variant)
        return np.minimum(np.abs(edge), np.abs(plane))

    def __call__(self, points) -> np.ndarray:
        """Unsigned reference distances (N,) of points (N, 3) in the mesh's frame, m."""
        p = _points(points)
        if self.brute or len(p) == 0:
            return np.abs(contact_distance_brute(p, self.vertices, self.faces, self.variant.name))
        cf = self._cf
        seed = cf.seeds(p)
        point, face = (np.concatenate(x) for x in zip(
            (np.arange(len(p)), seed), _csr_pairs(np.arange(len(p)), seed, cf.touch.offsets, cf.touch.nbrs)))
        upper = np.full(len(p), np.inf)
        np.minimum.at(upper, point, self._values(p, point, face))
        lists = self._tree.query_ball_point(p, upper * (1 + 1e-9) + 1e-9 + self._radius.max())
        counts = np.fromiter((len(x) for x in lists), np.int64, len(lists))
        point = np.repeat(np.arange(len(p)), counts)
        face = np.fromiter((j for x in lists for j in x), np.int64, int(counts.sum()))
        lower = (np.sqrt(np.square(p[point] - self._centre[face]).sum(-1)) - self._radius[face]) * self._shrink[face]
        keep = lower <= upper[point] * (1 + 1e-9) + 1e-9
        point, face = point[keep], face[keep]
        out = upper.copy()
        np.minimum.at(out, point, self._values(p, point, face))
        return out


def contact_distance_field(vertices, faces, variant: str = "reference") -> ContactDistanceField:
    """A cached :class:`ContactDistanceField`."""
    return _cached(ContactDistanceField, vertices, faces, variant)


__all__ = ["SOURCE", "KERNEL_BLOCK", "ContactVariant", "CONTACT_VARIANTS", "degenerate_faces",
           "exact_closest_point", "exact_triangle_distance", "KernelFaces", "kernel_pairs", "ClosestFace",
           "closest_face_brute", "Touching", "touching_faces", "ClosestFaceField", "closest_face_field",
           "contact_pairs", "contact_distance_brute", "ContactDistanceField", "contact_distance_field"]
