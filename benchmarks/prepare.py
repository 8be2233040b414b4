"""Throughput of ``hoibench prepare`` on generated sequences, 1 and 2 workers.

    python benchmarks/prepare.py [--clips 200] [--workers 1 2] [--fps 20] [--layouts behave omomo rich]

Generates the synthetic dataset in the BEHAVE raw layout (timed separately), then prepares
it into a fresh store once per worker count (1 = serial, N > 1 = processes:N) and prints
source frames/s (30 fps input) and output frames/s. Also checks that the stores are
byte-identical.
"""
from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

from hoibench.datasets import behave
from hoibench.datasets.synthetic import write_behave_layout
from hoibench.datasets.store import PrepareConfig, prepare


def _files(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def run_layout(layout: str, tmp: Path, args) -> None:
    raw = tmp / "raw"
    t0 = time.perf_counter()
    if layout == "behave":
        m = write_behave_layout(raw, args.clips, seed=0, progress=False)
        loader, split_file = behave, raw / "split.json"
    else:
        from hoibench.datasets import omomo, rich, synthetic_layouts
        m = getattr(synthetic_layouts, f"write_{layout}_layout")(raw, args.clips, seed=0)
        loader, split_file = {"omomo": omomo, "rich": rich}[layout], None
    src_frames = sum(c.get("num_frames", 0) for c in m.get("clips", [])) or None
    print(f"[{layout}] synth: {args.clips} sequences in {time.perf_counter() - t0:.1f} s"
          + (f", {src_frames} source frames at 30 fps" if src_frames else ""))
    cfg = PrepareConfig(layout, fps=args.fps, body_model_type="smplh" if layout == "behave" else "smplx")
    stores = {}
    for n in args.workers:
        out = tmp / f"store{n}"
        ex = "serial" if n == 1 else f"processes:{n}"
        t0 = time.perf_counter()
        man = prepare(loader.prepare_jobs(raw, raw / "body_models", out, cfg, split_file=split_file),
                      out, cfg, executor=ex)
        dt = time.perf_counter() - t0
        extra = f"{src_frames / dt:7.0f} source frames/s  " if src_frames else ""
        print(f"[{layout}] prepare, {ex:12s}: {dt:6.1f} s  {extra}"
              f"{man['counts']['frames'] / dt:7.0f} output frames/s ({args.fps:g} fps)  "
              f"{man['counts']['clips']} clips, {man['counts']['failed']} failed")
        stores[ex] = _files(out)
    ref = next(iter(stores.values()))
    print(f"[{layout}] stores byte-identical across worker counts:", all(s == ref for s in stores.values()))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--clips", type=int, default=200)
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--fps", type=float, default=20.0)
    ap.add_argument("--layouts", nargs="+", default=["behave", "omomo", "rich"],
                    help="raw layouts to generate and prepare")
    args = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="hoibench-bench-"))
    try:
        for layout in args.layouts:
            run_layout(layout, tmp / layout, args)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
