"""hoibench audit with an imported published evaluator: ChainHOI's MotionCLIP (random weights
at tiny sizes, ``tests/test_evaluator_chainhoi.py``'s fixture) on a BEHAVE store in its legacy
layout (synthetic clips in BEHAVE's raw layout, prepared as ``behave`` in mode
``legacy-hoidiff``), under ``behave-legacy`` with only its embedding metrics listed (the physical
metrics do not depend on the evaluator and are audited elsewhere; ChainHOI's loop needs more
than 32 test clips, so the store has 36)."""
from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

pytest.importorskip("smplx")
pytest.importorskip("transformers")
pytest.importorskip("matplotlib")

#: behave-legacy's embedding metrics (its loop has no MultiModality)
EMBEDDING = ["r_precision_top1", "r_precision_top2", "r_precision_top3", "fid", "mm_dist", "diversity"]


@pytest.fixture(scope="module")
def audited(tmp_path_factory):
    from test_evaluator_chainhoi import build

    import hoibench.tracks
    from hoibench.audit.document import run_audit
    from hoibench.datasets import behave
    from hoibench.datasets.store import PrepareConfig, prepare
    from hoibench.datasets.synthetic import write_behave_layout
    from hoibench.datasets.synthetic_store import write_template_texts
    from hoibench.evaluator.backends import import_evaluator
    from hoibench.scoring.evaluate import evaluate
    from hoibench.scoring.submission import from_store
    base = tmp_path_factory.mktemp("audit-chainhoi")
    raw, data = base / "raw", base / "data"
    write_behave_layout(raw, 40, seed=1, progress=False)
    split = json.loads((raw / "split.json").read_text())
    names = sorted(split["train"] + split["test"])
    (raw / "split.json").write_text(json.dumps({"train": names[:4], "test": names[4:]}))
    cfg = PrepareConfig("behave", fps=20.0, mode="legacy-hoidiff")
    prepare(behave.prepare_jobs(raw, raw / "body_models", data, cfg, split_file=raw / "split.json"), data, cfg)
    write_template_texts(data)
    files = build(base / "chainhoi")
    eid = import_evaluator("chainhoi", base / "ev", checkpoint=files["checkpoint"], text_model=files["text_model"],
                           stats=files["stats"])
    text = (Path(hoibench.tracks.__file__).parent / "protocols" / "behave-legacy.yaml").read_text()
    protocol = base / "behave-legacy-embedding.yaml"
    protocol.write_text(re.sub(r"(?m)^metrics: .*$", f"metrics: [{', '.join(EMBEDDING)}]", text))
    from_store(data, base / "gt")
    gt = evaluate(base / "gt", data, base / "ev", protocol=str(protocol), allow_failed_gate=True)
    doc = run_audit(data, base / "ev", base / "out", protocol=str(protocol), families=["jitter", "noun_swap"],
                    allow_failed_gate=True, log=lambda _m: None)
    return eid, gt, doc, base


def test_the_audit_scores_with_the_imported_chainhoi_evaluator(audited):
    eid, gt, doc, base = audited
    assert gt["evaluator_backend"] == "chainhoi" and doc["provenance"]["evaluator_id"] == eid
    assert (base / "out" / "audit.json").is_file() and (base / "out" / "heatmap.png").stat().st_size > 1000
    for family in ("jitter", "noun_swap"):
        values = doc["corruptions"][family]["values"]
        for name in ("fid", "mm_dist", "r_precision_top1"):      # severity 0 is the plain ground-truth scoring
            assert values[name][0] == pytest.approx(gt["metrics"][name]["mean"], abs=1e-9), (family, name)


def test_its_embeddings_see_jitter_and_its_text_side_sees_a_swapped_noun(audited):
    _, _, doc, _ = audited
    fid = doc["corruptions"]["jitter"]["values"]["fid"]
    assert fid[-1] > fid[0] + 1e-3 and doc["summary"]["fid"]["jitter"]["spearman"] > 0.5
    noun = doc["corruptions"]["noun_swap"]["values"]
    assert all(v == noun["fid"][0] for v in noun["fid"])          # the motions are untouched
    assert max(noun["mm_dist"]) > noun["mm_dist"][0]              # the captions are not
