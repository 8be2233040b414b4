"""The baseline tables of docs/baselines.md (synthetic and rich-cat tracks), end to end through the public path.

Rows: ground truth (real motion), ChainHOI tiny (paper chain mask), ChainHOI tiny with the
released code's mask, EJIM tiny (1.82 M parameters) and micro (0.04 M), CATMO tiny, the untrained ChainHOI and CATMO tiny (0 steps),
mean pose + static object, and the reference rows of :mod:`hoibench.scoring.reference_rows` (GT + 1
and 3 cm noise, static first pose, mismatched texts).
Each is written as a standard submission and scored by ``hoibench.scoring.evaluate.evaluate`` under
the store's default protocol (synthetic-clean: 20 replications, pools of 32) with the given
evaluator. Runs, submissions and results are reused when they already exist (training and
sampling are deterministic), so a rerun only redoes what is missing.

On a human-only store (``--track rich-cat``: RICH's static scenes) the joint-level
diffusion baselines do not apply (their representation carries an object node) and their
rows are left out; CATMO runs without its object extension.

    make demo                                            # demo-out/data and demo-out/evaluator
    python benchmarks/baselines_synthetic.py --data demo-out/data --evaluator demo-out/evaluator \\
        --work baseline-runs
    python benchmarks/baselines_synthetic.py --track rich-cat --data rich/data --evaluator rich/ev --work rich-runs
"""
from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

from hoibench.baselines.registry import get_spec
from hoibench.baselines.sampler import sample
from hoibench.baselines.trainer import train
from hoibench.scoring.mean_pose import write_mean_pose_submission
from hoibench.scoring.clip_data import write_clip_data
from hoibench.scoring.evaluate import evaluate
from hoibench.core.io import atomic_write_json, atomic_write_text
from hoibench.publish.leaderboard import entry_from_result, write_entry
from hoibench.publish.leaderboard import attach_clip_data
from hoibench.scoring.submission import from_store

COLUMNS = [("fid", "FID", "down"), ("r_precision_top1", "R@1", "up"), ("r_precision_top3", "R@3", "up"),
           ("mm_dist", "MM-Dist", "down"), ("diversity", "Diversity", "near GT"), ("cd", "CD (m^2)", "down"),
           ("ocd", "OCD (m^2)", "down"), ("ps", "PS", "down"), ("fsr", "FSR", "down")]


NOTES = {"gt": "the test clips themselves: the ceiling of every metric",
         "mean-pose": "text-blind floor: mean train pose and static object (train statistics only)",
         "ref:gt-noise": "reference row: the ground truth with i.i.d. Gaussian noise on joints and object translation",
         "ref:static-first-pose": "reference row: each clip's first frame held still (body and object)",
         "ref:mismatched-texts": "reference row: the ground-truth motions reassigned to other clips' texts "
                                 "(a seeded derangement)",
         "chainhoi": "hoibench's implementation from the paper, tiny config, docs/baselines.md",
         "ejim": "hoibench's implementation from the paper, tiny config, docs/baselines.md",
         "ejim-micro": "hoibench's implementation from the paper, micro config (0.04 M parameters: ChainHOI "
                       "tiny's training time on one CPU thread), docs/baselines.md",
         "catmo": "hoibench's implementation from the paper (object head: hoibench's extension), tiny config, "
                  "docs/baselines.md"}
CATMO_UNTRAINED = {k: 0 for k in ("train.vq_steps", "train.contact_steps", "text.movement_ae_steps",
                                  "text.match_steps", "train.gpt_steps", "object.steps")}


def rows_spec(steps: int | None, human_only: bool = False) -> list[tuple[str, str, dict | None]]:
    tiny = {} if steps is None else {"train.steps": steps}
    rows = [("GT (real motion)", "gt", None),
            ("ChainHOI tiny", "chainhoi", tiny),
            ("ChainHOI tiny, released mask", "chainhoi", {**tiny, "model.mask": "released"}),
            ("EJIM tiny", "ejim", tiny),
            ("EJIM micro", "ejim", {**tiny, "config": "micro"}),
            ("CATMO tiny", "catmo", None),
            ("ChainHOI tiny, untrained", "chainhoi", {"train.steps": 0}),
            ("CATMO tiny, untrained", "catmo", CATMO_UNTRAINED),
            ("mean pose + static object", "mean-pose", None),
            ("GT + 1 cm noise", "ref:gt-noise", {"sigma": 0.01}),
            ("GT + 3 cm noise", "ref:gt-noise", {"sigma": 0.03}),
            ("static first pose", "ref:static-first-pose", None),
            ("mismatched texts", "ref:mismatched-texts", None)]
    if human_only:
        rows = [(("mean pose" if k == "mean-pose" else label), k, o) for label, k, o in rows
                if k not in ("chainhoi", "ejim")]
    return rows


def fmt(stat: dict | None) -> str:
    if not stat:
        return "-"
    m, ci = stat["mean"], stat["ci95"]
    if isinstance(m, list):
        m, ci = m[0], ci[0]
    return f"{m:.4g} ± {ci:.2g}" if abs(m) >= 1e-3 or m == 0 else f"{m:.3e} ± {ci:.1e}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--track", default="synthetic", help="leaderboard track name (synthetic, rich-cat, ...)")
    ap.add_argument("--data", type=Path, default=Path("demo-out/data"))
    ap.add_argument("--evaluator", type=Path, default=Path("demo-out/evaluator"))
    ap.add_argument("--work", type=Path, default=Path("baseline-runs"))
    ap.add_argument("--steps", type=int, default=None, help="training steps (default: the tiny config's)")
    ap.add_argument("--samples", type=int, default=1, help="samples per prompt (K)")
    ap.add_argument("--executor", default="serial")
    ap.add_argument("--only", default=None,
                    help="comma-separated row slugs to (re)make, e.g. gt-real-motion,gt-1-cm-noise (default: all)")
    ap.add_argument("--entries", type=Path, default=None,
                    help="also write leaderboard entries here (e.g. leaderboards/synthetic/entries)")
    args = ap.parse_args()
    work = args.work
    results = {}
    t_all = time.perf_counter()
    from hoibench.baselines.catmo.data import has_objects
    from hoibench.datasets.store import Store
    store = Store(args.data)
    human_only = not has_objects(store, store.clip_ids("test"))
    for label, kind, over in rows_spec(args.steps, human_only):
        slug = label.split(" (")[0].replace(", ", "-").replace(" + ", "-").replace(" ", "-").lower()
        if args.only and slug not in args.only.split(","):
            continue
        sub = work / "submissions" / slug
        res_path = work / "results" / f"{slug}.json"
        timing = {}
        if not (sub / "submission.json").exists():
            t0 = time.perf_counter()
            if kind == "gt":
                from_store(args.data, sub)
            elif kind.startswith("ref:"):
                from hoibench.scoring.reference_rows import write_reference
                write_reference(kind[4:], args.data, sub, **(over or {}))
            elif kind == "mean-pose":
                write_mean_pose_submission(args.data, sub)
            else:
                spec = get_spec(kind)
                over = dict(over or {})
                cfg = spec.preset(over.pop("config", "tiny"))
                cfg = cfg.replace(**over) if over else cfg
                run = work / "runs" / slug
                r = train(kind, args.data, run, cfg)
                timing["train_s"] = round(r.seconds, 1)
                t1 = time.perf_counter()
                sample(run, args.data, sub, samples=args.samples, log=None)
                timing["sample_s"] = round(time.perf_counter() - t1, 1)
            timing["make_submission_s"] = round(time.perf_counter() - t0, 1)
        if res_path.exists():
            result = json.loads(res_path.read_text())
        else:
            clips: dict = {}
            result = evaluate(sub, args.data, args.evaluator, executor=args.executor, clip_data=clips)
            result["baseline_timings_s"] = timing
            if clips:
                write_clip_data(result, clips, res_path)
            atomic_write_json(res_path, result)
        results[label] = result
        if args.entries is not None:
            meta = json.loads((sub / "submission.json").read_text())
            note = NOTES.get("ejim-micro" if label == "EJIM micro" else kind, "")
            hw = ((meta.get("source") or {}).get("training") or {}).get("hardware")
            if hw:
                note += f"; trained on {hw}" + (" and sampled there (benchmarks/tiny_baselines_cuda.sh)"
                                                if "cuda" in hw else "")
            entry = entry_from_result(result, method=label, track=args.track, submission_meta=meta, notes=note)
            attach_clip_data(entry, result, res_path, args.entries)
            entry["role"] = ("ground-truth" if kind == "gt" else
                             "reference" if (kind == "mean-pose" or kind.startswith("ref:") or "untrained" in label)
                             else "baseline")
            write_entry(entry, args.entries)
        print(f"[{label}] scored: FID {fmt(result['metrics'].get('fid'))}, "
              f"R@1 {fmt(result['metrics'].get('r_precision_top1'))}", flush=True)
    any_res = next(iter(results.values()))
    head = (f"{args.track} track, protocol {any_res['protocol']}@{any_res['protocol_version']}, evaluator "
            f"{str(any_res['evaluator_id'])[:12]}, {any_res['counts']['test_ids']} test prompts, "
            f"K = {args.samples}, mean ± 95% CI over {any_res['replications']} replications")
    lines = [head, "", "| row | " + " | ".join(c[1] for c in COLUMNS) + " |",
             "|---|" + "|".join("---:" for _ in COLUMNS) + "|"]
    for label, r in results.items():
        lines.append(f"| {label} | " + " | ".join(fmt(r["metrics"].get(k)) for k, _, _ in COLUMNS) + " |")
    lines += ["", "direction: " + ", ".join(f"{n} {d}" for _, n, d in COLUMNS),
              f"machine load {os.getloadavg()[0]:.2f}; total {time.perf_counter() - t_all:.0f} s"]
    text = "\n".join(lines)
    atomic_write_text(work / "table.md", text + "\n")
    print(text)


if __name__ == "__main__":
    main()
