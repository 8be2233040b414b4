"""A new user's first run: each problem a fresh clone met, as one test per item (and family).

Every test here is cheap: stores are hand-written manifests (with a clip file where a command
opens one), slow work is replaced by a stand-in that fails if it is reached, so what is
checked is the order of the checks and the words of the answer, not timings."""
from __future__ import annotations

import argparse
import configparser
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hoibench.cli import build_parser, main

ROOT = Path(__file__).resolve().parent.parent
EV = "a" * 64


def _run(capsys, *argv) -> tuple[int, list[str], list[str]]:
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:            # argparse's own exits (usage errors)
        code = exc.code
    cap = capsys.readouterr()
    return code, cap.out.strip().splitlines(), cap.err.strip().splitlines()


def _store(root: Path, test_ids=("t0", "t1", "t2", "t3"), train_ids=("r0",), dataset="synthetic", frames=40,
           clip_files=False) -> Path:
    """A hand-written store: a manifest (human-only clips at 20 fps), optionally with clip files."""
    clips = [{"id": c, "split": "test", "frames": frames} for c in test_ids] + \
        [{"id": c, "split": "train", "frames": frames} for c in train_ids]
    root.mkdir(parents=True, exist_ok=True)
    (root / "manifest.json").write_text(json.dumps({"dataset": dataset, "clips": clips,
                                                    "config": {"fps": 20, "mode": "clean"}}))
    if clip_files:
        from hoibench.core.io import atomic_save_npz
        for c in clips:
            atomic_save_npz(root / "clips" / f"{c['id']}.npz", joints=np.zeros((frames, 22, 3), np.float32))
    return root


def _walking_joints(frames: int = 40) -> np.ndarray:
    """(frames, 22, 3) y-up joints of the proxy body leaning forward and stepping sideways,
    feet on the floor (along no horizontal axis are the feet the lowest joints)."""
    from hoibench.bodies import ProxyBody
    t = np.arange(frames) / 20.0
    poses = np.zeros((frames, 22, 3))
    poses[:, 3, 0] = 0.6                                  # the spine bends forward
    poses[:, 16, 2] = poses[:, 17, 2] = 1.2
    trans = np.stack([0.3 * t, np.full(frames, 0.95), 0.0 * t], 1)
    joints = ProxyBody().forward(poses, trans)[1][:, :22]
    joints[..., 1] -= joints[..., 1].min()
    return joints.astype(np.float32)


def _submission(out: Path, ids, joints: np.ndarray | None = None) -> Path:
    from hoibench.scoring.submission import write_submission
    joints = _walking_joints() if joints is None else joints
    meta = {"method": "Mine", "version": "1", "representation": "joints", "fps": 20,
            "flags": {"samples_per_prompt": 1}}
    return write_submission(out, meta, {i: {"joints": joints[None]} for i in ids})


def _result(fid: float = 0.2, ev: str = EV, method: str = "Mine", k: int = 1) -> dict:
    return {"metrics": {"fid": {"mean": fid, "ci95": 0.01, "n": 20},
                        "r_precision_top1": {"mean": 0.5, "ci95": 0.02, "n": 20}},
            "evaluator_id": ev, "protocol": "synthetic-clean", "protocol_version": "1.1", "complete": True,
            "overrides": [], "counts": {"samples_per_prompt": k, "scored_ids": 4, "test_ids": 4, "missing_ids": []},
            "submission": {"method": method, "flags": {}}, "notes": []}


@pytest.fixture
def no_store(monkeypatch):
    """Reading a store (or loading an evaluator) fails the test: the arguments must be refused first."""
    import hoibench.evaluator.backends as backends
    import hoibench.scoring.evaluate as ev_mod

    def forbidden(*a, **k):
        raise AssertionError("reached the store/evaluator before checking the arguments")
    monkeypatch.setattr(ev_mod, "Store", forbidden)
    monkeypatch.setattr(backends, "load_evaluator", forbidden)


@pytest.fixture
def scored(monkeypatch):
    """``evaluate`` replaced by a stand-in that returns a canned result (the CLI around it is tested)."""
    import hoibench.scoring.evaluate as ev_mod
    calls = []

    def fake(*a, **k):
        calls.append((a, k))
        if k.get("lead") is not None:            # the real evaluate leads with the foreign-store line
            from hoibench.datasets.store import Store
            from hoibench.scoring.submission import Submission
            from hoibench.scoring.validate import foreign_ids_line
            with Submission(a[0]) as sub:
                line = foreign_ids_line(a[0], a[1], list(sub.ids), Store(a[1]).clip_ids("test"))
            if line:
                k["lead"](line)
        return {**_result(), "kind": "hoi"}
    monkeypatch.setattr(ev_mod, "evaluate", fake)
    monkeypatch.setattr(ev_mod, "format_result", lambda r: "TABLE")
    return calls


# ---------------------------------------------------------------- 3. evaluate --out
def test_3_evaluate_refuses_an_existing_out_unless_overwrite_and_says_when_nothing_is_written(
        tmp_path, capsys, scored):
    data, ev, sub = _store(tmp_path / "data"), tmp_path / "ev", _submission(tmp_path / "sub", ["t0"])
    ev.mkdir()
    out = tmp_path / "result.json"
    out.write_text("{}")
    base = ["evaluate", sub, "--data", data, "--evaluator", ev]
    code, _, err = _run(capsys, *base, "--out", out)
    assert code == 2 and len(err) == 1 and str(out) in err[0] and "--overwrite" in err[0], err
    assert out.read_text() == "{}" and not scored
    code, lines, _ = _run(capsys, *base, "--out", out, "--overwrite")
    assert code == 0 and lines[-1] == f"wrote {out}" and json.loads(out.read_text())["evaluator_id"] == EV
    code, lines, _ = _run(capsys, *base)
    assert code == 0 and lines[-1] == "not written: pass --out result.json to keep it"


# ---------------------------------------------------------------- 4. leaderboard add
def test_4_leaderboard_add_needs_a_root_and_an_existing_track(tmp_path, capsys, monkeypatch):
    res = tmp_path / "r.json"
    res.write_text(json.dumps(_result()))
    empty = tmp_path / "fresh"
    empty.mkdir()
    monkeypatch.chdir(empty)
    code, _, err = _run(capsys, "leaderboard", "add", res, "--track", "synthetic", "--method", "X")
    assert code == 2 and len(err) == 1 and "no leaderboards/ folder" in err[0] and "--root" in err[0], err
    assert not (empty / "leaderboards").exists()
    root = tmp_path / "boards"
    code, _, err = _run(capsys, "leaderboard", "add", res, "--track", "synthetic", "--method", "X", "--root", root)
    assert code == 2 and len(err) == 1 and "'synthetic'" in err[0] and "--new-track" in err[0], err
    code, out, _ = _run(capsys, "leaderboard", "add", res, "--track", "synthetic", "--method", "X", "--root", root,
                        "--new-track")
    assert code == 0 and (root / "synthetic" / "entries" / "x.json").is_file(), out
    for bad in ("..", "../x", "/abs", "a/b", ".hidden"):
        code, _, err = _run(capsys, "leaderboard", "add", res, "--track", bad, "--method", "Y", "--root", root,
                            "--new-track")
        assert code == 2 and len(err) == 1 and "not a valid id" in err[0], (bad, err)
    code, _, err = _run(capsys, "leaderboard", "build", "--track", "../synthetic", "--root", root)
    assert code == 2 and "not a valid id" in err[0]


def test_4_leaderboard_finds_the_repository_root_from_below_and_says_so(tmp_path, capsys, monkeypatch):
    import hoibench.publish.leaderboard as lb
    res = tmp_path / "r.json"
    res.write_text(json.dumps(_result()))
    repo = tmp_path / "repo"
    lb.add_result(res, repo / "leaderboards" / "synthetic", method="GT", role="ground-truth")
    (repo / "docs" / "deep").mkdir(parents=True)
    (repo / "docs" / "leaderboards").mkdir()          # a folder of that name without tracks is passed over
    monkeypatch.chdir(repo / "docs" / "deep")
    code, out, _ = _run(capsys, "leaderboard", "ls")
    assert code == 0 and out[0].startswith(f"leaderboard root: {(repo / 'leaderboards').resolve()}"), out
    assert out[1].startswith("synthetic") and "GT" in out[1]
    code, out, _ = _run(capsys, "leaderboard", "add", res, "--track", "synthetic", "--method", "Mine")
    assert code == 0 and "leaderboard root:" in out[0] and (repo / "leaderboards/synthetic/entries/mine.json").exists()
    guide = (ROOT / "docs" / "guide.md").read_text()
    assert "`--root`" in guide and "--new-track" in guide


# ---------------------------------------------------------------- 7. compare
def test_7_compare_shows_zero_fid_entry_names_and_k_and_stars_only_on_one_scale(tmp_path):
    import hoibench.publish.leaderboard as lb
    from hoibench.scoring.compare import compare
    gt = tmp_path / "gt.json"
    gt.write_text(json.dumps(_result(fid=-4.408e-07, method="GT")))
    track = tmp_path / "leaderboards" / "synthetic"
    mine = tmp_path / "mine.json"
    mine.write_text(json.dumps(_result(fid=0.5, method=None, k=30)))
    entry = lb.add_result(mine, track, method="My Method (v2)")
    other = tmp_path / "other.json"
    other.write_text(json.dumps(_result(fid=0.9, ev="b" * 64, method="Other")))
    text = compare([gt, entry, other])
    header = text.splitlines()[:3]
    assert header[1].startswith("My Method (v2): ") and "K=30" in header[1] and "K=None" not in text, header
    fid = next(line for line in text.splitlines() if line.strip().startswith("fid"))
    assert "-4.4" not in fid and fid.split()[1] == "0", fid
    assert "0.5 ± 0.01*" in fid                            # on one scale with GT: starred
    assert "0.9 ± 0.01*" not in fid and "0.9 ± 0.01" in fid   # "not on one scale": never starred
    assert "not on one scale" in header[2]


def test_7_leaderboard_duplicate_refusal_quotes_the_existing_name(tmp_path):
    import hoibench.publish.leaderboard as lb
    res = tmp_path / "r.json"
    res.write_text(json.dumps(_result()))
    track = tmp_path / "lb" / "synthetic"
    lb.add_result(res, track, method="ChainHOI (tiny)")
    with pytest.raises(lb.LeaderboardError, match=r"an entry named 'ChainHOI \(tiny\)' exists already "
                                                  r"\(--method 'chainhoi tiny' has the same file name\)"):
        lb.add_result(res, track, method="chainhoi tiny")


# ---------------------------------------------------------------- 11. another store's submission
def test_11_a_submission_for_another_store_leads_with_one_line(tmp_path, capsys, scored):
    data = _store(tmp_path / "data")
    sub = _submission(tmp_path / "sub", [f"other_{i}" for i in range(5)] + ["t0"])
    code, out, _ = _run(capsys, "validate", sub, "--data", data)
    assert code == 1
    assert out[0] == (f"{sub}: these ids belong to no test split of this store (5 of 6, e.g. 'other_0'): "
                      f"is --data {data} the right store?"), out[:2]
    assert sum("these ids belong" in line for line in out) == 1
    ev = tmp_path / "ev"
    ev.mkdir()
    code, out, _ = _run(capsys, "evaluate", sub, "--data", data, "--evaluator", ev)
    assert out[0].startswith(f"{sub}: these ids belong to no test split of this store (5 of 6")
    fine = _submission(tmp_path / "fine", ["t0", "t1", "t2", "t3"])
    code, out, _ = _run(capsys, "validate", fine, "--data", data)
    assert not any("these ids belong" in line for line in out), out


def test_11_a_z_up_refusal_names_the_import_that_converts(tmp_path, capsys):
    data = _store(tmp_path / "data")
    swap = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], np.float32)      # y-up -> z-up
    sub = _submission(tmp_path / "sub", ["t0", "t1", "t2", "t3"], joints=_walking_joints() @ swap.T)
    code, out, _ = _run(capsys, "validate", sub, "--data", data)
    line = next(line for line in out if "z-up" in line)
    assert code == 1 and "hoibench import joints" in line and "--up z" in line, out


# ---------------------------------------------------------------- 12. render's argument
def test_12_render_says_what_its_argument_was_taken_for(tmp_path, capsys):
    data = _store(tmp_path / "data")
    sub = _submission(tmp_path / "sub", ["t0"])
    out = tmp_path / "a.png"
    for argv, needles in (
            (("render", "nonexistent_id", "--data", data), ("no clip 'nonexistent_id'", "taken for a clip id",
                                                             "expected", "--id")),
            (("render", sub, "--data", data), ("is a submission", "--id")),
            (("render", sub, "--id", "nope", "--data", data), ("no clip 'nope'", "--id", "expected")),
            (("render", data / "clips" / "gone.npz"), ("no clip 'gone'", "expected"))):
        code, _, err = _run(capsys, *argv, "--out", out)
        assert code == 2 and len(err) == 1, (argv, err)
        assert "rerun" not in err[0] and "in the manifest but" not in err[0], err
        assert all(n in err[0] for n in needles), (needles, err)
    assert not out.exists()


def test_12_store_load_names_an_unknown_id_as_such(tmp_path):
    from hoibench.datasets.store import Store
    store = Store(_store(tmp_path / "data"))
    with pytest.raises(FileNotFoundError, match="no clip 'zz'"):
        store.load("zz")
    with pytest.raises(FileNotFoundError, match="is in the manifest but its file is not"):
        store.load("t0")


# ---------------------------------------------------------------- 15. arguments before work
def test_15_evaluate_checks_every_argument_before_reading_the_store(tmp_path, capsys, no_store):
    from hoibench.scoring.evaluate import main_evaluate
    data, ev, sub = _store(tmp_path / "data"), tmp_path / "ev", _submission(tmp_path / "sub", ["t0"])
    ev.mkdir()
    taken = tmp_path / "taken.json"
    taken.write_text("{}")
    base = ["evaluate", sub, "--data", data, "--evaluator", ev]
    for extra, needle in ((["--executor", "2"], "processes:2"), (["--executor", "dask://"], "dask"),
                          (["--out", taken], "--overwrite"), (["--out", tmp_path], "is a folder"),
                          (["--protocol", "nope"], "nope")):
        code, _, err = _run(capsys, *base, *extra)
        assert code == 2 and len(err) == 1 and needle in err[0], (extra, err)
    for argv, needle in ((["evaluate", tmp_path / "none", "--data", data, "--evaluator", ev], "does not exist"),
                         (["evaluate", sub, "--data", tmp_path / "none", "--evaluator", ev], "not a hoibench store"),
                         (["evaluate", sub, "--data", data, "--evaluator", tmp_path / "none"], "--evaluator")):
        code, _, err = _run(capsys, *argv)
        assert code == 2 and len(err) == 1 and needle in err[0], (argv, err)
    with pytest.raises(ValueError, match="processes:2"):          # the library entry point checks too
        main_evaluate(sub, data, ev, executor="2")
    for cmd in (["synth", "--out", tmp_path / "s"], ["annotate", data],
                ["prepare", "behave", "--root", tmp_path, "--out", tmp_path / "p"]):
        code, _, err = _run(capsys, *cmd, "--executor", "2")
        assert code == 2 and len(err) == 1 and "processes:2" in err[0], (cmd, err)


def test_15_a_store_evaluator_mismatch_is_refused_before_the_evaluator_loads(tmp_path, capsys, monkeypatch):
    import hoibench.evaluator.backends as backends

    def forbidden(*a, **k):
        raise AssertionError("loaded the evaluator before checking its card against the store")
    monkeypatch.setattr(backends, "load_evaluator", forbidden)
    data = _store(tmp_path / "data", clip_files=True)
    ev = tmp_path / "ev"
    ev.mkdir()
    (ev / "card.json").write_text(json.dumps({"evaluator_id": EV, "dataset": {"name": "behave"}}))
    sub = _submission(tmp_path / "sub", ["t0"])
    code, _, err = _run(capsys, "evaluate", sub, "--data", data, "--evaluator", ev)
    assert code == 2 and len(err) == 1 and "trained on dataset 'behave'" in err[0], err
    assert "--allow-evaluator-mismatch" in err[0]


# ---------------------------------------------------------------- 16. install
def test_16_install_names_libusb_for_root_and_sudo_and_declares_package_data():
    readme = (ROOT / "README.md").read_text()
    setup = readme[readme.index("## Set-up"):readme.index("## Python")]
    assert "libusb-1.0-0" in setup and "open3d" in setup
    make = (ROOT / "Makefile").read_text()
    assert "apt-get install libusb-1.0-0" in make.replace("sudo apt-get", "")
    assert "sudo apt-get install libusb-1.0-0" in make and "as root" in make
    cfg = configparser.ConfigParser()
    cfg.read(ROOT / "setup.cfg")
    assert cfg["options"]["packages"].strip() == "find_namespace:"
    assert "*.yaml" in cfg["options.package_data"]["hoibench.tracks.protocols"]
    assert "tracks/protocols" not in cfg["options.package_data"]["hoibench"]


@pytest.mark.slow
def test_16_setuptools_builds_without_warnings_and_ships_every_folder(tmp_path):
    """The build setuptools runs for ``pip install``: no "absent from the packages
    configuration" warning, and folders without ``__init__.py`` (catmo, protocols) ship."""
    import shutil
    pytest.importorskip("setuptools")
    src = tmp_path / "src"
    shutil.copytree(ROOT / "hoibench", src / "hoibench", ignore=shutil.ignore_patterns("*.pyc"))
    for name in ("setup.cfg", "pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, src / name)
    r = subprocess.run([sys.executable, "-c", "import setuptools; setuptools.setup()", "-q", "build_py",
                        "--build-lib", str(tmp_path / "build")], cwd=src, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "absent from" not in r.stderr and "Deprecat" not in r.stderr, r.stderr[-2000:]
    built = tmp_path / "build" / "hoibench"
    assert (built / "baselines" / "catmo" / "gpt.py").is_file()
    assert sorted(p.name for p in (built / "tracks" / "protocols").glob("*.yaml")) == \
        sorted(p.name for p in (ROOT / "hoibench" / "tracks" / "protocols").glob("*.yaml"))
    assert not list(built.rglob("__pycache__"))


# ---------------------------------------------------------------- 17. --help
def _parsers(parser: argparse.ArgumentParser, prog: str = "hoibench"):
    yield prog, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _parsers(sub, f"{prog} {name}")


def test_17_every_argument_of_every_subcommand_has_help():
    missing = []
    for prog, parser in _parsers(build_parser()):
        for action in parser._actions:
            if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):
                continue
            if not action.help or action.help == argparse.SUPPRESS:
                missing.append(f"{prog} {'/'.join(action.option_strings) or action.dest}")
    assert not missing, missing


def test_17_submission_help_describes_its_actions(capsys):
    with pytest.raises(SystemExit):
        main(["submission", "--help"])
    text = capsys.readouterr().out
    for action in ("from-store", "reference", "prompts"):
        line = next(ln for ln in text.splitlines() if ln.strip().startswith(action + " "))
        assert len(line.split()) > 3, line


def test_17_a_misspelled_command_gets_one_line_and_a_suggestion(capsys):
    code, out, err = _run(capsys, "evalute", "sub")
    assert code == 2 and err == ["hoibench: error: unknown command 'evalute': did you mean 'evaluate'?"], err
    code, _, err = _run(capsys, "leaderboard", "biuld")
    assert code == 2 and len(err) == 1 and "did you mean 'build'?" in err[0]
    code, _, err = _run(capsys, "submission", "form-store", "data")
    assert code == 2 and len(err) == 1 and "did you mean 'from-store'?" in err[0]
    code, _, err = _run(capsys, "xyzzy")
    assert code == 2 and len(err) == 1 and "unknown command 'xyzzy'" in err[0] and "evaluate" in err[0]
    code, _, err = _run(capsys, "evaluate")                    # a missing argument: one line too
    assert code == 2 and len(err) == 1 and "--data" in err[0]
