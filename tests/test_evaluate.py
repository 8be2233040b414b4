"""hoibench evaluate end to end: GT submission, partial submission, executors."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("transformers")
pytest.importorskip("open3d")


@pytest.fixture(scope="module")
def setup(annotated_store_with_evaluator, tmp_path_factory):
    import shutil as sh

    from hoibench.scoring.submission import from_store
    shared, data, ev = annotated_store_with_evaluator
    base = tmp_path_factory.mktemp("evaluate")
    sh.copytree(ev, base / "ev")
    from_store(data, base / "gt")
    return base, data


def test_ground_truth_submission_scores_fid_zero_and_is_complete(setup, tmp_path):
    from hoibench.scoring.evaluate import evaluate
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
    from hoibench.scoring.evaluate import evaluate
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


def test_units_started_during_validation_are_kept_only_when_every_test_id_is_scored(setup, tmp_path, monkeypatch):
    from hoibench.scoring.evaluate import evaluate
    from hoibench.scoring.hoi import HOIScorer
    base, data = setup
    kept, keep = [], HOIScorer._keep_ahead

    def spy(self, ids):
        keep(self, ids)
        kept.append(len(self.st.ahead))
    monkeypatch.setattr(HOIScorer, "_keep_ahead", spy)
    full = evaluate(base / "gt", data, base / "ev", executor="processes:2")
    assert kept == [full["counts"]["scored_ids"]]          # K = 1: one unit per clip, all started ahead
    sub = tmp_path / "partial"                            # one file missing: the group members change
    shutil.copytree(base / "gt", sub)
    sorted((sub / "samples").glob("*.npz"))[0].unlink()
    pooled = evaluate(sub, data, base / "ev", executor="processes:2")
    assert kept[-1] == 0                                  # dropped: the stream scored every unit
    serial = evaluate(sub, data, base / "ev")
    assert json.dumps(pooled["metrics"], sort_keys=True) == json.dumps(serial["metrics"], sort_keys=True)


def test_executors_give_identical_results(setup):
    from hoibench.scoring.evaluate import evaluate
    base, data = setup
    a = evaluate(base / "gt", data, base / "ev", executor="serial", clip_data={})
    b = evaluate(base / "gt", data, base / "ev", executor="processes:2", clip_data={})
    assert json.dumps(a["metrics"], sort_keys=True) == json.dumps(b["metrics"], sort_keys=True)
    # the pool reads every test clip's slice labels ahead (a worker, while the evaluator loads);
    # the serial run reads the scored clips' at the end: the same slices
    assert json.dumps(a["slices"], sort_keys=True) == json.dumps(b["slices"], sort_keys=True)
    from hoibench.datasets.store import Store
    from hoibench.scoring.slices import clip_labels
    ids = sorted(next(iter(a["slices"]["labels"].values())))
    assert a["slices"]["labels"] == clip_labels(Store(data), ids)


def test_a_protocol_listing_no_object_metric_computes_none(setup, tmp_path):
    """The protocol's ``metrics:`` list decides what is computed: without an object metric the
    physical units skip the object's distances (the costly part), and nothing reports them."""
    import re
    from hoibench.metrics.catalog import object_metrics
    from hoibench.scoring.evaluate import evaluate
    import hoibench.tracks
    base, data = setup
    listed = ["r_precision_top1", "fid", "mm_dist", "diversity", "fsr", "jitter_mps3"]
    text = (Path(hoibench.tracks.__file__).parent / "protocols" / "synthetic-clean.yaml").read_text()
    (tmp_path / "embed.yaml").write_text(re.sub(r"(?m)^metrics: .*$", f"metrics: [{', '.join(listed)}]", text))
    a = evaluate(base / "gt", data, base / "ev", protocol=str(tmp_path / "embed.yaml"))
    b = evaluate(base / "gt", data, base / "ev")
    assert set(a["metrics"]) == set(listed) | {"clips", "clips_with_contact"}
    for name in listed:                                  # what is listed is what the full protocol gives
        assert a["metrics"][name]["mean"] == b["metrics"][name]["mean"], name
    assert not set(a["undefined_metrics"]) & set(object_metrics())
    assert not any(n.split(":")[0] in object_metrics() for n in a["notes"])
    rows = a["per_clip"]["rows"]
    assert all(r["cd"] is None and r["ps"] is None for r in rows) and any(r["fsr"] is not None for r in rows)
    assert any(r["ps"] is not None for r in b["per_clip"]["rows"])


# ---------------------------------------------------------------- labels that must not lie
def _store_copy(data, tmp_path, **manifest_changes):
    dst = tmp_path / "data"
    shutil.copytree(data, dst)
    m = json.loads((dst / "manifest.json").read_text())
    for k, v in manifest_changes.items():
        m[k] = v
    (dst / "manifest.json").write_text(json.dumps(m))
    return dst


def test_result_records_the_submission_flags_and_is_strict_json(setup, tmp_path):
    from hoibench.scoring.evaluate import main_evaluate
    base, data = setup
    out = tmp_path / "result.json"
    assert main_evaluate(base / "gt", data, base / "ev", out=out) == 0

    def no_constants(tok):
        raise AssertionError(f"{tok} in the result JSON")
    res = json.loads(out.read_text(), parse_constant=no_constants)
    meta = json.loads((base / "gt" / "submission.json").read_text())
    assert res["submission"]["flags"] == meta["flags"] != {}
    assert res["evaluator_gate"]["passed"] and res["overrides"] == []
    card = json.loads((base / "ev" / "card.json").read_text())["text_encoder"]
    assert res["evaluator_text_encoder"]["weights_sha256"] == card["weights_sha256"] and card["weights_sha256"]
    assert not any("conditioned on the evaluator" in n for n in res["notes"])    # the GT conditions on nothing
    for name, s in res["metrics"].items():
        assert np.all(np.isfinite(s["mean"])), name


@pytest.mark.parametrize("protocol, needle", [("behave-clean", "dataset"), ("synthetic-legacy", "mode")])
def test_a_protocol_for_another_dataset_or_mode_is_refused(setup, protocol, needle):
    from hoibench.scoring.evaluate import EvaluationRefused, evaluate
    base, data = setup
    with pytest.raises(EvaluationRefused, match=needle):
        evaluate(base / "gt", data, base / "ev", protocol=protocol)
    res = evaluate(base / "gt", data, base / "ev", protocol=protocol, allow_protocol_mismatch=True)
    assert res["protocol"] == protocol and not res["complete"] and res["submission_complete"]
    assert [o["override"] for o in res["overrides"]] == ["protocol_mismatch"]
    assert needle in res["overrides"][0]["reasons"][0]


def test_an_evaluator_trained_on_another_dataset_is_refused(setup, tmp_path):
    from hoibench.scoring.evaluate import EvaluationRefused, evaluate
    base, data = setup
    other = _store_copy(data, tmp_path, dataset="synthetic2")
    with pytest.raises(EvaluationRefused, match="allow-evaluator-mismatch"):
        evaluate(base / "gt", other, base / "ev", protocol="synthetic-clean", allow_protocol_mismatch=True)


def test_the_gate_is_measured_on_the_store_not_read_from_the_card(setup, tmp_path):
    """Captions permuted among clips: the evaluator no longer matches them to their motions on
    this store, whatever its card says; refused unless --allow-failed-gate, which marks it."""
    from hoibench.scoring.evaluate import EvaluationRefused, evaluate
    base, data = setup
    shuffled = _store_copy(data, tmp_path)
    texts = sorted((shuffled / "texts").glob("*.txt"))
    contents = [p.read_text() for p in texts]
    rng = np.random.default_rng(0)
    for p, i in zip(texts, rng.permutation(len(texts))):
        p.write_text(contents[i])
    with pytest.raises(EvaluationRefused, match="sanity gate"):
        evaluate(base / "gt", shuffled, base / "ev")
    res = evaluate(base / "gt", shuffled, base / "ev", allow_failed_gate=True)
    assert not res["complete"] and not res["evaluator_gate"]["passed"]
    assert [o["override"] for o in res["overrides"]] == ["failed_gate"]


def test_undefined_metrics_are_named_and_infinite_ones_stop_the_run():
    from hoibench.scoring.hoi import _finite_rows
    rows, undefined = _finite_rows([{"fid": 1.0, "fsr": float("nan")}, {"fid": 2.0, "fsr": float("nan")}])
    assert rows == [{"fid": 1.0}, {"fid": 2.0}] and "fsr" in undefined and "2 of 2" in undefined["fsr"]
    with pytest.raises(ValueError, match="'cd' is infinite in replication 1"):
        _finite_rows([{"cd": 0.1}, {"cd": float("inf")}])


def test_a_legacy_length_crop_scores_each_replication_on_its_own_windows(setup, tmp_path):
    """synthetic-legacy crops the evaluated lengths (ChainHOI's multiples of 4 at a random
    offset): replication r's physical metrics are those of the windows drawn for (clip, r)
    (the shipped protocol runs one replication, as ChainHOI's eval.py; a copy runs two)."""
    from pathlib import Path
    from hoibench.datasets.store import Store
    from hoibench.metrics.legacy_rules import replication_windows
    from hoibench.metrics.physical import clip_inputs, evaluate_physical_windows, load_groups
    from hoibench.scoring.evaluate import evaluate
    from hoibench.scoring.submission import Submission
    from hoibench.tracks.protocol import get_protocol
    base, data = setup
    src = Path(get_protocol("synthetic-legacy").source).read_text()
    two = tmp_path / "synthetic-legacy-2.yaml"
    two.write_text(src.replace("replications: 1 ", "replications: 2 "))
    res = evaluate(base / "gt", data, base / "ev", protocol=str(two), allow_protocol_mismatch=True)
    proto = get_protocol(str(two))
    assert proto.replications == 2
    cfg = proto.physical_config()
    store, sub = Store(data), Submission(base / "gt")
    motions = {cid: {k: v[0] for k, v in sub.load(cid).items()} for cid in sorted(sub.ids)}
    inputs = clip_inputs(store, motions, sample=0, groups=load_groups(data),
                         contact_mode=proto.physical["contact_thresholds"], gt_rule=cfg.contact_gt_rule,
                         gt_threshold_m=cfg.contact_gt_threshold_m)
    frames = {c["id"]: int(c["frames"]) for c in store.manifest["clips"]}
    for inp in inputs:
        inp.windows = replication_windows(inp.key[0], frames[inp.key[0]], cfg.length_crop, (0, 1), proto.seed_for)
    want = evaluate_physical_windows(inputs, cfg)
    for r in (0, 1):
        exp = want[r].compute()
        for name in ("cd", "ocd", "ps", "fsr", "jitter_mps3"):
            assert res["per_replication"][r].get(name, float("nan")) == pytest.approx(exp[name], rel=0, abs=0,
                                                                                      nan_ok=True), (r, name)
    assert len({row["jitter_mps3"] for row in res["per_replication"]}) > 1      # windows differ by replication


# ---------------------------------------------------------------- a human-only method on an HOI store
def test_a_human_only_submission_is_scored_on_the_human_and_marked(setup, tmp_path):
    """An MDM-style submission (joints only) on a human-object store: refused without the
    flag (the error says how), scored with it -- the embedding metrics equal those of the
    same joints with the GT object (a 'human' evaluator reads the 263 human channels), FSR
    is measured, every object metric is 'not applicable: human-only submission'."""
    from hoibench.scoring.evaluate import evaluate
    from hoibench.scoring.submission import validation_report
    base, data = setup
    sub = tmp_path / "human"
    shutil.copytree(base / "gt", sub)
    for f in sorted((sub / "samples").glob("*.npz")):
        z = dict(np.load(f))
        np.savez(f, joints=z["joints"])
    rep = validation_report(sub, data)
    assert not rep.complete and any("flags.human_only" in p.message for p in rep.errors)
    meta = json.loads((sub / "submission.json").read_text())
    meta.setdefault("flags", {})["human_only"] = True
    (sub / "submission.json").write_text(json.dumps(meta))
    assert validation_report(sub, data).complete
    res = evaluate(sub, data, base / "ev")
    full = evaluate(base / "gt", data, base / "ev")
    assert res["complete"] and res["human_only"] is True and res["submission"]["flags"]["human_only"] is True
    for m in ("fid", "r_precision_top1", "mm_dist", "diversity", "fsr"):
        assert res["metrics"][m]["mean"] == pytest.approx(full["metrics"][m]["mean"], abs=1e-6), m
    for m in ("cd", "ocd", "ps"):
        assert m not in res["metrics"] or res["metrics"][m].get("mean") is None
        assert res["undefined_metrics"][m].startswith("not applicable: human-only submission")
    # the flag with object arrays is a contradiction, named per file
    bad = tmp_path / "contradiction"
    shutil.copytree(base / "gt", bad)
    (bad / "submission.json").write_text(json.dumps(meta))
    errs = validation_report(bad, data).errors
    assert errs and all(p.field in ("obj_rot", "obj_rotvec", "obj_trans") for p in errs)
