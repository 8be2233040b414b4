"""Ctrl-C, then the same command again: ``hoibench annotate`` and ``hoibench train-evaluator``
resume and end byte-identical to an uninterrupted run.

    python benchmarks/interrupt_resume.py [--clips 24] [--epochs 4]

Builds a synthetic store, then for each command: one uninterrupted run (the reference); one
run in its own process group that gets SIGINT (a terminal's Ctrl-C) once its first output
appears (``annotations/*.json``; ``checkpoint/last.pt``), then the same command again. Prints
each run's exit status and seconds, and whether every output file is byte-identical to the
reference (annotate: ``annotations/`` and ``texts/``; train-evaluator: every file of the
evaluator folder but the training log's timings). Exit status 1 when a file differs.
"""
from __future__ import annotations

import argparse
import filecmp
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: files whose content records wall-clock time (not compared)
TIMED = {"train_log.json", "training_log.json"}


def run(cmd: list[str], wait_for: Path | None = None) -> tuple[int, float, bool]:
    """(exit status, seconds, interrupted?) of ``cmd``; with ``wait_for``, SIGINT to its process
    group once a file matching that glob pattern exists."""
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    t0 = time.monotonic()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, env=env)
    sent = False
    if wait_for is not None:
        while proc.poll() is None and not any(wait_for.parent.glob(wait_for.name)):
            time.sleep(0.05)
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGINT)
            sent = True
    _, err = proc.communicate(timeout=3600)
    if proc.returncode not in (0, 130):
        print(err.strip().splitlines()[-1:] if err.strip() else "", file=sys.stderr)
    return proc.returncode, time.monotonic() - t0, sent


def differing(a: Path, b: Path) -> list[str]:
    """Relative paths present in one tree only or with other bytes (timed logs skipped)."""
    files = lambda root: {p.relative_to(root) for p in root.rglob("*") if p.is_file()}  # noqa: E731
    fa, fb = files(a), files(b)
    out = sorted(str(p) for p in fa ^ fb if p.name not in TIMED)
    out += sorted(str(p) for p in fa & fb if p.name not in TIMED and not filecmp.cmp(a / p, b / p, shallow=False))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--clips", type=int, default=24)
    ap.add_argument("--epochs", type=int, default=4)
    args = ap.parse_args()
    from hoibench.datasets.synthetic_store import build_synthetic_store
    hb = [sys.executable, "-m", "hoibench.cli"]
    bad = 0
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        _, data, _ = build_synthetic_store(tmp / "base", args.clips, seed=0)
        ref, cut = tmp / "ref", tmp / "cut"
        shutil.copytree(data, ref)
        shutil.copytree(data, cut)
        code, s, _ = run(hb + ["annotate", str(ref)])
        print(f"annotate uninterrupted: exit {code} in {s:.1f} s")
        code, s, sent = run(hb + ["annotate", str(cut)], wait_for=cut / "annotations" / "*.json")
        print(f"annotate interrupted:   exit {code} after {s:.1f} s (SIGINT sent: {sent})")
        code, s, _ = run(hb + ["annotate", str(cut)])
        print(f"annotate rerun:         exit {code} in {s:.1f} s")
        diff = differing(ref / "annotations", cut / "annotations") + differing(ref / "texts", cut / "texts")
        n = sum(1 for d in ("annotations", "texts") for p in (ref / d).rglob("*") if p.is_file())
        print(f"annotate: {n} files, {'byte-identical' if not diff else 'DIFFERS: ' + ', '.join(diff[:5])}")
        bad += bool(diff)

        train = hb + ["train-evaluator", str(ref), "--size", "tiny", "--epochs", str(args.epochs), "--out"]
        code, s, _ = run(train + [str(tmp / "ev_ref")])
        print(f"train-evaluator uninterrupted: exit {code} in {s:.1f} s")
        code, s, sent = run(train + [str(tmp / "ev_cut")], wait_for=tmp / "ev_cut" / "checkpoint" / "last.pt")
        print(f"train-evaluator interrupted:   exit {code} after {s:.1f} s (SIGINT sent: {sent})")
        code, s, _ = run(train + [str(tmp / "ev_cut")])
        print(f"train-evaluator rerun:         exit {code} in {s:.1f} s")
        diff = differing(tmp / "ev_ref", tmp / "ev_cut")
        n = sum(1 for p in (tmp / "ev_ref").rglob("*") if p.is_file() and p.name not in TIMED)
        print(f"train-evaluator: {n} files, {'byte-identical' if not diff else 'DIFFERS: ' + ', '.join(diff[:5])}")
        bad += bool(diff)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
