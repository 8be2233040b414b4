"""Do CATMO's generated contacts touch with the body parts the text names? Against chance.

For every test clip: the text's body parts ``P_i`` are the parts the annotator named in the
clip's actions (``DATA/annotations/<id>.json``, the parts its captions mention); CATMO
generates ``K`` samples from the clip's first caption and the contact VQ-VAE's decoded
contacts (probability > 0.5) are turned into body parts ``G_ik`` the way the annotator turns
contact labels into parts (:func:`hoibench.text.annotate.body_part_timeline`, same minimum
segment length). Scores per clip: Jaccard ``|G n P| / |G u P|`` (1 when both are empty) and
recall ``|G n P| / |P|``, averaged over the K samples. Also printed: the per joint-frame
accuracy and F1 of the generated contacts against the clip's ground-truth contact labels.

Chance is the same score against the other clips' texts (``P_j``, j != i, averaged), so a
generator that ignores the text scores the same matched and mismatched. The table gives
matched, chance and the paired difference with a 95% CI over clips (1.96 std / sqrt(n));
the ground-truth contacts are the ceiling row.

    python benchmarks/catmo_contacts.py --run RUN --data DATA [--samples 10]
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from hoibench.text.annotate import body_part_timeline, load_spec
from hoibench.baselines import joint_data as D
from hoibench.baselines.catmo.sampler import LoadedCatmo
from hoibench.evaluator.text import read_captions
from hoibench.datasets.store import Store


def parts_of(contacts: np.ndarray, spec) -> set[str]:
    return {s.part for s in body_part_timeline(np.asarray(contacts, bool), spec) if not s.transition}


def jaccard(g: set, p: set) -> float:
    return 1.0 if not g and not p else len(g & p) / len(g | p)


def recall(g: set, p: set) -> float:
    return 1.0 if not p else len(g & p) / len(p)


def scores(generated: list[list[set]], text_parts: list[set]) -> dict:
    """Matched and chance (other clips' texts) Jaccard and recall, with the paired difference."""
    n = len(text_parts)
    out = {}
    for name, fn in (("jaccard", jaccard), ("recall", recall)):
        matched = np.array([np.mean([fn(g, text_parts[i]) for g in generated[i]]) for i in range(n)])
        chance = np.array([np.mean([fn(g, text_parts[j]) for g in generated[i] for j in range(n) if j != i])
                           for i in range(n)])
        diff = matched - chance
        out[name] = {"matched": float(matched.mean()), "chance": float(chance.mean()),
                     "difference": float(diff.mean()), "ci95": float(1.96 * diff.std() / np.sqrt(n))}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--run", type=Path, required=True)
    ap.add_argument("--data", type=Path, required=True)
    ap.add_argument("--samples", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=None, help="write the figures as JSON here")
    args = ap.parse_args()
    spec = load_spec()
    run = LoadedCatmo(args.run)
    store = Store(args.data)
    run.check_store(store)
    ids = store.clip_ids("test")
    gen_parts, gt_parts, text_parts, acc, f1 = [], [], [], [], []
    for cid in ids:
        ann = json.loads((store.root / "annotations" / f"{cid}.json").read_text())
        text_parts.append({p for a in ann["actions"] for p in a.get("parts", [])})
        clip = store.load(cid)
        T = int(clip["joints"].shape[0])
        gt_parts.append([parts_of(clip["contacts"], spec)])
        points = None
        if run.requires_object:
            v, f = store.object_template(str(clip["object_name"]))
            points = D.surface_points(v, f, run.object_points, str(clip["object_name"]))
        caption = read_captions(store.root, cid)[0].text
        out = run.generate(caption, points, T, args.samples, (args.seed, "sample", cid))
        gen_parts.append([parts_of(c, spec) for c in out["contacts"]])
        g, t = out["contacts"], np.asarray(clip["contacts"], bool)[None]
        acc.append(float((g == t).mean()))
        tp, fp, fn = (g & t).sum(), (g & ~t).sum(), (~g & t).sum()
        f1.append(float(2 * tp / max(2 * tp + fp + fn, 1)))
    res = {"run": run.id[:12], "clips": len(ids), "samples": args.samples,
           "catmo": scores(gen_parts, text_parts), "ground_truth": scores(gt_parts, text_parts),
           "joint_frames_vs_gt": {"accuracy": float(np.mean(acc)), "f1": float(np.mean(f1)),
                                  "gt_positive_rate": float(np.mean([np.asarray(store.load(c)["contacts"]).mean()
                                                                     for c in ids]))},
           "mean_parts": {"text": float(np.mean([len(p) for p in text_parts])),
                          "generated": float(np.mean([len(g) for gs in gen_parts for g in gs]))}}
    print(f"Contact agreement with the text's body parts, run {res['run']}, {len(ids)} test clips, "
          f"K = {args.samples}")
    print("| contacts | Jaccard matched | Jaccard chance | difference (95% CI) | recall matched | recall chance |")
    print("|---|---:|---:|---:|---:|---:|")
    for row, key in (("CATMO generated", "catmo"), ("ground truth", "ground_truth")):
        j, r = res[key]["jaccard"], res[key]["recall"]
        print(f"| {row} | {j['matched']:.3f} | {j['chance']:.3f} | {j['difference']:+.3f} ± {j['ci95']:.3f} | "
              f"{r['matched']:.3f} | {r['chance']:.3f} |")
    jf = res["joint_frames_vs_gt"]
    print(f"per joint-frame against the clip's ground-truth contacts: accuracy {jf['accuracy']:.3f}, F1 {jf['f1']:.3f} "
          f"(ground-truth positive rate {jf['gt_positive_rate']:.3f})")
    if args.out:
        args.out.write_text(json.dumps(res, indent=1) + "\n")


if __name__ == "__main__":
    main()
