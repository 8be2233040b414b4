"""Writers create only new paths or files they own: ``submission prompts --out``, ``export``,
``prepare --out`` (and its stale-temp cleanup), ``leaderboard add --track`` (no write outside
the leaderboards root); outputs get ``0666 & ~umask`` like any other program's files."""
from __future__ import annotations

import json
import os
import stat
from pathlib import Path

import numpy as np
import pytest


def test_prompts_out_refuses_any_file_but_an_earlier_prompts_file(tmp_path):
    from hoibench.scoring.prompts import check_prompts_out, is_prompts_file
    manifest = tmp_path / "store" / "manifest.json"
    manifest.parent.mkdir()
    manifest.write_text('{"dataset": "synthetic", "clips": []}')
    for victim in (manifest, tmp_path / "notes.txt"):
        if not victim.exists():
            victim.write_text("my notes\n")
        with pytest.raises(FileExistsError, match="not a prompts file written by hoibench: not overwritten"):
            check_prompts_out(victim)
    with pytest.raises(FileExistsError, match="is a folder"):
        check_prompts_out(tmp_path / "store")
    ours = tmp_path / "prompts.jsonl"
    ours.write_text(json.dumps({"id": "a", "captions": ["x"], "frames": 40, "fps": 20.0}) + "\n")
    assert is_prompts_file(ours) and not is_prompts_file(manifest)
    check_prompts_out(ours)                  # rerunning the command replaces its own file
    check_prompts_out(tmp_path / "new.jsonl")
    fifo = tmp_path / "fifo.jsonl"
    os.mkfifo(fifo)
    with pytest.raises(FileExistsError):
        check_prompts_out(fifo)              # never opened for reading (no hang)


def test_export_refuses_a_non_empty_folder_unless_told(tmp_path):
    from hoibench.datasets.export import REPORT, check_export_out
    out = tmp_path / "HumanML3D"
    out.mkdir()
    check_export_out(out)                    # empty
    (out / "train.txt").write_text("my own split\n")
    with pytest.raises(FileExistsError, match=r"not empty and not an earlier export \(holds train.txt\)"):
        check_export_out(out)
    check_export_out(out, overwrite=True)
    (out / REPORT).write_text("{}")
    check_export_out(out)                    # an earlier export: its files are ours
    (tmp_path / "file").write_text("x")
    with pytest.raises(FileExistsError, match="not a folder"):
        check_export_out(tmp_path / "file")


def test_prepare_refuses_a_folder_that_is_not_a_store_and_cleans_only_its_own_temp_files(tmp_path):
    from hoibench.core.io import atomic_write_text, clean_stale_tmp, is_atomic_tmp
    from hoibench.datasets.store import PrepareConfig, _refuse_foreign_store
    thesis = tmp_path / "thesis"
    thesis.mkdir()
    (thesis / "thesis.tex").write_text("\\chapter{}")
    (thesis / ".thesis.tex.tmp").write_text("editor backup")
    with pytest.raises(FileExistsError, match=r"not empty and not a store \(holds .thesis.tex.tmp, thesis.tex\)"):
        _refuse_foreign_store(thesis, PrepareConfig("synthetic"), {})
    ours = thesis / ".hoibench-clip.npz.x1y2.tmp"
    ours.write_bytes(b"half")
    assert clean_stale_tmp(thesis) == [ours]
    assert (thesis / ".thesis.tex.tmp").read_text() == "editor backup"
    assert not is_atomic_tmp(".thesis.tex.tmp") and is_atomic_tmp(".hoibench-a.json.k.tmp")
    store = tmp_path / "store"
    (store / "clips").mkdir(parents=True)
    (store / ".hoibench-manifest.json.q.tmp").write_text("{")
    _refuse_foreign_store(store, PrepareConfig("synthetic"), {})      # an interrupted first run resumes
    atomic_write_text(store / "x.txt", "y")
    assert [p.name for p in store.iterdir() if p.name.endswith(".tmp")] == [".hoibench-manifest.json.q.tmp"]


@pytest.mark.parametrize("track", ["../escaped_track", "/tmp/abs_track", "a/b", "..", ".hidden", "x\ny"])
def test_track_names_pass_the_id_rule(tmp_path, track):
    from hoibench.publish.leaderboard import track_folder
    (tmp_path / "lb" / "synthetic" / "entries").mkdir(parents=True)
    with pytest.raises(ValueError, match="--track"):
        track_folder(tmp_path / "lb", track, new_track=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["lb"]


def test_outputs_respect_the_umask(tmp_path):
    from hoibench.core.io import atomic_save_npz, atomic_write_json, atomic_write_text, current_umask
    old = os.umask(0o022)
    try:
        assert current_umask() == 0o022
        paths = [atomic_write_text(tmp_path / "index.html", "<p>"), atomic_write_json(tmp_path / "r.json", {"a": 1}),
                 atomic_save_npz(tmp_path / "s.npz", x=np.zeros(3))]
        assert {stat.S_IMODE(p.stat().st_mode) for p in paths} == {0o644}
        os.umask(0o077)
        assert stat.S_IMODE(atomic_write_text(tmp_path / "private.txt", "x").stat().st_mode) == 0o600
    finally:
        os.umask(old)
