"""The checked-in synthetic track can be joined: it ships its evaluator folder, every
reproduced row was scored with that evaluator, about.md gives the one command, and a result
scored with the shipped evaluator is added without rescoring any row (another evaluator is
refused naming the shipped folder)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from committed import committed_track
from hoibench.evaluator.card import verify_folder
from hoibench.publish import leaderboard as lb

TRACK = Path(__file__).resolve().parent.parent / "leaderboards" / "synthetic"


def test_the_shipped_evaluator_verifies_and_scored_every_reproduced_row(tmp_path):
    shipped = committed_track("synthetic", tmp_path)             # rows a user added are not the release's
    card, _ = verify_folder(shipped / lb.TRACK_EVALUATOR)
    entries = lb.load_track(shipped)
    ours = [e for e in entries if e["source"] == "reproduced"]
    assert ours and {e["evaluator_id"] for e in ours} == {card["evaluator_id"]}
    assert card["dataset"]["name"] == "synthetic" and card["config"]["size"] == "tiny"
    about = (shipped / "about.md").read_text()
    assert card["evaluator_id"][:12] in about and "--evaluator leaderboards/synthetic/evaluator" in about


def _result_like(entry: dict, evaluator_id: str) -> dict:
    """A result with an entry's numbers, as `hoibench evaluate` writes it."""
    return {"metrics": {k: {**v, "std": 0.0} for k, v in entry["metrics"].items()}, "evaluator_id": evaluator_id,
            "protocol": entry["protocol"], "protocol_version": entry["protocol_version"],
            "toolkit_version": "0.7.0", "replications": entry["replications"], "complete": True, "overrides": [],
            "counts": {"samples_per_prompt": 1, "scored_ids": entry["scored_ids"], "test_ids": entry["test_ids"],
                       "missing_ids": []},
            "submission": {"flags": {"samples_per_prompt": 1}}, "representation": entry["representation"]}


def test_a_result_scored_with_the_shipped_evaluator_joins_the_track(tmp_path):
    copy = committed_track("synthetic", tmp_path)                # the docs' "My method" may be in the working tree
    gt = next(e for e in lb.load_track(copy) if e["role"] == "ground-truth")
    eid = json.loads((copy / lb.TRACK_EVALUATOR / "card.json").read_text())["evaluator_id"]
    mine = tmp_path / "mine.json"
    mine.write_text(json.dumps(_result_like(gt, eid)))
    path = lb.add_result(mine, copy, method="My method")
    assert json.loads(path.read_text())["evaluator_id"] == eid
    other = tmp_path / "other.json"
    other.write_text(json.dumps(_result_like(gt, "0" * 64)))
    with pytest.raises(lb.LeaderboardError, match="--evaluator .*synthetic/evaluator"):
        lb.add_result(other, copy, method="Other method")


def test_the_demo_says_whether_its_evaluator_is_the_tracks(tmp_path):
    from hoibench.demo import track_evaluator_note
    card = json.loads((TRACK / lb.TRACK_EVALUATOR / "card.json").read_text())
    ev = tmp_path / "ev"
    ev.mkdir()
    (ev / "card.json").write_text(json.dumps(card))
    assert "is the evaluator of the track" in track_evaluator_note(ev, TRACK.parent)
    (ev / "card.json").write_text(json.dumps({**card, "evaluator_id": "1" * 64}))
    assert "the same weights" in track_evaluator_note(ev, TRACK.parent)
    other = {**card, "evaluator_id": "1" * 64, "integrity": {**card["integrity"], "weights_sha256": "2" * 64}}
    (ev / "card.json").write_text(json.dumps(other))
    note = track_evaluator_note(ev, TRACK.parent)
    assert "other weights" in note and "--evaluator" in note and "synthetic/evaluator" in note
    assert track_evaluator_note(ev, tmp_path) == ""                 # no leaderboards/ above tmp_path
