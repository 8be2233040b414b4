"""The metric catalogue (hoibench/metrics/catalog.py) is the one source of metric metadata:
no other module defines it, and a metric added as one catalogue entry plus its own module
reaches results, per-clip tables, pages, CSV and compare with no other change."""
from __future__ import annotations

import ast
import json
import sys
from pathlib import Path

import numpy as np
import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "hoibench"
#: tuples of metric names that are a track's configuration (which columns a page shows,
#: which metrics it plots), not metadata of the metrics themselves
TRACK_CONFIG_NAMES = ("_COLUMNS", "columns", "_HEADLINE", "headline")
#: class attributes that would repeat the catalogue's metadata on a metric class
METADATA_ATTRIBUTES = {"higher_is_better", "units", "paper_column", "direction"}


def _names() -> set[str]:
    from hoibench.metrics.catalog import METRICS
    return {n for n, i in METRICS.items() if i.kind in ("embedding", "physical", "multibody")}


def _metadata_sites(tree: ast.AST, names: set[str], metrics_module: bool = True) -> list[str]:
    """Dict literals keyed by three or more metric names with constant values (a table, not
    computed values), tuples or lists of three or more metric names (outside ``__all__`` and
    track configuration) and metadata class attributes."""
    found = []
    targets = {}
    for node in ast.walk(tree):
        if isinstance(node, (ast.Assign, ast.AnnAssign)):
            tgt = node.targets[0] if isinstance(node, ast.Assign) else node.target
            if isinstance(tgt, ast.Name) and node.value is not None:
                targets[id(node.value)] = tgt.id
        if isinstance(node, ast.keyword) and node.arg:
            targets[id(node.value)] = node.arg
        if isinstance(node, ast.ClassDef) and metrics_module:
            for stmt in node.body:
                tgt = stmt.targets[0] if isinstance(stmt, ast.Assign) else getattr(stmt, "target", None)
                if isinstance(tgt, ast.Name) and tgt.id in METADATA_ATTRIBUTES:
                    found.append(f"line {stmt.lineno}: class {node.name} sets {tgt.id}")
    for node in ast.walk(tree):
        keys = []
        if isinstance(node, ast.Dict):
            if not all(isinstance(v, (ast.Constant, ast.Tuple)) for v in node.values):
                continue                      # computed values, not a metadata table
            keys = [k.value for k in node.keys if isinstance(k, ast.Constant) and isinstance(k.value, str)]
        elif isinstance(node, (ast.Tuple, ast.List)):
            if targets.get(id(node)) == "__all__" or any(targets.get(id(node), "").endswith(s)
                                                        for s in TRACK_CONFIG_NAMES):
                continue
            keys = [e.value for e in node.elts if isinstance(e, ast.Constant) and isinstance(e.value, str)]
        if len([k for k in keys if k in names]) >= 3:
            found.append(f"line {node.lineno}: {type(node).__name__.lower()} of metric names {sorted(set(keys) & names)[:4]}")
    return found


def test_no_module_but_the_catalogue_defines_metric_metadata():
    names = _names()
    offenders = []
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.name == "catalog.py" and path.parent.name == "metrics":
            continue
        sites = _metadata_sites(ast.parse(path.read_text()), names, path.parent.name == "metrics")
        offenders += [f"{path.relative_to(PACKAGE.parent)} {s}" for s in sites]
    assert not offenders, "metric metadata outside hoibench/metrics/catalog.py:\n" + "\n".join(offenders)


def test_the_checker_finds_a_planted_metadata_table():
    planted = ast.parse('SHORTS = {"fid": "FID", "cd": "CD", "ps": "PS"}\n'
                        'class X:\n    higher_is_better = True\n'
                        'ORDER = ("fid", "cd", "fsr")\nHOI_COLUMNS = ("fid", "cd", "fsr")\n')
    sites = _metadata_sites(planted, _names())
    assert len(sites) == 3 and any("class X sets higher_is_better" in s for s in sites)


def test_every_entry_is_complete_and_directions_agree_with_the_metric_classes():
    from hoibench.metrics.catalog import ARROWS, METRICS
    for name, info in METRICS.items():
        assert info.unit and info.summary and info.direction in ARROWS, name
        if info.per_clip and info.kind != "clip":
            assert info.kind in ("physical", "task") or name == "mm_dist", name
    assert METRICS["csr"].higher_is_better is None and METRICS["od"].direction == "gt"   # closest to GT
    assert METRICS["fid"].set_level and not METRICS["cd"].set_level


def test_every_checked_in_entry_upgrades_with_its_numbers_unchanged():
    from hoibench.publish.leaderboard import ENTRY_FORMAT, read_entry
    root = PACKAGE.parent / "leaderboards"
    paths = sorted(root.glob("*/entries/*.json"))
    assert len(paths) > 50
    for path in paths:
        raw = json.loads(path.read_text())
        e = read_entry(path)
        assert e["format"] == ENTRY_FORMAT, path
        for k, m in raw["metrics"].items():
            got = e["metrics"][k]
            assert (got["mean"], got["ci95"], got.get("n")) == (m["mean"], m["ci95"], m.get("n")), (path, k)
            assert got["interval"] in ("replications", "samples", "none"), (path, k)
        multibody = raw["track"] == "multibody-synthetic"
        over = {m["interval"] for m in e["metrics"].values()} - {"none"}
        assert over <= ({"samples"} if multibody else {"replications"}), (path, over)


def test_old_results_of_both_kinds_read_into_one_format(tmp_path):
    from hoibench.scoring.results import RESULT_FORMAT, read_result
    hoi = {"protocol": "p", "metrics": {"fid": {"mean": 0.2, "ci95": 0.01, "n": 20, "std": 0.005}},
           "evaluator_id": "e" * 64, "counts": {"scored_ids": 3, "test_ids": 3, "samples_per_prompt": 1}}
    mb = {"kind": "multibody", "metrics": {"csiou": 0.8, "fid": 3.0, "sd": None}, "ci95": {"csiou": 0.05},
          "recognizer_id": "r" * 12, "counts": {"clips": 5, "samples": 5},
          "protocol_settings": {"samples_per_prompt": 1}}
    for name, res in (("hoi", hoi), ("mb", mb)):
        (tmp_path / f"{name}.json").write_text(json.dumps(res))
    a, b = read_result(tmp_path / "hoi.json"), read_result(tmp_path / "mb.json")
    for r in (a, b):
        assert r["format"] == RESULT_FORMAT and set(r["metrics"]["fid"]) >= {"mean", "ci95", "n", "unit", "direction"}
    assert a["metrics"]["fid"]["interval"] == "replications" and a["metrics"]["fid"]["std"] == 0.005
    assert b["evaluator_id"] == "r" * 12 and b["evaluator_backend"] == "recognizer" and "ci95" not in b
    assert b["metrics"]["csiou"] == {"mean": 0.8, "ci95": 0.05, "n": 5, "unit": "fraction", "direction": "higher",
                                     "interval": "samples"}
    assert b["metrics"]["fid"]["ci95"] is None and b["metrics"]["fid"]["interval"] == "none" and "sd" not in b["metrics"]
    assert b["counts"]["scored_ids"] == 5 and b["counts"]["samples_per_prompt"] == 1


# ------------------------------------------------------------------ a metric added as a plug-in
TOY = '''
import numpy as np

def root_height(inp, settings):
    """Mean pelvis height of the clip (m) times the protocol's scale."""
    return float(np.mean(np.asarray(inp.joints)[:, 0, 1])) * float(settings.get("scale", 1.0))
'''


@pytest.fixture
def toy_metric(tmp_path, monkeypatch):
    from hoibench.metrics import catalog
    (tmp_path / "toy_metric_mod.py").write_text(TOY)
    monkeypatch.syspath_prepend(str(tmp_path))
    info = catalog.MetricInfo("root_height_m", "physical", "gt", "m", "extras", "mean pelvis height",
                              clip_fn="toy_metric_mod:root_height", per_clip=True, failure_end="high",
                              settings_key="toy")
    monkeypatch.setitem(catalog.METRICS, info.name, info)
    yield info
    sys.modules.pop("toy_metric_mod", None)


def test_a_metric_added_in_one_module_and_one_entry_reaches_results_tables_pages_and_compare(
        toy_metric, annotated_store_with_evaluator, tmp_path):
    from hoibench.datasets.store import Store
    from hoibench.publish.leaderboard import entry_from_result
    from hoibench.publish.pages import markdown, write_csv
    from hoibench.scoring.compare import compare
    from hoibench.scoring.evaluate import evaluate
    from hoibench.scoring.submission_write import from_store
    from hoibench.tracks.protocol import get_protocol
    _, data, ev = annotated_store_with_evaluator
    src = Path(get_protocol("synthetic-clean").source).read_text().splitlines()
    lines = [ln.replace("jitter_mps3]", "jitter_mps3, root_height_m]") if ln.startswith("metrics:") else ln
             for ln in src if not ln.startswith("track:")]
    proto = tmp_path / "toy.yaml"
    proto.write_text("\n".join(lines) + "\ntoy:\n  scale: 2.0\n")
    sub = from_store(data, tmp_path / "gt")
    res = evaluate(sub, data, ev, protocol=str(proto))
    store = Store(data)
    want = {cid: 2.0 * float(np.mean(store.load(cid, keys=("joints",))["joints"][:, 0, 1]))
            for cid in store.clip_ids("test")}
    rows = {r["id"]: r for r in res["per_clip"]["rows"]}
    for cid, v in want.items():
        assert rows[cid]["root_height_m"] == pytest.approx(v, abs=2e-3), cid
    m = res["metrics"]["root_height_m"]
    assert m["mean"] == pytest.approx(np.mean(list(want.values())), abs=2e-3)
    assert m["unit"] == "m" and m["direction"] == "gt"
    (tmp_path / "a.json").write_text(json.dumps(res))
    (tmp_path / "b.json").write_text(json.dumps(res))
    assert any(line.strip().startswith("root_height_m") for line in compare([tmp_path / "a.json", tmp_path / "b.json"]).splitlines())
    e = entry_from_result(res, method="GT", track="toy")
    e.update(role="ground-truth", _file="gt.json")
    assert "root_height_m" in write_csv([e]).splitlines()[0]
    assert "GT" in markdown("toy", [e])


def test_a_metric_whose_optional_module_is_missing_is_not_computed_never_zero(monkeypatch):
    from hoibench.metrics import catalog
    info = catalog.MetricInfo("needs_engine", "physical", "lower", "m", "extras", "x", clip_fn="x:y",
                              requires="hoibench_no_such_engine", install_hint="install hoibench[engine]")
    monkeypatch.setitem(catalog.METRICS, info.name, info)
    assert catalog.unavailable("needs_engine") == "not computed: install hoibench[engine]"
    assert catalog.unavailable("fid") is None
