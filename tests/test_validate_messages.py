"""What validate says when every file is valid but the submission as a whole is not."""
from __future__ import annotations

import json


def test_a_wrong_fps_in_submission_json_is_named_and_the_summary_does_not_contradict_it(synthetic_store, tmp_path,
                                                                                          capsys):
    from hoibench.cli import main
    from hoibench.scoring.submission_write import from_store
    _, data, _ = synthetic_store
    sub = from_store(data, tmp_path / "gt")
    meta = json.loads((sub / "submission.json").read_text())
    meta["fps"] = 30
    (sub / "submission.json").write_text(json.dumps(meta))
    assert main(["validate", str(sub), "--data", str(data)]) == 1
    out = capsys.readouterr().out.strip().splitlines()
    assert any("fps 30" in line for line in out)
    assert "every sample file is valid, but 1 error(s) of the whole submission (submission.json)" in out[-1]


def test_readme_and_csv_keep_no_script_link_from_an_entry():
    from hoibench.publish.pages import csv_text, md_text
    for text in ("[paper](javascript:alert(1))", "see javascript:alert(document.cookie)", "data:text/html,x"):
        for out in (md_text(text), csv_text(text)):
            assert "javascript:" not in out.lower() and "data:text" not in out.lower() and "](javascript" not in out
    assert md_text("[p](https://arxiv.org/abs/1)") == "\\[p\\](https://arxiv.org/abs/1)"
    assert csv_text("Data: BEHAVE (CVPR 2022)") == "Data: BEHAVE (CVPR 2022)"


def test_leaderboard_add_refuses_a_method_that_is_not_valid_unicode(tmp_path):
    import pytest

    from hoibench.publish.leaderboard import LeaderboardError, add_result
    bad = "My method \udcff"                      # a byte the command line could not decode
    with pytest.raises(LeaderboardError, match=r"^--method: not valid Unicode text"):
        add_result(tmp_path / "r.json", tmp_path / "track", method=bad)
