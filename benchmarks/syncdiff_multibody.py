"""SyncDiff on the multi-body synthetic track: the full model, its ablations, the untrained
model and the static reference, every row a standard submission scored by `hoibench evaluate`
(docs/baselines.md, "SyncDiff").

    python benchmarks/syncdiff_multibody.py [--out /tmp/sd_bench] [--clips 216] [--steps N] [--set K=V]

Writes the synthetic multi-body store, trains the recognizer, trains SyncDiff tiny (``--steps``
overrides its step count) and the two ablations that change training (``decompose``,
``align_loss``), samples every row (the explicit-sync ablations from the same runs with
``syncdiff.explicit_sync=false``), evaluates them and prints the track's metrics with their
95% half-widths, the training times and the sampling time per sample (AIT). Every stage is
skipped when its output exists, so a rerun continues.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from hoibench.baselines.commands import parse_overrides
from hoibench.baselines.sampler import sample
from hoibench.baselines.syncdiff.config import preset
from hoibench.baselines.trainer import train
from hoibench.datasets import multibody as mbl
from hoibench.datasets import synthetic_multibody as syn
from hoibench.datasets.store import PrepareConfig, prepare
from hoibench.evaluator.recognizer import train_recognizer
from hoibench.scoring.evaluate import evaluate
from hoibench.scoring.multibody import write_multibody_submission

KEYS = ("csr", "crr", "csiou", "iv_cm3", "id_mm", "sd", "od", "ra", "fid")
RUNS = {"full": {}, "no_decompose": {"syncdiff.decompose": False}, "no_align": {"syncdiff.align_loss": False}}
ROWS = (("SyncDiff tiny", "full", {}), ("w/o decompose", "no_decompose", {}), ("w/o L_align", "no_align", {}),
        ("w/o exp sync", "full", {"syncdiff.explicit_sync": False}),
        ("w/o L_align, exp sync", "no_align", {"syncdiff.explicit_sync": False}),
        ("SyncDiff tiny, untrained", "untrained", {}))


def _fmt(res: dict, k: str) -> str:
    m = res["metrics"].get(k)
    if m is None:
        return "-"
    ci = m.get("ci95")
    return f"{m['mean']:.4g}" + (f" ± {ci:.2g}" if ci is not None else "")


def _test_clips(sub: Path, data: Path, family: str | None = None):
    """(clip id, ground-truth clip, generated clips) of each test clip (of ``family`` only when given)."""
    from hoibench.bodies.multibody import MultiBodyClip
    from hoibench.datasets.store import Store
    from hoibench.scoring.multibody_samples import clip_from_sample
    from hoibench.scoring.submission import Submission
    store = Store(data)
    with Submission(sub) as s:
        for cid in store.clip_ids("test"):
            if family is not None and f"_{family}_" not in cid:
                continue
            gt = MultiBodyClip.from_arrays(store.load(cid), store.object_template)
            arrays = s.load(cid, keys=None)
            yield cid, gt, [clip_from_sample(gt, arrays, k, cid) for k in range(len(next(iter(arrays.values()))))]


def family_scores(sub: Path, data: Path, rec_dir: Path, family: str = "hands") -> tuple[float, float]:
    """(RA, FID) of the recognizer on one family's test clips (the TACO-like ``hands`` by
    default): accuracy on the generated clips, Frechet distance to the ground truth's features."""
    from hoibench.evaluator.recognizer import load_recognizer
    from hoibench.metrics.embedding import fid
    rec = load_recognizer(rec_dir)
    gts, gens = [], []
    for _, gt, clips in _test_clips(sub, data, family):
        gts.append(gt)
        gens += clips
    gen_feats, pred = rec.run(gens)
    gt_feats, _ = rec.run(gts)
    return float(sum(p == g.action for p, g in zip(pred, gens)) / len(gens)), float(fid(gt_feats, gen_feats))


def clip_accuracy(sub: Path, data: Path, rec_dir: Path) -> dict[str, float]:
    """Per test clip: the fraction of its samples the recognizer labels with the clip's action."""
    from hoibench.evaluator.recognizer import load_recognizer
    rec = load_recognizer(rec_dir)
    out = {}
    for cid, _, gens in _test_clips(sub, data):
        _, pred = rec.run(gens)
        out[cid] = float(np.mean([p == g.action for p, g in zip(pred, gens)]))
    return out


def paired_ra_difference(a: dict[str, float], b: dict[str, float], reps: int = 10_000, seed: int = 0
                         ) -> tuple[float, float, float]:
    """RA(a) - RA(b) on the same clips, with a 95% paired bootstrap interval (clips resampled
    with replacement, ``reps`` times, seeded): the comparison the unpaired per-row intervals
    are too wide for, since both rows are scored on the same 54 prompts."""
    ids = sorted(a)
    if sorted(b) != ids:
        raise ValueError("paired_ra_difference: the two submissions cover different clips")
    d = np.array([a[c] - b[c] for c in ids])
    idx = np.random.default_rng(seed).integers(0, len(d), size=(reps, len(d)))
    boot = d[idx].mean(1)
    return float(d.mean()), float(np.quantile(boot, 0.025)), float(np.quantile(boot, 0.975))


def contact_and_recognizer_scores(sub: Path, data: Path, rec_dir: Path) -> dict:
    """CSIoU, RA and FID of a submission computed as the scorer does, without IV and ID: for a
    submission whose bodies are so far-flung that IV's 5 mm voxels over their overlapping
    boxes (about 10^8 per frame and pair for 2.5 m skeletons) cannot be counted in reasonable
    time -- the untrained model's."""
    from hoibench.bodies.capsules import object_fields, pair_contact_frames
    from hoibench.bodies.multibody import MultiBodyClip
    from hoibench.datasets.store import Store
    from hoibench.evaluator.recognizer import load_recognizer
    from hoibench.metrics import multibody as mbm
    from hoibench.metrics.embedding import fid
    from hoibench.scoring.multibody_samples import clip_from_sample
    from hoibench.scoring.submission import Submission
    from hoibench.tracks.protocol import get_protocol
    proto = get_protocol("multibody-synthetic")
    store, rec = Store(data), load_recognizer(rec_dir)
    csiou = mbm.CSIoU(threshold_m=proto.csr_threshold_m, empty_union=proto.csiou_empty_union)

    def contacts(clip, fields):
        out = {}
        for (skel, _), f in pair_contact_frames(clip, fields, proto.csr_threshold_m, proto.crr_threshold_m).items():
            out[skel] = out[skel] | f if skel in out else f
        return out
    gts, gens = [], []
    with Submission(sub) as s:
        for cid in store.clip_ids("test"):
            gt = MultiBodyClip.from_arrays(store.load(cid), store.object_template)
            fields = object_fields(gt)
            g = contacts(gt, fields)
            arrays = s.load(cid, keys=None)
            gts.append(gt)
            for k in range(len(next(iter(arrays.values())))):
                clip = clip_from_sample(gt, arrays, k, cid)
                gens.append(clip)
                c = contacts(clip, fields)
                skel = [b.name for b in gt.bodies if b.kind in ("hand", "human")]
                csiou.update_frames(f"{cid}#{k}", [c[n] for n in skel], [g[n] for n in skel])
    gen_feats, pred = rec.run(gens)
    gt_feats, _ = rec.run(gts)
    correct = [float(p == g.action) for p, g in zip(pred, gens)]
    v = list(csiou.per_clip().values())
    return {"csiou": (csiou.compute(), 1.96 * np.std(v) / np.sqrt(len(v))),
            "ra": (float(np.mean(correct)), 1.96 * np.std(correct) / np.sqrt(len(correct))),
            "fid": (float(fid(gt_feats, gen_feats)), None)}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", type=Path, default=Path("/tmp/sd_bench"))
    ap.add_argument("--clips", type=int, default=216)
    ap.add_argument("--steps", type=int, default=None, help="training steps (default: the tiny config's)")
    ap.add_argument("--set", action="append", default=[], metavar="SECTION.FIELD=VALUE",
                    help="override a config field of every trained run (JSON value), e.g. "
                         "syncdiff.freq_position='\"index\"' for the tiny config before 0.7.0")
    ap.add_argument("--executor", default="processes:2")
    args = ap.parse_args()
    try:
        overrides = parse_overrides(args.set)                # the CLI's --set: JSON values, bare words strings
        preset("tiny").replace(**overrides)                  # an unknown field or a bad value, named
    except ValueError as exc:
        ap.error(str(exc))
    out, data = args.out, args.out / "data"
    if not (data / "manifest.json").exists():
        mbl.write_synthetic_layout(out / "raw", args.clips, seed=0)
        cfg = PrepareConfig("multibody-synthetic", fps=syn.FPS)
        prepare(mbl.prepare_jobs(out / "raw", None, data, cfg), data, cfg)
    if not (out / "rec" / "recognizer.json").exists():
        train_recognizer(data, out / "rec")
    times = {}
    for name, over in {**RUNS, "untrained": None}.items():
        cfg = preset("tiny").replace(**({"train.steps": 0} if over is None else
                                        {**overrides, **over,
                                         **({"train.steps": args.steps} if args.steps else {})}))
        t = time.perf_counter()
        train("syncdiff", data, out / f"run_{name}", cfg, threads=1)
        times[name] = json.loads((out / f"run_{name}" / "train_log.json").read_text())["seconds"] \
            if (out / f"run_{name}" / "train_log.json").exists() else time.perf_counter() - t
    subs = {"static reference": write_multibody_submission(data, out / "sub_static", kind="static")} \
        if not (out / "sub_static").exists() else {"static reference": out / "sub_static"}
    for label, run, inference in ROWS:
        path = out / ("sub_" + label.replace(" ", "_").replace(",", "").replace("/", ""))
        if not path.exists():
            sample(out / f"run_{run}", data, path, inference=inference or None)
        subs[label] = path
    print(f"training seconds (1 thread): {json.dumps(times)}")
    print("| row | " + " | ".join(KEYS) + " |")
    for label, path in subs.items():
        res_path = path.with_suffix(".json")
        if res_path.exists():
            res = json.loads(res_path.read_text())
        else:
            res = evaluate(path, data, out / "rec", executor=args.executor)
            res_path.write_text(json.dumps(res, indent=1))
        print(f"| {label} | " + " | ".join(_fmt(res, k) for k in KEYS) + " |")
    print("RA minus the static reference's, paired over the test clips (95% bootstrap interval):")
    static = clip_accuracy(subs["static reference"], data, out / "rec")
    for label, path in subs.items():
        if label != "static reference":
            d, lo, hi = paired_ra_difference(clip_accuracy(path, data, out / "rec"), static)
            print(f"| {label} | {d:+.3f} [{lo:+.3f}, {hi:+.3f}] |")
    print("TACO-like family (hands), RA / FID:")
    for label, path in subs.items():
        ra, f = family_scores(path, data, out / "rec")
        print(f"| {label} | {ra:.3f} | {f:.3f} |")


if __name__ == "__main__":
    main()
