"""ChainHOI's released metric rules (legacy protocols 1.2) against hoibench's clean rules, measured
on a synthetic store.

    python benchmarks/legacy_physical.py [--work DIR] [--clips 60] [--executor serial]

Builds (in ``--work``, a temporary folder by default; reused when it already holds them) a
synthetic store as a user would::

    hoibench synth --out X/raw --clips 60
    hoibench prepare behave --root X/raw --body-models X/raw/body_models --split-file X/raw/split.json --out X/data
    hoibench annotate X/data                     # semantic groups, for OCD
    hoibench submission from-store X/data --out X/gt
    hoibench submission reference X/data --kind gt-noise --sigma 0.03 --out X/noise

then scores both submissions' physical metrics (``hoibench.metrics.physical``) under:
``behave-clean``; ``behave-legacy`` with every reference rule off (= protocol 1.1); each rule
of behave-legacy 1.2 switched on alone; behave-legacy 1.2; the same for ``omomo-legacy``.
With a length crop the value is the mean over the protocol's 20 replications (each clip and
replication draws its own window), with the range. Ground-truth contact labels come from
the joint-object distances under each rule (the store's synthetic labels are hidden), as on
real BEHAVE and OMOMO stores. Prints the Markdown tables of docs/metrics.md ("Legacy rules,
measured").
"""
from __future__ import annotations

import argparse
import dataclasses
import subprocess
import sys
import tempfile
from pathlib import Path

METRICS = ("cd", "ocd", "ps", "fsr", "contact_iou", "jitter_mps3")
#: per protocol: (label, settings switched on) -- applied on top of the protocol with every
#: reference rule at its clean default
STEPS = {
    "behave-legacy": [("ocd_members: crop", ("ocd_members",)),
                      ("contact_gt_rule: unsigned", ("contact_gt_rule",)),
                      ("fsr_frame: canonical", ("fsr_frame",)),
                      ("length_crop: unit4_random", ("length_crop",))],
    "omomo-legacy": [("ocd_members: crop", ("ocd_members",)),
                     ("contact_joints: wrists", ("contact_joints",)),
                     ("GT |d| <= 0.5 m", ("contact_gt_rule", "contact_gt_threshold_m")),
                     ("fsr_frame: canonical + feet to floor", ("fsr_frame", "fsr_feet_to_floor")),
                     ("length_crop: unit4_start", ("length_crop",))],
}
RULES = ("ocd_members", "contact_joints", "contact_gt_rule", "contact_gt_threshold_m", "fsr_frame",
         "fsr_feet_to_floor", "length_crop")


def _cli(*args: str) -> None:
    subprocess.run([sys.executable, "-m", "hoibench.cli", *args], check=True, stdout=subprocess.DEVNULL)


def build(work: Path, clips: int) -> None:
    """The store and the two submissions (skipped when present)."""
    x = str(work)
    if not (work / "data" / "manifest.json").exists():
        _cli("synth", "--out", f"{x}/raw", "--clips", str(clips))
        _cli("prepare", "behave", "--root", f"{x}/raw", "--body-models", f"{x}/raw/body_models",
             "--split-file", f"{x}/raw/split.json", "--out", f"{x}/data")
    if not (work / "data" / "annotations" / "index.json").exists():
        _cli("annotate", f"{x}/data")
    if not (work / "gt").exists():
        _cli("submission", "from-store", f"{x}/data", "--out", f"{x}/gt")
    if not (work / "noise").exists():
        _cli("submission", "reference", f"{x}/data", "--kind", "gt-noise", "--sigma", "0.03", "--out", f"{x}/noise")


def _without_rules(cfg):
    """``cfg`` with every reference rule at its clean default (the protocol's 1.1 semantics)."""
    default = {f.name: f.default for f in dataclasses.fields(cfg) if f.name in RULES}
    return dataclasses.replace(cfg, **default)


class _NoStoredLabels:
    """The store with its clips' stored ``contacts`` hidden: ground-truth labels then come from
    distances under each rule, as on real BEHAVE and OMOMO stores (which carry no labels)."""

    def __init__(self, store):
        self._store = store

    def __getattr__(self, name):
        return getattr(self._store, name)

    def load(self, cid, *args, **kwargs):
        clip = dict(self._store.load(cid, *args, **kwargs))
        clip.pop("contacts", None)
        return clip


def score(store, motions, groups, cfg, proto, executor: str) -> dict:
    """``{metric: (mean, lo, hi)}`` under ``cfg`` (over replications when lengths are cropped)."""
    from hoibench.metrics.legacy_rules import replication_windows
    from hoibench.metrics.physical import clip_inputs, evaluate_physical, evaluate_physical_windows

    inputs = clip_inputs(store, motions, sample=0, groups=groups, contact_mode=proto.physical["contact_thresholds"],
                         gt_rule=cfg.contact_gt_rule, gt_threshold_m=cfg.contact_gt_threshold_m)
    if cfg.length_crop == "none":
        r = evaluate_physical(inputs, cfg, executor=executor).compute()
        return {m: (r[m], r[m], r[m]) for m in METRICS}
    frames = {c["id"]: int(c["frames"]) for c in store.manifest["clips"]}
    for inp in inputs:
        inp.windows = replication_windows(inp.key[0], frames[inp.key[0]], cfg.length_crop,
                                          range(proto.replications), proto.seed_for)
    reps = [m.compute() for m in evaluate_physical_windows(inputs, cfg, executor=executor).values()]
    return {m: (sum(r[m] for r in reps) / len(reps), min(r[m] for r in reps), max(r[m] for r in reps))
            for m in METRICS}


def _fmt(name: str, v: tuple) -> str:
    mean, lo, hi = v
    scale = 1e3 if name in ("cd", "ocd") else 1.0
    if lo == hi:
        return f"{mean * scale:.4f}"
    return f"{mean * scale:.4f} [{lo * scale:.4f}, {hi * scale:.4f}]"


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--work", type=Path, default=None)
    ap.add_argument("--clips", type=int, default=60)
    ap.add_argument("--executor", default="serial")
    args = ap.parse_args(argv)
    from hoibench.datasets.store import Store
    from hoibench.metrics.physical import load_groups
    from hoibench.scoring.submission import Submission
    from hoibench.tracks.protocol import get_protocol

    work = args.work or Path(tempfile.mkdtemp(prefix="hoibench-legacy-physical-"))
    build(work, args.clips)
    store, groups = _NoStoredLabels(Store(work / "data")), load_groups(work / "data")
    print(f"store: {work / 'data'}, {len(store.clip_ids('test'))} test clips; CD, OCD x 1e-3 m^2; "
          f"[min, max] over 20 replications where lengths are cropped\n")
    for sub_name in ("gt", "noise"):
        sub = Submission(work / sub_name)
        motions = {cid: {k: v[0] for k, v in sub.load(cid).items()} for cid in sorted(sub.ids)}
        print(f"### submission: {sub_name}\n")
        print("| protocol / rule | " + " | ".join(METRICS) + " |")
        print("|---|" + "---|" * len(METRICS))
        clean = get_protocol("behave-clean")
        row = score(store, motions, groups, clean.physical_config(), clean, args.executor)
        print("| behave-clean | " + " | ".join(_fmt(m, row[m]) for m in METRICS) + " |")
        for pid, steps in STEPS.items():
            proto = get_protocol(pid)
            full = proto.physical_config()
            base = _without_rules(full)
            rows = [(f"{pid} 1.1 (no reference rule)", base)]
            rows += [(f"  + {label}", dataclasses.replace(base, **{k: getattr(full, k) for k in keys}))
                     for label, keys in steps]
            rows.append((f"{pid} {proto.version} (all)", full))
            for label, cfg in rows:
                row = score(store, motions, groups, cfg, proto, args.executor)
                print(f"| {label} | " + " | ".join(_fmt(m, row[m]) for m in METRICS) + " |")
        print()


if __name__ == "__main__":
    main()
