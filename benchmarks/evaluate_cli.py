"""``hoibench evaluate`` timed as a user runs it: the CLI on a submission zip of 196-frame clips.

    python benchmarks/evaluate_cli.py [--prompts 1000] [--frames 196] [--executor processes:2]

Builds the README store (120 synthetic clips), annotates it and trains a tiny evaluator (a
child process), then writes a *benchmark store*: the store with its test split replaced by
``--prompts`` clips made from its test clips looped in time (ping-pong) to ``--frames``
frames, every representation recomputed from the looped joints (``store.clip_arrays``), the
captions and annotations copied. Two submissions of about 1,000 samples each are zipped:

- K = 1: the ground truth of all ``--prompts`` prompts;
- K = 30: 30 samples (the ground truth plus 1 cm Gaussian noise per sample) of each prompt of
  a second benchmark store with ``round(prompts / 30)`` test prompts -- the same sample
  count, and what MultiModality needs.

Each is validated and scored by ``hoibench evaluate SUB.zip --data ... --evaluator ...
--executor ...`` in a child process, twice: first with an empty ground-truth cache
(``HOIBENCH_CACHE`` set to a fresh folder under the work folder: the ground truth is embedded
and the gate measured), then reading what the first run cached. Per run: wall-clock seconds
(reading and validating included),
the stage timings the result records, and the peak RSS of the CLI process and of its
largest worker (``getrusage`` in the CLI's own interpreter).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def _loop(a: np.ndarray, n: int) -> np.ndarray:
    idx = np.concatenate([np.arange(len(a)), np.arange(len(a) - 2, 0, -1)])  # ping-pong
    return a[np.resize(idx, n)]


def benchmark_store(src: Path, out: Path, prompts: int, frames: int) -> list[str]:
    """Copy the store ``src`` to ``out`` with a test split of ``prompts`` looped clips."""
    from hoibench.datasets.sequence import BodyParams, HOISequence
    from hoibench.core.io import atomic_write_json
    from hoibench.datasets.store import Store, clip_arrays
    from hoibench.core.io import npz_bytes, atomic_write_bytes

    shutil.copytree(src, out)
    st = Store(src)
    manifest = json.loads((src / "manifest.json").read_text())
    test = st.clip_ids("test")
    mode = manifest["config"]["mode"]
    for cid in test:
        (out / "clips" / f"{cid}.npz").unlink()
    clips = [c for c in manifest["clips"] if c["split"] != "test"]
    ids = []
    for i in range(prompts):
        src_id = test[i % len(test)]
        new_id = f"{src_id}_x{i:04d}"
        z = st.load(src_id)
        body = None
        if "poses" in z:
            body = BodyParams(str(z["body_model_type"]), str(z["gender"]), z["betas"], _loop(z["poses"], frames),
                              _loop(z["trans"], frames))
        seq = HOISequence(name=new_id, dataset=str(z["dataset"]), subject=str(z["subject"]), fps=float(z["fps"]),
                          joints=_loop(z["joints"], frames), object_name=str(z["object_name"]),
                          obj_rot=_loop(z["obj_rot"], frames), obj_trans=_loop(z["obj_trans"], frames),
                          body=body, contacts=_loop(z["contacts"], frames),
                          provenance={**json.loads(str(z["provenance"])), "benchmark": f"{src_id} looped"})
        atomic_write_bytes(out / "clips" / f"{new_id}.npz",
                           npz_bytes(clip_arrays(seq, mode, "test", str(z["source_sha256"]))))
        for folder, ext in (("texts", "txt"), ("annotations", "json")):
            p = src / folder / f"{src_id}.{ext}"
            if p.exists():
                text = p.read_text()
                if ext == "json":
                    d = json.loads(text)
                    d["clip"], d["num_frames"] = new_id, frames
                    text = json.dumps(d)
                (out / folder / f"{new_id}.{ext}").write_text(text)
        clips.append({"id": new_id, "split": "test", "frames": frames, "object": str(z["object_name"]),
                      "contact_frames": int(seq.contacts.any(-1).sum())})
        ids.append(new_id)
    manifest["clips"] = clips
    atomic_write_json(out / "manifest.json", manifest)
    index = out / "annotations" / "index.json"
    if index.exists():
        d = json.loads(index.read_text())
        d["clips"] = sorted(c["id"] for c in clips)
        groups: dict[str, list[str]] = {}
        for c in sorted(d["clips"]):
            a = out / "annotations" / f"{c}.json"
            if a.exists():
                groups.setdefault(json.loads(a.read_text())["group_id"], []).append(c)
        d["groups"] = groups
        index.write_text(json.dumps(d))
    return ids


def write_zip(store: Path, ids: list[str], k: int, out: Path, seed: int = 0) -> Path:
    from hoibench.datasets.store import Store
    from hoibench.scoring.submission import write_submission
    st = Store(store)
    rng = np.random.default_rng(seed)
    meta = {"method": f"GT{' + 1 cm noise' if k > 1 else ''}, benchmark", "version": "", "url": "",
            "representation": st.manifest["representations"]["hml263"], "fps": float(st.manifest["config"]["fps"]),
            "flags": {"uses_gt_length": True, "samples_per_prompt": k, "checkpoint_selection": "n/a"}}

    def gen():
        for cid in ids:
            z = st.load(cid)
            j = np.repeat(z["joints"][None], k, 0).astype(np.float32)
            if k > 1:
                j = j + rng.normal(scale=0.01, size=j.shape).astype(np.float32)
            yield cid, {"joints": j, "obj_rot": np.repeat(z["obj_rot"][None], k, 0),
                        "obj_trans": np.repeat(z["obj_trans"][None], k, 0)}
    return write_submission(out, meta, gen(), as_zip=True)


_RUNNER = """
import json, resource, runpy, sys
out = sys.argv[1]
sys.argv = ["hoibench"] + sys.argv[2:]
code = 0
try:
    runpy.run_module("hoibench.cli", run_name="__main__")
except SystemExit as exc:
    code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
me = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
kids = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
json.dump({"self_mib": me / 1024, "workers_mib": kids / 1024}, open(out, "w"))
sys.exit(code)
"""


def timed_cli(args: list[str], rss_file: Path) -> tuple[float, dict, subprocess.CompletedProcess]:
    """Run ``hoibench ARGS`` in a fresh interpreter: (wall s, peak RSS of the CLI process and
    of its largest worker in MiB, the completed process)."""
    t = time.perf_counter()
    r = subprocess.run([sys.executable, "-c", _RUNNER, str(rss_file)] + args, capture_output=True, text=True)
    wall = time.perf_counter() - t
    rss = json.loads(rss_file.read_text()) if rss_file.exists() else {}
    return wall, rss, r


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--prompts", type=int, default=1000)
    ap.add_argument("--frames", type=int, default=196)
    ap.add_argument("--executor", default="processes:2")
    ap.add_argument("--work", type=Path, default=None, help="keep the stores and zips here (default: a temp dir)")
    ap.add_argument("--samples", type=int, nargs="+", default=[1, 30], choices=[1, 30],
                    help="which submissions to score: K = 1 and/or K = 30 (default both)")
    args = ap.parse_args(argv)
    from hoibench.text.annotate import annotate_store
    from hoibench.datasets.synthetic_store import build_synthetic_store

    tmp = args.work or Path(tempfile.mkdtemp(prefix="hoibench-eval-cli-"))
    tmp.mkdir(parents=True, exist_ok=True)
    try:
        t0 = time.perf_counter()
        data = tmp / "readme" / "data"
        if not (data / "manifest.json").exists():
            _, data, _ = build_synthetic_store(tmp / "readme", 120, seed=0)
            annotate_store(data)
        ev = tmp / "ev"
        if not (ev / "card.json").exists():
            subprocess.run([sys.executable, "-m", "hoibench.cli", "train-evaluator", str(data), "--out", str(ev),
                            "--size", "tiny"], check=True, capture_output=True)
        from hoibench.datasets.store import Store
        cases = []
        for k, n in ((1, args.prompts), (30, max(2, round(args.prompts / 30)))):
            big = tmp / f"bench_{n}x{args.frames}"
            if not big.exists():
                benchmark_store(data, big, n, args.frames)
            cases.append((k, big, Store(big).clip_ids("test")))
        print(f"# set-up {time.perf_counter() - t0:.0f} s; benchmark stores: {args.prompts} and {len(cases[1][2])} "
              f"test prompts x {args.frames} frames; executor {args.executor}; load {os.getloadavg()[0]:.2f}",
              flush=True)
        print("| submission | ground truth | samples | zip (MB) | wall (s) | load | ground truth + gate | validate | "
              "stream (read, embed, physical) | replications | peak RSS (MiB) |")
        print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        cache = tmp / "reference-cache"
        shutil.rmtree(cache, ignore_errors=True)       # the first run computes, the second reads
        os.environ["HOIBENCH_CACHE"] = str(cache)
        for k, big, ids in cases:
            if k not in args.samples:
                continue
            n = len(ids)
            z = tmp / f"sub_k{k}.zip"
            if not z.exists():
                write_zip(big, ids, k, z)
            for state in ("computed", "cached"):
                res = tmp / f"result_k{k}.json"
                if res.exists():
                    res.unlink()
                wall, rss, r = timed_cli(["evaluate", str(z), "--data", str(big), "--evaluator", str(ev),
                                          "--executor", args.executor, "--out", str(res)], tmp / f"rss_k{k}.json")
                if r.returncode != 0:
                    print(r.stdout[-1500:], r.stderr[-1500:])
                    raise SystemExit(f"evaluate K={k} failed")
                t = json.loads(res.read_text())["timings_s"]
                print(f"| K = {k} ({n} prompts) | {state} | {n * k} | {z.stat().st_size / 1e6:.0f} | {wall:.1f} | "
                      f"{t.get('load_s', 0):.1f} | {t.get('ground_truth_s', 0):.1f} | {t.get('validate_s', 0):.1f} | "
                      f"{t.get('stream_s', 0):.1f} | {t.get('replications_s', 0):.1f} | "
                      f"{rss.get('self_mib', 0):.0f} (workers {rss.get('workers_mib', 0):.0f}) |", flush=True)
    finally:
        if args.work is None:
            shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
