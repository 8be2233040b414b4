"""Physical metrics, legacy vs clean, on synthetic ground truth and injected defects.

    python benchmarks/physical_modes.py [--clips 16] [--seed 1]

Writes ``--clips`` synthetic clips (BEHAVE layout, seed ``--seed``) four times: clean, with
foot skating (1.5 m/s) injected into clips 4 and 13, with a 3 cm penetration into clips 11
and 13, and with 5 cm of lost contact into clips 11 and 13; prepares each at 20 fps and
scores every clip of it as a submission with ``PhysicalConfig(mode)`` for both modes
(contact thresholds ``chainhoi``). Ground-truth contact labels always come from the clean
data. Prints the Markdown table of docs/metrics.md ("Legacy vs clean, measured").
"""
from __future__ import annotations

import argparse
import shutil
import tempfile
from pathlib import Path

VARIANTS = {
    "ground truth": None,
    "skating": {4: ("foot_skating", 1.5), 13: ("foot_skating", 1.5)},
    "penetration": {11: ("penetration", 0.03), 13: ("penetration", 0.03)},
    "lost contact": {11: ("lost_contact", 0.05), 13: ("lost_contact", 0.05)},
}


def _store(base: Path, clips: int, seed: int, defects):
    from hoibench.datasets import behave
    from hoibench.datasets.synthetic import Defect, write_behave_layout
    from hoibench.datasets.store import PrepareConfig, Store, prepare
    raw, data = base / "raw", base / "data"
    d = None if defects is None else {i: Defect(k, m) for i, (k, m) in defects.items()}
    write_behave_layout(raw, clips, seed=seed, defects=d, progress=False)
    cfg = PrepareConfig("synthetic", fps=20.0)
    prepare(behave.prepare_jobs(raw, raw / "body_models", data, cfg, split_file=raw / "split.json"),
            data, cfg, source={"root": str(raw)})
    return Store(data)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--clips", type=int, default=16)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)

    from hoibench.metrics.physical import PhysicalConfig, clip_inputs, evaluate_physical

    tmp = Path(tempfile.mkdtemp(prefix="hoibench-physical-modes-"))
    try:
        gt = _store(tmp / "clean", args.clips, args.seed, None)
        print("| data | mode | CD ×1e-3 | PS | depth max / mean (m) | FSR | FSR (GMD) | IoU | floating |")
        print("|---|---|---|---|---|---|---|---|---|")
        for name, defects in VARIANTS.items():
            store = gt if defects is None else _store(tmp / name.replace(" ", "_"), args.clips, args.seed, defects)
            motions = {c: store.load(c) for c in store.clip_ids()}
            for mode in ("legacy", "clean"):
                inputs = clip_inputs(gt, motions, contact_mode="chainhoi")
                r = evaluate_physical(inputs, PhysicalConfig(mode)).compute()
                print(f"| {name} | {mode} | {r['cd'] * 1e3:.3f} | {r['ps']:.4f} | "
                      f"{r['penetration_depth_max_m']:.3f} / {r['penetration_depth_mean_m']:.4f} | "
                      f"{r['fsr']:.4f} | {r['fsr_gmd']:.4f} | {r['contact_iou']:.3f} | "
                      f"{r['object_floating_ratio']:.4f} |")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
