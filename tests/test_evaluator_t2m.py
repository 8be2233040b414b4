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
    root = tmp_path_factory.mktemp("t2m")
    files = write_fixture(root / "release")
    eid = import_t2m(root / "ev", files["checkpoint"], files["glove"], files["meta"], dims=DIMS)
    return root, files, eid


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
