"""Cost of evaluating 1,000 samples of 196 frames with every metric and 20 replications.

    python benchmarks/evaluate.py [--samples 1000] [--frames 196] [--physical-samples N]
                                  [--executor processes:2] [--trimesh-samples 2]
    python benchmarks/evaluate.py --cli [--prompts 1000]   # the CLI end to end: benchmarks/evaluate_cli.py

Builds clips from a synthetic store (each test clip looped in time to ``--frames``), then
times the parts of ``hoibench evaluate`` separately: embedding all samples with a tiny
evaluator, the 20 replications of the embedding metrics, and the physical metrics
(CD, OCD, PS, FSR, extras) on all samples, or on ``--physical-samples`` of them
(extrapolated linearly to ``--samples``, and said so). PS vertex-queries/s are compared side by side with a
straightforward trimesh PS (``trimesh.proximity.signed_distance`` on every proxy body vertex)
on ``--trimesh-samples`` clips. Peak memory is the process's max RSS (the evaluator is
trained in a child process beforehand) and the largest child's (workers).
"""
from __future__ import annotations

import argparse
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def _loop(a: np.ndarray, n: int) -> np.ndarray:
    idx = np.concatenate([np.arange(len(a)), np.arange(len(a) - 2, 0, -1)])  # ping-pong
    return a[np.resize(idx, n)]


def _peak_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def main(argv=None) -> None:
    argv = sys.argv[1:] if argv is None else list(argv)
    if "--cli" in argv:                     # `hoibench evaluate` as a user runs it
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from evaluate_cli import main as cli_main
        return cli_main([a for a in argv if a != "--cli"])
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--samples", type=int, default=1000)
    ap.add_argument("--frames", type=int, default=196)
    ap.add_argument("--physical-samples", type=int, default=None)
    ap.add_argument("--executor", default="processes:2")
    ap.add_argument("--trimesh-samples", type=int, default=2)
    args = ap.parse_args(argv)

    from hoibench.text.annotate import annotate_store
    from hoibench.datasets.synthetic_store import build_synthetic_store
    from hoibench.evaluator import load_evaluator
    from hoibench.metrics import embedding as em
    from hoibench.metrics.physical import clip_inputs, evaluate_physical, load_groups
    from hoibench.tracks.protocol import get_protocol
    from hoibench.representations import hoi269
    from hoibench.datasets.store import Store

    tmp = Path(tempfile.mkdtemp(prefix="hoibench-eval-bench-"))
    try:
        _, data, _ = build_synthetic_store(tmp, 120, seed=0)
        annotate_store(data)
        # in a child process, so that training's memory is not in this process's peak RSS
        subprocess.run([sys.executable, "-m", "hoibench.cli", "train-evaluator", str(data), "--out",
                        str(tmp / "ev"), "--size", "tiny", "--seed", "0"], check=True, stdout=subprocess.DEVNULL)
        store = Store(data)
        proto = get_protocol("behave-clean")           # full-size protocol: pools of 32, 200 pairs
        ev = load_evaluator(tmp / "ev")
        test = store.clip_ids("test")
        clips = {c: store.load(c) for c in test}
        ids = [f"{test[i % len(test)]}#{i}" for i in range(args.samples)]
        src = [clips[test[i % len(test)]] for i in range(args.samples)]
        joints = [_loop(c["joints"], args.frames) for c in src]
        rots = [_loop(c["obj_rot"], args.frames) for c in src]
        trans = [_loop(c["obj_trans"], args.frames) for c in src]
        print(f"{args.samples} samples x {args.frames} frames (test clips looped in time), protocol {proto.ref}")

        t0 = time.perf_counter()
        feats = [hoi269.encode(j, r, t, fps=20.0) for j, r, t in zip(joints, rots, trans)]
        t_enc = time.perf_counter() - t0
        t0 = time.perf_counter()
        gen = ev.embed_motion(feats)
        real = ev.embed_motion([c["hoi269"] for c in clips.values()] * max(1, 64 // len(clips)))
        text = ev.embed_text([f"a person handles object {i % 17}" for i in range(args.samples)])
        t_emb = time.perf_counter() - t0
        t0 = time.perf_counter()
        fid = em.fid(real, gen)
        for r in range(proto.replications):
            pools = [[int(i.split("#")[1]) for i in p] for p in proto.pools(ids, r)]
            em.r_precision(text, gen, pools)
            em.mm_dist(text, gen, pools)
            em.diversity(gen, proto.effective_diversity_pairs(len(ids)), proto.seed_for("diversity", r))
        t_rep = time.perf_counter() - t0
        print(f"peak RSS so far (store, annotations, embeddings): {_peak_mib():.0f} MiB")
        print(f"encode hoi269: {t_enc:6.1f} s   embed (tiny evaluator): {t_emb:6.1f} s   "
              f"20 replications (R-precision, MM-Dist, Diversity; FID once {fid:.3g}): {t_rep:6.2f} s")

        n = args.samples if args.physical_samples is None else min(args.physical_samples, args.samples)
        motions = {ids[i]: {"joints": joints[i], "obj_rot": rots[i], "obj_trans": trans[i]} for i in range(n)}

        class _Alias:   # the physical metrics look up each sample's test clip by id
            def __init__(self, s):
                self.s = s

            def load(self, cid):
                return self.s.load(cid.split("#")[0])

            def object_template(self, name):
                return self.s.object_template(name)

            def __getattr__(self, k):
                return getattr(self.s, k)

        inputs = clip_inputs(_Alias(store), motions, groups=load_groups(data), contact_mode="chainhoi", fps=20.0)
        for inp, i in zip(inputs, range(n)):       # GT contacts were looped too
            if inp.gt_contacts is not None:
                object.__setattr__(inp, "gt_contacts", _loop(src[i]["contacts"], args.frames))
        t0 = time.perf_counter()
        phys = evaluate_physical(inputs, proto.physical_config(), executor=args.executor).compute()
        t_phys = time.perf_counter() - t0
        vq = n * args.frames * 6890 / t_phys
        scaled = "" if n == args.samples else f" -> {t_phys * args.samples / n:7.1f} s for {args.samples} (linear)"
        print(f"physical metrics on {n} samples ({args.executor}): {t_phys:6.1f} s{scaled}; "
              f"{vq / 1e6:.2f} M body-vertex-frames/s (PS {phys['ps']:.4f}, depth max "
              f"{phys['penetration_depth_max_m']:.3f} m)")

        print(f"peak RSS after the physical metrics: {_peak_mib():.0f} MiB")
        import trimesh

        from hoibench.metrics.body_surface import proxy_vertices_from_joints
        m = min(args.trimesh_samples, n)
        t0 = time.perf_counter()
        neg = tot = 0
        for i in range(m):
            v, f = store.object_template(str(src[i]["object_name"]))
            mesh = trimesh.Trimesh(v, f, process=False)
            verts = proxy_vertices_from_joints(joints[i])
            for t in range(0, args.frames, 4):       # every 4th frame: trimesh is slow
                local = (verts[t] - trans[i][t]) @ rots[i][t]
                d = trimesh.proximity.signed_distance(mesh, local)   # positive inside
                neg += int((d > 0).sum())
                tot += len(d)
        t_tm = time.perf_counter() - t0
        print(f"trimesh PS: {tot / t_tm / 1e3:7.1f} k vertex-queries/s ({m} samples, every 4th frame) vs "
              f"hoibench {vq / 1e3:7.1f} k/s -> {vq / (tot / t_tm):.0f}x")
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        worker = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
        total = t_enc + t_emb + t_rep + t_phys * args.samples / n
        word = "total" if n == args.samples else "estimated total"
        print(f"{word} for {args.samples} samples: {total:.0f} s; peak RSS {peak:.0f} MiB "
              f"(largest child process: {worker:.0f} MiB, including the evaluator training run)")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
