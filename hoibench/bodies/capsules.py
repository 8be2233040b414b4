"""Body surfaces the multi-body metrics measure: skeletons as capsules around their bones,
objects as their template meshes.

Generators output joints, not meshes, so one surface model is applied to generated and
ground-truth skeletons alike: every bone is a capsule (a segment with a radius) between a
joint and its child (:func:`bones`). Hands use the proxy MANO hand's finger radii (9 mm,
palm 12 mm); humans the proxy body's proportions, with a 9 cm "hand" capsule extending each
wrist along its forearm (SMPL's 22 joints stop at the wrist). The model is hoibench's
choice, documented in docs/multibody.md; numbers are comparable between submissions scored
the same way, not with a paper's MANO/SMPL-X meshes.

Distances to objects are signed distances to the object's closed template mesh (open3d
``RaycastingScene``; query points are moved into the object's frame, so one scene per
template serves every frame): a capsule ``(a, b, r)`` is at distance ``min_p sd(p) - r``
over points ``p`` sampled on its axis (negative: it penetrates).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from .multibody import Body, MultiBodyClip

__all__ = ["bones", "axis_points", "ObjectField", "object_fields", "skeleton_object_distance", "capsule_depth_into",
           "capsule_grid_mask", "pair_contact_frames", "pair_penetration", "HAND_RADIUS_M", "AXIS_SAMPLES"]

HAND_RADIUS_M = 0.009
PALM_RADIUS_M = 0.012
AXIS_SAMPLES = 5
#: length of the virtual hand capsule past a human wrist, metres, and its radius
HUMAN_HAND_LENGTH_M, HUMAN_HAND_RADIUS_M = 0.09, 0.03

# hand: 0 wrist, 1-3 index, 4-6 middle, 7-9 pinky, 10-12 ring, 13-15 thumb, 16-20 tips
# (thumb, index, middle, ring, pinky)
_HAND_BONES = ([(0, 1, PALM_RADIUS_M), (0, 4, PALM_RADIUS_M), (0, 7, PALM_RADIUS_M), (0, 10, PALM_RADIUS_M),
                (0, 13, 0.011)]
               + [(a, b, HAND_RADIUS_M) for a, b in ((1, 2), (2, 3), (3, 17), (4, 5), (5, 6), (6, 18), (7, 8), (8, 9),
                                                     (9, 20), (10, 11), (11, 12), (12, 19), (13, 14), (14, 15),
                                                     (15, 16))])
# human: SMPL's 22 joints; (parent, child, radius); 22/23 are the virtual hand points
_HUMAN_BONES = [(0, 1, 0.07), (0, 2, 0.07), (0, 3, 0.09), (1, 4, 0.065), (2, 5, 0.065), (3, 6, 0.09), (4, 7, 0.05),
                (5, 8, 0.05), (6, 9, 0.1), (7, 10, 0.04), (8, 11, 0.04), (9, 12, 0.06), (9, 13, 0.05), (9, 14, 0.05),
                (12, 15, 0.09), (13, 16, 0.045), (14, 17, 0.045), (16, 18, 0.04), (17, 19, 0.04), (18, 20, 0.033),
                (19, 21, 0.033), (20, 22, HUMAN_HAND_RADIUS_M), (21, 23, HUMAN_HAND_RADIUS_M)]


def bones(kind: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(parents, children, radii) of a skeleton kind's capsules."""
    table = {"hand": _HAND_BONES, "human": _HUMAN_BONES}.get(kind)
    if table is None:
        raise ValueError(f"bones: kind {kind!r} has no skeleton (expected 'hand' or 'human')")
    a = np.array([t[0] for t in table])
    b = np.array([t[1] for t in table])
    return a, b, np.array([t[2] for t in table], dtype=np.float64)


def _extended(joints: np.ndarray, kind: str) -> np.ndarray:
    """(T, J', 3): the joints plus a human's virtual hand points (wrist + 9 cm along the
    forearm)."""
    J = np.asarray(joints, np.float64)
    if kind != "human":
        return J
    ext = []
    for elbow, wrist in ((18, 20), (19, 21)):
        d = J[:, wrist] - J[:, elbow]
        d /= np.maximum(np.linalg.norm(d, axis=-1, keepdims=True), 1e-9)
        ext.append(J[:, wrist] + HUMAN_HAND_LENGTH_M * d)
    return np.concatenate([J, np.stack(ext, 1)], 1)


def segments(joints, kind: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Capsule axes ``(a (T, S, 3), b (T, S, 3), radii (S,))`` of a skeleton's frames."""
    J = _extended(joints, kind)
    pa, pb, r = bones(kind)
    return J[:, pa], J[:, pb], r


def axis_points(joints, kind: str, samples: int = AXIS_SAMPLES) -> tuple[np.ndarray, np.ndarray]:
    """(T, S * samples, 3) points along every capsule axis (ends included) and their radii."""
    a, b, r = segments(joints, kind)
    s = np.linspace(0.0, 1.0, samples)
    p = a[:, :, None] + (b - a)[:, :, None] * s[None, None, :, None]
    return p.reshape(len(p), -1, 3), np.repeat(r, samples)


def hand_root_points(body: Body) -> np.ndarray:
    """(T, 2, 3): a human's hand capsules' far ends (left, right), or a hand's wrist twice."""
    if body.kind == "human":
        J = _extended(body.joints, "human")
        return J[:, [22, 23]]
    return np.repeat(np.asarray(body.joints, np.float64)[:, :1], 2, 1)


class ObjectField:
    """Signed distance (metres, positive outside) to one closed template mesh, queried in
    the world through the object's per-frame pose."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray):
        self.vertices = np.asarray(vertices, np.float64)
        self.faces = np.asarray(faces, np.int64)
        self._scene = _scene(self.vertices.tobytes(), self.faces.tobytes(), self.vertices.shape, self.faces.shape)
        self.probes = np.concatenate([self.vertices, surface_samples(self.vertices, self.faces)])


    def signed(self, points: np.ndarray, rot: np.ndarray, trans: np.ndarray) -> np.ndarray:
        """``points`` (T, P, 3) world -> (T, P) signed distance to the posed mesh."""
        import open3d as o3d
        local = np.einsum("tji,tpj->tpi", np.asarray(rot, np.float64), points - np.asarray(trans, np.float64)[:, None])
        flat = o3d.core.Tensor(local.reshape(-1, 3).astype(np.float32))
        d = self._scene.compute_signed_distance(flat, nsamples=3).numpy().astype(np.float64)
        return d.reshape(local.shape[:2])

    def inside(self, points: np.ndarray, rot: np.ndarray, trans: np.ndarray) -> np.ndarray:
        """``points`` (T, P, 3) world -> (T, P) bool inside the posed closed mesh (ray-parity
        occupancy, majority of 3 rays)."""
        import open3d as o3d
        local = np.einsum("tji,tpj->tpi", np.asarray(rot, np.float64), points - np.asarray(trans, np.float64)[:, None])
        flat = o3d.core.Tensor(local.reshape(-1, 3).astype(np.float32))
        occ = self._scene.compute_occupancy(flat, nsamples=3).numpy()
        return occ.reshape(local.shape[:2]) > 0.5


#: surface points per template used, with its vertices, to probe how deep it penetrates
PROBE_SAMPLES = 512


def surface_samples(vertices: np.ndarray, faces: np.ndarray, n: int = PROBE_SAMPLES, seed: int = 0) -> np.ndarray:
    """(n, 3) points on a mesh's surface, area-weighted, from a seeded generator (the same
    mesh gives the same points everywhere)."""
    tri = np.asarray(vertices, np.float64)[np.asarray(faces)]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=-1)
    rng = np.random.default_rng(seed)
    cdf = np.cumsum(area) / area.sum()
    f = np.minimum(np.searchsorted(cdf, rng.random(n)), len(tri) - 1)
    u, v = rng.random(n), rng.random(n)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    t = tri[f]
    return t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + v[:, None] * (t[:, 2] - t[:, 0])


@lru_cache(maxsize=64)
def _scene(vb: bytes, fb: bytes, vshape: tuple, fshape: tuple):
    import open3d as o3d
    scene = o3d.t.geometry.RaycastingScene()
    mesh = o3d.t.geometry.TriangleMesh()
    mesh.vertex.positions = o3d.core.Tensor(np.frombuffer(vb, np.float64).reshape(vshape).astype(np.float32))
    mesh.triangle.indices = o3d.core.Tensor(np.frombuffer(fb, np.int64).reshape(fshape).astype(np.int32))
    scene.add_triangles(mesh)
    return scene


def object_fields(clip: MultiBodyClip) -> dict[str, ObjectField]:
    """One :class:`ObjectField` per template of ``clip``."""
    return {name: ObjectField(*clip.templates[name]) for name in clip.templates}


def skeleton_object_distance(body: Body, field: ObjectField, obj: Body) -> np.ndarray:
    """(T,) signed distance between a skeleton's capsule surface and an object: the
    smallest ``sd(axis point) - radius`` (negative when a capsule penetrates)."""
    pts, r = axis_points(body.joints, body.kind)
    return (field.signed(pts, obj.rot, obj.trans) - r[None]).min(1)


def pair_contact_frames(clip: MultiBodyClip, fields: dict[str, ObjectField], csr_threshold_m: float,
                        crr_threshold_m: float) -> dict[tuple[str, str], np.ndarray]:
    """Per (skeleton, object) pair, the frames in contact by SyncDiff's rules on these
    surfaces: a hand's capsule surface within ``csr_threshold_m`` of the object (CSR), both
    hand roots of a human (the ends of its hand capsules) within ``crr_threshold_m`` of it
    (CRR)."""
    out = {}
    for b in clip.bodies:
        if b.is_rigid:
            continue
        for o in clip.of_kind("object"):
            fld = fields[o.template]
            if b.kind == "hand":
                out[(b.name, o.name)] = skeleton_object_distance(b, fld, o) <= csr_threshold_m
            else:
                d = fld.signed(hand_root_points(b), o.rot, o.trans) - HUMAN_HAND_RADIUS_M
                out[(b.name, o.name)] = (d <= crr_threshold_m).all(1)
    return out


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from points ``p`` (N, 3) to segments ``a``-``b`` (S, 3): (N, S)."""
    ab = b - a
    denom = np.maximum((ab * ab).sum(-1), 1e-18)
    t = np.clip(np.einsum("nsk,sk->ns", p[:, None] - a[None], ab) / denom, 0.0, 1.0)
    closest = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(p[:, None] - closest, axis=-1)


def capsule_depth_into(points: np.ndarray, pr: np.ndarray, a: np.ndarray, b: np.ndarray, r: np.ndarray) -> float:
    """Deepest overlap (metres) of spheres ``(points, pr)`` with capsules ``(a, b, r)``:
    ``max(pr + r - distance)`` clipped at 0 (one frame)."""
    d = _segment_distance(points, a, b)
    return float(max(0.0, (pr[:, None] + r[None] - d).max()))


def _bbox(points: np.ndarray, pad: float) -> tuple[np.ndarray, np.ndarray]:
    return points.min(0) - pad, points.max(0) + pad


def _grid(lo: np.ndarray, hi: np.ndarray, voxel: float) -> np.ndarray:
    axes = [np.arange(lo[k] + voxel / 2, hi[k], voxel) for k in range(3)]
    if any(len(x) == 0 for x in axes):
        return np.zeros((0, 3))
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)


def capsule_grid_mask(lo: np.ndarray, hi: np.ndarray, voxel: float, a: np.ndarray, b: np.ndarray,
                      r: np.ndarray) -> np.ndarray:
    """Flat bool mask over :func:`_grid` ``(lo, hi, voxel)``: voxel centres inside any capsule.
    Each capsule is tested only on the block of voxels its bounding box covers."""
    axes = [np.arange(lo[k] + voxel / 2, hi[k], voxel) for k in range(3)]
    shape = tuple(len(x) for x in axes)
    mask = np.zeros(shape, bool)
    if 0 in shape:
        return mask.reshape(-1)
    for s in range(len(r)):
        blo = np.minimum(a[s], b[s]) - r[s]
        bhi = np.maximum(a[s], b[s]) + r[s]
        idx = [(np.searchsorted(x, blo[k]), np.searchsorted(x, bhi[k], side="right")) for k, x in enumerate(axes)]
        if any(i0 >= i1 for i0, i1 in idx):
            continue
        sub = np.stack(np.meshgrid(*(axes[k][i0:i1] for k, (i0, i1) in enumerate(idx)), indexing="ij"), -1)
        d = _segment_distance(sub.reshape(-1, 3), a[s:s + 1], b[s:s + 1])[:, 0].reshape(sub.shape[:3])
        view = mask[idx[0][0]:idx[0][1], idx[1][0]:idx[1][1], idx[2][0]:idx[2][1]]
        view |= d < r[s]
    return mask.reshape(-1)


def pair_penetration(clip: MultiBodyClip, i: int, j: int, fields: dict[str, ObjectField],
                     voxel_m: float = 0.005, frames: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Interpenetration volume (m^3) and depth (m) per frame between bodies ``i`` and ``j``:
    the deepest point of one inside the other (probes: capsule axis points with their radii,
    object vertices plus :data:`PROBE_SAMPLES` surface samples), and, when that depth is
    positive, the voxel centres (``voxel_m``) of the overlap of their bounding boxes inside
    both (capsules analytically, objects by their mesh's signed distance)."""
    A, B = clip.bodies[i], clip.bodies[j]
    T = clip.num_frames
    frames = np.arange(T) if frames is None else np.asarray(frames)
    vol, dep = np.zeros(len(frames)), np.zeros(len(frames))
    geo = {}
    for key, body in (("A", A), ("B", B)):
        if body.is_rigid:
            v = fields[body.template].probes          # vertices + surface samples
            geo[key] = ("object", np.einsum("tij,vj->tvi", body.rot, v) + body.trans[:, None], fields[body.template])
        else:
            a, b, r = segments(body.joints, body.kind)
            geo[key] = ("skeleton", (a, b, r), axis_points(body.joints, body.kind))
    for n, t in enumerate(frames):
        # depth first: each side's probe points (capsule axis points with their radii, object
        # vertices) against the other side's shape; no probe inside means no volume either
        depth = 0.0
        for (kp, bp), (kq, bq) in ((("A", A), ("B", B)), (("B", B), ("A", A))):
            kind_p, g_p, extra_p = geo[kp]
            kind_q, g_q, extra_q = geo[kq]
            if kind_p == "skeleton":
                pts, pr = extra_p[0][t], extra_p[1]
            else:
                pts, pr = g_p[t], np.zeros(len(g_p[t]))
            if kind_q == "object":
                sd = extra_q.signed(pts[None], bq.rot[t:t + 1], bq.trans[t:t + 1])[0]
                depth = max(depth, float(max(0.0, (pr - sd).max())))
            else:
                a, b, r = g_q
                depth = max(depth, capsule_depth_into(pts, pr, a[t], b[t], r))
        dep[n] = depth
        if depth <= 0.0:
            continue
        boxes = []
        for key in ("A", "B"):
            kind, g, extra = geo[key]
            if kind == "object":
                boxes.append(_bbox(g[t], 0.0))
            else:
                a, b, r = g
                boxes.append(_bbox(np.concatenate([a[t], b[t]]), float(r.max())))
        lo = np.maximum(boxes[0][0], boxes[1][0])
        hi = np.minimum(boxes[0][1], boxes[1][1])
        if np.any(hi <= lo):
            continue
        order = sorted((("A", geo["A"], A), ("B", geo["B"], B)), key=lambda kb: kb[1][0] == "object")  # capsules first
        if _voxel_count(lo, hi, voxel_m) <= GRID_BLOCK_VOXELS:
            vol[n] = _inside_both(lo, hi, voxel_m, order, t) * voxel_m ** 3
        else:
            vol[n] = _inside_both_by_parts(lo, hi, voxel_m, order, t) * voxel_m ** 3
    return vol, dep


#: voxels of one block of the overlap grid: a larger overlap -- far-flung generated bodies --
#: is counted part pair by part pair, in blocks of at most this many voxels
GRID_BLOCK_VOXELS = 2_000_000


def _voxel_count(lo: np.ndarray, hi: np.ndarray, voxel: float) -> int:
    n = [len(np.arange(lo[k] + voxel / 2, hi[k], voxel)) for k in range(3)]
    return n[0] * n[1] * n[2]


def _parts(geometry, t: int) -> list[tuple[np.ndarray, np.ndarray, int]]:
    """(box lo, box hi, capsule index or -1 for the object) of a body's parts at frame ``t``."""
    kind, g, _ = geometry
    if kind == "object":
        return [(g[t].min(0), g[t].max(0), -1)]
    a, b, r = g
    lo = np.minimum(a[t], b[t]) - r[:, None]
    hi = np.maximum(a[t], b[t]) + r[:, None]
    return [(lo[s], hi[s], s) for s in range(len(r))]


def _in_part(centres: np.ndarray, geometry, body, t: int, s: int) -> np.ndarray:
    kind, g, extra = geometry
    if kind == "object":
        return extra.inside(centres[None], body.rot[t:t + 1], body.trans[t:t + 1])[0]
    a, b, r = g
    return _segment_distance(centres, a[t][s:s + 1], b[t][s:s + 1])[:, 0] < r[s]


def segment_segment_distance(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Distance (m) between segments ``p1 q1`` and ``p2 q2`` (broadcast over leading axes; the
    last axis is xyz): the closest pair of points, parameters clamped to the segments
    (Ericson, Real-Time Collision Detection, 5.1.9)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e = (d1 * d1).sum(-1), (d2 * d2).sum(-1)
    b, c, f = (d1 * d2).sum(-1), (d1 * r).sum(-1), (d2 * r).sum(-1)
    tiny = 1e-18
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = a * e - b * b
        s = np.where(denom > tiny, np.clip((b * f - c * e) / np.where(denom > tiny, denom, 1.0), 0.0, 1.0), 0.0)
        t = np.where(e > tiny, (b * s + f) / np.where(e > tiny, e, 1.0), 0.0)
        safe_a = np.where(a > tiny, a, 1.0)
        s = np.where(t < 0, np.clip(-c / safe_a, 0.0, 1.0), np.where(t > 1, np.clip((b - c) / safe_a, 0.0, 1.0), s))
        s = np.where(a > tiny, s, 0.0)
        t = np.clip(t, 0.0, 1.0)
    return np.linalg.norm(p1 + d1 * s[..., None] - p2 - d2 * t[..., None], axis=-1)


def _meeting(geo_p, geo_q, t: int):
    """Bool (parts of p, parts of q): whether two capsules come within the sum of their radii
    (a voxel centre inside both needs it); object pairs are always kept."""
    if geo_p[0] != "skeleton" or geo_q[0] != "skeleton":
        return None
    (ap, bp, rp), (aq, bq, rq) = geo_p[1], geo_q[1]
    d = segment_segment_distance(ap[t][:, None], bp[t][:, None], aq[t][None], bq[t][None])
    return d < rp[:, None] + rq[None] + 1e-6


def _near_part_box(a: np.ndarray, b: np.ndarray, r: float, a2: np.ndarray, b2: np.ndarray, reach: float,
                   samples: int = 64) -> tuple[np.ndarray, np.ndarray] | None:
    """Box holding every point within ``r`` of the part of segment ``a b`` that comes within
    ``reach`` of segment ``a2 b2`` (None: no part does). The distance to ``a2 b2`` moves at
    most ``|b - a|`` per unit of the segment's parameter, so a sample cell whose centre is
    farther than ``reach`` plus that bound times the half-cell holds no such point."""
    s = (np.arange(samples) + 0.5) / samples
    pts = a + (b - a) * s[:, None]
    d = _segment_distance(pts, a2[None], b2[None])[:, 0]
    keep = np.flatnonzero(d < reach + np.linalg.norm(b - a) * 0.5 / samples)
    if not len(keep):
        return None
    ends = a + (b - a) * np.array([keep[0] / samples, (keep[-1] + 1) / samples])[:, None]
    return ends.min(0) - r, ends.max(0) + r


def _inside_both_by_parts(lo: np.ndarray, hi: np.ndarray, voxel: float, order, t: int) -> int:
    """:func:`_inside_both` for an overlap too large for one grid: a voxel is inside both
    bodies when it is inside some part of each (a capsule, or the object), so only the boxes
    where a part of one meets a part of the other (two capsules: where their segments come
    within the sum of their radii) are gridded, on the whole box's voxel centres, and each
    voxel found is counted once. Same count, bounded memory, and time proportional to where
    the parts meet instead of to the bodies' far-flung boxes."""
    axes = [np.arange(lo[k] + voxel / 2, hi[k], voxel) for k in range(3)]
    shape = tuple(len(x) for x in axes)
    (_, geo_p, body_p), (_, geo_q, body_q) = order          # capsules first
    found = []
    meets = _meeting(geo_p, geo_q, t)
    if meets is not None:
        (ap, bp, rp), (aq, bq, rq) = geo_p[1], geo_q[1]
    for plo, phi, ps in _parts(geo_p, t):
        for qlo, qhi, qs in _parts(geo_q, t):
            if meets is not None:
                if not meets[ps, qs]:
                    continue
                reach = float(rp[ps] + rq[qs]) + 1e-6
                near_p = _near_part_box(ap[t][ps], bp[t][ps], float(rp[ps]), aq[t][qs], bq[t][qs], reach)
                near_q = _near_part_box(aq[t][qs], bq[t][qs], float(rq[qs]), ap[t][ps], bp[t][ps], reach)
                if near_p is None or near_q is None:
                    continue
                blo = np.maximum.reduce([plo, qlo, near_p[0], near_q[0], lo])
                bhi = np.minimum.reduce([phi, qhi, near_p[1], near_q[1], hi])
            else:
                blo, bhi = np.maximum(np.maximum(plo, qlo), lo), np.minimum(np.minimum(phi, qhi), hi)
            idx = [(int(np.searchsorted(x, blo[k])), int(np.searchsorted(x, bhi[k], side="right")))
                   for k, x in enumerate(axes)]
            if any(i0 >= i1 for i0, i1 in idx):
                continue
            plane = (idx[1][1] - idx[1][0]) * (idx[2][1] - idx[2][0])
            rows = max(1, GRID_BLOCK_VOXELS // plane)
            for x0 in range(idx[0][0], idx[0][1], rows):
                rng = [np.arange(x0, min(idx[0][1], x0 + rows)), np.arange(*idx[1]), np.arange(*idx[2])]
                ii = np.stack(np.meshgrid(*rng, indexing="ij"), -1).reshape(-1, 3)
                centres = np.stack([axes[k][ii[:, k]] for k in range(3)], -1)
                sel = np.flatnonzero(_in_part(centres, geo_p, body_p, t, ps))
                if len(sel):
                    sel = sel[_in_part(centres[sel], geo_q, body_q, t, qs)]
                    found.append(np.ravel_multi_index(tuple(ii[sel].T), shape))
    return int(len(np.unique(np.concatenate(found)))) if found else 0


def _inside_both(lo: np.ndarray, hi: np.ndarray, voxel: float, order, t: int) -> int:
    """Voxel centres of the ``(lo, hi)`` grid inside both bodies at frame ``t`` (``order``:
    ``(key, (kind, geometry, extra), body)`` with capsules first)."""
    grid = _grid(lo, hi, voxel)
    mask = np.ones(len(grid), bool)
    for _, (kind, g, extra), body in order:
        if not mask.any():
            break
        if kind == "object":
            sel = np.flatnonzero(mask)
            mask[sel] = extra.inside(grid[sel][None], body.rot[t:t + 1], body.trans[t:t + 1])[0]
        else:
            a, b, r = g
            mask &= capsule_grid_mask(lo, hi, voxel, a[t], b[t], r)
    return int(mask.sum())
