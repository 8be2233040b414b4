"""Text-model folders in the layouts users download them: an evaluator imported from each one
embeds text, its tokenizer class is recorded in the card (and so in the evaluator id), and a
folder that cannot tokenize is refused at import in one line naming the folder and the file.

Layouts (written here, as the hub folders have them):

* ``distilbert-base-uncased``: ``config.json`` (``"model_type": "distilbert"``),
  ``tokenizer.json``, ``tokenizer_config.json`` = ``{"do_lower_case": true,
  "model_max_length": 512}`` (no ``tokenizer_class``), ``vocab.txt``;
* the same without ``tokenizer.json`` (``vocab.txt`` only);
* ``save_pretrained``'s layout (``tokenizer_config.json`` names ``tokenizer_class``).
"""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

pytest.importorskip("transformers")

from interact_fixture import CAPTIONS, VOCAB, write_interact_files  # noqa: E402

HUB_TOKENIZER_CONFIG = {"do_lower_case": True, "model_max_length": 512}


def _hub_layout(src, dst, with_tokenizer_json: bool):
    """``src``'s DistilBERT folder rewritten as distilbert-base-uncased is on the hub."""
    from tokenizers import Tokenizer, decoders, normalizers, pre_tokenizers, processors
    from tokenizers.models import WordPiece
    dst.mkdir()
    shutil.copy(src / "config.json", dst / "config.json")
    shutil.copy(src / "vocab.txt", dst / "vocab.txt")
    cfg = json.loads((dst / "config.json").read_text())
    cfg.pop("tokenizer_class", None)
    assert cfg["model_type"] == "distilbert"
    (dst / "config.json").write_text(json.dumps(cfg))
    (dst / "tokenizer_config.json").write_text(json.dumps(HUB_TOKENIZER_CONFIG))
    if with_tokenizer_json:                         # the hub's tokenizer.json: a WordPiece with BERT's post-processor
        tok = Tokenizer(WordPiece({t: i for i, t in enumerate(VOCAB)}, unk_token="[UNK]"))
        tok.normalizer = normalizers.BertNormalizer(lowercase=True)
        tok.pre_tokenizer = pre_tokenizers.BertPreTokenizer()
        tok.post_processor = processors.TemplateProcessing(
            single="[CLS] $A [SEP]", pair="[CLS] $A [SEP] $B:1 [SEP]:1",
            special_tokens=[("[CLS]", VOCAB.index("[CLS]")), ("[SEP]", VOCAB.index("[SEP]"))])
        tok.decoder = decoders.WordPiece()
        tok.save(str(dst / "tokenizer.json"))
    return dst


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """(root, files, token ids and text embeddings of CAPTIONS) with the hub folder's tokenizer as
    InterAct loads it (``AutoTokenizer`` on the whole folder, config.json included)."""
    from transformers import AutoTokenizer
    from hoibench.evaluator.backends import import_evaluator, load_evaluator
    root = tmp_path_factory.mktemp("interact_layouts")
    files = write_interact_files(root)
    hub = _hub_layout(files["distilbert"], root / "distilbert-base-uncased", with_tokenizer_json=True)
    ids = AutoTokenizer.from_pretrained(str(hub), local_files_only=True)(CAPTIONS, padding=True)["input_ids"]
    assert ids[0][0] == VOCAB.index("[CLS]") and VOCAB.index("[UNK]") not in ids[0]
    import_evaluator("interact", root / "ev", **{**files, "distilbert": hub})
    return root, files, ids, load_evaluator(root / "ev").embed_text(CAPTIONS)


@pytest.mark.parametrize("layout", ["hub", "hub-without-tokenizer.json", "save_pretrained"])
def test_each_distilbert_layout_imports_and_embeds_with_interacts_tokens(reference, tmp_path, layout):
    from transformers import AutoTokenizer
    from hoibench.evaluator.backends import import_evaluator, load_evaluator
    root, files, ids, ref = reference
    folder = _hub_layout(files["distilbert"], tmp_path / "bert", layout == "hub")
    if layout == "save_pretrained":                  # tokenizer_config.json names tokenizer_class
        AutoTokenizer.from_pretrained(str(root / "distilbert-base-uncased"),
                                      local_files_only=True).save_pretrained(str(folder))
        assert "tokenizer_class" in json.loads((folder / "tokenizer_config.json").read_text())
    eid = import_evaluator("interact", tmp_path / "ev", **{**files, "distilbert": folder})
    card = json.loads((tmp_path / "ev" / "card.json").read_text())
    assert "BertTokenizer" in card["text_model"]["tokenizer_class"] and card["evaluator_id"] == eid
    ev = load_evaluator(tmp_path / "ev")
    assert ev.tokenizer(CAPTIONS, padding=True)["input_ids"] == ids
    emb = ev.embed_text(CAPTIONS)
    assert np.isfinite(emb).all() and np.abs(emb[0] - emb[1]).max() > 1e-3
    np.testing.assert_allclose(emb, ref, atol=1e-5)


def test_a_distilbert_folder_that_cannot_tokenize_is_refused_at_import(reference, tmp_path):
    from hoibench.evaluator.backends import import_evaluator
    from hoibench.evaluator.errors import EvaluatorError
    root, files, _, _ = reference
    hub = _hub_layout(files["distilbert"], tmp_path / "bert", with_tokenizer_json=False)
    (hub / "vocab.txt").unlink()
    with pytest.raises(EvaluatorError) as exc:
        import_evaluator("interact", tmp_path / "ev", **{**files, "distilbert": hub})
    assert str(hub) in str(exc.value) and "vocab.txt" in str(exc.value) and "\n" not in str(exc.value)
    assert not (tmp_path / "ev" / "card.json").exists()
    bad = _hub_layout(files["distilbert"], tmp_path / "bert2", with_tokenizer_json=False)
    (bad / "tokenizer_config.json").write_text(json.dumps({**HUB_TOKENIZER_CONFIG, "tokenizer_class": "NoSuchTok"}))
    with pytest.raises(EvaluatorError) as exc:
        import_evaluator("interact", tmp_path / "ev3", **{**files, "distilbert": bad})
    assert "tokenizer_config.json" in str(exc.value) and "tokenizer_class" in str(exc.value)


def test_chainhois_roberta_folder_as_downloaded_is_checked_at_import(tmp_path):
    """roberta-base on the hub: config.json, vocab.json, merges.txt (tokenizer.json; no
    tokenizer_config.json); the tokenizer must load and pad at import."""
    from hoibench.evaluator.published_chainhoi import ChainHOIImportError, _text_model
    from test_evaluator_chainhoi import write_roberta_folder
    folder = tmp_path / "roberta-base"
    write_roberta_folder(folder)
    assert not (folder / "tokenizer_config.json").exists()
    config, files = _text_model(folder)
    assert config.model_type == "roberta" and {"config.json", "vocab.json", "merges.txt"} <= set(files)
    (folder / "vocab.json").write_text("{}")
    with pytest.raises(ChainHOIImportError) as exc:
        _text_model(folder)
    assert str(folder) in str(exc.value) and "\n" not in str(exc.value)


def test_a_baseline_run_folder_given_as_evaluator_is_named_as_one(tmp_path):
    from hoibench.evaluator.backends import load_evaluator, peek_card
    run = tmp_path / "run"
    run.mkdir()
    (run / "card.json").write_text(json.dumps({"baseline": "chainhoi", "checkpoint_id": "0" * 64,
                                               "dataset": {"representation": "hoi269-clean-1.0"}}))
    assert peek_card(run) == {}
    with pytest.raises(ValueError) as exc:
        load_evaluator(run)
    msg = str(exc.value)
    assert "baseline run folder" in msg and "chainhoi" in msg and "evaluator_id" in msg and "\n" not in msg


@pytest.mark.parametrize("content,needle", [
    (b"<!DOCTYPE html>\n<html><head><title>Sign in</title></head><body>...</body></html>", "HTML page"),
    (b"\n  <html lang='en'>" + b"x" * 5000, "HTML page"),
    (b"Not Found\n", "text file")])
def test_a_web_page_saved_as_a_checkpoint_is_named_as_one(tmp_path, content, needle):
    from hoibench.evaluator.errors import EvaluatorError
    from hoibench.evaluator.published_t2m import read_checkpoint
    from hoibench.evaluator.safe_checkpoint import CheckpointReadError, load_checkpoint
    path = tmp_path / "finest.tar"
    path.write_bytes(content)
    for read, error in ((load_checkpoint, CheckpointReadError), (read_checkpoint, EvaluatorError)):
        with pytest.raises(error) as exc:
            read(path)
        msg = str(exc.value)
        assert f"not a PyTorch checkpoint (looks like an {needle}" in msg or f"(looks like a {needle}" in msg, msg
        assert str(path) in msg and "\n" not in msg
