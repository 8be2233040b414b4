"""``hoibench evaluator import chois``: CHOIS's text-motion evaluator (t2m architecture on
joints24) from random weights saved in CHOIS's checkpoint layout.

Layout and input rules: GitHub lijiaman/chois_release (commit 9cd4cf6):
``t2m_eval/networks/evaluator_wrapper.py`` (``build_models`` loads
``<checkpoints>/<dataset>/text_motion_features/model/finest.tar`` with keys
``movement_encoder``, ``text_encoder``, ``motion_encoder``, ``epoch``; ``dim_pose = 24 * 3``,
``max_motion_length = 120``, ``max_text_len = 30``; ``get_co_embeddings`` feeds the whole
72 columns), ``t2m_eval/networks/modules.py`` (``MovementConvEncoder(input_size=dim_pose)``),
``t2m_eval/motion_loaders/chois_eval_dataset.py`` (``(x - mean) / std`` on (T, 72), no crop)
and ``t2m_eval/data/omomo_dataset.py`` (zero rows after normalisation up to 120). The
reference below rebuilds those modules with plain torch layers (not hoibench's classes) and
applies those rules by hand.
"""
from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest
import torch
from torch import nn
from torch.nn.utils.rnn import pack_padded_sequence

from t2m_release import import_release

from hoibench.evaluator.published_t2m import T2MDims, expected_shapes

DIMS = T2MDims(pose=72, movement_hidden=16, movement_latent=12, motion_hidden=20, text_hidden=10, output=8)
WORDS = ["sos", "eos", "unk", "a", "person", "lift", "the", "box", "and", "put", "it", "down", "on", "floor",
         "push", "chair", "with", "left", "hand", "walk", "forward"]


def _tensors(seed: int = 0) -> dict[str, dict[str, torch.Tensor]]:
    rs = np.random.RandomState(seed)
    return {part: {k: torch.from_numpy((rs.standard_normal(s[k]) * 0.3).astype(np.float32)) for k in sorted(s)}
            for part, s in expected_shapes(DIMS, 0).items()}


def write_release(root: Path) -> dict[str, Path]:
    """finest.tar, glove_840B/ and meta/ (mean.npy, std.npy of 72) as CHOIS's files are laid out."""
    parts = _tensors()
    ckpt = root / "checkpoints/omomo/text_motion_features/model/finest.tar"
    ckpt.parent.mkdir(parents=True)
    torch.save({**parts, "opt_motion_encoder": {"state": {}, "param_groups": []}, "epoch": 120, "iter": 9000}, ckpt)
    rs = np.random.RandomState(1)
    glove = root / "glove_840B"
    glove.mkdir()
    np.save(glove / "our_vab_data.npy", rs.standard_normal((len(WORDS), 300)).astype(np.float32))
    (glove / "our_vab_words.pkl").write_bytes(pickle.dumps(WORDS, protocol=2))
    (glove / "our_vab_idx.pkl").write_bytes(pickle.dumps({w: i for i, w in enumerate(WORDS)}, protocol=2))
    meta = root / "meta"
    meta.mkdir()
    np.save(meta / "mean.npy", rs.standard_normal(72) * 0.3)
    np.save(meta / "std.npy", rs.uniform(0.2, 0.9, 72))
    return {"checkpoint": ckpt, "glove": glove, "meta": meta}


@pytest.fixture(scope="module")
def release(tmp_path_factory):
    from hoibench.evaluator.chois_t2m import import_chois
    return import_release(tmp_path_factory, "chois", write_release, import_chois, DIMS)


def _reference_motion(files, clips) -> np.ndarray:
    """CHOIS's path by hand: (T, 72) rows normalised, zero rows to 120 after normalisation,
    movement convs on all 72 columns, steps = T // 4, GRU packed longest first, input order back."""
    p = _tensors()
    conv = nn.Sequential(nn.Conv1d(72, 16, 4, 2, 1), nn.Dropout(0.2), nn.LeakyReLU(0.2), nn.Conv1d(16, 12, 4, 2, 1),
                         nn.Dropout(0.2), nn.LeakyReLU(0.2))
    conv.load_state_dict({k[5:]: v for k, v in p["movement_encoder"].items() if k.startswith("main.")})
    out_net = nn.Linear(12, 12)
    out_net.load_state_dict({k[8:]: v for k, v in p["movement_encoder"].items() if k.startswith("out_net.")})
    me = p["motion_encoder"]
    emb, gru = nn.Linear(12, 20), nn.GRU(20, 20, batch_first=True, bidirectional=True)
    head = nn.Sequential(nn.Linear(40, 20), nn.LayerNorm(20), nn.LeakyReLU(0.2), nn.Linear(20, 8))
    emb.load_state_dict({k[10:]: v for k, v in me.items() if k.startswith("input_emb.")})
    gru.load_state_dict({k[4:]: v for k, v in me.items() if k.startswith("gru.")})
    head.load_state_dict({k[11:]: v for k, v in me.items() if k.startswith("output_net.")})
    for m in (conv, out_net, emb, gru, head):
        m.eval()
    mean, std = np.load(files["meta"] / "mean.npy"), np.load(files["meta"] / "std.npy")
    rows, lens = [], []
    for c in clips:
        x = ((c.reshape(len(c), 72)[:120] - mean) / std).astype(np.float32)
        rows.append(np.concatenate([x, np.zeros((120 - len(x), 72), np.float32)]))
        lens.append(len(x))
    order = np.argsort(lens)[::-1].copy()
    x = torch.from_numpy(np.stack(rows)[order])
    with torch.no_grad():
        mov = out_net(conv(x.transpose(1, 2)).transpose(1, 2))
        steps = torch.tensor(np.asarray(lens)[order] // 4)
        _, last = gru(pack_padded_sequence(emb(mov), steps, batch_first=True),
                      me["hidden"].repeat(1, len(clips), 1))
        e = head(torch.cat([last[0], last[1]], dim=-1)).numpy()
    out = np.zeros_like(e)
    out[order] = e
    return out


def test_import_layout_card_and_embeddings_follow_chois(release):
    from hoibench.evaluator.backends import load_evaluator
    root, files, eid = release
    ev = load_evaluator(root / "ev", kind="contrastive")
    assert ev.id == eid and type(ev).__name__ == "ChoisEvaluator"
    card = ev.card
    assert card["backend"] == "chois" and card["dims"]["pose"] == 72 and card["max_frames"] == 120
    assert card["max_tokens"] == 30 and card["dataset"]["features"] == "joints24" and card["fps"] == 30
    assert card["sources"]["checkpoint"]["epoch"] == 120
    rs = np.random.RandomState(3)
    clips = [rs.standard_normal((n, 24, 3)).astype(np.float32) for n in (120, 97, 150, 64)]
    got = ev.embed_motion(clips)
    np.testing.assert_allclose(got, _reference_motion(files, clips), atol=1e-5)
    # (T, 72) rows are the same input; frames past 120 are never read; 97 frames are not cropped to 96
    np.testing.assert_array_equal(ev.embed_motion([c.reshape(len(c), 72) for c in clips]), got)
    np.testing.assert_allclose(ev.embed_motion([clips[2][:120]]), got[2:3], atol=1e-6)
    assert not np.allclose(ev.embed_motion([clips[1][:96]]), got[1:2])
    with pytest.raises(ValueError, match=r"features\[0\]: expected joints24 positions"):
        ev.embed_motion([np.zeros((120, 66), np.float32)])


def test_captions_keep_thirty_tokens(release):
    """max_text_len = 30 (chois_eval_dataset.py): the 25th token still changes the embedding,
    which the t2m backend's 20-token crop would drop."""
    from hoibench.evaluator.chois_t2m import load_chois
    root, _, _ = release
    ev = load_chois(root / "ev")
    base = "a/DET person/NOUN lift/VERB the/DET box/NOUN and/CCONJ put/VERB it/PRON down/ADP on/ADP the/DET " \
           "floor/NOUN and/CCONJ push/VERB the/DET chair/NOUN with/ADP the/DET left/ADJ hand/NOUN and/CCONJ " \
           "walk/VERB forward/ADV".split()
    assert len(base) == 23
    a = ev.embed_text(["x", "y"], tokens=[base + ["box/NOUN"], base + ["chair/NOUN"]])
    assert not np.allclose(a[0], a[1])
    words, onehot, n = ev.vocab.encode(base + ["box/NOUN"] * 10, max_tokens=30)
    assert n == 32 and words.shape == (32, 300) and onehot.shape == (32, 15)


def test_cli_import_and_refusals(release, tmp_path, capsys):
    from hoibench import cli
    from hoibench.evaluator.backends import backend_of
    root, files, eid = release
    # the published sizes: random weights of the small fixture are refused with the key and shapes
    rc = cli.main(["evaluator", "import", "chois", "--checkpoint", str(files["checkpoint"]), "--glove",
                   str(files["glove"]), "--meta", str(files["meta"]), "--out", str(tmp_path / "ev")])
    err = capsys.readouterr().err
    assert rc != 0 and "movement_encoder.main.0.weight has shape (16, 72, 4), expected (512, 72, 4)" in err
    assert backend_of(root / "ev").name == "chois"
    assert cli.main(["evaluator", "show", str(root / "ev")]) == 0
    assert eid[:12] in capsys.readouterr().out


def test_published_sizes_read_seventy_two_columns():
    from hoibench.evaluator.chois_t2m import DEFAULT_DIMS
    shapes = expected_shapes(DEFAULT_DIMS, 0)
    assert shapes["movement_encoder"]["main.0.weight"] == (512, 72, 4)
    assert shapes["motion_encoder"]["input_emb.weight"] == (1024, 512)
    assert shapes["text_encoder"]["pos_emb.weight"] == (300, 15)
