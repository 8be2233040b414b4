"""Physics metrics (MuJoCo) over a store's test split, ground truth as the generated motion:
per-clip values, their means, the time per clip and per clip-second.

    .venv/bin/hoibench synth --out /tmp/ph/raw --clips 120
    .venv/bin/hoibench prepare behave --root /tmp/ph/raw --body-models /tmp/ph/raw/body_models \\
        --split-file /tmp/ph/raw/split.json --out /tmp/ph/data
    .venv/bin/python benchmarks/physics.py /tmp/ph/data [--processes 2] [--clips N] [--set key=value ...]
    .venv/bin/python benchmarks/physics.py /tmp/ph/data --raw-world /tmp/ph/raw    # the generator's world

``--raw-world RAW``: score the same test ids in the synthetic generator's own world
(``RAW/sequences/<id>/hoibench_gt.npz``, 30 fps, floor exactly y = 0, gravity -y) instead of
the store's (BEHAVE layout: the camera frame turned y-up, floor shifted to y = 0 but not
levelled, so the store's floor is tilted by the camera's pitch).

Target: the synthetic test split (34 clips) in < 60 s on 2 cores.
"""
from __future__ import annotations

import argparse
import math
import os
import time
from collections import defaultdict
from concurrent.futures import ProcessPoolExecutor

import numpy as np


def _inputs(data: str, clips: int | None):
    from hoibench.datasets.store import Store
    from hoibench.metrics.physical import clip_inputs
    store = Store(data)
    ids = store.clip_ids("test")[:clips] if clips else store.clip_ids("test")
    keys = ("joints", "obj_rot", "obj_trans")
    motions = {cid: {k: v for k, v in store.load(cid).items() if k in keys} for cid in ids}
    return clip_inputs(store, motions)


def _raw_inputs(data: str, raw: str, clips: int | None):
    """The test ids' ground truth in the generator's world (floor y = 0, gravity -y)."""
    import json
    from pathlib import Path
    from hoibench.datasets.store import Store
    from hoibench.datasets.synthetic_objects import build_object
    from hoibench.metrics.physical import ClipInput
    ids = Store(data).clip_ids("test")
    out = []
    for cid in ids[:clips] if clips else ids:
        seq = Path(raw) / "sequences" / cid
        z = np.load(seq / "hoibench_gt.npz")
        meta = json.loads((seq / "hoibench_gt.json").read_text())
        name = meta["object"] if isinstance(meta["object"], str) else meta["object"]["name"]
        ob = build_object(name)
        out.append(ClipInput(key=cid, joints=z["joints"], fps=float(z["fps"]), obj_rot=z["obj_rot"],
                             obj_trans=z["obj_trans"], object_name=name, template_vertices=np.asarray(ob.vertices),
                             template_faces=np.asarray(ob.faces)))
    return out


def _one(args):
    inp, settings = args
    from hoibench.metrics.physics import physics_clip_values
    from hoibench.metrics.physics_scene import object_geometry
    t = time.perf_counter()
    out = physics_clip_values(inp, settings)
    hull = object_geometry(inp.template_vertices, inp.template_faces).hull_ratio if inp.template_vertices is not None \
        else float("nan")
    return inp.key, inp.object_name, len(inp.joints) / inp.fps, time.perf_counter() - t, hull, out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data")
    ap.add_argument("--processes", type=int, default=2)
    ap.add_argument("--clips", type=int, default=None)
    ap.add_argument("--raw-world", default=None, help="synthetic raw root: score the generator's world instead")
    ap.add_argument("--set", action="append", default=[], help="physics setting key=value")
    a = ap.parse_args()
    settings = {k: (int(v) if k == "settle_frames" else float(v)) for k, v in (s.split("=", 1) for s in a.set)}
    t0 = time.perf_counter()
    inputs = _raw_inputs(a.data, a.raw_world, a.clips) if a.raw_world else _inputs(a.data, a.clips)
    t_load = time.perf_counter() - t0
    t1 = time.perf_counter()
    jobs = [(inp, settings) for inp in inputs]
    if a.processes > 1:
        with ProcessPoolExecutor(a.processes) as ex:
            rows = list(ex.map(_one, jobs))
    else:
        rows = [_one(j) for j in jobs]
    wall = time.perf_counter() - t1
    names = list(rows[0][5])
    head = f"{'clip':40s} {'object':10s} {'s':>5s} {'cost':>6s} {'hull':>5s} "
    print(head + " ".join(f"{n[5:]:>17s}" for n in names))
    by_action = defaultdict(list)
    for key, obj, secs, cost, hull, out in sorted(rows):
        print(f"{key:40s} {obj:10s} {secs:5.1f} {cost:6.2f} {hull:5.2f} " + " ".join(f"{out[n]:17.4f}" for n in names))
        by_action[str(key).rsplit("_", 1)[-1]].append(out)
    print("\nmean over clips with a value:")
    for n in names:
        vals = [r[5][n] for r in rows if not math.isnan(r[5][n])]
        print(f"  {n:24s} {np.mean(vals):.4f}  ({len(vals)} clips)")
    print("\nby action (mean support error m / unsupported / settle m / balance):")
    for act, outs in sorted(by_action.items()):
        print(f"  {act:8s} n={len(outs):2d} " + " ".join(f"{np.nanmean([o[n] for o in outs]):8.4f}" for n in names))
    clip_s = sum(r[2] for r in rows)
    cpu = sum(r[3] for r in rows)
    print(f"\n{len(rows)} clips, {clip_s:.1f} clip-seconds; load {t_load:.1f} s; physics wall {wall:.1f} s on "
          f"{a.processes} process(es) ({os.cpu_count()} cpus); {cpu / len(rows):.2f} s per clip, "
          f"{cpu / clip_s:.3f} s per clip-second (one core)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
