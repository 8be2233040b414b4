"""Split files: provenance, consistency with their rules, CLI listing."""
from __future__ import annotations

import re

import pytest

from hoibench.datasets import splits
from hoibench.cli import main


def test_every_split_names_its_source_and_level():
    assert set(splits.available()) >= {"behave", "omomo", "rich", "synthetic"}
    for ds in splits.available():
        data = splits.load(ds)
        assert data["default"] in data["splits"]
        for sp in data["splits"].values():
            assert sp["source"] and sp["level"] in ("sequence", "clip")
            assert "rule" in sp or "test" in sp


def test_behave_clip_split_follows_the_official_date03_rule():
    sp = splits.get("behave", "hoidiff-clips")
    assert len(sp["train"]) == 693 and len(sp["test"]) == 330
    assert all(n.startswith("Date03_") for n in sp["test"])
    assert not any(n.startswith("Date03_") for n in sp["train"])


def test_omomo_unseen_object_split_holds_out_objects():
    sp = splits.get("omomo")
    obj = lambda n: re.match(r"sub\d+_(.+)_\d+$", n).group(1)
    held_out = {obj(n) for n in sp["test"]} - {obj(n) for n in sp["train"]}
    assert held_out == {"smalltable", "suitcase", "tripod", "whitechair"}
    assert not set(sp["train"]) & set(sp["test"])


def test_cli_lists_and_shows(capsys):
    assert main(["splits", "ls"]) == 0
    assert "hoidiff-clips" in capsys.readouterr().out
    assert main(["splits", "show", "behave", "--split", "nope"]) == 2
    with pytest.raises(SystemExit):
        main(["splits", "frobnicate"])
