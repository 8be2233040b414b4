"""The CLI answers bad input with one line and an exit status, never a traceback.

Each case runs ``hoibench.cli.main`` in-process (an exception escaping it would fail the
test) and checks the one stderr line: it starts with ``hoibench <command>:`` and names what
was wrong."""
from __future__ import annotations

import json
import os

import numpy as np
import pytest

from hoibench.cli import main


def _run(capsys, *argv):
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err.strip().splitlines()
    return code, err


@pytest.fixture
def files(tmp_path):
    fifo = tmp_path / "fifo.npy"
    os.mkfifo(fifo)
    pickled = tmp_path / "pickled.npy"
    np.save(pickled, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    nested = tmp_path / "store"
    nested.mkdir()
    (nested / "manifest.json").write_text("[" * 50_000 + "]" * 50_000)
    badmanifest = tmp_path / "store2"
    badmanifest.mkdir()
    (badmanifest / "manifest.json").write_text(json.dumps({"clips": [{"id": "../x", "split": "test"}],
                                                           "config": {"fps": 20, "mode": "clean"}}))
    return {"fifo": fifo, "pickled": pickled, "nested": nested, "badmanifest": badmanifest, "tmp": tmp_path}


CASES = [
    (("represent", "{fifo}", "--out", "{tmp}/o.npy"), "FIFO"),
    (("represent", "{pickled}", "--out", "{tmp}/o.npy"), "pickled"),
    (("represent", "{tmp}/nothing.npy", "--out", "{tmp}/o.npy"), "nothing.npy"),
    (("synth", "--out", "{tmp}/s", "--clips", "-3"), "n_clips"),
    (("synth", "--out", "{tmp}/s", "--defect", "3:warp=1"), "defect"),
    (("prepare", "behave", "--root", "{tmp}/none", "--body-models", "{tmp}", "--out", "{tmp}/p"), "--root"),
    (("prepare", "omomo", "--root", "{tmp}/none", "--body-models", "{tmp}", "--out", "{tmp}/p"), "--root"),
    (("prepare", "behave", "--root", "{tmp}/none", "--body-models", "{tmp}", "--out", "{tmp}/p", "--fps", "nan"),
     "fps"),
    (("annotate", "{nested}"), "nested too deeply"),
    (("annotate", "{tmp}/none"), "not a hoibench store"),
    (("export", "{badmanifest}", "{tmp}/ex"), "not a valid id"),
    (("render", "../../etc/passwd", "--data", "{badmanifest}", "--out", "{tmp}/a.png"), "not a valid id"),
    (("splits", "show", "nope"), "nope"),
    (("protocols", "show", "nope"), "unknown protocol"),
    (("validate", "{tmp}", "--data", "{nested}"), "nested too deeply"),
    (("validate", "{tmp}/sub", "--data", "{nested}"), "does not exist"),
    (("evaluate", "{tmp}/sub", "--data", "{tmp}/none", "--evaluator", "{tmp}"), "not a hoibench store"),
    (("evaluator", "show", "{tmp}"), "card.json"),
    (("train-evaluator", "{tmp}/none", "--out", "{tmp}/ev"), "not a hoibench store"),
    (("submission", "from-store", "{tmp}/none", "--out", "{tmp}/gt"), "not a hoibench store"),
]


@pytest.mark.parametrize("argv, needle", CASES, ids=[" ".join(c[0][:2]) + f"-{i}" for i, c in enumerate(CASES)])
def test_bad_input_is_one_line_with_exit_status_2(capsys, files, argv, needle):
    argv = [a.format(**files) for a in argv]
    code, err = _run(capsys, *argv)
    assert code == 2, (code, err)
    assert len(err) == 1 and err[0].startswith(f"hoibench {argv[0]}"), err
    assert needle.lower() in err[0].lower(), err
    assert "Traceback" not in err[0]


def test_an_unexpected_defect_is_one_line_too(capsys, monkeypatch):
    import hoibench.cli as cli

    def boom(args):
        raise ZeroDivisionError("a defect")
    monkeypatch.setattr(cli, "_cmd_version", boom)
    code, err = _run(capsys, "version")
    assert code == 3 and len(err) == 1 and "internal error: ZeroDivisionError" in err[0]
    assert "HOIBENCH_DEBUG=1" in err[0]
    monkeypatch.setenv("HOIBENCH_DEBUG", "1")
    with pytest.raises(ZeroDivisionError):
        main(["version"])
