"""The InterAct test fixture's tokenizer reads its vocabulary: the reference text embeddings
(``tests/data/interact_evaluator_reference.npz``) then exercise real word ids, not [UNK]."""
from __future__ import annotations

import pytest

from interact_fixture import CAPTIONS, VOCAB, write_interact_files


def test_fixture_tokenizer_gives_each_vocabulary_word_its_own_id(tmp_path):
    transformers = pytest.importorskip("transformers")
    files = write_interact_files(tmp_path)
    tok = transformers.AutoTokenizer.from_pretrained(str(files["distilbert"]))
    words = [w for w in VOCAB if not w.startswith("[")]
    ids = tok(" ".join(words), add_special_tokens=False)["input_ids"]
    assert ids == [VOCAB.index(w) for w in words]                # the vocab.txt line numbers
    for caption in CAPTIONS:                                     # every caption word is in VOCAB
        row = tok(caption)["input_ids"]
        assert tok.unk_token_id not in row and row[0] == VOCAB.index("[CLS]") and row[-1] == VOCAB.index("[SEP]")
    assert tok("a zebra")["input_ids"][1:-1] == [VOCAB.index("a"), VOCAB.index("[UNK]")]   # out of vocabulary
