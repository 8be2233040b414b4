"""Byte-identity check for refactors: run the README walk-through (single-body synthetic
store, the rich-cat track, the multi-body track, reference rows and short baseline runs)
with two source trees and compare every output file.

    python benchmarks/identical_outputs.py --ref main~3          # that commit vs this tree
    python benchmarks/identical_outputs.py --tree . --out /tmp/a  # one run: writes /tmp/a/hashes.json
    python benchmarks/identical_outputs.py --compare /tmp/a/hashes.json /tmp/b/hashes.json

Each tree runs ``python -m hoibench.cli`` with that tree first on ``PYTHONPATH``. Files are
compared by sha256; result JSONs first drop what legitimately varies (timings, the paths
given on the command line, progress). Exit 1 when anything differs, listing what.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: keys dropped from JSON files before hashing: wall-clock figures and the paths of this run
VOLATILE_KEYS = {"timings", "path", "root", "created", "seconds", "wall_s", "elapsed_s", "train_seconds",
                 "wall_time_s", "started", "finished", "hostname", "platform", "python", "executor", "timings_s",
                 "wall_s_this_call", "steps_per_second", "stage_seconds", "wall_seconds", "segment_seconds"}

STEPS = [
    # (name, argv) -- {o} is the output folder
    ("synth", ["synth", "--out", "{o}/raw", "--clips", "120"]),
    ("prepare", ["prepare", "behave", "--root", "{o}/raw", "--body-models", "{o}/raw/body_models",
                 "--split-file", "{o}/raw/split.json", "--out", "{o}/data"]),
    ("annotate", ["annotate", "{o}/data"]),
    ("train-evaluator", ["train-evaluator", "{o}/data", "--out", "{o}/ev", "--size", "tiny"]),
    ("gt", ["submission", "from-store", "{o}/data", "--out", "{o}/gt"]),
    ("evaluate-gt", ["evaluate", "{o}/gt", "--data", "{o}/data", "--evaluator", "{o}/ev", "--out", "{o}/gt.json"]),
    ("noise", ["submission", "reference", "{o}/data", "--kind", "gt-noise", "--out", "{o}/noise"]),
    ("evaluate-noise", ["evaluate", "{o}/noise", "--data", "{o}/data", "--evaluator", "{o}/ev",
                        "--out", "{o}/noise.json"]),
    ("mean-pose", ["baseline", "sample", "mean-pose", "--data", "{o}/data", "--out", "{o}/meanpose"]),
    ("chainhoi-train", ["baseline", "train", "chainhoi", "{o}/data", "--out", "{o}/run-chainhoi", "--steps", "6"]),
    ("chainhoi-sample", ["baseline", "sample", "chainhoi", "{o}/run-chainhoi", "--data", "{o}/data",
                         "--out", "{o}/chainhoi", "--ddim-steps", "3"]),
    ("chainhoi-evaluate", ["evaluate", "{o}/chainhoi", "--data", "{o}/data", "--evaluator", "{o}/ev",
                           "--out", "{o}/chainhoi.json"]),
    ("ejim-train", ["baseline", "train", "ejim", "{o}/data", "--out", "{o}/run-ejim", "--steps", "6"]),
    ("ejim-sample", ["baseline", "sample", "ejim", "{o}/run-ejim", "--data", "{o}/data", "--out", "{o}/ejim",
                     "--ddim-steps", "3"]),
    ("catmo-train", ["baseline", "train", "catmo", "{o}/data", "--out", "{o}/run-catmo"]
     + [a for f in ("train.vq_steps", "train.contact_steps", "text.movement_ae_steps", "text.match_steps",
                    "train.gpt_steps", "object.steps") for a in ("--set", f"{f}=3")]),
    ("catmo-sample", ["baseline", "sample", "catmo", "{o}/run-catmo", "--data", "{o}/data", "--out", "{o}/catmo"]),
    # rich-cat: a human-only store
    ("rich-synth", ["synth", "--layout", "rich", "--out", "{o}/rraw", "--clips", "40"]),
    ("rich-prepare", ["prepare", "rich", "--root", "{o}/rraw", "--body-models", "{o}/rraw/body_models",
                      "--out", "{o}/rdata"]),
    ("rich-annotate", ["annotate", "{o}/rdata"]),
    ("rich-gt", ["submission", "from-store", "{o}/rdata", "--out", "{o}/rgt"]),
    ("rich-evaluate", ["evaluate", "{o}/rgt", "--data", "{o}/rdata", "--evaluator", "{o}/ev", "--out",
                       "{o}/rgt.json", "--allow-failed-gate", "--allow-evaluator-mismatch"]),
    # multi-body
    ("mb-synth", ["synth", "--layout", "multibody", "--out", "{o}/mraw", "--clips", "54"]),
    ("mb-prepare", ["prepare", "multibody", "--root", "{o}/mraw", "--out", "{o}/mdata"]),
    ("mb-recognizer", ["train-recognizer", "{o}/mdata", "--out", "{o}/rec"]),
    ("mb-gt", ["submission", "reference", "{o}/mdata", "--kind", "gt", "--out", "{o}/mgt"]),
    ("mb-evaluate", ["evaluate", "{o}/mgt", "--data", "{o}/mdata", "--evaluator", "{o}/rec", "--out", "{o}/mgt.json"]),
    ("mb-desync", ["submission", "reference", "{o}/mdata", "--kind", "desync", "--out", "{o}/mdesync"]),
    ("mb-evaluate-desync", ["evaluate", "{o}/mdesync", "--data", "{o}/mdata", "--evaluator", "{o}/rec",
                            "--out", "{o}/mdesync.json"]),
]


def _scrub(obj, out_dir: str):
    if isinstance(obj, dict):
        return {k: _scrub(v, out_dir) for k, v in obj.items() if k not in VOLATILE_KEYS}
    if isinstance(obj, list):
        return [_scrub(v, out_dir) for v in obj]
    if isinstance(obj, str):
        return obj.replace(out_dir, "<OUT>")
    return obj


def file_digest(path: Path, out_dir: str) -> str:
    data = path.read_bytes()
    if path.suffix in (".json", ".jsonl"):
        try:
            if path.suffix == ".json":
                data = json.dumps(_scrub(json.loads(data), out_dir), sort_keys=True).encode()
            else:
                data = "\n".join(json.dumps(_scrub(json.loads(line), out_dir), sort_keys=True)
                                 for line in data.decode().splitlines() if line.strip()).encode()
        except ValueError:
            pass
    return hashlib.sha256(data).hexdigest()


def run_tree(tree: Path, out: Path) -> dict:
    """Run every step with ``tree`` on PYTHONPATH; return {relative path: sha256}."""
    out.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "PYTHONPATH": str(tree.resolve()), "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    times = {}
    done_file = out / "steps_done.txt"          # a rerun resumes after the last finished step
    done = set(done_file.read_text().split()) if done_file.exists() else set()
    for name, argv in STEPS:
        if name in done:
            continue
        t0 = time.perf_counter()
        cmd = [sys.executable, "-m", "hoibench.cli"] + [a.format(o=out) for a in argv]
        p = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=tree)
        times[name] = round(time.perf_counter() - t0, 1)
        if p.returncode != 0 and not (p.returncode == 1 and "evaluate" in name):   # 1: scored, incomplete
            sys.exit(f"{tree}: step {name} failed ({p.returncode}):\n{p.stdout[-2000:]}\n{p.stderr[-3000:]}")
        print(f"  [{tree}] {name}: {times[name]} s", flush=True)
        with open(done_file, "a") as f:
            f.write(name + "\n")
    hashes = {}
    for path in sorted(out.rglob("*")):
        if path.is_file() and path.name not in ("hashes.json", "steps_done.txt") and "loss" not in path.name:
            rel = str(path.relative_to(out))
            if rel.endswith((".png", ".gif", ".log")):
                continue
            hashes[rel] = file_digest(path, str(out))
    (out / "hashes.json").write_text(json.dumps(hashes, indent=1, sort_keys=True))
    return hashes


def compare(a: dict, b: dict) -> list[str]:
    diffs = [f"only in before: {k}" for k in sorted(set(a) - set(b))]
    diffs += [f"only in after: {k}" for k in sorted(set(b) - set(a))]
    diffs += [f"differs: {k}" for k in sorted(set(a) & set(b)) if a[k] != b[k]]
    return diffs


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ref", help="git ref of the 'before' tree (checked out into a temporary worktree)")
    ap.add_argument("--tree", type=Path, default=Path(__file__).resolve().parent.parent)
    ap.add_argument("--out", type=Path)
    ap.add_argument("--compare", nargs=2, type=Path, metavar=("BEFORE", "AFTER"))
    args = ap.parse_args()
    if args.compare:
        diffs = compare(*(json.loads(p.read_text()) for p in args.compare))
    elif args.ref:
        base = Path(args.out or tempfile.mkdtemp(prefix="hoibench-identity-"))
        before_tree = base / "before-tree"
        subprocess.run(["git", "worktree", "add", "--detach", str(before_tree), args.ref], check=True,
                       cwd=args.tree, capture_output=True)
        try:
            before = run_tree(before_tree, base / "before")
            after = run_tree(args.tree, base / "after")
        finally:
            subprocess.run(["git", "worktree", "remove", "--force", str(before_tree)], cwd=args.tree)
        diffs = compare(before, after)
    else:
        hashes = run_tree(args.tree, args.out or Path(tempfile.mkdtemp(prefix="hoibench-identity-")))
        print(f"{len(hashes)} files hashed")
        return 0
    for d in diffs:
        print(d)
    print("identical" if not diffs else f"{len(diffs)} difference(s)")
    return 1 if diffs else 0


if __name__ == "__main__":
    sys.exit(main())
