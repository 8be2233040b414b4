"""Evaluator figures: embedding throughput, and GT retrieval of tiny evaluators on synthetic data.

    python benchmarks/evaluator.py speed   [--clips 256] [--frames 196 60] [--threads 1 2]
    python benchmarks/evaluator.py quality [--clips 200] [--epochs 60] [--variants human hoi] [--keep DIR]

``speed``: motion embeddings/s (clips of ``--frames`` rows, batches of 64) and text
embeddings/s (captions of 6-12 words, batches of 128) on CPU for the ``paper`` and ``tiny``
sizes, random weights (speed does not depend on them), best of 3.

``quality``: generates ``--clips`` synthetic clips in the BEHAVE layout, prepares them,
writes template captions from the clip names (4 paraphrases per clip: "a person <verb>s
the <object>", ...; stand-ins until ``hoibench annotate`` writes real ones), trains a tiny
evaluator per variant and a shuffled-text control, and prints the card's GT retrieval
scores, how often the nearest motion to a caption has the caption's action / object (on
the whole test split, one pool), the ceiling that shared captions impose on top-1 in the
same pools, and the training time.
"""
from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

def build_store(tmp: Path, clips: int) -> Path:
    from hoibench.datasets.synthetic_store import build_synthetic_store, write_template_texts
    t0 = time.perf_counter()
    _, data, m = build_synthetic_store(tmp, clips, seed=0)
    write_template_texts(data)
    print(f"store: {m['counts']['clips']} clips {m['counts']['by_split']} in {time.perf_counter() - t0:.1f} s")
    return data


def separation(ev, items) -> dict:
    """Nearest motion (whole test split, first caption) has the caption's action / object."""
    motion = ev.embed_motion([it.features for it in items])
    text = ev.embed_text([it.captions[0] for it in items])
    d = ((text[:, None, :] - motion[None, :, :]) ** 2).sum(-1)
    nn = d.argmin(1)
    act = [it.clip_id.split("_")[3] for it in items]
    obj = [it.clip_id.split("_")[2] for it in items]
    n = len(items)
    chance_a = sum(v * v for v in Counter(act).values()) / n ** 2
    chance_o = sum(v * v for v in Counter(obj).values()) / n ** 2
    return {"action": float(np.mean([act[j] == act[i] for i, j in enumerate(nn)])), "action_chance": chance_a,
            "object": float(np.mean([obj[j] == obj[i] for i, j in enumerate(nn)])), "object_chance": chance_o}


def ceiling_top1(items, pool_size: int = 32, replications: int = 20, seed: int = 0) -> float:
    """Best expected top-1 when clips with the same (action, object) share their captions:
    the pools of :func:`retrieval.retrieval_scores` (same permutations), 1 / (clips of the
    item's group in its pool) per item."""
    group = [tuple(it.clip_id.split("_")[2:4]) for it in items]
    n = len(items)
    size = min(pool_size, n)
    vals = []
    for r in range(replications):
        perm = np.random.default_rng([seed, r]).permutation(n)
        for p in range(n // size):
            pool = [group[i] for i in perm[p * size:(p + 1) * size]]
            c = Counter(pool)
            vals.append(np.mean([1.0 / c[g] for g in pool]))
    return float(np.mean(vals))


def quality(args) -> None:
    from hoibench.evaluator import load_evaluator, load_items, preset, train_evaluator
    tmp = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="hoibench-evaluator-"))
    try:
        data = tmp / "data" if (tmp / "data" / "manifest.json").exists() else build_store(tmp, args.clips)
        runs = [(v, "none") for v in args.variants] + [("human", "shuffled_texts")]
        for variant, control in runs:
            cfg = preset("tiny", variant, epochs=args.epochs, seed=args.seed, control=control)
            out = tmp / f"ev-{variant}-{control}"
            shutil.rmtree(out, ignore_errors=True)
            t0 = time.perf_counter()
            res = train_evaluator(data, out, cfg, log=lambda s: None)
            dt = time.perf_counter() - t0
            g = res.card["gt_retrieval"]
            tr = res.card["train_retrieval"]
            ev = load_evaluator(out, allow_failed_gate=True)
            test_items = load_items(data, "test", variant).items
            sep = separation(ev, test_items)
            ceiling = ceiling_top1(test_items, g["requested_pool_size"], g["replications"], g["seed"])
            print(f"\n[{variant}, control={control}] evaluator {res.evaluator_id[:12]}  trained in {dt:.1f} s "
                  f"({cfg.train.epochs} epochs, text frozen for {cfg.train.text_unfreeze_epoch})")
            print(f"  test: {g['items']} items, pool {g['pool_size']} ({g['pools_per_replication']} per replication, "
                  f"{g['replications']} replications), chance {g['chance_top1']:.3f}")
            print(f"  R-precision top-1 {g['top1']['mean']:.3f} +- {g['top1']['ci95']:.3f}  "
                  f"top-2 {g['top2']['mean']:.3f}  top-3 {g['top3']['mean']:.3f}  MM-Dist {g['mm_dist']['mean']:.3f}  "
                  f"(train top-1 {tr['top1']['mean']:.3f})")
            print(f"  GT-vs-GT FID {g['fid_gt_halves']:.4f} (halves of {g['half_size']}, "
                  f"relative {g['fid_gt_relative']:.3f})")
            print(f"  nearest motion has the caption's action {sep['action']:.3f} (chance {sep['action_chance']:.3f}), "
                  f"object {sep['object']:.3f} (chance {sep['object_chance']:.3f})")
            print(f"  top-1 ceiling when same-(action, object) clips share captions: {ceiling:.3f}")
            print(f"  sanity gate: {'passed' if res.gate.passed else 'FAILED'}")
    finally:
        if not args.keep:
            shutil.rmtree(tmp, ignore_errors=True)


def speed(args) -> None:
    import torch

    from hoibench.evaluator import build_untrained, preset
    from hoibench.evaluator.features import FeatureStats
    from hoibench.representations import hml263
    rng = np.random.default_rng(0)
    stats = FeatureStats(np.zeros(hml263.DIM, np.float32), np.ones(hml263.DIM, np.float32))
    words = "a person lifts carries pushes the small large box chair with both hands slowly and then".split()
    texts = [" ".join(rng.choice(words, size=int(rng.integers(6, 13)))) for _ in range(512)]
    print(f"torch {torch.__version__}, {torch.get_num_threads()} default threads")
    for size in ("paper", "tiny"):
        for threads in args.threads:
            ev = build_untrained(preset(size), stats)
            ev.threads = threads
            for frames in args.frames:
                feats = rng.normal(size=(args.clips, frames, hml263.DIM)).astype(np.float32)
                ev.embed_motion(feats[:8])
                best = min(_timed(lambda: ev.embed_motion(feats)) for _ in range(3))
                print(f"{size:5s} threads {threads}: motion {frames:3d} rows: {args.clips / best:8.1f} clips/s")
            ev.embed_text(texts[:8])
            best = min(_timed(lambda: ev.embed_text(texts)) for _ in range(3))
            print(f"{size:5s} threads {threads}: text: {len(texts) / best:8.1f} captions/s")


def _timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("speed")
    s.add_argument("--clips", type=int, default=256)
    s.add_argument("--frames", type=int, nargs="+", default=[196, 60])
    s.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    q = sub.add_parser("quality")
    q.add_argument("--clips", type=int, default=200)
    q.add_argument("--epochs", type=int, default=60)
    q.add_argument("--seed", type=int, default=0)
    q.add_argument("--variants", nargs="+", default=["human", "hoi"])
    q.add_argument("--keep", help="work folder to keep (store and evaluators); reused when it holds a store")
    args = ap.parse_args(argv)
    speed(args) if args.cmd == "speed" else quality(args)


if __name__ == "__main__":
    main()
