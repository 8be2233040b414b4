"""How fast an interrupted ``hoibench prepare`` stops.

    python benchmarks/interrupts.py [--clips 12] [--repeats 3]

Writes a synthetic raw folder, starts ``hoibench prepare behave --executor processes:2`` in
its own process group, waits for the first clip, sends SIGINT to the group (a terminal's
Ctrl-C) or SIGTERM to the parent, and prints the seconds until the command exits and its
exit status (target: < 2 s, status 130; docs/security.md, "Interrupts").
"""
from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def one_run(raw: Path, out: Path, sig: int, group: bool) -> tuple[float, int]:
    cmd = [sys.executable, "-m", "hoibench.cli", "prepare", "behave", "--root", str(raw), "--body-models",
           str(raw / "body_models"), "--split-file", str(raw / "split.json"), "--out", str(out),
           "--executor", "processes:2"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    while not any((out / "clips").glob("*.npz")):
        if proc.poll() is not None:
            raise RuntimeError(f"prepare ended before the first clip: {proc.stderr.read()}")
        time.sleep(0.05)
    t0 = time.monotonic()
    if group:
        os.killpg(proc.pid, sig)
    else:
        proc.send_signal(sig)
    proc.communicate(timeout=60)
    return time.monotonic() - t0, proc.returncode


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--clips", type=int, default=12)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    from hoibench.datasets.synthetic import write_behave_layout
    with tempfile.TemporaryDirectory() as tmp:
        raw = Path(tmp) / "raw"
        write_behave_layout(raw, args.clips, seed=0, progress=False)
        for name, sig, group in (("SIGINT to the group", signal.SIGINT, True),
                                 ("SIGTERM to the parent", signal.SIGTERM, False)):
            for r in range(args.repeats):
                s, code = one_run(raw, Path(tmp) / f"out-{sig}-{r}", sig, group)
                print(f"{name:22s} run {r}: exit {code} after {s:.2f} s")


if __name__ == "__main__":
    main()
