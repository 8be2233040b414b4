"""The published ``t2m`` evaluator backend: text-to-motion's files in their real layout
(``finest.tar`` as ``TextMotionMatchTrainer.save`` writes it, ``glove/`` with its pickles,
``meta/``), imported into an evaluator folder, loaded, and compared with the reference code.

Reference values (``REF_TEXT``, ``REF_MOTION``): EricGuo5513/text-to-motion at commit
72df96ec453edea2fbe9603b1d58a955eaf71636, run in a scratch folder on the files
:func:`write_fixture` writes (same weights, GloVe, meta and inputs; small layer sizes
:data:`DIMS`, the reference modules take them as constructor arguments): ``networks/modules.py``
``MovementConvEncoder``/``MotionEncoderBiGRUCo``/``TextEncoderBiGRUCo`` built by
``networks/evaluator_wrapper.py`` ``build_models`` (which loads ``finest.tar``),
``utils/word_vectorizer.py`` ``WordVectorizer`` on the glove folder, ``data/dataset.py``
``Text2MotionDatasetV2.__getitem__`` (one caption per motion; its random length coin fixed to
'single' and its crop offset to 0, the window hoibench embeds), ``collate_fn``, and
``EvaluatorModelWrapper.get_co_embeddings``, rows put back in input order; torch 2.13 CPU,
float32. Printed with ``repr`` of the float32 values.
"""
from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from t2m_release import import_release

from hoibench.evaluator.published_t2m import T2MDims, expected_shapes, import_t2m, load_t2m

DIMS = T2MDims(movement_hidden=16, movement_latent=12, motion_hidden=20, text_hidden=10, output=8)
WORDS = ["sos", "eos", "unk", "a", "man", "kick", "with", "his", "left", "leg", "person", "walk", "forward",
         "slowly", "and", "then", "turn", "around", "lift", "the", "box", "up", "chair", "sit", "on", "hand",
         "down", "put", "it", "man"]                      # "man" twice, as the published list may repeat
LENGTHS = (57, 40, 196, 123)
TOKENS = [
    "a/DET man/NOUN kick/VERB with/ADP his/DET left/ADJ leg/NOUN",
    "a/DET person/NOUN walk/VERB forward/ADV slowly/ADV and/CCONJ then/ADV turn/VERB around/ADV and/CCONJ "
    "lift/VERB the/DET box/NOUN up/ADP and/CCONJ put/VERB it/PRON down/ADP on/ADP the/DET zebra/NOUN "
    "with/ADP his/DET hand/NOUN",                          # 25 tokens: cropped to 20; zebra is unknown
    "a/DET man/NOUN sit/VERB on/ADP the/DET chair/NOUN",   # same length as the first: stable order
    "walk/VERB forward/PROPN",                             # a tag outside the 15 slots: OTHER
]
CAPTIONS = ["a man kicks with his left leg", "a person walks forward slowly and then turns around and lifts "
            "the box up and puts it down on the zebra with his hand", "a man sits on the chair", "walk forward"]


def fixture_tensors(seed: int = 0) -> dict[str, dict[str, torch.Tensor]]:
    """Per encoder: every tensor of the reference state dict, in sorted-name order, drawn
    ``RandomState(seed).standard_normal(shape) * 0.3`` (float32)."""
    rs = np.random.RandomState(seed)
    out = {}
    for part, shapes in expected_shapes(DIMS).items():
        out[part] = {k: torch.from_numpy((rs.standard_normal(shapes[k]) * 0.3).astype(np.float32))
                     for k in sorted(shapes)}
    return out


def write_fixture(root: Path) -> dict[str, Path]:
    """finest.tar, glove/ and meta/ in text-to-motion's layout, plus the test inputs
    (``motions.npy``: (4, 196, 263) raw rows, zero past ``LENGTHS``)."""
    root.mkdir(parents=True, exist_ok=True)
    parts = fixture_tensors()
    opt_states = {}
    for part in ("text_encoder", "motion_encoder"):   # Adam.state_dict()'s layout, as save() writes it
        ts = list(parts[part].values())
        opt_states[f"opt_{part}"] = {
            "state": {i: {"step": torch.tensor(81000.0), "exp_avg": t * 0.01, "exp_avg_sq": t * t * 1e-4}
                      for i, t in enumerate(ts)},
            "param_groups": [{"lr": 1e-4, "betas": (0.9, 0.999), "eps": 1e-8, "weight_decay": 0, "amsgrad": False,
                              "maximize": False, "foreach": None, "params": list(range(len(ts)))}]}
    ckpt = root / "checkpoints/t2m/text_mot_match/model/finest.tar"
    ckpt.parent.mkdir(parents=True, exist_ok=True)
    torch.save({**parts, **opt_states, "epoch": 270, "iter": 81000}, ckpt)
    rs = np.random.RandomState(1)
    glove = root / "glove"
    glove.mkdir(exist_ok=True)
    unique = list(dict.fromkeys(WORDS))
    rows = rs.permutation(len(unique) + 3)[:len(unique)]          # rows out of order, some unused
    np.save(glove / "our_vab_data.npy", rs.standard_normal((len(unique) + 3, 300)).astype(np.float32))
    (glove / "our_vab_words.pkl").write_bytes(pickle.dumps(WORDS, protocol=2))
    (glove / "our_vab_idx.pkl").write_bytes(pickle.dumps({w: int(r) for w, r in zip(unique, rows)}, protocol=2))
    meta = root / "checkpoints/t2m/Comp_v6_KLD01/meta"
    meta.mkdir(parents=True, exist_ok=True)
    np.save(meta / "mean.npy", (rs.standard_normal(263) * 0.2).astype(np.float32))
    np.save(meta / "std.npy", rs.uniform(0.5, 1.5, 263).astype(np.float32))
    motions = np.zeros((len(LENGTHS), 196, 263), np.float32)
    for i, n in enumerate(LENGTHS):
        motions[i, :n] = rs.standard_normal((n, 263)).astype(np.float32)
    np.save(root / "motions.npy", motions)
    return {"checkpoint": ckpt, "glove": glove, "meta": meta, "motions": root / "motions.npy"}


# reference outputs (see the module docstring), rows in input order
REF_TEXT = [
    [0.012008100748062134, 0.1904311627149582, -0.1123666912317276, 0.028896331787109375, 0.019844900816679, 0.19454620778560638, 0.002521755173802376, -0.48111823201179504],
    [0.09334373474121094, 0.051643580198287964, -0.18317893147468567, 0.03048969805240631, -0.05616283416748047, 0.15424849092960358, -0.1263716220855713, -0.4501446485519409],
    [0.1647079885005951, 0.04747539013624191, -0.04348777234554291, -0.009342595934867859, -0.0013904720544815063, 0.17944492399692535, -0.10689634084701538, -0.19176557660102844],
    [0.3044477701187134, -0.0649799257516861, -0.0012103766202926636, -0.28736719489097595, 0.0007732883095741272, 0.20751811563968658, -0.2780267000198364, -0.18634235858917236],
]
REF_MOTION = [
    [0.27930596470832825, -0.19522924721240997, -0.2927817702293396, -0.061499711126089096, -0.3378840684890747, -0.9030573964118958, -0.1238664761185646, -0.013238027691841125],
    [0.6291369795799255, -0.9346379041671753, -1.3604440689086914, -0.7970583438873291, -0.5006874203681946, -1.2413485050201416, -0.49158740043640137, -2.013221025466919],
    [0.2127494513988495, -0.32310372591018677, -0.04077892750501633, -0.1576106697320938, -0.4690445065498352, -0.9640283584594727, -0.2209833413362503, -0.5070073008537292],
    [0.5436855554580688, -0.31806740164756775, -0.43278414011001587, -0.24258528649806976, -0.41687268018722534, -0.9499305486679077, -0.12480968981981277, -0.4167593717575073],
]


@pytest.fixture(scope="module")
def imported(tmp_path_factory):
    return import_release(tmp_path_factory, "t2m", write_fixture, import_t2m, DIMS)


def test_embeddings_equal_the_reference_code(imported):
    root, files, eid = imported
    ev = load_t2m(root / "ev")
    assert ev.id == eid and ev.embed_dim == DIMS.output
    motions = np.load(files["motions"])
    m = ev.embed_motion(motions, LENGTHS)
    t = ev.embed_text(CAPTIONS, tokens=TOKENS)
    print(np.abs(m - np.asarray(REF_MOTION, np.float32)).max(), np.abs(t - np.asarray(REF_TEXT, np.float32)).max())
    assert np.abs(m - np.asarray(REF_MOTION, np.float32)).max() <= 1e-5
    assert np.abs(t - np.asarray(REF_TEXT, np.float32)).max() <= 1e-5


#: every tensor of the published evaluator, from the reference modules built with the sizes
#: EvaluatorModelWrapper sets for 't2m' (dim_pose 263, word 300, POS 15, text hidden 512,
#: motion hidden 1024, co-embedding 512) and the options' defaults (movement hidden/latent
#: 512): ``{part: {name: tuple(shape)}}`` printed from the modules' ``state_dict()`` at the
#: commit named in the module docstring
PUBLISHED_SHAPES = {
    "movement_encoder": {"main.0.weight": (512, 259, 4), "main.0.bias": (512,), "main.3.weight": (512, 512, 4),
                         "main.3.bias": (512,), "out_net.weight": (512, 512), "out_net.bias": (512,)},
    "motion_encoder": {"hidden": (2, 1, 1024), "input_emb.weight": (1024, 512), "input_emb.bias": (1024,),
                       "gru.weight_ih_l0": (3072, 1024), "gru.weight_hh_l0": (3072, 1024), "gru.bias_ih_l0": (3072,),
                       "gru.bias_hh_l0": (3072,), "gru.weight_ih_l0_reverse": (3072, 1024),
                       "gru.weight_hh_l0_reverse": (3072, 1024), "gru.bias_ih_l0_reverse": (3072,),
                       "gru.bias_hh_l0_reverse": (3072,), "output_net.0.weight": (1024, 2048),
                       "output_net.0.bias": (1024,), "output_net.1.weight": (1024,), "output_net.1.bias": (1024,),
                       "output_net.3.weight": (512, 1024), "output_net.3.bias": (512,)},
    "text_encoder": {"hidden": (2, 1, 512), "pos_emb.weight": (300, 15), "pos_emb.bias": (300,),
                     "input_emb.weight": (512, 300), "input_emb.bias": (512,), "gru.weight_ih_l0": (1536, 512),
                     "gru.weight_hh_l0": (1536, 512), "gru.bias_ih_l0": (1536,), "gru.bias_hh_l0": (1536,),
                     "gru.weight_ih_l0_reverse": (1536, 512), "gru.weight_hh_l0_reverse": (1536, 512),
                     "gru.bias_ih_l0_reverse": (1536,), "gru.bias_hh_l0_reverse": (1536,),
                     "output_net.0.weight": (512, 1024), "output_net.0.bias": (512,), "output_net.1.weight": (512,),
                     "output_net.1.bias": (512,), "output_net.3.weight": (512, 512), "output_net.3.bias": (512,)},
}


def test_the_published_sizes_give_the_reference_state_dict():
    assert expected_shapes(T2MDims()) == PUBLISHED_SHAPES


def test_motion_crops_padding_columns_and_order(imported):
    """The first 196 rows, cropped to a multiple of 4; hoi269 rows read by their first 263
    columns; a batch in any order or size gives the same rows; fewer than 4 rows refused."""
    root, files, _ = imported
    ev = load_t2m(root / "ev")
    rs = np.random.RandomState(5)
    long = rs.standard_normal((210, 263)).astype(np.float32)
    odd = rs.standard_normal((59, 263)).astype(np.float32)
    base = ev.embed_motion([long[:196], odd[:56]])
    np.testing.assert_array_equal(ev.embed_motion([long, odd]), base)
    hoi = np.concatenate([odd, rs.standard_normal((59, 6)).astype(np.float32)], axis=1)
    np.testing.assert_array_equal(ev.embed_motion([long, hoi]), base)
    clips = [rs.standard_normal((n, 263)).astype(np.float32) for n in (44, 80, 60, 44, 120)]
    all5 = ev.embed_motion(clips)
    np.testing.assert_allclose(ev.embed_motion(clips[::-1])[::-1], all5, atol=1e-6)
    np.testing.assert_allclose(ev.embed_motion(clips, batch_size=2), all5, atol=1e-6)
    assert not np.allclose(all5[0], all5[3])                # different clips of equal length
    with pytest.raises(ValueError, match=r"features\[0\]: 3 frame\(s\); the t2m evaluator needs at least 4"):
        ev.embed_motion([long[:3]])


def test_text_tokens_come_from_the_caller_or_the_tagger(imported):
    from hoibench.text.tokens import tokens as tag
    root, _, _ = imported
    ev = load_t2m(root / "ev")
    t = ev.embed_text(CAPTIONS, tokens=TOKENS)
    np.testing.assert_array_equal(ev.embed_text(CAPTIONS, tokens=[s.split() for s in TOKENS]), t)
    np.testing.assert_array_equal(ev.embed_text(CAPTIONS[:2], tokens=[None, TOKENS[1]]),
                                  ev.embed_text(CAPTIONS[:2], tokens=[tag(CAPTIONS[0]), TOKENS[1]]))
    np.testing.assert_array_equal(ev.embed_text(CAPTIONS), ev.embed_text(CAPTIONS, [tag(c) for c in CAPTIONS]))
    with pytest.raises(ValueError, match=r"tokens\[0\]: token 'kick' is not 'word/POS'"):
        ev.embed_text(["x"], tokens=[["kick"]])


def test_text_sequences_follow_the_reference_rules():
    """sos + 20 tokens + eos, unk padding; VIP lists override the tag; unknown words are
    unk/OTHER (slots: text-to-motion's POS_enumerator)."""
    from hoibench.evaluator.t2m_text import POS_SLOTS, Vocabulary, pos_slot, sequence
    seq, n = sequence([f"w{i}/NOUN" for i in range(25)])
    assert n == 22 and seq[0] == "sos/OTHER" and seq[-1] == "eos/OTHER" and seq[-2] == "w19/NOUN"
    seq, n = sequence(["a/DET"])
    assert n == 3 and seq[3:] == ["unk/OTHER"] * 19 and len(seq) == 22
    assert POS_SLOTS[pos_slot("left", "ADJ")] == "Loc_VIP" and POS_SLOTS[pos_slot("walk", "NOUN")] == "Act_VIP"
    assert POS_SLOTS[pos_slot("box", "PROPN")] == "OTHER" and POS_SLOTS[pos_slot("box", "NOUN")] == "NOUN"
    vocab = Vocabulary(["sos", "eos", "unk", "box"], np.arange(4 * 300, dtype=np.float32).reshape(4, 300))
    words, onehot, n = vocab.encode(["box/NOUN", "zebra/NOUN"])
    assert n == 4 and words[1, 0] == 900 and words[2, 0] == 600 and onehot[2].argmax() == 14
    assert onehot.sum() == 22 and onehot[1].argmax() == 1


# ----------------------------------------------------------------------------- refusals
def _release(tmp_path) -> dict[str, Path]:
    return write_fixture(tmp_path / "release")


def test_wrong_truncated_or_mismatched_checkpoints_are_one_line_errors(imported, tmp_path):
    from hoibench.evaluator.errors import EvaluatorError
    _, files, _ = imported
    bad = tmp_path / "finest.tar"

    def refused(pattern):
        with pytest.raises(EvaluatorError, match=pattern) as exc:
            import_t2m(tmp_path / "ev", bad, files["glove"], files["meta"], dims=DIMS)
        assert "\n" not in str(exc.value) and not (tmp_path / "ev").exists()

    bad.write_text("not a checkpoint")
    refused(r"finest.tar: not a PyTorch checkpoint \(looks like a text file")
    raw = files["checkpoint"].read_bytes()
    bad.write_bytes(raw[: len(raw) // 2])
    refused(r"finest.tar: not a readable torch checkpoint")
    ckpt = torch.load(files["checkpoint"], weights_only=True)
    torch.save({k: v for k, v in ckpt.items() if k != "movement_encoder"}, bad)
    refused(r"finest.tar: no key 'movement_encoder'")
    wrong = {**ckpt, "text_encoder": {**ckpt["text_encoder"], "pos_emb.weight": torch.zeros(300, 14)}}
    torch.save(wrong, bad)
    refused(r"finest.tar: text_encoder.pos_emb.weight has shape \(300, 14\), expected \(300, 15\)")
    with pytest.raises(EvaluatorError, match=r"movement_encoder.main.0.weight has shape \(16, 259, 4\), expected "
                                             r"\(512, 259, 4\)"):
        import_t2m(tmp_path / "ev", files["checkpoint"], files["glove"], files["meta"])   # published sizes
    with pytest.raises(EvaluatorError, match=r"--checkpoint .*nothing.tar: no such file"):
        import_t2m(tmp_path / "ev", tmp_path / "nothing.tar", files["glove"], files["meta"], dims=DIMS)


def test_missing_glove_and_meta_files_are_named(imported, tmp_path):
    import shutil
    from hoibench.evaluator.errors import EvaluatorError
    _, files, _ = imported
    glove = tmp_path / "glove"
    shutil.copytree(files["glove"], glove)
    (glove / "our_vab_idx.pkl").unlink()
    with pytest.raises(EvaluatorError, match=r"--glove .*glove: our_vab_idx.pkl is missing"):
        import_t2m(tmp_path / "ev", files["checkpoint"], glove, files["meta"], dims=DIMS)
    with pytest.raises(EvaluatorError, match=r"--meta .*glove: mean.npy is missing"):
        import_t2m(tmp_path / "ev", files["checkpoint"], files["glove"], glove, dims=DIMS)
    assert not (tmp_path / "ev").exists()


class _RunsCode:
    """Pickles as a call of os.system: loading it with pickle.load would run the command."""

    def __init__(self, marker: Path):
        self.marker = marker

    def __reduce__(self):
        return os.system, (f"touch {self.marker}",)


def test_a_vocabulary_pickle_that_would_run_code_is_refused_and_runs_nothing(imported, tmp_path):
    import shutil
    from hoibench.evaluator.errors import EvaluatorError
    from hoibench.evaluator.t2m_text import read_plain_pickle
    _, files, _ = imported
    glove = tmp_path / "glove"
    shutil.copytree(files["glove"], glove)
    marker = tmp_path / "ran"
    words = pickle.loads((glove / "our_vab_words.pkl").read_bytes())
    (glove / "our_vab_words.pkl").write_bytes(pickle.dumps(words + [_RunsCode(marker)], protocol=2))
    with pytest.raises(EvaluatorError, match=r"our_vab_words.pkl: refused: refers to posix.system") as exc:
        import_t2m(tmp_path / "ev", files["checkpoint"], glove, files["meta"], dims=DIMS)
    assert "\n" not in str(exc.value) and not marker.exists() and not (tmp_path / "ev").exists()
    for obj, kind in (({"a", "b"}, "set"), ([1.5], "float"), ({"a": (1, 2)}, "tuple"), (["a", (1, 2)], "tuple")):
        (tmp_path / "x.pkl").write_bytes(pickle.dumps(obj, protocol=4))
        with pytest.raises(EvaluatorError, match=f"x.pkl: holds a {kind}; only lists, dicts, strings and integers"):
            read_plain_pickle(tmp_path / "x.pkl")
    (tmp_path / "x.pkl").write_bytes(pickle.dumps({"sos": 0, "unk": [1, "x"]}, protocol=0))
    assert read_plain_pickle(tmp_path / "x.pkl") == {"sos": 0, "unk": [1, "x"]}


# ----------------------------------------------------------------------------- folder
def test_cli_import_then_load_evaluator_and_store_fit(imported, tmp_path, monkeypatch, capsys):
    """``hoibench evaluator import t2m`` writes an ordinary folder (no pickle in it) that
    ``load_evaluator`` recognises by its card; a modified folder is refused; the card
    accepts legacy hml263 stores only."""
    from hoibench import cli
    from hoibench.evaluator import load_evaluator, store_mismatches
    from hoibench.evaluator import published_t2m
    from hoibench.evaluator.backends import backend_of
    from hoibench.evaluator.errors import EvaluatorIntegrityError
    _, files, eid = imported
    monkeypatch.setattr(published_t2m, "DEFAULT_DIMS", DIMS)       # the fixture's small sizes
    out = tmp_path / "ev-t2m"
    assert cli.main(["evaluator", "import", "t2m", "--checkpoint", str(files["checkpoint"]), "--glove",
                     str(files["glove"]), "--meta", str(files["meta"]), "--out", str(out)]) == 0
    assert f"wrote t2m evaluator {eid}" in capsys.readouterr().out        # same files, same id
    assert sorted(p.name for p in out.iterdir()) == ["card.json", "weights.safetensors"]
    card = json.loads((out / "card.json").read_text())
    assert card["backend"] == "t2m" and card["sources"]["checkpoint"]["epoch"] == 270
    assert backend_of(out).name == "t2m"
    ev = load_evaluator(out, kind="contrastive")
    assert type(ev).__name__ == "T2MEvaluator" and ev.id == eid
    np.testing.assert_allclose(ev.embed_text(CAPTIONS, tokens=TOKENS), np.asarray(REF_TEXT, np.float32), atol=1e-5)
    legacy = {"dataset": "behave", "representations": {"hml263": "hml263-legacy-hoidiff-1.0"}}
    assert store_mismatches(ev, legacy) == []
    clean = {"dataset": "behave", "representations": {"hml263": "hml263-clean-1.0"}}
    assert "the store has 'hml263-clean-1.0'" in store_mismatches(ev, clean)[0]
    shown = published_t2m.summary(*published_t2m.verify_folder(out)[:1], True)   # what evaluator show prints
    assert shown.startswith(f"evaluator {eid}  (id verified)\n  backend t2m:") and "words" in shown
    card["vocabulary"][3] = "an"
    (out / "card.json").write_text(json.dumps(card))
    with pytest.raises(EvaluatorIntegrityError, match=r"evaluator id mismatch: .*card.json field\(s\) vocabulary"):
        load_evaluator(out)



def test_leaderboard_rows_are_comparable_only_with_the_t2m_backend_its_weights_and_t2m_legacy():
    from hoibench.publish.leaderboard import comparable, entry_from_result
    paper = {"source": "reported", "citation": "HOI-Diff Tab. 1",
             "comparable_with": {"protocol": "t2m-legacy", "evaluator_backend": "t2m", "evaluator_id": "abc"}}
    result = {"metrics": {}, "evaluator_id": "abc", "protocol": "t2m-legacy", "protocol_version": "1.0",
              "evaluator_backend": "t2m", "complete": True}
    ours = entry_from_result(result, method="mine", track="behave")
    assert comparable(ours, paper)
    assert not comparable({**ours, "evaluator_id": "other-weights"}, paper)
    assert not comparable({**ours, "protocol": "behave-legacy"}, paper)
    assert not comparable({**ours, "evaluator_backend": "contrastive"}, paper)
    any_weights = {**paper, "comparable_with": {"protocol": "t2m-legacy", "evaluator_backend": "t2m"}}
    assert comparable({**ours, "evaluator_id": "other-weights"}, any_weights)


def test_caption_lines_keep_their_humanml3d_tokens():
    """What ``hoibench evaluate`` passes to ``embed_text(..., tokens=...)``."""
    from hoibench.evaluator.text import parse_text_file
    caps = parse_text_file("a man walks#a/DET man/NOUN walk/VERB#0.0#0.0\njust a caption\n")
    assert caps[0].tokens == ("a/DET", "man/NOUN", "walk/VERB") and caps[1].tokens == ()
    assert caps[0].whole_clip and caps[1].text == "just a caption"
