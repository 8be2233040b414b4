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
    assert e["metrics"]["fid"] == {"mean": 0.2, "ci95": 0.0, "n": 20}
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
