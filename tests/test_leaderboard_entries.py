"""Leaderboard entries carry what a reader needs to compare rows, and refuse what they cannot be."""
from __future__ import annotations

import json

import pytest

from hoibench.publish.leaderboard import entry_from_result, slug, write_entry

RESULT = {
    "metrics": {"fid": {"mean": 0.2, "ci95": 0.0, "n": 20}, "r_precision_top1": {"mean": 0.58, "ci95": 0.02, "n": 20}},
    "undefined_metrics": {"fsr": "undefined (0/0) in 20 of 20 replications"},
    "evaluator_id": "e" * 64, "protocol": "synthetic-clean", "protocol_version": "1.1",
    "representation": {"hml263": "hml263-clean-1.0"}, "toolkit_version": "0.4.0", "replications": 20,
    "counts": {"samples_per_prompt": 1, "scored_ids": 33, "test_ids": 34, "missing_ids": ["clip_x"]},
    "submission": {"flags": {"uses_gt_length": True}}, "complete": False, "overrides": [],
}


def test_entry_copies_versions_counts_and_completeness(tmp_path):
    e = entry_from_result(RESULT, method="ChainHOI (tiny)", track="synthetic",
                          submission_meta={"source": {"checkpoint_id": "c" * 64}})
    assert e["metrics"]["fid"] == {"mean": 0.2, "ci95": 0.0, "n": 20, "unit": "squared embedding distance",
                                   "direction": "lower", "interval": "replications"}
    assert e["missing_ids"] == ["clip_x"] and e["complete"] is False and e["scored_ids"] == 33
    assert e["evaluator_id"] == "e" * 64 and e["protocol_version"] == "1.1" and e["toolkit_version"] == "0.4.0"
    assert e["submission_source"]["checkpoint_id"] == "c" * 64 and e["undefined_metrics"]["fsr"]
    path = write_entry(e, tmp_path)
    assert path.name == "chainhoi-tiny.json" and json.loads(path.read_text()) == e


def test_slug_and_source_are_checked():
    assert slug("mean pose + static object") == "mean-pose-static-object"
    with pytest.raises(ValueError):
        slug("+++")
    with pytest.raises(ValueError, match="source"):
        entry_from_result(RESULT, method="x", track="synthetic", source="claimed")


def test_a_row_is_comparable_with_a_paper_only_under_its_legacy_protocol_and_evaluator(tmp_path):
    from hoibench.publish.leaderboard import LeaderboardError, comparable, comparable_citations, read_entry
    from hoibench.publish.pages import _flags
    paper = {"source": "reported", "citation": "ChainHOI Tab. 1", "method": "ChainHOI",
             "comparable_with": {"protocol": "behave-legacy", "evaluator_backend": "chainhoi"}}
    ours = entry_from_result({**RESULT, "protocol": "behave-legacy", "evaluator_backend": "chainhoi"},
                             method="mine", track="behave")
    assert comparable(ours, paper) and comparable_citations(ours, [paper]) == ["ChainHOI Tab. 1"]
    assert _flags(ours, [paper]) == ["comparable with ChainHOI Tab. 1", "incomplete", "1 missing ids"]
    assert _flags({**paper, "metrics": {}}, [ours])[0] == "reported, comparable with 1 scored row(s)"
    # hoibench's own evaluator (results before backends were recorded count as it), another
    # protocol, a paper row that names nothing: not comparable
    assert entry_from_result(RESULT, method="x", track="behave")["evaluator_backend"] == "contrastive"
    assert not comparable({**ours, "evaluator_backend": "contrastive"}, paper)
    assert not comparable({**ours, "protocol": "behave-clean"}, paper)
    assert not comparable(ours, {k: v for k, v in paper.items() if k != "comparable_with"})
    assert not comparable(paper, paper)
    bad = {**paper, "format": "hoibench-entry-1", "track": "behave", "metrics": {},
           "comparable_with": {"protocol": "behave-legacy"}}
    (tmp_path / "bad.json").write_text(json.dumps(bad))
    with pytest.raises(LeaderboardError, match="bad.json: field comparable_with"):
        read_entry(tmp_path / "bad.json")


def test_no_checked_in_row_is_comparable_until_a_published_evaluator_scores_one(tmp_path):
    """The ChainHOI rows name behave-legacy/omomo-legacy with ChainHOI's evaluator; every
    hoibench row was scored with hoibench's own, so none is comparable (docs/leaderboards.md)."""
    from committed import committed_track
    from hoibench.publish.leaderboard import comparable, load_track
    root = tmp_path / "leaderboards"                                 # the committed rows, not a user's
    for track in ("behave", "omomo", "rich-cat", "synthetic"):
        entries = load_track(committed_track(track, tmp_path))
        papers = [e for e in entries if e["source"] == "reported"]
        assert not any(comparable(e, p) for e in entries for p in papers)
    assert all(p.get("comparable_with", {}).get("evaluator_backend") == "chainhoi"
               for p in load_track(root / "behave") if p["source"] == "reported")


def test_rows_state_their_training_budget_and_a_shared_text_encoder_is_flagged():
    import csv
    import io
    from hoibench.publish.pages import _flags, budget, write_csv
    training = {"steps": 1500, "parameters": 1_783_436, "wall_seconds": 612.0, "hardware": "CPU Xeon, 2 thread(s)",
                "text_encoder": {"encoder": "minilm", "weights_sha256": "m" * 64}}
    own = {**RESULT, "complete": True, "counts": {**RESULT["counts"], "missing_ids": []},
           "evaluator_text_encoder": {"name": "all-MiniLM-L6-v2", "weights_sha256": "m" * 64}}
    shared = {**entry_from_result(own, method="ChainHOI paper", track="synthetic",
                                  submission_meta={"source": {"training": training}}), "role": "baseline"}
    assert budget(shared) == "1,500 steps, 1.78 M params, 10.2 min, CPU Xeon, 2 threads"
    assert _flags(shared) == ["conditioned on the evaluator's text encoder"]
    tokens = {**shared, "submission_source": {"training": {**training, "text_encoder": {"encoder": "tokens"}}}}
    assert _flags(tokens) == []
    other = {**shared, "evaluator_text_encoder": {"weights_sha256": "r" * 64}}
    assert _flags(other) == []
    bare = {**shared, "submission_source": {}}
    assert budget(bare) == "not stated" and _flags(bare) == ["training budget not stated"]
    assert budget({**bare, "role": "method"}) == "" and _flags({**bare, "role": "method"}) == []
    row = next(csv.DictReader(io.StringIO(write_csv([shared]))))
    assert row["train_steps"] == "1500" and row["train_parameters"] == "1783436"
    assert row["train_hardware"] == "CPU Xeon, 2 thread(s)" and row["conditioner_text_encoder"] == "minilm"


def test_scoring_notes_a_generator_conditioned_on_the_evaluators_text_encoder():
    from types import SimpleNamespace
    from hoibench.scoring.hoi import _shares_text_encoder, _text_encoder
    ev = SimpleNamespace(card={"text_encoder": {"name": "all-MiniLM-L6-v2", "weights_sha256": "m" * 64,
                                                "pooling": "mean", "fine_tuned": True}})
    assert _text_encoder(ev) == {"name": "all-MiniLM-L6-v2", "weights_sha256": "m" * 64, "fine_tuned": True}
    meta = {"source": {"training": {"text_encoder": {"encoder": "minilm", "weights_sha256": "m" * 64}}}}
    assert _shares_text_encoder(meta, ev) == "all-MiniLM-L6-v2"
    meta_tokens = {"source": {"training": {"text_encoder": {"encoder": "tokens"}}}}
    assert _shares_text_encoder(meta_tokens, ev) == "" and _shares_text_encoder({}, ev) == ""
    other = SimpleNamespace(card={"text_encoder": {"name": "roberta", "weights_sha256": "r" * 64}})
    assert _shares_text_encoder(meta, other) == "" and _text_encoder(SimpleNamespace(card=None)) == {}

def test_the_multibody_track_renders_its_own_columns(tmp_path):
    """The checked-in multi-body track: SyncDiff's metrics as columns, with arrows, and
    value ± half-width cells; no FID-vs-R@1 plot."""
    from committed import committed_track
    from hoibench.publish.leaderboard import load_track, order
    from hoibench.publish.pages import markdown
    entries = order(load_track(committed_track("multibody-synthetic", tmp_path)))
    assert entries[0]["role"] == "ground-truth" and entries[0]["evaluator_id"] == entries[-1]["evaluator_id"]
    text = markdown("multibody-synthetic", entries)
    header = next(line for line in text.splitlines() if line.startswith("| # |"))
    assert [c.strip() for c in header.split("|")[4:-2]] == ["CSR ≈GT", "CRR ≈GT", "CSIoU ↑", "IV ↓", "ID ↓", "OD ≈GT",
                                                            "RA ↑", "FID ↓"]
    assert "half-width" in text and "fid_vs_r1" not in text
    sync = next(e for e in entries if e["method"] == "SyncDiff tiny")
    assert 0 < sync["metrics"]["csiou"]["ci95"] < 0.2 and sync["metrics"]["iv_cm3"]["mean"] > 0
    # multi-body CIs are over clips or samples: a zero half-width is a zero spread, not "n/a (K = 1)"
    gt_row = next(line for line in text.splitlines() if "GT (real motion)" in line)
    assert entries[0]["metrics"]["crr"]["ci95"] == 0 and "1.000 ± 0.000" in gt_row and "n/a" not in text
    from hoibench.publish.pages import page
    legend = page("multibody-synthetic", entries, {})
    assert "over clips or samples" in legend and "over the protocol's replications" not in legend


def test_a_multibody_result_file_is_read_and_becomes_an_entry(tmp_path):
    """`leaderboard add` reads multi-body results (plain values, half-widths in ci95, null
    for an undefined metric) and refuses a malformed one naming the field."""
    import json

    from hoibench.scoring.results import ResultError, read_result
    res = {"kind": "multibody", "metrics": {"csiou": 0.85, "ra": 0.39, "sd": None},
           "ci95": {"csiou": 0.06, "ra": 0.13, "sd": None}, "counts": {"clips": 54, "samples": 54},
           "protocol": "multibody-synthetic", "protocol_version": "1.0", "recognizer_id": "f831072f3a33",
           "protocol_settings": {"samples_per_prompt": 1}, "complete": True}
    path = tmp_path / "mb.json"
    path.write_text(json.dumps(res))
    e = entry_from_result(read_result(path), method="SyncDiff tiny", track="multibody-synthetic")
    over = {"unit": "fraction", "interval": "samples"}
    assert e["metrics"] == {"csiou": {"mean": 0.85, "ci95": 0.06, "n": 54, "direction": "higher", **over},
                            "ra": {"mean": 0.39, "ci95": 0.13, "n": 54, "direction": "higher", **over}}
    assert e["evaluator_id"] == "f831072f3a33" and e["scored_ids"] == 54 and e["samples_per_prompt"] == 1
    path.write_text(json.dumps({**res, "metrics": {**res["metrics"], "ra": "0.39"}}))
    with pytest.raises(ResultError, match=r"mb.json: field metrics.ra: expected a number or null"):
        read_result(path)


def test_add_reads_the_scored_submissions_training_budget(tmp_path):
    """`leaderboard add` finds the submission a result names (beside the result file) and keeps
    its source block, so a baseline row states its training budget."""
    import json

    from hoibench.publish.leaderboard import add_result
    res = {"kind": "multibody", "metrics": {"ra": 0.39}, "ci95": {"ra": 0.13}, "counts": {"clips": 54, "samples": 54},
           "protocol": "multibody-synthetic", "protocol_version": "1.0", "recognizer_id": "f831072f3a33",
           "complete": True, "submission": {"path": "sub_rate"}}
    (tmp_path / "sub_rate").mkdir()
    budget = {"steps": 1000, "parameters": 264460, "wall_seconds": 556.0, "hardware": "cpu"}
    (tmp_path / "sub_rate" / "submission.json").write_text(json.dumps({"source": {"training": budget}}))
    (tmp_path / "res.json").write_text(json.dumps(res))
    path = add_result(tmp_path / "res.json", tmp_path / "lb" / "multibody-synthetic", method="SyncDiff tiny",
                      role="baseline")
    assert json.loads(path.read_text())["submission_source"]["training"] == budget
    (tmp_path / "sub_rate" / "submission.json").unlink()                  # not here: nothing claimed
    path = add_result(tmp_path / "res.json", tmp_path / "lb" / "multibody-synthetic", method="SyncDiff tiny",
                      role="baseline", replace=True)
    assert json.loads(path.read_text())["submission_source"] == {}
    import zipfile                                                          # a .zip submission too
    with zipfile.ZipFile(tmp_path / "sub.zip", "w") as z:
        z.writestr("submission.json", json.dumps({"source": {"training": budget}}))
    (tmp_path / "res_zip.json").write_text(json.dumps({**res, "submission": {"path": "sub.zip"}}))
    path = add_result(tmp_path / "res_zip.json", tmp_path / "lb" / "multibody-synthetic", method="SyncDiff tiny",
                      role="baseline", replace=True)
    assert json.loads(path.read_text())["submission_source"]["training"] == budget
    # another recognizer than the track's: refused naming the multi-body result's field
    from hoibench.publish.leaderboard import LeaderboardError
    (tmp_path / "other.json").write_text(json.dumps({**res, "recognizer_id": "c0ca5e7a1536"}))
    with pytest.raises(LeaderboardError, match=r"other.json: field evaluator_id: c0ca5e7a1536 is not the evaluator"):
        add_result(tmp_path / "other.json", tmp_path / "lb" / "multibody-synthetic", method="Other", role="method")
