"""Rebuild the multibody-synthetic track's entries from SyncDiff bench folders.

    python benchmarks/syncdiff_multibody.py --out B                       # tiny config (3,000 steps)
    python benchmarks/syncdiff_multibody.py --out B1 --steps 1000 --set 'syncdiff.freq_position="index"'
    python benchmarks/syncdiff_multibody.py --out B2 --steps 1000         # 1,000 steps, rate positions
    python benchmarks/multibody_entries.py --bench B --bench-index B1 --bench-rate B2 \
        --track leaderboards/multibody-synthetic [--work W]

Every row's submission is scored with ``hoibench evaluate --out`` against B's store and
recognizer (the three bench folders write byte-identical stores; the script checks their
manifests), so each result keeps its per-clip data, and is added to the track with its
method name, role and note (``leaderboard add --replace``); entries of the track scored with
another recognizer are removed first (a track has one evaluator). Then ``leaderboard build``.
Prints each row's FID, RA and CSIoU.

    python benchmarks/multibody_entries.py --bench B --bench-index B1 --bench-rate B2 --physics W

scores the same submissions under the physics preview (``--protocol multibody-synthetic@1.1``)
into ``W/<entry slug>.json`` and touches no entry; ``python benchmarks/physics_rows.py
--results W --entries leaderboards/multibody-synthetic/entries`` then gives the physics table
(leaderboards/multibody-synthetic/about.md).
"""
from __future__ import annotations

import argparse
from pathlib import Path

#: (method, role, note, bench, submission folder)
ROWS = (
    ("GT (real motion)", "ground-truth", "", "main", "sub_gt"),
    ("static first frame", "reference", "", "main", "sub_static"),
    ("SyncDiff tiny, untrained", "reference", "the tiny config at 0 steps: calibrates each metric's scale", "main",
     "sub_SyncDiff_tiny_untrained"),
    ("SyncDiff tiny", "baseline", "tiny config: 3,000 steps, frequency tokens told their rate k/n", "main",
     "sub_SyncDiff_tiny"),
    ("SyncDiff tiny w/o decompose", "baseline", "", "main", "sub_wo_decompose"),
    ("SyncDiff tiny w/o L_align", "baseline", "", "main", "sub_wo_L_align"),
    ("SyncDiff tiny w/o exp sync", "baseline", "the SyncDiff tiny run sampled with syncdiff.explicit_sync=false",
     "main", "sub_wo_exp_sync"),
    ("SyncDiff tiny w/o L_align, exp sync", "baseline", "the w/o L_align run sampled with syncdiff.explicit_sync=false",
     "main", "sub_wo_L_align_exp_sync"),
    ("SyncDiff tiny (1000 steps)", "baseline",
     "1,000 steps, frequency tokens told their row index (the tiny config before 0.7.0)", "index", "sub_SyncDiff_tiny"),
    ("SyncDiff tiny (1000 steps) w/o decompose", "baseline", "1,000 steps (the tiny config before 0.7.0)", "index",
     "sub_wo_decompose"),
    ("SyncDiff tiny (1000 steps) w/o L_align", "baseline",
     "1,000 steps, frequency tokens told their row index (the tiny config before 0.7.0)", "index", "sub_wo_L_align"),
    ("SyncDiff tiny (1000 steps) w/o exp sync", "baseline",
     "1,000 steps, frequency tokens told their row index (the tiny config before 0.7.0); sampled with "
     "syncdiff.explicit_sync=false", "index", "sub_wo_exp_sync"),
    ("SyncDiff tiny (1000 steps) w/o L_align, exp sync", "baseline",
     "1,000 steps, frequency tokens told their row index (the tiny config before 0.7.0); the w/o L_align run "
     "sampled with syncdiff.explicit_sync=false", "index", "sub_wo_L_align_exp_sync"),
    ("SyncDiff tiny (1000 steps), rate positions", "baseline",
     "syncdiff.freq_position=rate: the frequency tokens are told k/n cycles per frame instead of their row index; "
     "docs/baselines.md", "rate", "sub_SyncDiff_tiny"),
)


#: the preview protocol version that lists the physics tier
PHYSICS_PROTOCOL = "multibody-synthetic@1.1"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bench", type=Path, required=True)
    ap.add_argument("--bench-index", type=Path, required=True)
    ap.add_argument("--bench-rate", type=Path, required=True)
    ap.add_argument("--track", type=Path, default=Path("leaderboards/multibody-synthetic"))
    ap.add_argument("--work", type=Path, default=None, help="where the results go (default: BENCH/results)")
    ap.add_argument("--executor", default="processes:2")
    ap.add_argument("--physics", type=Path, default=None, metavar="W",
                    help="score every row under multibody-synthetic@1.1 into W/<slug>.json; no entry is changed")
    args = ap.parse_args()
    from hoibench.core.io import read_json_object
    from hoibench.publish.leaderboard import add_result, load_track
    from hoibench.publish.pages import build
    from hoibench.scoring.evaluate import main_evaluate
    from hoibench.scoring.multibody import write_multibody_submission
    benches = {"main": args.bench, "index": args.bench_index, "rate": args.bench_rate}
    data, rec = args.bench / "data", args.bench / "rec"
    manifests = {k: read_json_object(b / "data" / "manifest.json") for k, b in benches.items()}
    for k, m in manifests.items():
        if m.get("config_sha256") != manifests["main"].get("config_sha256") or m["clips"] != manifests["main"]["clips"]:
            raise SystemExit(f"--bench-{k} {benches[k]}: its store differs from --bench's")
    if not (args.bench / "sub_gt").exists():
        write_multibody_submission(data, args.bench / "sub_gt", kind="gt")
    if args.physics is not None:
        from hoibench.publish.leaderboard import slug
        args.physics.mkdir(parents=True, exist_ok=True)
        for method, _, _, bench, folder in ROWS:
            out = args.physics / f"{slug(method)}.json"
            if not out.exists():
                main_evaluate(benches[bench] / folder, data, rec, out=out, protocol=PHYSICS_PROTOCOL,
                              executor=args.executor)
        return
    work = args.work or args.bench / "results"
    work.mkdir(parents=True, exist_ok=True)
    rec_id = read_json_object(rec / "recognizer.json")["recognizer_id"]
    for e in load_track(args.track):
        if str(e.get("evaluator_id")) != rec_id[:len(str(e.get("evaluator_id")))]:
            for suffix in (".json", ".clips.npz"):
                stale = args.track / "entries" / (Path(e["_file"]).stem + suffix)
                if stale.exists():
                    stale.unlink()
    for method, role, note, bench, folder in ROWS:
        out = work / (folder + f"_{bench}.json")
        if not out.exists():
            main_evaluate(benches[bench] / folder, data, rec, out=out, executor=args.executor)
        add_result(out, args.track, method=method, role=role, notes=note, replace=True)
        res = read_json_object(out)
        print(f"| {method} | " + " | ".join(f"{res['metrics'][m]['mean']:.4g}" if m in res["metrics"] else "-"
                                            for m in ("fid", "ra", "csiou")) + " |")
    print("built:", ", ".join(str(p) for p in build(args.track).values()))


if __name__ == "__main__":
    main()
