"""The ``chainhoi`` evaluator backend: ChainHOI's published MotionCLIP evaluator.

Fixtures are written in the real file layouts, with random weights at tiny sizes (no
download, no licensed data): a Lightning checkpoint (``state_dict`` under ``motion_clip.``,
plus the ``epoch``/``global_step``/``hyper_parameters`` entries Lightning writes, one of
them a ``functools.partial`` as the lightning-hydra template stores optimisers), a RoBERTa
folder (``config.json`` of a 1-layer, 768-wide RoBERTa -- 768 because ChainHOI's class
fixes ``text_dim = 768`` -- with a byte-level BPE ``vocab.json``/``merges.txt`` built
here) and ``Mean_local.npy``/``Std_local.npy`` (269 entries, as ChainHOI's) in a folder
named ``behave_t2m``. Every random value comes from ``numpy.random.default_rng`` so the
same fixture can be rebuilt anywhere.

Reference values (``tests/data/chainhoi_evaluator_reference.npz``, README there): ChainHOI's
own evaluator code run outside the project on this fixture (repository
``Huanggh531/ChainHOI``, commit ``4990160``, ``src/models/evaluator/MotionCLIP/
{evaluator,motion_clip}.py`` unmodified; ``MotionCLIPEvaluator`` with ``MotionCLIP``
bound to ``model_dim=32, num_layers=2`` and the tokenizer/model paths pointed at the
fixture folder; motions normalised as ``hoidataset.py`` does, ``(motion[:199] - mean) /
std`` over all 269 columns then ``[..., :263]``, length floored to a multiple of 4
("single" crop), zero-padded as ``collate_tensors`` does), torch 2.13.0 CPU,
transformers 5.24.0.
"""
from __future__ import annotations

import functools
import json
import shutil
from collections import OrderedDict
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("transformers")

from hoibench.evaluator.backends import backend_of, import_evaluator, load_evaluator, peek_card  # noqa: E402
from hoibench.evaluator.card import store_mismatches  # noqa: E402

REF = Path(__file__).parent / "data" / "chainhoi_evaluator_reference.npz"
WIDTH, LAYERS = 32, 2
#: merges of the tiny BPE vocabulary (after the 256 byte symbols)
MERGES = [("Ġ", "a"), ("Ġ", "p"), ("e", "r"), ("Ġp", "er"), ("o", "n"), ("Ġ", "t"), ("h", "e"), ("Ġt", "he"),
          ("Ġ", "b"), ("o", "x"), ("Ġb", "ox"), ("Ġ", "s"), ("i", "t"), ("Ġs", "it"), ("Ġ", "c"), ("a", "i")]
CAPTIONS = ["a person picks up the box", "someone sits on the chair and then stands up again",
            "the person lifts the box over the head, turns around, walks forward, puts it down on the table, "
            "and sits on the chair while waving both arms"]


def _bytes_to_unicode() -> list[str]:
    """GPT-2's byte -> printable character table (the byte-level BPE alphabet)."""
    bs = list(range(ord("!"), ord("~") + 1)) + list(range(ord("¡"), ord("¬") + 1)) + list(range(ord("®"), ord("ÿ") + 1))
    cs, n = bs[:], 0
    for b in range(256):
        if b not in bs:
            bs.append(b)
            cs.append(256 + n)
            n += 1
    return [chr(c) for _, c in sorted(zip(bs, cs))]


def write_roberta_folder(folder: Path) -> Path:
    """config.json of a tiny 768-wide RoBERTa + a byte-level BPE tokenizer (vocab.json, merges.txt)."""
    from transformers import RobertaConfig
    folder.mkdir(parents=True, exist_ok=True)
    vocab = {"<s>": 0, "<pad>": 1, "</s>": 2, "<unk>": 3}
    for ch in _bytes_to_unicode():
        vocab[ch] = len(vocab)
    for a, b in MERGES:
        vocab.setdefault(a + b, len(vocab))
    vocab["<mask>"] = len(vocab)
    (folder / "vocab.json").write_text(json.dumps(vocab))
    (folder / "merges.txt").write_text("#version: 0.2\n" + "".join(f"{a} {b}\n" for a, b in MERGES))
    RobertaConfig(vocab_size=len(vocab), hidden_size=768, num_hidden_layers=1, num_attention_heads=12,
                  intermediate_size=64, max_position_embeddings=40, type_vocab_size=1, pad_token_id=1,
                  bos_token_id=0, eos_token_id=2).save_pretrained(folder)
    return folder


def _random(shape, name: str, rng) -> np.ndarray:
    """A float32 draw for parameter ``name``: LayerNorm gains near 1, biases small, matrices
    scaled by their fan-in."""
    if name.endswith("bias"):
        return (0.02 * rng.standard_normal(shape)).astype(np.float32)
    if len(shape) == 1 and ("norm" in name.lower() or "ln_" in name):
        return (1 + 0.1 * rng.standard_normal(shape)).astype(np.float32)
    fan = int(np.prod(shape[1:])) if len(shape) > 1 else shape[0]
    return (rng.standard_normal(shape) / np.sqrt(fan)).astype(np.float32)


def lightning_state_dict(roberta: Path, width: int = WIDTH, layers: int = LAYERS, seed: int = 0) -> OrderedDict:
    """ChainHOI's evaluator state dict (``motion_clip.`` keys) with seeded random values."""
    from transformers import AutoConfig

    from hoibench.evaluator.published_chainhoi import _roberta_shapes, expected_shapes
    arch = {"width": width, "layers": layers, "ff": 4 * width, "max_positions": 256, "output_dim": 512,
            "text_dim": 768}
    shapes = expected_shapes(arch, _roberta_shapes(AutoConfig.from_pretrained(str(roberta))))
    rng = np.random.default_rng(seed)
    sd = OrderedDict()
    for k in sorted(shapes):
        if k == "logit_scale":
            sd["motion_clip." + k] = torch.tensor(float(np.log(1 / 0.07)))
        else:
            sd["motion_clip." + k] = torch.from_numpy(_random(shapes[k], k, rng))
    return sd


def write_checkpoint(path: Path, sd: OrderedDict, extras: bool = True) -> Path:
    """A Lightning-style checkpoint around ``sd``."""
    ckpt = {"epoch": 24, "global_step": 325, "pytorch-lightning_version": "2.1.0", "state_dict": sd,
            "loops": {}, "callbacks": {}, "optimizer_states": [], "lr_schedulers": []}
    if extras:
        ckpt["hyper_parameters"] = {"optimizer": functools.partial(torch.optim.AdamW, lr=1e-4), "dropout": 0.3}
    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save(ckpt, path)
    return path


def write_stats(folder: Path, seed: int = 1, dims: int = 269) -> Path:
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True, exist_ok=True)
    np.save(folder / "Mean_local.npy", (0.5 * rng.standard_normal(dims)).astype(np.float32))
    np.save(folder / "Std_local.npy", rng.uniform(0.5, 1.5, dims).astype(np.float32))
    return folder


def motions(seed: int = 2) -> list[np.ndarray]:
    """Raw hoi269 rows of four clips: 40, 24 and 8 frames, and 210 (cropped to 196)."""
    rng = np.random.default_rng(seed)
    return [rng.standard_normal((t, 269)).astype(np.float32) for t in (40, 24, 8, 210)]


def build(root: Path, extras: bool = True) -> dict:
    """Every input file of an import under ``root``."""
    roberta = write_roberta_folder(root / "roberta-base")
    sd = lightning_state_dict(roberta)
    return {"checkpoint": write_checkpoint(root / "checkpoint" / "behave_t2m" / "epoch=24-step=325.ckpt", sd, extras),
            "text_model": roberta, "stats": write_stats(root / "dataset" / "behave_t2m"), "state_dict": sd}
