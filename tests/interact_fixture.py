"""Files of InterAct's evaluator in their real containers, with random weights (test fixture).

``write_interact_files(root)`` writes, deterministically (fixed seeds, CPU torch):

* ``distilbert/``: a tiny DistilBERT folder (``config.json``: dim 32, 2 layers, 2 heads,
  hidden 64, 64 positions; ``vocab.txt`` of :data:`VOCAB`; tokenizer files as
  ``DistilBertTokenizer.from_pretrained(folder).save_pretrained(folder)`` writes them, so
  every word of :data:`VOCAB` is its own token), the layout of a local
  ``distilbert-base-uncased`` download;
* ``markersbps.ckpt``: a Lightning-style checkpoint ``{"state_dict": ..., "epoch": ...}``
  saved with ``torch.save``: ``textencoder.text_model.*`` (the DistilBERT's own state dict),
  ``textencoder.projection.1.*``, ``{text,motion}encoder.{mu,logvar}_token``,
  ``*.sequence_pos_encoding.pe`` (5000, 1, 256) sinusoids, ``*.seqTransEncoder.layers.<i>.*``
  (4 post-norm layers, d 256, ff 1024), ``motionencoder.skel_embedding.*`` (615 -> 256) and an
  unrelated ``motiondecoder.*`` tensor; every parameter is random (seeded);
* ``mean.npy`` / ``std.npy`` (615,) float64 and ``bps_basis.npy`` (128, 3) float64;

and ``clip_inputs()`` gives the motion inputs (markers, object points, rotations as
matrices and InterAct's 6D rows, translations) of three short clips plus three captions.
The same functions built the inputs of the reference run recorded in
``tests/data/interact_evaluator_reference.npz`` (see tests/data/README.md).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

VOCAB = ["[PAD]", "[UNK]", "[CLS]", "[SEP]", "[MASK]", "a", "person", "lifts", "the", "box", "and", "puts",
         "it", "down", "sits", "on", "chair", "kicks", "ball", "with", "right", "foot", "walks", "carrying",
         "small", "table", ".", ","]
CAPTIONS = ["a person lifts the box and puts it down.",
            "a person sits on the chair",
            "a person kicks the ball with the right foot, and walks carrying a small table."]
LENGTHS = (12, 7, 9)
N_POINTS = 40


def sinusoid_table(max_len: int, dim: int) -> np.ndarray:
    """(max_len, 1, dim) float32: sin at even, cos at odd channels, frequency 10000^(-2i/dim)."""
    pos = np.arange(max_len, dtype=np.float64)[:, None]
    freq = np.exp(np.arange(0, dim, 2, dtype=np.float64) * (-math.log(10000.0) / dim))
    pe = np.zeros((max_len, dim))
    pe[:, 0::2] = np.sin(pos * freq)
    pe[:, 1::2] = np.cos(pos * freq)
    return pe[:, None, :].astype(np.float32)


def _transformer_state(prefix: str, gen) -> dict:
    import torch
    from torch import nn
    layer = nn.TransformerEncoderLayer(d_model=256, nhead=4, dim_feedforward=1024, activation="gelu")
    enc = nn.TransformerEncoder(layer, num_layers=4, enable_nested_tensor=False)
    out = {}
    for k, v in enc.state_dict().items():
        noise = torch.randn(v.shape, generator=gen) * (0.1 if v.ndim == 1 else 0.05)
        out[prefix + "seqTransEncoder." + k] = (v + noise) if "norm" not in k else (1.0 + noise if k.endswith(
            "weight") else noise)
    return out


def write_interact_files(root: Path) -> dict[str, Path]:
    """Write the fixture files under ``root``; return their paths by importer option."""
    import torch
    from transformers import DistilBertConfig, DistilBertModel, DistilBertTokenizer
    root = Path(root)
    bert = root / "distilbert"
    bert.mkdir(parents=True, exist_ok=True)
    (bert / "vocab.txt").write_text("\n".join(VOCAB) + "\n")
    # read the vocabulary from the folder, as a hub download is read: transformers 5 ignores
    # ``DistilBertTokenizer(vocab_file=...)``, whose tokenizer knows only the special tokens
    # (every word [UNK])
    DistilBertTokenizer.from_pretrained(str(bert), do_lower_case=True).save_pretrained(str(bert))
    cfg = DistilBertConfig(vocab_size=len(VOCAB), dim=32, n_layers=2, n_heads=2, hidden_dim=64,
                           max_position_embeddings=64)
    cfg.save_pretrained(str(bert))
    torch.manual_seed(0)
    text_model = DistilBertModel(cfg)
    gen = torch.Generator().manual_seed(1)
    sd = {}
    for k, v in text_model.state_dict().items():
        if v.dtype.is_floating_point:
            v = v + torch.randn(v.shape, generator=gen) * 0.05
        sd["textencoder.text_model." + k] = v
    pe = torch.from_numpy(sinusoid_table(5000, 256))
    for p in ("textencoder.", "motionencoder."):
        sd[p + "mu_token"] = torch.randn(256, generator=gen)
        sd[p + "logvar_token"] = torch.randn(256, generator=gen)
        sd[p + "sequence_pos_encoding.pe"] = pe.clone()
        sd.update(_transformer_state(p, gen))
    sd["textencoder.projection.1.weight"] = torch.randn(256, 32, generator=gen) * 0.2
    sd["textencoder.projection.1.bias"] = torch.randn(256, generator=gen) * 0.1
    sd["motionencoder.skel_embedding.weight"] = torch.randn(256, 615, generator=gen) * 0.05
    sd["motionencoder.skel_embedding.bias"] = torch.randn(256, generator=gen) * 0.1
    sd["motiondecoder.final.weight"] = torch.randn(4, 4, generator=gen)
    ckpt = root / "markersbps.ckpt"
    torch.save({"state_dict": sd, "epoch": 2099, "global_step": 0}, ckpt)
    rng = np.random.default_rng(2)
    np.save(root / "mean.npy", rng.normal(0.0, 0.3, 615))
    np.save(root / "std.npy", rng.uniform(0.05, 0.6, 615))
    basis = rng.normal(size=(128, 3))
    basis *= (rng.uniform(0, 1, 128) ** (1 / 3) / np.linalg.norm(basis, axis=1))[:, None]
    np.save(root / "bps_basis.npy", basis)
    return {"checkpoint": ckpt, "distilbert": bert, "mean": root / "mean.npy", "std": root / "std.npy",
            "bps_basis": root / "bps_basis.npy"}


def _rotations(rng, n: int) -> np.ndarray:
    """(n, 3, 3) rotation matrices from random axis-angles (Rodrigues' formula)."""
    aa = rng.normal(0, 1.0, (n, 3))
    th = np.linalg.norm(aa, axis=1)[:, None, None]
    k = aa / np.linalg.norm(aa, axis=1, keepdims=True)
    K = np.zeros((n, 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    K = K - K.transpose(0, 2, 1)
    return np.eye(3)[None] + np.sin(th) * K + (1 - np.cos(th)) * (K @ K)


def clip_inputs() -> list[dict]:
    """Three clips: ``markers`` (T, 77, 3), ``points`` (40, 3), ``rot`` (T, 3, 3), ``rot6d``
    (T, 6) (the matrix's first two rows, InterAct's 6D layout), ``trans`` (T, 3); metres."""
    rng = np.random.default_rng(3)
    clips = []
    for T in LENGTHS:
        root = np.array([0.0, 0.9, 0.0]) + np.cumsum(rng.normal(0, 0.02, (T, 3)), axis=0)
        markers = root[:, None, :] + rng.normal(0, 0.35, (1, 77, 3)) + rng.normal(0, 0.01, (T, 77, 3))
        rot = _rotations(rng, T)
        trans = root + np.array([0.4, -0.3, 0.2]) + rng.normal(0, 0.02, (T, 3))
        clips.append({"markers": markers.astype(np.float32), "points": rng.normal(0, 0.25, (N_POINTS, 3)).astype(
            np.float32), "rot": rot.astype(np.float32), "rot6d": rot[:, :2, :].reshape(T, 6).astype(np.float32),
            "trans": trans.astype(np.float32)})
    return clips


def prepare_interact_store(raw: Path, data: Path, sequences: int = 12, seed: int = 0, fps: float = 30.0) -> Path:
    """A synthetic InterAct-layout release of ``sequences`` sequences written to ``raw``,
    prepared into the store ``data`` at ``fps`` (SMPL-X proxy body models) with its texts:
    the store the InterAct tests score. Returns ``data``."""
    from hoibench.datasets import interact
    from hoibench.datasets.interact_layout import write_interact_layout
    from hoibench.datasets.store import PrepareConfig, prepare
    write_interact_layout(raw, sequences, seed=seed)
    cfg = PrepareConfig("interact", fps=fps, body_model_type="smplx")
    manifest = prepare(interact.prepare_jobs(raw, raw / "body_models", data, cfg), data, cfg)
    interact.write_texts(data, manifest)
    return data
