"""Throughput of signed-distance queries and contact labels (hoibench.bodies.contact).

    python benchmarks/contact.py [--frames 20] [--repeats 3] [--trimesh-points 5000]

Query points: the proxy body's 6,890 vertices over ``--frames`` frames of synthetic clips
(seated on ``chairwood``, lifting ``yogaball``), moved into the object's template frame.
Prints points/s (best of ``--repeats``) for

* open3d ``compute_distance`` (unsigned) and ``compute_occupancy`` (3 rays) alone,
* open3d ``compute_signed_distance`` (whole-mesh ray parity, 3 rays: what open3d offers),
* hoibench ``SignedDistance`` (distance + the inside test its mesh report chose),
* the generalised winding number (numpy) and trimesh ``signed_distance`` (reference, on the
  first ``--trimesh-points`` points only: it is slow),
* bounding-box culling: ``SignedDistance.query`` with ``max_distance`` 0.5 / 0.1 m,
* an open mesh (the yogaball with 40 faces removed, not repaired): each inside test's
  points/s and sign errors against the analytic sphere,
* ``joint_contact_labels`` in frames/s over 64 synthetic clips.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from hoibench.bodies import contact as C
from hoibench.bodies.proxy import ProxyBody
from hoibench.datasets import synthetic as syn


def best(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def clip_for(obj: str, action: str):
    for i, spec in enumerate(syn.plan_clips(64, seed=0)):
        if spec.object == obj and spec.action == action:
            return syn.generate_clip(spec, (0, i))
    raise LookupError(f"no {obj}/{action} clip in the plan")


def bench_object(obj: str, action: str, frames: int, repeats: int, n_trimesh: int) -> None:
    import open3d as o3d

    clip = clip_for(obj, action)
    sel = slice(len(clip.joints) - frames, len(clip.joints))          # the end: touching
    verts, _ = ProxyBody().forward(clip.rotations[sel], clip.trans[sel], clip.betas)
    local = C.to_template_frame(verts, clip.obj_rot[sel], clip.obj_trans[sel]).reshape(-1, 3)
    n = len(local)
    field = C.SignedDistance(clip.object.vertices, clip.object.faces)
    scene = field._scene
    pt = o3d.core.Tensor(local.astype(np.float32))
    rep = field.report
    print(f"\n{obj} ({action}): {rep.faces} faces, {rep.components} component(s), inside test "
          f"{rep.inside_test}; {n:,} query points ({frames} frames x 6,890 proxy vertices)")
    rows = [
        ("open3d compute_distance (unsigned)", n, lambda: scene.compute_distance(pt)),
        ("open3d compute_occupancy (3 rays)", n, lambda: scene.compute_occupancy(pt, nsamples=3)),
        ("open3d compute_signed_distance (3 rays, whole-mesh parity)", n,
         lambda: scene.compute_signed_distance(pt, nsamples=3)),
        (f"hoibench SignedDistance, no culling ({rep.inside_test})", n, lambda: field(local)),
    ]
    inbox = local[np.all((local >= field.box_min) & (local <= field.box_max), axis=1)]
    if len(inbox):
        rows.append((f"winding number (numpy), {len(inbox):,} points in the bounding box", len(inbox),
                     lambda: C.winding_number(inbox, field.vertices, field.faces)))
    tm = C.SignedDistance(clip.object.vertices, clip.object.faces, method="trimesh")
    sub = local[:n_trimesh]
    rows.append((f"trimesh signed_distance (first {len(sub):,} points)", len(sub), lambda: tm(sub)))
    for md in (0.5, 0.1):
        _, ex = field.query(local, md)
        rows.append((f"hoibench query, max_distance {md} m ({ex.mean():.1%} exact)", n,
                     lambda md=md: field.query(local, md)))
    ref = field(local)
    d3 = scene.compute_signed_distance(pt, nsamples=3).numpy()
    exact = clip.object.sdf_local(local)
    print(f"sign disagreements with the analytic SDF (|d| > 3 mm): hoibench "
          f"{int(((ref < 0) != (exact < 0))[np.abs(exact) > 3e-3].sum())}, open3d whole-mesh parity "
          f"{int(((d3 < 0) != (exact < 0))[np.abs(exact) > 3e-3].sum())}")
    print("| query | points/s |\n|---|---|")
    for name, count, fn in rows:
        dt = best(fn, repeats if count > 10_000 or "trimesh" not in name else 1)
        print(f"| {name} | {count / dt:,.0f} |")


def bench_open_mesh(frames: int, repeats: int) -> None:
    """The yogaball with 40 faces removed and no repair: the hybrid test vs the exact
    winding number vs open3d's own occupancy, on proxy vertices inside the bounding box."""
    clip = clip_for("yogaball", "lift")
    sel = slice(len(clip.joints) - frames, len(clip.joints))
    verts, _ = ProxyBody().forward(clip.rotations[sel], clip.trans[sel], clip.betas)
    local = C.to_template_frame(verts, clip.obj_rot[sel], clip.obj_trans[sel]).reshape(-1, 3)
    obj = clip.object
    faces = np.delete(obj.faces, np.random.default_rng(0).choice(len(obj.faces), 40, replace=False), 0)
    exact = obj.sdf_local(local)
    clear = np.abs(exact) > 3e-3
    print(f"\nyogaball with 40 faces removed, not repaired; {len(local):,} query points")
    print("| inside test | points/s | sign errors (|d| > 3 mm) |\n|---|---|---|")
    for test in ("ray-vote+winding", "winding", "ray-vote", "occupancy"):
        field = C.SignedDistance(obj.vertices, faces, repair=False, inside_test=test)
        d = field(local)
        err = int(((d < 0) != (exact < 0))[clear].sum())
        dt = best(lambda: field(local), 1 if test == "winding" else repeats)
        print(f"| {field.inside_test} | {len(local) / dt:,.0f} | {err} |")


def bench_labels(repeats: int) -> None:
    clips = [syn.generate_clip(s, (0, i)) for i, s in enumerate(syn.plan_clips(64, seed=0))]
    frames = sum(c.num_frames for c in clips)

    def run(mode):
        for c in clips:
            C.joint_contact_labels(c.joints, c.object.vertices, c.object.faces, c.obj_rot,
                                   c.obj_trans, c.spec.object, mode=mode)

    run("surface")                                                    # build the cached scenes
    print(f"\njoint_contact_labels over 64 clips ({frames:,} frames, scenes cached):")
    for mode in ("surface", "chainhoi"):
        dt = best(lambda: run(mode), repeats)
        print(f"  {mode:9s}: {dt:.3f} s, {frames / dt:,.0f} frames/s")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--trimesh-points", type=int, default=5000)
    args = ap.parse_args(argv)
    import open3d
    import trimesh
    print(f"open3d {open3d.__version__}, trimesh {trimesh.__version__}, numpy {np.__version__}")
    bench_object("chairwood", "sit", args.frames, args.repeats, args.trimesh_points)
    bench_object("yogaball", "lift", args.frames, args.repeats, args.trimesh_points)
    bench_open_mesh(args.frames, args.repeats)
    bench_labels(args.repeats)


if __name__ == "__main__":
    main()
