"""hoibench.commands: help lists come from the registries, prepare and synth run what the
registries state (no dataset-name branches), every registered loader meets the DatasetLoader
contract, and the challenge's phase dates."""
from __future__ import annotations

import argparse
import io
import re
import sys
import types
import zipfile
from datetime import date, timedelta

import pytest
import yaml

from hoibench.cli import build_parser, main


def _sub(parser: argparse.ArgumentParser, *names: str) -> argparse.ArgumentParser:
    for name in names:
        action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        parser = action.choices[name]
    return parser


def _action(parser: argparse.ArgumentParser, dest: str) -> argparse.Action:
    return next(a for a in parser._actions if a.dest == dest)


def _run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out.strip().splitlines(), out.err.strip().splitlines()


# --- help lists -----------------------------------------------------------------------------

def test_every_baseline_is_in_the_baseline_help_and_choices():
    from hoibench.baselines.registry import SPECS
    top = " ".join(build_parser().format_help().split())
    listed = re.search(r"train and sample reference baselines \(([^)]*)\)", top).group(1).split(", ")
    assert set(SPECS) <= set(listed) and "mean-pose" in listed
    sample = _sub(build_parser(), "baseline", "sample")
    assert set(_action(sample, "name").choices) == set(SPECS) | {"mean-pose"}
    assert set(_action(_sub(build_parser(), "baseline", "train"), "name").choices) == set(SPECS)
    run_help = " ".join(_action(sample, "run").help.split())
    assert all(name in run_help for name in SPECS)


def test_tracks_protocols_backends_formats_and_layouts_come_from_their_registries():
    from hoibench.datasets.synth_registry import SYNTH_LAYOUTS, layout_names
    from hoibench.evaluator.backends import list_backends
    from hoibench.scoring.importers import FORMATS
    from hoibench.tracks.protocol import list_protocols
    from hoibench.tracks.registry import list_tracks
    # the help strings themselves: argparse's wrapping may break a name at its hyphen
    tracks = _action(_sub(build_parser(), "tracks"), "name").help
    assert all(t.name in tracks.split("(")[1].rstrip(")").split(", ") for t in list_tracks())
    protocols = _action(_sub(build_parser(), "protocols"), "name").help
    assert protocols.split("(")[1].rstrip(")").split(", ") == sorted({p.id for p in list_protocols()})
    evaluator = _action(_sub(build_parser(), "evaluator"), "dir").help
    importable = [b.name for b in list_backends() if b.importer]
    assert importable and all(f"{n}," in evaluator or f"{n};" in evaluator for n in importable)
    assert list(_action(_sub(build_parser(), "import"), "format").choices) == list(FORMATS)
    assert "{" + ",".join(FORMATS) + "}" in _sub(build_parser(), "import").format_usage()
    synth = _sub(build_parser(), "synth")
    assert list(_action(synth, "layout").choices) == layout_names()
    layout_help = " ".join(_action(synth, "layout").help.split())
    for name in layout_names():
        if SYNTH_LAYOUTS.get(name).help:
            assert name in layout_help and SYNTH_LAYOUTS.get(name).help in layout_help


def test_the_prepare_choices_options_and_datasets_ls_follow_the_loader_registry(capsys):
    from hoibench.datasets.catalog import get_loader, loader_names
    prepare = _sub(build_parser(), "prepare")
    assert list(_action(prepare, "dataset").choices) == loader_names()
    for option in ("sources", "split"):
        readers = [n for n in loader_names() if option in get_loader(n).options]
        assert readers and _action(prepare, option).help.startswith(", ".join(readers) + ": ")
    no_models = [n for n in loader_names() if not get_loader(n).needs_body_models]
    assert f"not needed for {', '.join(no_models)}" in " ".join(_action(prepare, "body_models").help.split())
    code, out, _ = _run(capsys, "datasets", "ls")
    assert code == 0 and [ln for ln in out if not ln.startswith(" ")][:-1] == loader_names()


def test_building_the_parser_does_not_import_the_importers():
    import subprocess
    code = ("import sys; from hoibench.cli import build_parser; build_parser(); "
            "print('hoibench.scoring.importers' in sys.modules, 'numpy' in sys.modules)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.stdout.split() == ["False", "False"], r.stderr


# --- loaders: the contract and prepare's use of the registry --------------------------------

def test_every_registered_loader_meets_the_dataset_loader_contract():
    from hoibench.datasets.catalog import get_loader, loader_names
    from hoibench.datasets.loader_protocol import DatasetLoader, loader_problems
    assert len(loader_names()) >= 9
    for name in loader_names():
        loader = get_loader(name)
        assert isinstance(loader.load(), DatasetLoader), name
        assert loader_problems(loader) == [], name


def test_the_contract_check_sees_a_broken_loader(monkeypatch):
    from hoibench.datasets.catalog import Loader
    from hoibench.datasets.loader_protocol import DatasetLoader, loader_problems
    bad = types.ModuleType("bad_loader")
    assert not isinstance(bad, DatasetLoader)
    monkeypatch.setitem(sys.modules, "bad_loader", bad)
    row = Loader("bad", "-", "-", "-", "-", module="bad_loader")
    assert loader_problems(row) == ["bad (bad_loader): no prepare_jobs function"]
    bad.prepare_jobs = lambda root, models, out, config, split_file=None: []
    bad.name_of = lambda: "x"
    row = Loader("bad", "-", "-", "-", "-", module="bad_loader", options=("sources",),
                 dataset_name="bad_loader:name_of")
    probs = loader_problems(row)
    assert len(probs) == 3, probs
    assert "expected the parameters" in probs[0] and "'sources'" in probs[1] and "dataset_name" in probs[2]


@pytest.fixture
def fake_loaders(monkeypatch):
    """Every registered loader's prepare_jobs replaced by a recorder that stops the run."""
    from hoibench.datasets.catalog import get_loader, loader_names
    calls = []

    class Stop(Exception):
        pass

    def recorder(name):
        def prepare_jobs(root, body_models, out, config, split_file=None, **options):
            calls.append((name, config, body_models, options))
            raise Stop(name)
        return prepare_jobs
    for name in loader_names():
        monkeypatch.setattr(get_loader(name).load(), "prepare_jobs", recorder(name))
    monkeypatch.setenv("HOIBENCH_DEBUG", "1")      # let Stop through
    return calls, Stop


def test_prepare_finds_every_registered_loader_and_runs_it_as_its_row_says(fake_loaders, tmp_path):
    from hoibench.datasets.catalog import get_loader, loader_names
    calls, stop = fake_loaders
    for name in loader_names():
        row = get_loader(name)
        argv = ["prepare", name, "--root", str(tmp_path), "--out", str(tmp_path / "out"), "--fps", "20"]
        if row.needs_body_models:
            with pytest.raises(ValueError, match="--body-models is required"):
                main(argv)
            argv += ["--body-models", str(tmp_path / "models")]
        with pytest.raises(stop, match=name):
            main(argv)
        got, cfg, models, options = calls[-1]
        assert got == name and cfg.body_model_type == row.body_model_type and options == {}
        assert cfg.dataset == row.name_for(tmp_path)
    behave = loader_names().index("behave")
    assert calls and calls[behave][1].dataset == "behave"
    (tmp_path / "hoibench_synthetic.json").write_text("{}")
    assert get_loader("behave").name_for(tmp_path) == "synthetic"


def test_prepare_passes_a_loaders_own_options_and_refuses_them_elsewhere(fake_loaders, tmp_path, capsys):
    from hoibench.datasets.catalog import get_loader, loader_names
    calls, stop = fake_loaders
    reader = next(n for n in loader_names() if "sources" in get_loader(n).options)
    other = next(n for n in loader_names() if "sources" not in get_loader(n).options)
    base = ["--root", str(tmp_path), "--out", str(tmp_path / "o"), "--body-models", str(tmp_path)]
    with pytest.raises(stop):
        main(["prepare", reader, *base, "--sources", "behave,grab", "--split", "object"])
    assert calls[-1][3] == {"sources": "behave,grab", "split": "object"}
    with pytest.raises(ValueError, match=rf"--sources is read by `prepare {reader}` only"):
        main(["prepare", other, *base, "--sources", "behave"])


def test_a_newly_registered_loader_is_a_prepare_choice_and_runs(monkeypatch, tmp_path):
    from hoibench.datasets import catalog
    monkeypatch.setattr(catalog.LOADER_REGISTRY, "_entries", dict(catalog.LOADER_REGISTRY._entries))
    mod = types.ModuleType("extra_loader")
    seen = []
    mod.prepare_jobs = lambda root, body_models, out, config, split_file=None: seen.append(config) or []
    mod.name = lambda root: "extra-named"
    monkeypatch.setitem(sys.modules, "extra_loader", mod)
    catalog.register_loader(catalog.Loader("extra", "-", "-", "-", "-", module="extra_loader",
                                           needs_body_models=False, dataset_name="extra_loader:name"))
    assert "extra" in _action(_sub(build_parser(), "prepare"), "dataset").choices
    from hoibench.datasets.loader_protocol import loader_problems
    assert loader_problems(catalog.get_loader("extra")) == []
    main(["prepare", "extra", "--root", str(tmp_path), "--out", str(tmp_path / "store")])
    assert [c.dataset for c in seen] == ["extra-named"] and seen[0].body_model_type == "smplx"
    with pytest.raises(ValueError, match="registered twice"):
        catalog.register_loader(catalog.Loader("extra", "-", "-", "-", "-"))


# --- synth layouts --------------------------------------------------------------------------

def test_synth_calls_a_registered_writer_with_what_its_entry_takes(monkeypatch, tmp_path, capsys):
    from hoibench.datasets import synth_registry as reg
    monkeypatch.setattr(reg.SYNTH_LAYOUTS, "_entries", dict(reg.SYNTH_LAYOUTS._entries))
    mod = types.ModuleType("extra_writer")
    got = []
    mod.write = lambda out, n, seed=0, **kw: got.append((n, seed, kw))
    monkeypatch.setitem(sys.modules, "extra_writer", mod)
    reg.register_layout(reg.SynthLayout("plain", "extra_writer:write", "plain clips", "in a plain layout",
                                        writes_body_models=False))
    reg.register_layout(reg.SynthLayout("full", "extra_writer:write", "full clips", "in a full layout",
                                        takes_defects=True, takes_executor=True))
    code, out, _ = _run(capsys, "synth", "--layout", "plain", "--out", str(tmp_path), "--clips", "3", "--seed", "4")
    assert code == 0 and got[-1] == (3, 4, {}) and out == [f"wrote 3 synthetic plain clips to {tmp_path} in a plain layout"]
    code, out, _ = _run(capsys, "synth", "--layout", "full", "--out", str(tmp_path), "--clips", "2",
                        "--defect", "1:penetration=0.02", "--executor", "processes:2")
    assert code == 0 and got[-1][2]["executor"] == "processes:2"
    assert [(d.kind, d.magnitude) for d in got[-1][2]["defects"][1]] == [("penetration", 0.02)]
    assert out[0].endswith(f"in a full layout; body models in {tmp_path / 'body_models'}")
    code, _, err = _run(capsys, "synth", "--layout", "plain", "--out", str(tmp_path), "--defect", "1:penetration=1")
    assert code == 2 and err == ["hoibench synth: error: --defect: defects are injected in the behave, full "
                                 "layout only"]


# --- challenge phase dates ------------------------------------------------------------------

def test_phase_dates_default_to_90_days_each_and_split_a_given_range():
    from hoibench.challenge.bundle import PHASE_DAYS, phase_dates
    start = date(2027, 3, 1)
    two = phase_dates(2, start)
    assert two == [(start, start + timedelta(days=PHASE_DAYS - 1)),
                   (start + timedelta(days=PHASE_DAYS), start + timedelta(days=2 * PHASE_DAYS - 1))]
    three = phase_dates(3, start, date(2027, 3, 10))          # 10 days: 3 + 3 + 4
    assert three == [(date(2027, 3, 1), date(2027, 3, 3)), (date(2027, 3, 4), date(2027, 3, 6)),
                     (date(2027, 3, 7), date(2027, 3, 10))]
    with pytest.raises(ValueError, match="--end 2027-02-01: before --start 2027-03-01"):
        phase_dates(2, start, date(2027, 2, 1))
    with pytest.raises(ValueError, match="2 phases need at least 2 days"):
        phase_dates(2, start, start)


@pytest.mark.parametrize("option, value", [("--start", "2027-13-01"), ("--end", "next week"),
                                           ("--end", "2020-01-01")])
def test_bad_phase_dates_are_one_line_naming_the_option(capsys, tmp_path, option, value):
    code, _, err = _run(capsys, "challenge", "bundle", "--data", str(tmp_path), "--evaluator", str(tmp_path),
                        "--out", str(tmp_path / "b.zip"), "--start", "2026-06-01", option, value)
    assert code == 2 and len(err) == 1 and err[0].startswith("hoibench challenge: error: "), err
    assert option in err[0] and value in err[0]
    assert not (tmp_path / "b.zip").exists()


def _bundle(path, phases: list[dict]):
    """A bundle with every file and key Codabench's unpacker needs and ``phases``."""
    prog = io.BytesIO()
    with zipfile.ZipFile(prog, "w") as z:
        z.writestr("metadata.yaml", "command: python3 score.py\n")
    comp = {"version": 2, "title": "t", "terms": "terms.md", "pages": [],
            "tasks": [{"index": 0, "name": "t", "scoring_program": "scoring_program.zip",
                       "reference_data": "reference_data.zip"}],
            "phases": phases, "leaderboards": []}
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("competition.yaml", yaml.safe_dump(comp))
        for name in ("terms.md", "logo.png", "reference_data.zip"):
            z.writestr(name, "x")
        z.writestr("scoring_program.zip", prog.getvalue())
    return path


def test_challenge_check_warns_of_phases_that_ended_or_never_start(capsys, tmp_path):
    from hoibench.challenge.bundle import inspect_bundle, phase_warnings
    today = date.today()
    past, soon, later = today - timedelta(days=10), today + timedelta(days=5), today + timedelta(days=50)
    phases = [{"index": 0, "name": "old", "tasks": [0], "start": (past - timedelta(days=30)).isoformat(),
               "end": past.isoformat()},
              {"index": 1, "name": "backwards", "tasks": [0], "start": later.isoformat(), "end": soon.isoformat()},
              {"index": 2, "name": "nostart", "tasks": [0]},
              {"index": 3, "name": "fine", "tasks": [0], "start": soon.isoformat(), "end": later.isoformat()}]
    bundle = _bundle(tmp_path / "b.zip", phases)
    probs, warns = inspect_bundle(bundle)
    assert probs == [] and len(warns) == 3
    assert [w.split(":")[0] for w in warns] == ["phase old", "phase backwards", "phase nostart"]
    assert f"ended on {past.isoformat()}" in warns[0] and "never starts" in warns[1] and "never starts" in warns[2]
    assert phase_warnings(phases, past - timedelta(days=40))[0].startswith("phase backwards")
    code, out, _ = _run(capsys, "challenge", "check", str(bundle))
    assert code == 0 and out[-1] == f"{bundle}: OK"
    assert [ln for ln in out if ": warning: " in ln] == [f"{bundle}: warning: {w}" for w in warns]
    good = _bundle(tmp_path / "g.zip", phases[3:])
    code, out, _ = _run(capsys, "challenge", "check", str(good))
    assert code == 0 and out == [f"{good}: OK"]


def test_a_phase_date_that_is_not_iso_is_a_problem(capsys, tmp_path):
    bundle = _bundle(tmp_path / "b.zip", [{"index": 0, "name": "dev", "tasks": [0], "start": "soon",
                                           "end": "2030-01-01"}])
    code, out, _ = _run(capsys, "challenge", "check", str(bundle))
    assert code == 1 and out == [f"{bundle}: phase dev: start 'soon' is not an ISO date (YYYY-MM-DD)",
                                 f"{bundle}: 1 problem(s)"]


def test_the_bundles_phases_start_today_by_default():
    from hoibench.challenge.bundle import PHASE_DAYS, competition_yaml
    today = date.today()
    comp = competition_yaml("t", "synthetic", ["dev", "test"], "img", today)
    assert [(p["start"], p["end"]) for p in comp["phases"]] == [
        (today.isoformat(), (today + timedelta(days=PHASE_DAYS - 1)).isoformat()),
        ((today + timedelta(days=PHASE_DAYS)).isoformat(), (today + timedelta(days=2 * PHASE_DAYS - 1)).isoformat())]
