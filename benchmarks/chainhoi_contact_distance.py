"""How far is "the nearest of N surface samples" from the exact point-to-mesh distance?

ChainHOI's ``L_h`` pulls each gated interaction joint onto the GT object surface. With
``train.contact_distance = "samples"`` the distance is to the nearest of ``train.contact_points``
area-weighted surface samples (:func:`hoibench.baselines.joint_data.surface_points`, the
training samples); ``"exact"`` is the exact point-to-triangle distance. This prints, per object
and sample count (256 / 512 / 1024), the error ``d_samples - d_exact`` (always >= 0) for query
points at contact distances: random surface points (a second, independent draw) pushed out
along their face normal by 0, 1, 2 and 5 cm -- the regime of joints labelled in contact.

Objects: the synthetic track's eight templates, and a BEHAVE-sized mesh (the synthetic small
table scaled to 1.0 m across, about the size of BEHAVE's square table, subdivided twice so the
face count is that of a BEHAVE template).

Then times the exact ``L_h``'s face search (:func:`hoibench.baselines.mesh_distance.nearest_face`)
on a training batch's worth of queries (16 clips x 96 frames x 8 interaction joints, in
contact or not) with its two backends, torch (pruned search) and open3d (BVH; the scenes are
cached per template, so the first call, which builds them, is shown apart), one thread.

    python benchmarks/chainhoi_contact_distance.py
"""
from __future__ import annotations

import time

import numpy as np

from hoibench.baselines import joint_data as D
from hoibench.bodies.reference_distance import exact_triangle_distance
from hoibench.datasets.synthetic_constants import OBJECTS
from hoibench.datasets.synthetic_objects import build_object

OFFSETS_M = (0.0, 0.01, 0.02, 0.05)
COUNTS = (256, 512, 1024)
QUERIES = 400


def subdivide(v: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Midpoint subdivision (each face -> 4), same surface."""
    a, b, c = f[:, 0], f[:, 1], f[:, 2]
    n = len(v)
    mids = np.concatenate([(v[a] + v[b]) / 2, (v[b] + v[c]) / 2, (v[c] + v[a]) / 2])
    ab, bc, ca = np.arange(len(f)) + n, np.arange(len(f)) + n + len(f), np.arange(len(f)) + n + 2 * len(f)
    faces = np.concatenate([np.stack([a, ab, ca], 1), np.stack([ab, b, bc], 1), np.stack([ca, bc, c], 1),
                            np.stack([ab, bc, ca], 1)])
    return np.concatenate([v, mids]), faces


def behave_sized() -> tuple[np.ndarray, np.ndarray]:
    obj = build_object("tablesmall")
    v = obj.vertices.astype(np.float64)
    v = v * (1.0 / np.ptp(v[:, [0, 2]], axis=0).max())
    f = obj.faces.astype(np.int64)
    for _ in range(2):
        v, f = subdivide(v, f)
    return v, f


def queries(v: np.ndarray, f: np.ndarray, name: str) -> tuple[np.ndarray, np.ndarray]:
    """(points, offset) for every offset: surface points pushed along their face normal."""
    rng = np.random.default_rng(0)
    tri = v[f]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(normal, axis=1)
    pick = rng.choice(len(f), size=QUERIES, p=area / area.sum())
    u, w = rng.random(QUERIES), rng.random(QUERIES)
    flip = u + w > 1
    u[flip], w[flip] = 1 - u[flip], 1 - w[flip]
    t = tri[pick]
    p = t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + w[:, None] * (t[:, 2] - t[:, 0])
    n = normal[pick] / np.linalg.norm(normal[pick], axis=1, keepdims=True)
    pts = np.concatenate([p + d * n for d in OFFSETS_M])
    return pts, np.repeat(OFFSETS_M, QUERIES)


def measure(name: str, v: np.ndarray, f: np.ndarray) -> list[tuple]:
    pts, _ = queries(v, f, name)
    exact = exact_triangle_distance(pts, v, f)
    rows = []
    for n in COUNTS:
        s = D.surface_points(v, f, n, name).astype(np.float64)
        near = np.sqrt(((pts[:, None] - s[None]) ** 2).sum(-1)).min(1)
        err = near - exact
        rows.append((name, len(f), n, err.mean(), np.percentile(err, 95), err.max()))
    return rows


def main() -> None:
    t0 = time.time()
    meshes = [(name, build_object(name).vertices.astype(np.float64), build_object(name).faces.astype(np.int64))
              for name in OBJECTS]
    meshes.append(("behave-sized table", *behave_sized()))
    print(f"queries: {QUERIES} surface points x offsets {[int(d * 100) for d in OFFSETS_M]} cm along the normal")
    print(f"{'object':20s} {'faces':>6s} {'area m2':>8s} {'samples':>7s} {'mean cm':>8s} {'p95 cm':>7s} {'max cm':>7s}")
    summary = {n: [] for n in COUNTS}
    for name, v, f in meshes:
        tri = v[f]
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
        for _, nf, n, mean, p95, mx in measure(name, v, f):
            print(f"{name:20s} {nf:6d} {area:8.2f} {n:7d} {100 * mean:8.2f} {100 * p95:7.2f} {100 * mx:7.2f}")
            if name != "behave-sized table":
                summary[n].append(mean)
    for n in COUNTS:
        print(f"synthetic objects, {n} samples: mean error {100 * np.mean(summary[n]):.2f} cm "
              f"(objects' means {100 * min(summary[n]):.2f}-{100 * max(summary[n]):.2f} cm)")
    time_nearest_face(meshes)
    print(f"({time.time() - t0:.1f} s)")


def time_nearest_face(meshes: list, batch: int = 16, frames: int = 96, joints: int = 8, reps: int = 3) -> None:
    import torch

    from hoibench.baselines.joint_data import stack_meshes
    from hoibench.baselines.mesh_distance import nearest_face
    torch.set_num_threads(1)
    for label, chosen in (("synthetic templates", meshes[:-1]), ("behave-sized table", meshes[-1:])):
        tris = [v[f].astype(np.float32) for _, v, f in chosen]
        stacked = torch.from_numpy(stack_meshes([tris[i % len(tris)] for i in range(batch)]))
        g = torch.Generator().manual_seed(0)
        owner = torch.arange(batch).repeat_interleave(frames * joints)
        pts = torch.randn(len(owner), 3, generator=g) * 0.4
        found = {}
        from hoibench.baselines import mesh_distance
        mesh_distance._SCENES.clear()
        for backend in ("torch", "open3d"):
            times = []
            for _ in range(reps + 1):
                t = time.perf_counter()
                found[backend] = nearest_face(pts, owner, stacked, backend=backend)
                times.append(time.perf_counter() - t)
            first = f" (first call, BVHs built: {1000 * times[0]:.0f} ms)" if backend == "open3d" else ""
            print(f"nearest face, {label} ({stacked.shape[1]} faces padded), {len(pts)} points, {backend}: "
                  f"{1000 * sum(times[1:]) / reps:.0f} ms per batch{first}")
        from hoibench.baselines.mesh_distance import closest_point_on_triangle
        dist = {}
        for k, idx in found.items():
            tri = stacked[owner, idx]
            dist[k] = (pts - closest_point_on_triangle(pts, tri[:, 0], tri[:, 1], tri[:, 2])).norm(dim=-1)
        same = (found["torch"] == found["open3d"]).float().mean().item()
        print(f"  same face for {100 * same:.2f}% of the points; distance to the chosen faces differs by at most "
              f"{(dist['torch'] - dist['open3d']).abs().max().item():.1e} m")


if __name__ == "__main__":
    main()
