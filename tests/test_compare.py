"""``hoibench compare``: side by side, with the differences outside the CIs marked."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from hoibench.scoring.compare import compare, outside


def res(fid, ci, r1=0.5, ev="a" * 64, k=30) -> dict:
    return {"metrics": {"fid": {"mean": fid, "ci95": ci}, "r_precision_top1": {"mean": r1, "ci95": 0.02}},
            "evaluator_id": ev, "protocol": "p", "protocol_version": "1", "complete": True,
            "counts": {"samples_per_prompt": k}, "submission": {"method": "m"}}


def test_outside_means_the_intervals_do_not_overlap():
    assert outside((1.0, 0.1), (1.3, 0.1)) and not outside((1.0, 0.2), (1.3, 0.1))


def test_table_marks_differences_outside_the_cis_and_flags_other_evaluators(tmp_path):
    paths = []
    for i, r in enumerate((res(0.20, 0.01), res(0.25, 0.01), res(0.21, 0.02), res(0.5, 0.01, ev="b" * 64))):
        p = tmp_path / f"r{i}.json"
        p.write_text(json.dumps(r))
        paths.append(p)
    text = compare(paths, ["A", "B", "C", "D"])
    fid = next(line for line in text.splitlines() if line.strip().startswith("fid"))
    cells = fid.split()[1:]
    assert cells[:3] == ["0.2", "±", "0.01"] and "0.25 ± 0.01*" in fid and "0.21 ± 0.02 " in fid + " "
    assert "D: " in text and "not on one scale" in text.split("\n")[3]
    with pytest.raises(ValueError, match="at least two"):
        compare(paths[:1])


def test_cli_compare_plots_and_names_a_bad_file(tmp_path):
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text(json.dumps(res(0.2, 0.01)))
    b.write_text("{not json")
    exe = [sys.executable, "-m", "hoibench.cli", "compare"]
    r = subprocess.run(exe + [str(a), str(a), "--plot", str(tmp_path / "c.png")], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0 and (tmp_path / "c.png").read_bytes()[:4] == b"\x89PNG", r.stderr
    r = subprocess.run(exe + [str(a), str(b)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "b.json" in r.stderr
