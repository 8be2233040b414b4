"""hoibench evaluate end to end: GT submission, partial submission, executors."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

pytest.importorskip("transformers")
pytest.importorskip("open3d")


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    from hoibench.annotate import annotate_store
    from hoibench.datasets.synthetic_store import build_synthetic_store
    from hoibench.evaluator import main_train_evaluator
    from hoibench.submission import from_store

    base = tmp_path_factory.mktemp("evaluate")
    _, data, _ = build_synthetic_store(base, 44, seed=0)
    annotate_store(data)
    assert main_train_evaluator(data, base / "ev", size="tiny", seed=0) == 0
    from_store(data, base / "gt")
    return base, data


def test_ground_truth_submission_scores_fid_zero_and_is_complete(setup, tmp_path):
    from hoibench.evaluate import evaluate
    base, data = setup
    res = evaluate(base / "gt", data, base / "ev")
    assert res["complete"] and res["protocol"] == "synthetic-clean"
    assert abs(res["metrics"]["fid"]["mean"]) < 1e-4
    assert res["metrics"]["r_precision_top3"]["mean"] >= res["metrics"]["r_precision_top1"]["mean"] > 0
    assert len(res["per_replication"]) == 20 and res["evaluator_id"]
    for key in ("protocol_version", "protocol_sha256", "representation", "toolkit_version", "counts", "timings_s"):
        assert key in res
    # the evaluator card's GT scores were computed with the same protocol draw: equal
    card = json.loads((base / "ev" / "card.json").read_text())["gt_retrieval"]
    assert card["protocol"] == "synthetic-clean@1.1"
    for k in (1, 2, 3):
        assert res["metrics"][f"r_precision_top{k}"]["mean"] == pytest.approx(card[f"top{k}"]["mean"], abs=1e-12)
    assert res["metrics"]["mm_dist"]["mean"] == pytest.approx(card["mm_dist"]["mean"], rel=1e-6)


def test_partial_submission_is_scored_on_valid_ids_and_marked_incomplete(setup, tmp_path):
    from hoibench.evaluate import evaluate
    base, data = setup
    sub = tmp_path / "partial"
    shutil.copytree(base / "gt", sub)
    victims = sorted((sub / "samples").glob("*.npz"))[:2]
    victims[0].unlink()                                  # missing id
    z = dict(np.load(victims[1]))
    z["joints"] = z["joints"] * 100.0                    # centimetres
    np.savez(victims[1], **z)
    res = evaluate(sub, data, base / "ev")
    assert not res["complete"]
    assert {victims[0].stem, victims[1].stem} <= set(res["counts"]["missing_ids"])
    assert res["counts"]["scored_ids"] == res["counts"]["test_ids"] - 2


def test_executors_give_identical_results(setup):
    from hoibench.evaluate import evaluate
    base, data = setup
    a = evaluate(base / "gt", data, base / "ev", executor="serial")
    b = evaluate(base / "gt", data, base / "ev", executor="processes:2")
    assert json.dumps(a["metrics"], sort_keys=True) == json.dumps(b["metrics"], sort_keys=True)
