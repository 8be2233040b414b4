"""PS and CD under ChainHOI's released distance rules (legacy) vs hoibench's (clean).

    python benchmarks/legacy_ps.py [--data STORE] [--clips 24]

Without ``--data`` it writes and prepares a synthetic store as the CLI does (``hoibench synth
--out T/raw --clips N``, ``hoibench prepare behave ...``) in a temporary folder. Every test
and train clip's ground-truth motion is scored as a submission. Prints (docs/metrics.md, "PS:
legacy vs clean"):

1. per object, the vertex-frames of the floor-shifted proxy body (the body legacy PS
   measures) whose sign differs between hoibench's inside test (all parts, repaired mesh: the
   clean rule) and the closest-face rule (torchsdf, mesh as loaded:
   :mod:`hoibench.bodies.reference_distance`), and how many of those lie more than 1 cm from
   the surface;
2. PS, the deepest penetration and CD under synthetic-clean, legacy 1.1's rules
   (``PhysicalConfig("legacy")``) and synthetic-legacy 1.2 (closest-face sign, edge quirk, no
   repair), with the time each takes;
3. the same on the boxlarge/boxsmall clips with the box replaced by a constructed mesh: the
   box with two triangles missing (a hole) and an inward-facing handle (an inverted part);
4. the edge quirk: object edges that are ``v0 -> v2`` in every face holding them, and on a
   1,000-face decimated sphere (pymeshlab, like BEHAVE's ``*_f1000`` meshes) the share of
   near-surface points whose reference distance exceeds the exact one;
5. speed of the closest-face rule on a BEHAVE-sized mesh (a sphere decimated to 10,000
   faces) for 3 frames of 6,890 points within 1 m of it: the fast path, and the brute force
   on a tenth of a frame (times 10).
"""
from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np


def _store(base: Path, clips: int):
    from hoibench.cli import main as cli
    raw, data = base / "raw", base / "data"
    assert cli(["synth", "--out", str(raw), "--clips", str(clips)]) == 0
    assert cli(["prepare", "behave", "--root", str(raw), "--body-models", str(raw / "body_models"),
                "--split-file", str(raw / "split.json"), "--out", str(data)]) == 0
    return data


def _sign_table(inputs, label: str | None = None, header: bool = True) -> None:
    from hoibench.bodies.distance import signed_distance_field, to_template_frame
    from hoibench.bodies.reference_distance import closest_face_field
    from hoibench.metrics.body_surface import proxy_vertices_from_joints
    rows: dict[str, np.ndarray] = {}
    for inp in inputs:
        J = np.asarray(inp.joints, dtype=np.float64)
        J = J - np.array([0.0, J[..., 1].min(), 0.0])                    # legacy floor shift
        pts = to_template_frame(proxy_vertices_from_joints(J), inp.obj_rot, inp.obj_trans).reshape(-1, 3)
        inside = signed_distance_field(inp.template_vertices, inp.template_faces).contains(pts)   # clean
        cf = closest_face_field(inp.template_vertices, inp.template_faces)(pts)                # as loaded
        differ = inside != cf.penetrating
        row = rows.setdefault(label or inp.object_name, np.zeros(6, np.int64))
        row += [len(pts), inside.sum(), cf.penetrating.sum(), (cf.penetrating & ~inside).sum(),
                (inside & ~cf.penetrating).sum(), (differ & (cf.distance > 0.01)).sum()]
    if header:
        print("| object | vertex-frames | inside (clean rule) | closest face says inside | "
              "only closest face | only inside test | of these > 1 cm from the surface |")
        print("|---|---|---|---|---|---|---|")
    tot = np.zeros(6, np.int64)
    for name, r in sorted(rows.items()):
        tot += r
        print(f"| {name} | " + " | ".join(f"{x:,}" for x in r) + " |")
    if len(rows) > 1:
        print("| all | " + " | ".join(f"{x:,}" for x in tot) + " |")


def _scores(label: str, inputs, configs) -> None:
    from hoibench.metrics.physical import evaluate_physical
    for name, cfg in configs:
        t0 = time.perf_counter()
        r = evaluate_physical(inputs, cfg).compute()
        dt = time.perf_counter() - t0
        print(f"| {label} | {name} | {r['ps']:.5f} | {r['penetration_depth_max_m']:.3f} | "
              f"{r['cd'] * 1e3:.4f} | {dt:.1f} s |")


def constructed_mesh(hole: bool = True, inverted: bool = True, half=(0.3, 0.2, 0.25)
                     ) -> tuple[np.ndarray, np.ndarray]:
    """A box of half-sizes ``half`` (m), with ``hole``: its two bottom triangles missing, plus a
    handle on its top (a closed 0.2 x 0.04 x 0.06 m box), with ``inverted``: facing inward."""
    import trimesh
    box = trimesh.creation.box(extents=2 * np.asarray(half))
    v, f = np.asarray(box.vertices), np.asarray(box.faces)
    if hole:
        f = np.delete(f, np.flatnonzero(np.all(np.isclose(v[f][:, :, 1], -half[1]), axis=1)), axis=0)
    handle = trimesh.creation.box(extents=(0.2, 0.04, 0.06))
    hv = np.asarray(handle.vertices) + (0.0, half[1] + 0.02, 0.0)
    hf = np.asarray(handle.faces)[:, ::-1 if inverted else 1] + len(v)
    return np.vstack([v, hv]), np.vstack([f, hf])


def _quirk_edges(faces: np.ndarray) -> tuple[int, int]:
    """(edges that are v0 -> v2 in every face holding them, edges)."""
    e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [0, 2]], faces[:, [1, 2]]]), axis=1)
    k = np.repeat([0, 1, 2], len(faces))
    keys, inv = np.unique(e, axis=0, return_inverse=True)
    other = np.bincount(inv.reshape(-1), weights=(k != 1), minlength=len(keys))
    return int((other == 0).sum()), len(keys)


def _decimated_sphere(faces: int, radius: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    import pymeshlab
    import trimesh
    sphere = trimesh.creation.icosphere(subdivisions=6 if faces > 5000 else 5, radius=radius)
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(np.asarray(sphere.vertices), np.asarray(sphere.faces)))
    ms.meshing_decimation_quadric_edge_collapse(targetfacenum=faces)
    m = ms.current_mesh()
    return np.asarray(m.vertex_matrix(), np.float64), np.asarray(m.face_matrix(), np.int64)


def _speed() -> None:
    from hoibench.bodies import reference_distance as rd
    v, f = _decimated_sphere(10_000)
    rng = np.random.default_rng(1)
    d = rng.normal(size=(3 * 6890, 3))
    pts = d / np.linalg.norm(d, axis=1, keepdims=True) * rng.uniform(0.2, 1.3, (len(d), 1))
    t0 = time.perf_counter()
    field = rd.ClosestFaceField(v, f)
    t1 = time.perf_counter()
    fast = field(pts)
    t2 = time.perf_counter()
    brute = rd.closest_face_brute(pts[:689], v, f)
    t3 = time.perf_counter()
    same = (brute.sign == fast.sign[:689]).mean()
    print(f"closest-face rule, {len(f):,}-face mesh: set-up {t1 - t0:.2f} s; fast path "
          f"{(t2 - t1) / 3:.2f} s per frame of 6,890 points; brute force {(t3 - t2) * 10:.1f} s per frame "
          f"(689 points timed); signs equal on the 689: {same:.1%}")


def _quirk_table(store) -> None:
    from hoibench.bodies import reference_distance as rd
    print("| mesh | faces | edges v0 -> v2 in every face | near-surface points with reference > exact | "
          "largest excess (mm) |")
    print("|---|---|---|---|---|")
    names = sorted(x.stem for x in (Path(store.root) / "objects").glob("*.npz"))
    meshes = [(n, *store.object_template(n)) for n in names]
    meshes.append(("sphere r 0.3 m, decimated", *_decimated_sphere(1000)))
    rng = np.random.default_rng(0)
    for name, v, f in meshes:
        v, f = np.asarray(v, np.float64), np.asarray(f, np.int64)
        q, n = _quirk_edges(f)
        i = rng.integers(0, len(f), 4000)
        b = rng.dirichlet([1, 1, 1], 4000)
        pts = np.einsum("nk,nkd->nd", b, v[f[i]]) + rng.normal(scale=0.02, size=(4000, 3))
        ref = rd.contact_distance_field(v, f)(pts)
        ex = rd.exact_triangle_distance(pts, v, f)
        over = ref - ex > 1e-9
        print(f"| {name} | {len(f):,} | {q:,} of {n:,} | {over.mean():.1%} | {1e3 * (ref - ex).max():.2f} |")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=None, help="a prepared synthetic store (default: make one)")
    ap.add_argument("--clips", type=int, default=24)
    args = ap.parse_args(argv)

    from hoibench.datasets.store import Store
    from hoibench.metrics.physical import PhysicalConfig, clip_inputs
    from hoibench.tracks.protocol import get_protocol

    data = args.data or _store(Path(tempfile.mkdtemp(prefix="hoibench-legacy-ps-")), args.clips)
    store = Store(data)
    motions = {c: store.load(c) for c in store.clip_ids()}
    inputs = clip_inputs(store, motions, contact_mode="surface")
    print(f"store {data}: {len(inputs)} clips, {sum(len(i.joints) for i in inputs):,} frames\n")
    _sign_table(inputs)
    clean, legacy = get_protocol("synthetic-clean").physical_config(), get_protocol("synthetic-legacy").physical_config()
    configs = [("synthetic-clean", clean), ("legacy 1.1 rules", PhysicalConfig("legacy", contact_mode="surface")),
               ("synthetic-legacy 1.2", legacy)]
    print("\n| data | rules | PS | depth max (m) | CD ×1e-3 | time |")
    print("|---|---|---|---|---|---|")
    _scores("synthetic store", inputs, configs)
    variants = {"box + handle, closed": (False, False), "hole": (True, False),
                "inverted handle": (False, True), "hole + inverted handle": (True, True)}
    made = {}
    for name, (hole, inverted) in variants.items():
        v, f = constructed_mesh(hole, inverted)
        made[name] = [replace(i, template_vertices=v, template_faces=f) for i in inputs
                      if i.object_name.startswith("box")]
        _scores(f"{name} ({len(made[name])} box clips)", made[name], configs[::2])
    print()
    for k, (name, boxes) in enumerate(made.items()):
        _sign_table(boxes, name, header=k == 0)
    print()
    _quirk_table(store)
    print()
    _speed()


if __name__ == "__main__":
    main()
