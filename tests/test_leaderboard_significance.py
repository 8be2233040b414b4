"""Leaderboard rows that keep per-clip data: the file an entry keeps, the paired test against
the row above and the bootstrap rank interval, on constructed embeddings with known answers."""
from __future__ import annotations

import json

import numpy as np
import pytest

from hoibench.core.io import npz_bytes

N, D = 40, 16


def _arrays(motion: np.ndarray, real: np.ndarray, k: int = 1, phys: float = 0.01) -> dict:
    ids = np.array([f"c{i:03d}" for i in range(N)])
    text = real + 0.01 * np.random.default_rng(7).normal(size=real.shape)       # one caption per clip
    return {"ids": ids, "motion": np.repeat(motion[None], k, 0).astype(np.float32), "real": real.astype(np.float32),
            "text": text.astype(np.float32), "text_offsets": np.arange(N + 1, dtype=np.int64),
            "physical": np.full((k, N, 1), phys), "physical_samples": np.arange(k, dtype=np.int64),
            "physical_names": np.array(["cd"])}


def _write(folder, name: str, arrays: dict, fid: float, role: str = "baseline") -> None:
    from hoibench.publish.leaderboard import ENTRY_FORMAT
    import hashlib
    data = npz_bytes(arrays)
    (folder / f"{name}.clips.npz").write_bytes(data)
    entry = {"format": ENTRY_FORMAT, "track": "synthetic", "method": name, "source": "reproduced", "role": role,
             "protocol": "synthetic-clean", "protocol_version": "1.1", "evaluator_id": "e" * 64, "complete": True,
             "samples_per_prompt": 1,
             "metrics": {"fid": {"mean": fid, "ci95": 0.0}, "r_precision_top1": {"mean": 0.5, "ci95": 0.01},
                         "cd": {"mean": 0.01, "ci95": 0.0}},
             "per_clip_data": {"file": f"{name}.clips.npz", "sha256": hashlib.sha256(data).hexdigest(),
                               "bytes": len(data), "samples": "all"}}
    (folder / f"{name}.json").write_text(json.dumps(entry))


@pytest.fixture()
def track(tmp_path):
    """Three ranked rows: 'near' and 'twin' (the same embeddings) close to the ground truth,
    'far' shifted by 3 units in every dimension; and the ground truth row."""
    rng = np.random.default_rng(0)
    real = rng.normal(size=(N, D))
    near = real + 0.05 * rng.normal(size=(N, D))
    t = tmp_path / "synthetic"
    (t / "entries").mkdir(parents=True)
    _write(t / "entries", "near", _arrays(near, real), 0.01)
    _write(t / "entries", "twin", _arrays(near, real), 0.0100001)
    _write(t / "entries", "far", _arrays(real + 3.0, real, phys=0.2), 9.0)
    _write(t / "entries", "gt", _arrays(real, real, phys=0.0), 0.0, role="ground-truth")
    return t


def test_identical_rows_are_not_distinguishable_and_a_far_row_is(track):
    from hoibench.publish.leaderboard import load_track, order
    from hoibench.publish.significance import track_significance
    entries = order(load_track(track))
    assert [e["method"] for e in entries] == ["gt", "near", "twin", "far"]
    sig = track_significance(track, entries, ("fid", "r_precision_top1", "cd"), resamples=2000)
    assert "gt.json" not in sig                                   # the ground truth is not ranked
    assert "vs_above" not in sig["near.json"]                     # the first ranked row has nothing above
    twin = sig["twin.json"]["vs_above"]
    assert twin["method"] == "near" and twin["n_clips"] == N and not twin["distinguishable"]
    assert twin["metrics"]["fid"]["diff"] == 0.0 and twin["metrics"]["fid"]["p_holm"] > 0.9
    far = sig["far.json"]["vs_above"]
    assert far["distinguishable"]
    assert far["metrics"]["fid"]["verdict"] == "the row above better"
    assert far["metrics"]["fid"]["ci95"][0] > 0                   # FID 3^2 * D higher, every draw
    assert far["metrics"]["cd"]["diff"] == pytest.approx(0.19)
    # ranks: the twins share ranks 1-2, the far row is third on every draw
    assert sig["near.json"]["rank_ci95"] == [1, 2] and sig["twin.json"]["rank_ci95"] == [1, 2]
    assert sig["far.json"]["rank_ci95"] == [3, 3]


def test_holm_is_over_the_headline_metrics_only(track):
    """With one headline metric the adjusted p is the raw p; with three it is at least it."""
    from hoibench.publish.leaderboard import load_track, order
    from hoibench.publish.significance import track_significance
    entries = order(load_track(track))
    one = track_significance(track, entries, ("cd",))["far.json"]["vs_above"]["metrics"]["cd"]
    three = track_significance(track, entries, ("fid", "r_precision_top1", "cd"))["far.json"]["vs_above"]["metrics"]
    assert one["p_holm"] == one["p"]
    assert three["cd"]["p_holm"] >= three["cd"]["p"]


def test_no_rank_interval_when_a_ranked_row_lacks_per_clip_data(track):
    from hoibench.publish.leaderboard import load_track, order
    from hoibench.publish.significance import track_significance
    p = track / "entries" / "twin.json"
    e = json.loads(p.read_text())
    del e["per_clip_data"]
    p.write_text(json.dumps(e))
    sig = track_significance(track, order(load_track(track)), ("fid",))
    assert all("rank_ci95" not in s for s in sig.values())
    assert "vs_above" not in sig["far.json"]                      # the row above it kept nothing


def test_pages_show_the_columns_and_rebuild_byte_identical(track):
    from hoibench.publish.pages import build
    first = {k: p.read_bytes() for k, p in build(track).items()}
    second = {k: p.read_bytes() for k, p in build(track).items()}
    assert first == second
    md = first["README.md"].decode()
    assert "rank 95%" in md and "vs row above" in md
    far_line = next(line for line in md.splitlines() if "| far |" in line)
    assert "| 3 | yes: FID p" in far_line and "(above better)" in far_line
    twin_line = next(line for line in md.splitlines() if "| twin |" in line)
    assert f"| 1-2 | no ({N} clips) |" in twin_line
    csv = first["leaderboard.csv"].decode().splitlines()
    assert csv[0].endswith("rank_ci95,vs_above_distinguishable,vs_above")
    assert "rank 95%" in first["index.html"].decode()


def test_a_changed_clip_file_is_refused_naming_the_field(track):
    from hoibench.publish.leaderboard import LeaderboardError
    from hoibench.publish.pages import build
    (track / "entries" / "far.clips.npz").write_bytes(b"not the file")
    with pytest.raises(LeaderboardError, match="per_clip_data.sha256"):
        build(track)


def test_an_entry_keeps_sample_0_when_all_samples_exceed_the_limit(tmp_path):
    from hoibench.publish.leaderboard import attach_clip_data
    from hoibench.scoring.clip_data import read_clip_data, write_clip_data
    rng = np.random.default_rng(1)
    real = rng.normal(size=(N, D))
    arrays = _arrays(real + 0.1, real, k=30)
    arrays["motion"] = (arrays["motion"] + rng.normal(size=arrays["motion"].shape)).astype(np.float32)
    result = {}
    write_clip_data(result, arrays, tmp_path / "r.json")
    entries = tmp_path / "entries"
    entries.mkdir()
    small = {"method": "m"}
    attach_clip_data(small, result, tmp_path / "r.json", entries, max_bytes=len(npz_bytes(arrays)) // 4)
    assert small["per_clip_data"]["samples"] == "sample 0"
    kept = read_clip_data(small, entries / "m.json")
    assert kept["motion"].shape == (1, N, D) and kept["physical"].shape == (1, N, 1)
    np.testing.assert_array_equal(kept["motion"][0], arrays["motion"][0])
    big = {"method": "m"}
    attach_clip_data(big, result, tmp_path / "r.json", entries)
    assert big["per_clip_data"]["samples"] == "all"
    assert read_clip_data(big, entries / "m.json")["motion"].shape == (30, N, D)
    assert attach_clip_data({"method": "x"}, {}, tmp_path / "r.json", entries) is None   # nothing kept: no file


def test_a_result_already_on_the_track_under_another_name_is_refused(track, tmp_path):
    from hoibench.publish import leaderboard as lb
    from hoibench.scoring.clip_data import write_clip_data
    from hoibench.scoring.results import metric_entry
    rng = np.random.default_rng(0)
    real = rng.normal(size=(N, D))
    near = real + 0.05 * rng.normal(size=(N, D))              # the 'near' row's embeddings, rebuilt
    result = {"format": "hoibench-result-2", "protocol": "synthetic-clean", "protocol_version": "1.1",
              "evaluator_id": "e" * 64, "complete": True, "submission": {"method": "again"},
              "counts": {"test_ids": N, "scored_ids": N, "samples_per_prompt": 1},
              "metrics": {m: metric_entry(m, 0.0, 0.0, 20) for m in ("fid", "r_precision_top1", "cd")}}
    path = tmp_path / "again.json"
    write_clip_data(result, _arrays(near, real), path)
    path.write_text(json.dumps(result))
    with pytest.raises(lb.LeaderboardError, match=r"again.json: field per_clip_data.sha256: the same per-clip data "
                                                  r"as the entry '(near|twin)' \((near|twin).json\)"):
        lb.add_result(path, track, method="Near again")
    (track / "entries" / "twin.json").unlink()               # the fixture's twin shares the data too
    lb.add_result(path, track, method="near", replace=True)   # replacing that very entry is allowed
