"""The interact leaderboard's synthetic rows: reference submissions of a synthetic
InterAct-layout store scored with InterAct's evaluator architecture under random weights.

    .venv/bin/python benchmarks/interact_synthetic_rows.py --work /tmp/interact-rows [--add]

1. ``hoibench synth --layout interact --clips 200 --seed 0`` and ``hoibench prepare interact
   --fps 30`` (66 test clips of the sequence split, 36 frames each);
2. the evaluator: the files of ``tests/interact_fixture.py`` (InterAct's checkpoint layout,
   every weight random with torch seeds 0 and 1, statistics and BPS basis from numpy seed 2;
   a 28-word DistilBERT vocabulary) imported with ``hoibench evaluator import interact``.
   It does not match texts to motions (its sanity gate fails, and every row says so): the
   rows show each protocol's scale and how the reference rows order, not a model's quality;
3. the reference submissions, written here because the interact track's evaluator reads
   ``markers`` (``hoibench submission reference`` writes joints and object poses only):
   ground truth, ground truth + 1 cm and + 3 cm Gaussian noise (joints, markers and object
   translation; seeded by clip id), static first pose (body, markers and object held), and
   mismatched texts (another test clip's motion; a seeded derangement);
4. each scored under ``interact-clean`` (and the ground truth and static first pose also
   under ``interact-legacy``) with ``--allow-failed-gate``; with ``--add`` the
   ``interact-clean`` results are added to ``leaderboards/interact`` (``hoibench leaderboard
   add --replace``: a track's page holds the rows of one protocol, its default); the
   ``interact-legacy`` figures are the ones docs/metrics.md compares;
5. with ``--physics DIR`` every row is also scored under ``interact-clean@1.1`` (the physics
   tier, a preview) into ``DIR/<entry name>.json``, the folder ``benchmarks/physics_rows.py
   --results DIR --entries leaderboards/interact/entries`` reads.

Prints one line per row (the headline metrics). Deterministic for the seeds above.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
HB = [sys.executable, "-m", "hoibench.cli"]
ROWS = (  # (kind, method, role, protocols)
    ("gt", "Real motion", "ground-truth", ("interact-clean", "interact-legacy")),
    ("noise1", "GT + 1 cm noise", "reference", ("interact-clean",)),
    ("noise3", "GT + 3 cm noise", "reference", ("interact-clean",)),
    ("static", "static first pose", "reference", ("interact-clean", "interact-legacy")),
    ("mismatched", "mismatched texts", "reference", ("interact-clean",)),
)
NOTE = ("Synthetic InterAct-layout store (hoibench synth --layout interact --clips 200 --seed 0; 66 test clips, "
        "30 fps); InterAct's evaluator architecture with RANDOM weights (tests/interact_fixture.py, torch seeds 0/1, "
        "numpy seed 2), which fails its sanity gate: the numbers show the protocol's scale and the reference rows' "
        "order, not a model's quality (benchmarks/interact_synthetic_rows.py).")


def _run(args: list, ok: tuple = (0,), **kw) -> None:
    rc = subprocess.run([str(a) for a in args], cwd=ROOT, **kw).returncode
    if rc not in ok:
        raise SystemExit(f"{' '.join(map(str, args[2:4]))}: exit status {rc}")


def _rng(kind: str, cid: str) -> np.random.Generator:
    return np.random.default_rng(int.from_bytes(hashlib.sha256(f"{kind}:{cid}".encode()).digest()[:8], "little"))


def write_rows(data: Path, out: Path) -> dict[str, Path]:
    """The reference submissions of ``ROWS`` for the store ``data`` under ``out``."""
    from hoibench import __version__
    from hoibench.datasets.store import Store
    from hoibench.scoring.reference_rows import derangement
    from hoibench.scoring.submission_write import write_submission
    st = Store(data)
    ids = st.clip_ids("test")
    keys = ("joints", "markers", "obj_rot", "obj_trans")
    clips = {c: st.load(c, keys=keys) for c in ids}
    partner = derangement(len(ids), 0)
    paths = {}
    for kind, method, _, _ in ROWS:
        def arrays(i: int, cid: str, kind: str = kind) -> dict:
            c = clips[cid]
            if kind == "mismatched":
                c = clips[ids[partner[i]]]
            a = {k: np.asarray(c[k], np.float32) for k in keys}
            if kind.startswith("noise"):
                sigma, rng = int(kind[-1]) / 100.0, _rng(kind, cid)
                for k in ("joints", "markers", "obj_trans"):
                    a[k] = (a[k] + rng.normal(scale=sigma, size=a[k].shape)).astype(np.float32)
            if kind == "static":
                a = {k: np.repeat(v[:1], len(v), 0) for k, v in a.items()}
            return {k: v[None] for k, v in a.items()}
        meta = {"method": method, "version": __version__, "url": "", "fps": float(st.manifest["config"]["fps"]),
                "representation": st.manifest.get("representations", {}).get("hml263", ""),
                "flags": {"uses_gt_length": kind != "mismatched", "samples_per_prompt": 1,
                          "checkpoint_selection": "n/a"},
                "source": {"reference": kind, "store": "interact (synthetic)", "split": "test"}}
        paths[kind] = write_submission(out / kind, meta, ((c, arrays(i, c)) for i, c in enumerate(ids)))
    return paths


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", type=Path, required=True, help="a new folder for the store, evaluator and results")
    ap.add_argument("--add", action="store_true", help="add the results to leaderboards/interact")
    ap.add_argument("--physics", type=Path, default=None,
                    help="also score every row under interact-clean@1.1 (physics tier) into this folder")
    args = ap.parse_args()
    w = args.work
    if not (w / "data").is_dir():
        _run(HB + ["synth", "--layout", "interact", "--out", w / "raw", "--clips", 200, "--seed", 0])
        _run(HB + ["prepare", "interact", "--root", w / "raw", "--body-models", w / "raw" / "body_models",
                   "--out", w / "data", "--fps", 30])
    if not (w / "ev").is_dir():
        sys.path.insert(0, str(ROOT / "tests"))
        from interact_fixture import write_interact_files
        from hoibench.evaluator.backends import import_evaluator
        import_evaluator("interact", w / "ev", **write_interact_files(w / "evsrc"))
    subs = write_rows(w / "data", w / "subs") if not (w / "subs").is_dir() else \
        {k: w / "subs" / k for k, *_ in ROWS}
    for kind, method, role, protocols in ROWS:
        for proto in protocols:
            res = w / f"{kind}-{proto}.json"
            if not res.exists():
                _run(HB + ["evaluate", subs[kind], "--data", w / "data", "--evaluator", w / "ev", "--protocol", proto,
                           "--allow-failed-gate", "--out", res], ok=(0, 1, 2), stdout=subprocess.DEVNULL)
                # exit 1: scored but marked (the failed gate's override), as every row here; exit 2:
                # refused (interact-legacy keeps clips of 40-300 frames, the synthetic ones have 36)
            if not res.exists():
                print(f"{method:22s} {proto:16s} refused (its one line is above)")
                continue
            r = json.loads(res.read_text())
            line = {k: round(r["metrics"][k]["mean"], 4) for k in ("r_precision_top1", "fid", "mm_dist", "diversity")
                    if k in r["metrics"]}
            print(f"{method:22s} {proto:16s} {line}")
            if args.add and proto == "interact-clean":      # a track's page holds one protocol's rows
                name = f"{method} (random-weight evaluator)"
                _run(HB + ["leaderboard", "add", res, "--track", "interact", "--method", name, "--role", role,
                           "--notes", NOTE, "--allow-incomplete", "--replace", "--root", ROOT / "leaderboards"])
        if args.physics is not None:
            from hoibench.publish.leaderboard import slug
            res = args.physics / f"{slug(f'{method} (random-weight evaluator)')}.json"
            if not res.exists():
                args.physics.mkdir(parents=True, exist_ok=True)
                _run(HB + ["evaluate", subs[kind], "--data", w / "data", "--evaluator", w / "ev", "--protocol",
                           "interact-clean@1.1", "--executor", "processes:2", "--allow-failed-gate", "--out", res],
                     ok=(0, 1), stdout=subprocess.DEVNULL)
    return 0


if __name__ == "__main__":
    sys.exit(main())
