"""The per-clip physical metrics of ``hoibench evaluate`` in one process: time, profile, and
the exact per-clip statistics to compare two trees with.

    python benchmarks/physical_per_clip.py STORE [--clips 200] [--protocol synthetic-clean]
        [--profile out.prof] [--save stats.json] [--compare stats.json]

``STORE``: a store whose test clips are scored as their own submission (the ground truth
at K = 1, as ``benchmarks/evaluate_cli.py``'s K = 1 case; e.g. its ``bench_1000x196``).
For the first ``--clips`` test ids it builds the :class:`~hoibench.metrics.physical.ClipInput`
the scorer's stream stage builds, warms the object fields up (one clip per object), then runs
the worker's unit (:func:`hoibench.metrics.physical._unit`) on each clip in this process and
prints ms per clip; ``--profile`` writes a cProfile of that loop; ``--save`` writes every
clip's statistics (floats as ``float.hex``, so equality is exact); ``--compare`` checks them
against a saved file and prints the differences.
"""
from __future__ import annotations

import argparse
import cProfile
import json
import os
import time
from functools import partial
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")            # one thread, as a process-pool worker
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402


def _exact(x):
    """JSON-able, exact: floats as hex strings, arrays as lists of those."""
    if isinstance(x, dict):
        return {str(k): _exact(v) for k, v in sorted(x.items(), key=lambda kv: str(kv[0]))}
    if isinstance(x, (list, tuple)):
        return [_exact(v) for v in x]
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return float(x).hex()
    if isinstance(x, np.ndarray):
        return _exact(x.tolist())
    return x


def clip_inputs(store_path: Path, n: int, protocol: str) -> tuple[list, object]:
    """The first ``n`` test clips of the store as the scorer's ClipInputs (the ground truth as
    the generated motion), and the protocol's PhysicalConfig."""
    from hoibench.datasets.store import Store
    from hoibench.metrics.physical import clip_input_factory, load_groups
    from hoibench.tracks.protocol import get_protocol
    store = Store(store_path)
    proto = get_protocol(protocol)
    cfg = proto.physical_config()
    ids = store.clip_ids("test")
    make = clip_input_factory(store, ids, load_groups(store.root), proto.physical["contact_thresholds"],
                              float(proto.fps), cfg.contact_gt_rule, cfg.contact_gt_threshold_m)
    out = []
    for cid in ids[:n]:
        z = store.load(cid, keys=("joints", "obj_rot", "obj_trans"))
        out.append(make(cid, {k: np.asarray(v, np.float32 if k == "joints" else v.dtype) for k, v in z.items()}, 0))
    return out, cfg


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("store", type=Path)
    ap.add_argument("--clips", type=int, default=200)
    ap.add_argument("--protocol", default="synthetic-clean")
    ap.add_argument("--profile", type=Path)
    ap.add_argument("--save", type=Path)
    ap.add_argument("--compare", type=Path)
    ap.add_argument("--repeat", type=int, default=1, help="time the loop this many times, report the fastest")
    args = ap.parse_args(argv)
    from hoibench.metrics.physical import _unit
    t0 = time.perf_counter()
    inputs, cfg = clip_inputs(args.store, args.clips, args.protocol)
    t_in = time.perf_counter() - t0
    unit = partial(_unit, config=cfg)
    t0 = time.perf_counter()
    seen = set()
    for inp in inputs:                                     # fields (mesh checks, grids) once per object
        if inp.object_name not in seen:
            seen.add(inp.object_name)
            unit(inp)
    t_warm = time.perf_counter() - t0
    prof = cProfile.Profile() if args.profile else None
    best = (np.inf, np.inf)
    for _ in range(max(1, args.repeat)):
        t0, c0 = time.perf_counter(), time.process_time()
        if prof:
            prof.enable()
        stats = {}
        for inp in inputs:
            key, st = unit(inp)
            stats[str(key)] = st
        if prof:
            prof.disable()
        best = min(best, (time.process_time() - c0, time.perf_counter() - t0))
    if prof:
        prof.dump_stats(str(args.profile))
    cpu, dt = best
    print(f"{len(inputs)} clips x {len(inputs[0].joints)} frames, {len(seen)} objects: inputs {t_in:.1f} s, "
          f"warm-up {t_warm:.1f} s, units {dt:.2f} s wall = {1000 * dt / len(inputs):.1f} ms/clip, "
          f"{1000 * cpu / len(inputs):.1f} ms CPU/clip (best of {max(1, args.repeat)}; load {os.getloadavg()[0]:.2f})")
    exact = _exact(stats)
    if args.save:
        args.save.write_text(json.dumps(exact, indent=0))
    if args.compare:
        ref = json.loads(args.compare.read_text())
        bad = [(k, f, ref[k].get(f), exact.get(k, {}).get(f)) for k in ref for f in ref[k]
               if exact.get(k, {}).get(f) != ref[k][f]]
        bad += [(k, f, None, v) for k in exact for f, v in exact[k].items() if f not in ref.get(k, {})]
        print(f"compare: {len(ref)} clips, {len(bad)} differing values")
        for row in bad[:20]:
            print("  ", row)
        if bad:
            raise SystemExit(1)


if __name__ == "__main__":
    main()
