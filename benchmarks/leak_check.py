"""Time and calibration of the leak check (hoibench.datasets.leak_motion, leak_text).

    python benchmarks/leak_check.py [--clips 10000] [--test-fraction 0.2] [--planted 20]
    python benchmarks/leak_check.py --calibrate [--interact 60] [--behave 48] [--work DIR]

Timing (default): ``--clips`` generated clips (no store: joints made here at 20 fps, 2-10 s
each, a walking root with a random heading and speed, every joint swinging with its own
amplitudes, frequencies and phases), split train/test, plus ``--planted`` renamed, mirrored
and shifted (a crop 3.3 frames in, interpolated) copies of train clips in the test set, and
templated captions. Prints the time of the motion search (index + re-rank) and of the caption
search, and the planted copies found and the other pairs flagged.

Calibration (``--calibrate``): builds a synthetic InterAct-layout store and a synthetic
BEHAVE-layout store (``hoibench synth`` data prepared at 20 fps), runs the leak check on each
clean store and on copies with planted duplicates (shifts 3.3 and 3.125 frames: 3.125 is the
worst case of the quarter-frame grid), and prints the closest clean pair, the farthest planted
pair and the margin to the threshold.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from hoibench.core.skeleton import SMPL_REST_JOINTS
from hoibench.datasets import leak_motion as lm
from hoibench.datasets import leak_text as lt


def generated_clip(rng: np.random.Generator) -> np.ndarray:
    """(T, 22, 3) joints at 20 fps: rest pose at standing height, per-joint swings, a walking root."""
    T = int(rng.integers(40, 201))
    t = np.arange(T)[:, None, None] / 20.0
    amp = rng.uniform(0.0, 0.12, (22, 3)) * rng.uniform(0.3, 1.0)
    J = SMPL_REST_JOINTS[None] + np.array([0.0, 1.15, 0.0])
    for _ in range(2):
        J = J + amp * np.sin(2 * np.pi * rng.uniform(0.2, 1.5, (22, 3)) * t + rng.uniform(0, 2 * np.pi, (22, 3)))
    yaw = rng.uniform(-np.pi, np.pi) + np.cumsum(rng.normal(0, 0.01, T))
    step = rng.uniform(0.0, 1.2) / 20.0
    path = np.cumsum(np.stack([np.sin(yaw), np.zeros(T), np.cos(yaw)], 1) * step, 0)
    c, s = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
    x, z = J[..., 0] - J[:, :1, 0], J[..., 2] - J[:, :1, 2]
    out = np.stack([c * x + s * z, J[..., 1], -s * x + c * z], -1) + path[:, None] + rng.uniform(-3, 3, 3) * [1, 0, 1]
    return out.astype(np.float32)


def _caption(rng) -> str:
    verb = rng.choice(["lifts", "carries", "pushes", "pulls", "holds", "kicks", "sits on", "puts down"])
    obj = rng.choice(["box", "chair", "stool", "ball", "table", "suitcase", "monitor", "backpack"])
    how = rng.choice(["with both hands", "with the left hand", "with the right hand", "slowly", "quickly", ""])
    return f"a person {verb} the {obj} {how}".strip()


def _plant(train, rng, n):
    """(clips, kinds, sources): n renamed, mirrored and shifted copies of train clips."""
    src = rng.choice(len(train), 3 * n, replace=False)
    out, kinds = [], []
    for k, i in enumerate(src):
        j = train[i]
        kind = ("renamed", "mirrored", "shifted")[k // n]
        if kind == "mirrored":
            j = lm.mirror(j)
        elif kind == "shifted":
            m = int(np.floor(len(j) - 1 - 6.6)) + 1
            t = 3.3 + np.arange(m)
            i0 = np.floor(t).astype(int)
            w = (t - i0)[:, None, None]
            j = ((1 - w) * j[i0] + w * j[i0 + 1]).astype(np.float32)
        out.append(j), kinds.append(kind)
    return out, kinds, [int(i) for i in src]


def timing(args) -> None:
    rng = np.random.default_rng(args.seed)
    t0 = time.perf_counter()
    clips = [generated_clip(rng) for _ in range(args.clips)]
    caps = [[_caption(rng) for _ in range(3)] for _ in clips]
    n_test = int(round(args.test_fraction * args.clips))
    test, train = clips[:n_test], clips[n_test:]
    planted, kinds, sources = _plant(train, rng, args.planted)
    query = test + planted
    qcaps = caps[:n_test] + [caps[n_test + s] for s in sources]
    frames = sum(len(c) for c in clips)
    print(f"generated {len(clips)} clips ({frames} frames, {frames / 20 / 3600:.1f} h at 20 fps) + "
          f"{len(planted)} planted in {time.perf_counter() - t0:.1f} s")
    t0 = time.perf_counter()
    matches = lm.match_sets(query, train)
    t_motion = time.perf_counter() - t0
    t0 = time.perf_counter()
    texts = lt.match_captions(qcaps, caps[n_test:])
    t_text = time.perf_counter() - t0
    dup = [m for m in matches if m.distance_m <= lm.THRESHOLD_M]
    found = {m.query - n_test for m in dup if m.query >= n_test and m.ref == sources[m.query - n_test]}
    other = [m for m in dup if m.query < n_test or m.ref != sources[m.query - n_test]]
    by_kind = ", ".join(f"{k} {sum(1 for i in found if kinds[i] == k)}" for k in ("renamed", "mirrored", "shifted"))
    print(f"motion: {len(query)} query clips x {len(train)} reference clips: {t_motion:.1f} s; planted found "
          f"{len(found)}/{len(planted)} ({by_kind}); other pairs flagged: {len(other)}")
    near = sorted(m.distance_m for m in matches if m.query < n_test)
    if near:
        print(f"closest pair among the generated (non-planted) test clips: {1000 * near[0]:.1f} mm")
    print(f"captions: {t_text:.1f} s ({len(texts)} test clips with a caption duplicate)")
    print(f"total {t_motion + t_text:.1f} s")


def _interact_store(work: Path, n: int) -> Path:
    from hoibench.datasets import interact
    from hoibench.datasets.interact_layout import write_interact_layout
    from hoibench.datasets.store import PrepareConfig, prepare
    raw, out = work / "interact_raw", work / "interact"
    if not (out / "manifest.json").is_file():
        write_interact_layout(raw, n, seed=0)
        cfg = PrepareConfig("interact", fps=20.0, body_model_type="smplx")
        interact.write_texts(out, prepare(interact.prepare_jobs(raw, raw / "body_models", out, cfg), out, cfg))
    return out


def _behave_store(work: Path, n: int) -> Path:
    from hoibench.datasets.synthetic_store import build_synthetic_store, write_template_texts
    if not (work / "behave" / "data" / "manifest.json").is_file():
        _, data, _ = build_synthetic_store(work / "behave", n, seed=0)
        write_template_texts(data)
    return work / "behave" / "data"


def calibrate(args) -> None:
    from hoibench.datasets.leak_check import leak_check
    from hoibench.datasets.leak_plant import plant_duplicates
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    stores = {"interact": _interact_store(work, args.interact), "behave": _behave_store(work, args.behave)}
    clean_min, planted_max = np.inf, 0.0
    for name, store in stores.items():
        r = leak_check(store)
        near = r["summary"]["nearest_distance_m"]
        print(f"{name} clean: {r['query']['clips']} test / {r['reference']['clips']} train clips, motion duplicates "
              f"{r['summary']['motion_duplicates']}, nearest {1000 * near['min']:.1f} mm (median "
              f"{1000 * near['median']:.1f} mm)")
        clean_min = min(clean_min, near["min"])
        for shift in (3.3, 3.125):
            out = work / f"{name}_planted_{shift}"
            if not out.exists():
                planted = plant_duplicates(store, out, n=args.planted, seed=0, shift_frames=shift)
            else:
                import json
                planted = json.loads((out / "manifest.json").read_text())["planted"]
            r = leak_check(out)
            dups = {d["query"]: d for d in r["motion"]["duplicates"]}
            hit = [c for c, p in planted.items() if c in dups and dups[c]["reference"] == p["source"]]
            worst = max(dups[c]["distance_m"] for c in hit) if hit else float("nan")
            extra = [d for d in r["motion"]["duplicates"] if d["query"] not in planted]
            print(f"{name} planted (shift {shift} frames): found {len(hit)}/{len(planted)}, farthest "
                  f"{1000 * worst:.2f} mm, other pairs flagged {len(extra)}")
            planted_max = max(planted_max, worst)
    print(f"threshold {1000 * lm.THRESHOLD_M:.0f} mm: closest clean pair {1000 * clean_min:.1f} mm "
          f"({clean_min / lm.THRESHOLD_M:.1f}x), farthest planted {1000 * planted_max:.2f} mm "
          f"({lm.THRESHOLD_M / planted_max:.1f}x below)")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--clips", type=int, default=10000)
    p.add_argument("--test-fraction", type=float, default=0.2)
    p.add_argument("--planted", type=int, default=20, help="planted copies of each kind")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--calibrate", action="store_true")
    p.add_argument("--interact", type=int, default=60, help="--calibrate: InterAct-layout sequences")
    p.add_argument("--behave", type=int, default=48, help="--calibrate: BEHAVE-layout clips")
    p.add_argument("--work", default="/tmp/hoibench-leak-calibration", help="--calibrate: where stores are built")
    args = p.parse_args()
    calibrate(args) if args.calibrate else timing(args)


if __name__ == "__main__":
    main()
