"""Leaderboard tracks: add results (refusing another evaluator, protocol, duplicates,
incomplete results), order rows, and render Markdown, CSV and HTML with CIs and flags."""
from __future__ import annotations

import csv
import io
import json
import subprocess
import sys

import pytest

from hoibench.publish import leaderboard as lb
from hoibench.publish.pages import build, fmt

EV = "a" * 64


def result(fid: float, r1: float, *, ev: str = EV, complete: bool = True, proto: str = "synthetic-clean",
           k: int = 1) -> dict:
    return {"metrics": {"fid": {"mean": fid, "ci95": 0.01, "n": 20},
                        "r_precision_top1": {"mean": r1, "ci95": 0.02, "n": 20},
                        "cd": {"mean": 0.02, "ci95": 0.0, "n": 20}},
            "evaluator_id": ev, "protocol": proto, "protocol_version": "1.1", "toolkit_version": "0.5.0",
            "replications": 20, "complete": complete, "overrides": [] if complete else [{"override": "failed_gate"}],
            "counts": {"samples_per_prompt": k, "scored_ids": 34, "test_ids": 34, "missing_ids": []},
            "submission": {"flags": {"samples_per_prompt": k}}, "representation": {"hml263": "hml263-clean-1.0"}}


@pytest.fixture
def track(tmp_path):
    t = tmp_path / "leaderboards" / "synthetic"
    for name, fid, r1, role in (("GT (real motion)", -4e-7, 0.61, "ground-truth"), ("Model B", 0.30, 0.50, "method"),
                                ("Model A", 0.20, 0.55, "method"), ("mean pose", 1.9, 0.06, "reference")):
        p = tmp_path / f"{name}.json"
        p.write_text(json.dumps(result(fid, r1)))
        lb.add_result(p, t, method=name, role=role)
    reported = {**lb.entry_from_result(result(0.5, 0.45, ev="b" * 64), method="Paper X", track="synthetic",
                                       source="reported"), "citation": "X et al. 2025, Table 1", "role": "method"}
    lb.write_entry(reported, t / "entries")
    return t


def test_rows_are_ordered_gt_first_then_by_fid_then_reported(track):
    names = [e["method"] for e in lb.order(lb.load_track(track))]
    assert names == ["GT (real motion)", "Model A", "Model B", "mean pose", "Paper X"]


def test_markdown_csv_and_html_carry_cis_arrows_and_flags(track, tmp_path):
    paths = build(track)
    md = paths["README.md"].read_text()
    assert md.index("**GT (real motion)**") < md.index("Model A") < md.index("Model B") < md.index("Paper X")
    assert "FID ↓" in md and "R@1 ↑" in md and "0.200 ± 0.010" in md and "0.000 ± 0.010" in md   # GT's -4e-7 as 0
    assert "Paper X (X et al. 2025, Table 1)" in md and "reported, not comparable" in md
    rows = list(csv.DictReader(io.StringIO(paths["leaderboard.csv"].read_text())))
    assert [r["method"] for r in rows][:3] == ["GT (real motion)", "Model A", "Model B"]
    assert float(rows[0]["fid"]) == -4e-7 and float(rows[1]["fid_ci95"]) == 0.01      # the CSV keeps raw values
    page = paths["index.html"].read_text()
    assert '<tr class="gt">' in page and '<tr class="reported">' in page and "not comparable" in page
    assert page.count("data:image/png;base64,") == 2 and "addEventListener('click'" in page
    assert paths["metrics.png"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_adding_a_result_with_another_evaluator_is_refused_naming_both_ids(track, tmp_path):
    p = tmp_path / "other.json"
    p.write_text(json.dumps(result(0.1, 0.6, ev="c" * 64)))
    with pytest.raises(lb.LeaderboardError, match=r"evaluator_id: cccccccccccc is not the evaluator .*aaaaaaaaaaaa"):
        lb.add_result(p, track, method="Model C")


def test_duplicates_other_protocols_and_incomplete_results_are_refused(track, tmp_path):
    p = tmp_path / "r.json"
    p.write_text(json.dumps(result(0.1, 0.6)))
    with pytest.raises(lb.LeaderboardError, match="exists already"):
        lb.add_result(p, track, method="Model A")
    lb.add_result(p, track, method="Model A", replace=True)
    p.write_text(json.dumps(result(0.1, 0.6, proto="behave-clean")))
    with pytest.raises(lb.LeaderboardError, match="protocol"):
        lb.add_result(p, track, method="Model D")
    p.write_text(json.dumps(result(0.1, 0.6, complete=False)))
    with pytest.raises(lb.LeaderboardError, match="complete: false .*failed_gate"):
        lb.add_result(p, track, method="Model E")
    lb.add_result(p, track, method="Model E", allow_incomplete=True)
    md = build(track)["README.md"].read_text()
    assert "Model E" in md and "incomplete" in md


def test_a_broken_entry_is_named_by_file_and_field(track):
    bad = track / "entries" / "bad.json"
    bad.write_text(json.dumps({"format": lb.ENTRY_FORMAT, "track": "synthetic", "method": "x", "source": "reproduced",
                               "metrics": {"fid": {"mean": "low"}}}))
    with pytest.raises(lb.LeaderboardError, match=r"bad.json: field metrics.fid"):
        lb.load_track(track)


def test_fmt_shows_tiny_negative_fid_as_zero():
    assert fmt({"mean": -3e-7, "ci95": 0.0}, name="fid") == "0.000 ± 0.000" and fmt(None) == "-"
    assert fmt({"mean": -4.6e-4, "ci95": None}, name="fid") == "0.000"      # one rule for every track
    assert fmt({"mean": -3e-7, "ci95": 0.0}, name="cd") == "-0.00000 ± 0.00000"
    assert fmt({"mean": 0.00125, "ci95": 0.0}) == "0.00125 ± 0.00000"


def test_cli_add_build_and_one_line_errors(track, tmp_path):
    root = track.parent
    exe = [sys.executable, "-m", "hoibench.cli", "leaderboard"]
    p = tmp_path / "new.json"
    p.write_text(json.dumps(result(0.05, 0.6)))
    r = subprocess.run(exe + ["add", str(p), "--track", "synthetic", "--method", "Model F", "--root", str(root)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    r = subprocess.run(exe + ["build", "--root", str(root)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and "index.html" in r.stdout, r.stderr
    assert "Model F" in (track / "README.md").read_text()
    p.write_text(json.dumps(result(0.05, 0.6, ev="d" * 64)))
    r = subprocess.run(exe + ["add", str(p), "--track", "synthetic", "--method", "Model G", "--root", str(root)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "dddddddddddd" in r.stderr


def test_evaluate_prints_groups_arrows_units_and_zero_for_tiny_negative_fid():
    from hoibench.scoring.evaluate import format_result
    res = result(-3e-7, 0.5)
    res.update({"protocol": "synthetic-clean", "protocol_version": "1.1", "notes": ["x"],
                "undefined_metrics": {"ocd": "no group", "ps": "no group"}})
    res["metrics"]["clips"] = {"mean": 34.0, "ci95": 0.0}
    text = format_result(res)
    lines = text.splitlines()
    assert lines[1] == "semantic:" and "physical:" in lines
    fid = next(line for line in lines if line.strip().startswith("fid"))
    assert "↓" in fid and " 0 ± " in fid and "squared embedding distance" in fid
    assert any(line.strip().startswith("r_precision_top1") and "↑" in line for line in lines)
    assert "counts: clips 34" in text and "undefined: ocd, ps: no group" in text


def test_a_human_only_row_is_marked_on_every_page(track, tmp_path):
    r = result(0.4, 0.5)
    r["submission"]["flags"]["human_only"] = True
    p = tmp_path / "mdm.json"
    p.write_text(json.dumps(r))
    lb.add_result(p, track, method="MDM (human only)")
    paths = build(track)
    row = next(line for line in paths["README.md"].read_text().splitlines() if "MDM (human only)" in line)
    assert "human-only (object metrics n/a)" in row
    assert "human-only (object metrics n/a)" in paths["index.html"].read_text()
    other = next(line for line in paths["README.md"].read_text().splitlines() if "Model A" in line)
    assert "human-only" not in other


def test_a_result_of_another_split_size_is_refused_even_when_incomplete_results_are_allowed(track, tmp_path):
    r = result(0.1, 0.6, complete=False)
    r["counts"]["test_ids"] = 7
    p = tmp_path / "other-store.json"
    p.write_text(json.dumps(r))
    with pytest.raises(lb.LeaderboardError, match=r"other-store.json: field counts.test_ids: 7 test clips, not the 34"):
        lb.add_result(p, track, method="Other store", allow_incomplete=True)
