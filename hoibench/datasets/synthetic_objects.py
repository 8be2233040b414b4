"""``synthetic_objects``: the primitive-built objects of the synthetic HOI dataset.

Boxes, cylinders and spheres (exact signed distances, tessellated meshes), the objects of
:data:`~hoibench.datasets.synthetic_constants.OBJECTS` built from them with their grips and
seats (:class:`ObjectModel`, :func:`build_object`), and the binary PLY writer of their
templates (:func:`ply_bytes`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from .synthetic_constants import OBJECTS


# =========================================================================== objects
@dataclass(frozen=True)
class _Box:
    center: tuple
    half: tuple

    def sdf(self, p: np.ndarray) -> np.ndarray:
        q = np.abs(p - np.asarray(self.center)) - np.asarray(self.half)
        return np.linalg.norm(np.maximum(q, 0.0), axis=-1) + np.minimum(q.max(-1), 0.0)

    def mesh(self) -> tuple[np.ndarray, np.ndarray]:
        c, h = np.asarray(self.center), np.asarray(self.half)
        corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
        faces = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                          [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
        return c + corners * h, faces

    def shifted(self, d):
        return _Box(tuple(np.asarray(self.center) - d), self.half)


@dataclass(frozen=True)
class _Cylinder:
    center: tuple
    axis: int          # 0 x, 1 y, 2 z
    radius: float
    half_length: float
    segments: int = 48

    def sdf(self, p: np.ndarray) -> np.ndarray:
        q = p - np.asarray(self.center)
        a = q[..., self.axis]
        other = [i for i in range(3) if i != self.axis]
        r = np.linalg.norm(q[..., other], axis=-1)
        d = np.stack([r - self.radius, np.abs(a) - self.half_length], -1)
        return np.minimum(d.max(-1), 0.0) + np.linalg.norm(np.maximum(d, 0.0), axis=-1)

    def mesh(self) -> tuple[np.ndarray, np.ndarray]:
        n = self.segments
        ang = 2 * np.pi * np.arange(n) / n
        # local frame: axis along +e2 of (e0, e1, e2) = cyclic permutation keeping handedness
        e2 = self.axis
        e0, e1 = (e2 + 1) % 3, (e2 + 2) % 3
        ring = np.zeros((n, 3))
        ring[:, e0] = self.radius * np.cos(ang)
        ring[:, e1] = self.radius * np.sin(ang)
        lo, hi = ring.copy(), ring.copy()
        lo[:, e2], hi[:, e2] = -self.half_length, self.half_length
        cap_lo, cap_hi = np.zeros(3), np.zeros(3)
        cap_lo[e2], cap_hi[e2] = -self.half_length, self.half_length
        v = np.concatenate([lo, hi, cap_lo[None], cap_hi[None]]) + np.asarray(self.center)
        i = np.arange(n)
        j = (i + 1) % n
        side = np.concatenate([np.stack([i, j, n + j], 1), np.stack([i, n + j, n + i], 1)])
        bottom = np.stack([np.full(n, 2 * n), j, i], 1)
        top = np.stack([np.full(n, 2 * n + 1), n + i, n + j], 1)
        return v, np.concatenate([side, bottom, top])

    def shifted(self, d):
        return _Cylinder(tuple(np.asarray(self.center) - d), self.axis, self.radius,
                         self.half_length, self.segments)


@dataclass(frozen=True)
class _Sphere:
    center: tuple
    radius: float
    n_lon: int = 48
    n_lat: int = 24

    def sdf(self, p: np.ndarray) -> np.ndarray:
        return np.linalg.norm(p - np.asarray(self.center), axis=-1) - self.radius

    def mesh(self) -> tuple[np.ndarray, np.ndarray]:
        nl, nb = self.n_lon, self.n_lat
        theta = np.pi * np.arange(1, nb) / nb                       # polar angle from +y
        phi = 2 * np.pi * np.arange(nl) / nl
        st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
        ring = np.stack([st * np.sin(phi), np.broadcast_to(ct, (nb - 1, nl)), st * np.cos(phi)], -1)
        v = np.concatenate([[[0, 1, 0]], ring.reshape(-1, 3), [[0, -1, 0]]]) * self.radius
        v = v + np.asarray(self.center)
        top, bot = 0, 1 + (nb - 1) * nl
        idx = lambda r, k: 1 + r * nl + (k % nl)  # noqa: E731
        f = []
        for k in range(nl):
            f.append([top, idx(0, k), idx(0, k + 1)])
            f.append([bot, idx(nb - 2, k + 1), idx(nb - 2, k)])
        for r in range(nb - 2):
            for k in range(nl):
                a, b, c, d = idx(r, k), idx(r, k + 1), idx(r + 1, k), idx(r + 1, k + 1)
                f.append([a, c, d])
                f.append([a, d, b])
        return v, np.array(f)

    def shifted(self, d):
        return _Sphere(tuple(np.asarray(self.center) - d), self.radius, self.n_lon, self.n_lat)


@dataclass
class ObjectModel:
    """A primitive-built object in its *centred* local frame (template vertex mean at 0).

    ``vertices`` (V, 3) float64 (exactly float32-representable, as written to the PLY),
    ``faces`` (F, 3) int32; posed vertices ``v = R v_template + t``. Local axes: x to the
    person's left, y up, z away from the person (the person stands on the -z side).
    ``grips[purpose][hands][hand] = (point, outward normal)`` on the surface;
    ``seat = (top y, x, z)`` of a sittable surface; all local, metres.
    """
    name: str
    primitives: tuple
    vertices: np.ndarray
    faces: np.ndarray
    grips: dict
    seat: tuple | None = None
    kind: str = "rigid"

    def sdf_local(self, p: np.ndarray) -> np.ndarray:
        """Signed distance (m) of local points (..., 3): the minimum over the primitives'
        exact signed distances (exact outside the union; negative inside)."""
        p = np.asarray(p, dtype=np.float64)
        return np.min(np.stack([prim.sdf(p) for prim in self.primitives]), axis=0)

    def sdf(self, points: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Signed distance of world points (T, N, 3) to the object posed by ``R`` (T,3,3),
        ``t`` (T,3): evaluated at ``R^T (p - t)``."""
        local = np.einsum("tnj,tjk->tnk", np.asarray(points) - t[:, None], R)
        return self.sdf_local(local)

    @property
    def size(self) -> np.ndarray:
        """Bounding-box extents (x, y, z), metres."""
        return self.vertices.max(0) - self.vertices.min(0)


def _object_spec(name: str):
    """Canonical primitives (base on y = 0, centred in x/z), grips and seat."""
    X, Y, nZ = (1.0, 0, 0), (0, 1.0, 0), (0, 0, -1.0)

    def pair(p, n, mirror_normal=True):
        (x, y, z), m = p, n
        mn = (-m[0], m[1], m[2]) if mirror_normal else m
        return {"left": ((x, y, z), m), "right": ((-x, y, z), mn)}

    def single(p, n):
        (x, y, z) = p
        return {"left": ((x, y, z), n), "right": ((-x, y, z), n)}

    def one_hand(both, single_grips):
        return {"both": both, "left": {"left": single_grips["left"]},
                "right": {"right": single_grips["right"]}}

    grips: dict = {}
    seat = None
    if name == "boxsmall":
        W, H, D = 0.38, 0.28, 0.30
        prims = [_Box((0, H / 2, 0), (W / 2, H / 2, D / 2))]
        grips["lift"] = {"both": pair((W / 2, H - 0.06, -D / 2 + 0.10), X)}
    elif name == "boxlarge":
        W, H, D = 0.56, 0.42, 0.44
        prims = [_Box((0, H / 2, 0), (W / 2, H / 2, D / 2))]
        grips["lift"] = {"both": pair((W / 2, H - 0.07, -D / 2 + 0.10), X)}
        grips["push"] = one_hand(pair((0.16, H - 0.07, -D / 2), nZ, False),
                                 single((0.07, H - 0.07, -D / 2), nZ))
        grips["pull"] = one_hand(pair((0.16, H, -D / 2 + 0.06), Y, False),
                                 single((0.07, H, -D / 2 + 0.06), Y))
        seat = (H, 0.0, 0.0)
    elif name == "chairwood":
        prims = [_Box((0, 0.445, 0), (0.22, 0.015, 0.21))]                        # seat
        prims += [_Box((sx * 0.1925, 0.215, 0.1925), (0.0175, 0.215, 0.0175)) for sx in (1, -1)]
        prims += [_Box((sx * 0.1925, 0.44, -0.1925), (0.0175, 0.44, 0.0175)) for sx in (1, -1)]
        prims += [_Box((0, 0.80, -0.1925), (0.175, 0.06, 0.0125)),                  # top rail
                  _Box((0, 0.60, -0.1925), (0.175, 0.03, 0.0100))]                  # slat
        rail = single((0.04, 0.86, -0.1925), Y)
        grips["lift"] = one_hand(pair((0.10, 0.86, -0.1925), Y, False), rail)
        grips["pull"] = grips["lift"]
        grips["push"] = one_hand(pair((0.10, 0.80, -0.205), nZ, False),
                                 single((0.05, 0.80, -0.205), nZ))
        seat = (0.46, 0.0, 0.0)
    elif name == "tablesmall":
        prims = [_Box((0, 0.535, 0), (0.30, 0.015, 0.25))]
        prims += [_Box((sx * 0.26, 0.26, sz * 0.21), (0.02, 0.26, 0.02))
                  for sx in (1, -1) for sz in (1, -1)]
        grips["lift"] = {"both": pair((0.30, 0.535, -0.12), X)}
        grips["push"] = one_hand(pair((0.15, 0.535, -0.25), nZ, False),
                                 single((0.06, 0.535, -0.25), nZ))
        grips["pull"] = one_hand(pair((0.15, 0.55, -0.19), Y, False),
                                 single((0.06, 0.55, -0.19), Y))
    elif name == "stool":
        prims = [_Cylinder((0, 0.44, 0), 1, 0.17, 0.02)]
        prims += [_Cylinder(c, 1, 0.016, 0.21, 16) for c in
                  ((0.11, 0.21, 0), (-0.11, 0.21, 0), (0, 0.21, 0.11), (0, 0.21, -0.11))]
        grips["lift"] = {"both": pair((0.17, 0.44, 0.0), X)}
        ph = math.radians(40.0)
        grips["push"] = {"both": pair((0.17 * math.sin(ph), 0.44, -0.17 * math.cos(ph)),
                                      (math.sin(ph), 0.0, -math.cos(ph)))}
        grips["pull"] = {"both": pair((0.07, 0.46, -0.10), Y, False)}
        seat = (0.46, 0.0, 0.0)
    elif name == "yogaball":
        r = 0.30
        prims = [_Sphere((0, r, 0), r)]
        th = math.radians(35.0)
        grips["lift"] = {"both": pair((r * math.cos(th), r, -r * math.sin(th)),
                                      (math.cos(th), 0.0, -math.sin(th)))}
        seat = (2 * r, 0.0, 0.0)
    elif name == "yogamat":
        r = 0.075
        prims = [_Cylinder((0, r, 0), 0, r, 0.31)]
        grips["lift"] = one_hand(pair((0.20, 2 * r, 0.0), Y, False), single((0.0, 2 * r, 0.0), Y))
    elif name == "backpack":
        prims = [_Box((0, 0.20, 0), (0.15, 0.20, 0.08)),
                 _Box((0, 0.14, 0.095), (0.12, 0.09, 0.015)),     # front pocket (away side)
                 _Box((0, 0.415, 0), (0.05, 0.015, 0.012))]       # top handle
        grips["lift"] = one_hand(pair((0.15, 0.28, 0.0), X), single((0.0, 0.43, 0.0), Y))
    else:
        raise ValueError(f"object: expected one of {OBJECTS}, got {name!r}")
    return prims, grips, seat


@lru_cache(maxsize=None)
def build_object(name: str) -> ObjectModel:
    """The object ``name`` (one of :data:`OBJECTS`) centred on its template vertex mean."""
    prims, grips, seat = _object_spec(name)
    vs, fs, n = [], [], 0
    for p in prims:
        v, f = p.mesh()
        vs.append(v)
        fs.append(f + n)
        n += len(v)
    v = np.concatenate(vs)
    mean = v.mean(0)
    verts = (v - mean).astype(np.float32).astype(np.float64)
    prims = tuple(p.shifted(mean) for p in prims)
    shift = lambda p: tuple(float(x) for x in np.asarray(p) - mean)  # noqa: E731
    g = {purpose: {hands: {h: (np.asarray(shift(p)), np.asarray(nv, float) / np.linalg.norm(nv))
                           for h, (p, nv) in d.items()} for hands, d in by.items()}
         for purpose, by in grips.items()}
    seat_local = None if seat is None else (seat[0] - mean[1], seat[1] - mean[0], seat[2] - mean[2])
    return ObjectModel(name, prims, verts, np.concatenate(fs).astype(np.int32), g, seat_local,
                       "ball" if name == "yogaball" else "rigid")


def ply_bytes(vertices: np.ndarray, faces: np.ndarray, comment: str = "") -> bytes:
    """Binary little-endian PLY: float32 x, y, z; faces as ``uchar`` count + ``int`` ids."""
    v = np.ascontiguousarray(vertices, dtype="<f4")
    f = np.asarray(faces)
    head = ["ply", "format binary_little_endian 1.0"]
    if comment:
        head.append(f"comment {comment}")
    head += [f"element vertex {len(v)}", "property float x", "property float y",
             "property float z", f"element face {len(f)}",
             "property list uchar int vertex_indices", "end_header"]
    rec = np.zeros(len(f), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    rec["n"] = 3
    rec["i"] = f
    return ("\n".join(head) + "\n").encode("ascii") + v.tobytes() + rec.tobytes()
