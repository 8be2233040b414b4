"""The per-test-clip table of a result: one row per scored test id with its embedding
distance to its captions, text rank and physical metrics; the worst-k selection; the
worst clips rendered beside their ground truth."""
from __future__ import annotations

import json

import numpy as np
import pytest

from hoibench.scoring.per_clip import caption_distances, per_clip_table, worst


def test_caption_distances_and_ranks_on_known_embeddings():
    motions = np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 1.0]])
    texts = [np.array([[0.0, 0.0], [0.0, 2.0]]), np.array([[3.0, 4.0]]), np.array([[3.0, 0.0]])]
    d = caption_distances(motions, texts)
    assert np.allclose(d[0], [1.0, 5.0, 3.0]) and np.allclose(d[1], [(3 + 13 ** 0.5) / 2, 4.0, 0.0])
    table = per_clip_table(["a", "b", "c"], motions, motions, texts, {"a": {"cd": 0.1, "ps": float("nan")}}, 0)
    rows = {r["id"]: r for r in table["rows"]}
    assert rows["a"]["mm_dist"] == pytest.approx(1.0) and rows["a"]["text_rank"] == 1
    assert rows["b"]["text_rank"] == 3        # its own caption (4.0) is the farthest of the three
    assert rows["c"]["mm_dist"] == pytest.approx(np.hypot(3.0, 1.0)) and rows["c"]["text_rank"] == 2
    assert rows["a"]["cd"] == 0.1 and rows["a"]["ps"] is None and rows["b"]["cd"] is None
    assert all(r["mm_dist"] == r["gt_mm_dist"] for r in table["rows"])      # motions == real here


def test_worst_orders_by_the_failure_end_and_skips_undefined():
    rows = [{"id": "a", "mm_dist": 1.0, "contact_iou": 0.9, "cd": None}, {"id": "b", "mm_dist": 3.0, "contact_iou": 0.2,
                                                                          "cd": 0.5},
            {"id": "c", "mm_dist": 2.0, "contact_iou": 0.5, "cd": 0.1}, {"id": "d", "mm_dist": 3.0, "contact_iou": 0.2,
                                                                          "cd": 0.2}]
    res = {"per_clip": {"sample": 0, "rows": rows}}
    assert [r["id"] for r in worst(res, 3, "mm_dist")] == ["b", "d", "c"]          # ties by id
    assert [r["id"] for r in worst(res, 2, "contact_iou")] == ["b", "d"]           # low IoU is the failure end
    assert [r["id"] for r in worst(res, 5, "cd")] == ["b", "d", "c"]               # a's CD is undefined
    with pytest.raises(ValueError, match="--by 'fid'"):
        worst(res, 1, "fid")
    with pytest.raises(ValueError, match="per_clip: absent"):
        worst({"metrics": {}}, 1)


@pytest.fixture(scope="module")
def scored(tmp_path_factory):
    """An 8-clip store (4 train / 4 test), a 1-epoch tiny evaluator, and the ground-truth
    submission scored with it."""
    from hoibench.scoring.evaluate import evaluate
    from hoibench.scoring.submission import from_store
    from _small_store import eight_clip_store
    base = tmp_path_factory.mktemp("per_clip")
    data, ev = eight_clip_store(base)
    from_store(data, base / "gt")
    return data, base, evaluate(base / "gt", data, ev, allow_failed_gate=True)


def test_one_row_per_test_clip_with_sane_values(scored):
    data, _, res = scored
    from hoibench.datasets.store import Store
    test_ids = Store(data).clip_ids("test")
    gt = res["per_clip"]
    assert gt["sample"] == 0 and [r["id"] for r in gt["rows"]] == sorted(test_ids) and gt["clips"] == len(test_ids)
    for r in gt["rows"]:
        assert r["mm_dist"] == pytest.approx(r["gt_mm_dist"], abs=1e-5)     # the GT's own motion
        assert 1 <= r["text_rank"] <= len(test_ids) and r["jitter_mps3"] >= 0
        assert r["fsr"] is None or 0 <= r["fsr"] <= 1                        # None: no foot on the ground
        assert r["penetration_depth_max_m"] >= r["penetration_depth_mean_m"] >= 0
    # the pooled metrics are the per-clip values pooled: CD (clean) is the mean over clips with contact
    cds = [r["cd"] for r in gt["rows"] if r["cd"] is not None]
    assert np.mean(cds) == pytest.approx(res["metrics"]["cd"]["mean"], rel=1e-9)
    gmd = [r["fsr_gmd"] for r in gt["rows"] if r["fsr_gmd"] is not None]
    assert np.mean(gmd) == pytest.approx(res["metrics"]["fsr_gmd"]["mean"], rel=1e-9)
    json.dumps(res, allow_nan=False)                                         # strict JSON
    from hoibench.scoring.evaluate import format_result
    far = worst(res, 1)[0]
    assert f"per-clip table: {len(test_ids)} test clips (sample 0); farthest from its text: {far['id']}" \
        in format_result(res)


def test_render_worst_draws_the_worst_clip(scored, tmp_path):
    pytest.importorskip("imageio")
    from hoibench.publish.renderers import main_render_worst
    data, base, res = scored
    path = tmp_path / "gt.json"
    path.write_text(json.dumps(res))
    want = worst(res, 1, "mm_dist")[0]["id"]
    lines = []
    written = main_render_worst(path, 1, "mm_dist", data, None, tmp_path / "worst", fmt=".png", log=lines.append)
    assert [p.name for p in written] == [f"01_{want}.png"] and written[0].read_bytes()[:4] == b"\x89PNG"
    assert want in lines[0] and "mm_dist" in lines[0]
    with pytest.raises(ValueError, match="--data DATA"):
        main_render_worst(path, 1, "mm_dist", None, None, tmp_path / "w2")
