"""Measure hml263 legacy vs clean on the same clips, overall and quirk by quirk.

    python benchmarks/legacy_vs_clean.py [--clips 200] [--frames 196] [--turn-dps 30]

Prints Markdown tables (used in docs/representations.md): the per-group difference between
the two modes, and for each legacy quirk alone (clean with that one switch set as legacy)
the mean absolute feature difference it causes and the round-trip error it leaves.
"""
from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from hoibench.datasets.random_motion import random_motion
from hoibench.representations import compare, hml263

QUIRKS = {
    "retarget to reference skeleton": {"retarget": True},
    "floor = global min y": {"floor": "global_min"},
    "swapped hips in facing (IK)": {"swap_hips_in_ik": True},
    "identity heading on frame 0": {"identity_first_root": True},
    "Gaussian heading smoothing (20 frames)": {"heading_sigma_frames": 20.0},
    "float32 quaternion arithmetic": {"float32": True},
    "arcsin heading step": {"signed_heading_step": False},
    "contacts: 0.002 sq. disp., no height test": {"foot_sq_disp_thresh": 0.002, "foot_speed_mps": None,
                                                  "foot_height_m": None},
}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--clips", type=int, default=200)
    ap.add_argument("--frames", type=int, default=196)
    ap.add_argument("--turn-dps", type=float, default=30.0)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    joints = random_motion(args.frames, seed=args.seed, batch=args.clips, turn_dps=args.turn_dps)
    legacy, gl = hml263.encode(joints, mode="legacy", return_positions=True)
    clean, gc = hml263.encode(joints, mode="clean", return_positions=True)
    print(f"{args.clips} clips x {args.frames} frames, turn rate up to {args.turn_dps} deg/s, seed {args.seed}\n")
    print(compare.markdown_table(compare.group_differences(legacy, clean)))
    rt_l = np.abs(hml263.decode(legacy) - gl[:, :-1]).max(axis=(1, 2, 3))
    rt_c = np.abs(hml263.decode(clean) - gc[:, :-1]).max(axis=(1, 2, 3))
    print(f"\nround trip max error: legacy {rt_l.max():.3g} m ({(rt_l > 1e-4).mean():.1%} of clips > 0.1 mm), "
          f"clean {rt_c.max():.3g} m\n")
    print("| quirk alone (clean + one legacy switch) | mean abs feature diff | max | round trip max (m) |")
    print("|---|---|---|---|")
    base = hml263.MODES["clean"]
    for name, change in QUIRKS.items():
        cfg = dataclasses.replace(base, **change)
        pos = joints.astype(np.float32) if cfg.float32 else joints
        feats, P, _ = hml263._encode_batch(pos, cfg, 20.0)
        g = hml263._from_soa(P)
        d = np.abs(feats.astype(np.float64) - clean)
        rt = np.abs(hml263.decode(feats) - g[:, :-1]).max()
        print(f"| {name} | {d.mean():.3g} | {d.max():.3g} | {rt:.3g} |")


if __name__ == "__main__":
    main()
