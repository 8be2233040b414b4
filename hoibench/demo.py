"""``hoibench demo``: the main job on data hoibench makes itself.

Stage 1 (representations): encodes generated clips into hml263 (legacy and clean), hoi269
and joint_level, decodes them again and reports round-trip errors and the legacy-vs-clean
difference per feature group. Stage 2 (synthetic): writes the synthetic HOI dataset in the
BEHAVE raw layout, prepares it with the BEHAVE loader into a processed store, prints the
summary table, annotates it with contact-aware texts, trains a tiny evaluator, scores the
ground-truth submission under the synthetic protocol and renders one clip to a GIF.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from .io import atomic_save_npy, atomic_write_json


def representation_stage(out: Path, seed: int = 0, clips: int = 8, frames: int = 120) -> dict:
    from .datasets.random_motion import random_motion
    from .representations import compare, hml263, hoi269, joint_level

    joints = random_motion(frames, seed=seed, batch=clips, turn_dps=90.0)
    t0 = time.perf_counter()
    legacy, gl = hml263.encode(joints, mode="legacy", return_positions=True)
    clean, gc = hml263.encode(joints, mode="clean", return_positions=True)
    seconds = time.perf_counter() - t0
    # an object carried 0.4 m in front of the pelvis, for the HOI layouts
    aa = np.zeros(joints.shape[:2] + (3,))
    aa[..., 1] = np.linspace(0, 1.5, frames)
    trans = joints[:, :, 0] + np.array([0.0, 0.2, 0.4])
    hoi = hoi269.encode(joints, aa, trans, mode="clean")
    jl = joint_level.from_hoi269(hoi)
    report = {
        "clips": clips, "frames": frames, "encode_seconds_both_modes": round(seconds, 4),
        "roundtrip_max_error_m": {
            "legacy": float(np.abs(hml263.decode(legacy) - gl[:, :-1]).max()),
            "clean": float(np.abs(hml263.decode(clean) - gc[:, :-1]).max()),
        },
        "joint_level_roundtrip_exact": bool(np.array_equal(joint_level.to_hoi269(jl), hoi)),
        "legacy_vs_clean": compare.group_differences(legacy, clean),
        "versions": {"legacy": hml263.VERSION["legacy"], "clean": hml263.VERSION["clean"]},
    }
    out.mkdir(parents=True, exist_ok=True)
    atomic_save_npy(out / "hml263_clean.npy", clean)
    atomic_save_npy(out / "joint_level.npy", jl)
    atomic_write_json(out / "representations_report.json", report)
    print(f"[representations] {clips} clips x {frames} frames encoded in legacy and clean mode "
          f"in {seconds:.3f} s")
    for mode, err in report["roundtrip_max_error_m"].items():
        print(f"  decode(encode(x)) vs repositioned joints, {mode:6s}: max error {err:.2e} m")
    print(f"  hoi269 -> joint_level -> hoi269 exact: {report['joint_level_roundtrip_exact']}")
    print("  legacy vs clean, per feature group:")
    print("  " + compare.markdown_table(report["legacy_vs_clean"]).replace("\n", "\n  "))
    return report


def synthetic_stage(out: Path, seed: int = 0, clips: int = 120, executor: str = "serial") -> dict:
    """synth (BEHAVE layout) -> prepare -> annotate -> train a tiny evaluator -> score the
    ground-truth submission -> render one clip."""
    from .annotate import annotate_store, preview_table
    from .datasets.synthetic_store import build_synthetic_store
    from .evaluate import evaluate, format_result
    from .evaluator import main_train_evaluator
    from .store import summary_table
    from .submission import from_store

    t0 = time.perf_counter()
    raw, data, manifest = build_synthetic_store(out, clips, seed=seed, executor=executor)
    t1 = time.perf_counter()
    print(f"[synthetic] generated and prepared {clips} clips in {t1 - t0:.1f} s")
    print("  " + summary_table(manifest).replace("\n", "\n  "))
    annotate_store(data, executor=executor)
    print("  " + preview_table(data, 3).replace("\n", "\n  "))
    report = {"raw": str(raw), "store": str(data), "counts": manifest["counts"]}
    print("[evaluator] training a tiny contrastive text-motion evaluator on the train split")
    ev_dir = out / "evaluator"
    main_train_evaluator(data, ev_dir, size="tiny", seed=seed)
    gt_sub = out / "gt_submission"
    if (gt_sub / "submission.json").exists():     # the demo's own output from an earlier run
        import shutil
        shutil.rmtree(gt_sub)
    from_store(data, gt_sub)
    result = evaluate(out / "gt_submission", data, ev_dir, executor=executor)
    atomic_write_json(out / "gt_result.json", result)
    print("[evaluate] the ground-truth ('real motion') submission:")
    print("  " + format_result(result).replace("\n", "\n  "))
    report["gt_result"] = str(out / "gt_result.json")
    try:
        from .render import render_clip
        clip = next(c["id"] for c in manifest["clips"] if c["contact_frames"] > 0)
        gif = render_clip(data, clip, out / f"{clip}.gif")
        report["render"] = str(gif)
        print(f"  rendered {clip} -> {gif}")
    except ImportError as exc:  # pyvista is a dependency, but keep the demo useful without it
        print(f"  (render skipped: {exc})")
    report["seconds"] = round(time.perf_counter() - t0, 1)
    return report


def run_demo(out: Path, seed: int = 0) -> dict:
    out = Path(out)
    report = {"representations": representation_stage(out / "representations", seed=seed)}
    report["synthetic"] = synthetic_stage(out, seed=seed)
    atomic_write_json(out / "demo_report.json", report)
    print(f"wrote {out / 'demo_report.json'}")
    return report
