"""The ``interact`` evaluator backend: InterAct's published text-to-interaction evaluator.

An ``interact`` folder (written by ``hoibench evaluator import interact``, see
:mod:`hoibench.evaluator.interact_import`)::

    EV/weights.safetensors   textencoder.* (with the DistilBERT text_model.*), motionencoder.*,
                             normalization.mean / normalization.std (615,), bps.basis (128, 3)
    EV/tokenizer/            the DistilBERT tokenizer files (vocab.txt, tokenizer_config.json, ...)
    EV/card.json             "backend": "interact", the DistilBERT config, the tokenizer files'
                             sha256, the source files' sha256, sizes, evaluator_id

The evaluator id is ``sha256(weights || canonical card)`` as for every evaluator folder; the
tokenizer files are covered through their hashes in the card.

:class:`InteractEvaluator` has the evaluator interface: ``id``, ``card``,
``embed_motion(rows, lengths) -> (N, 256)`` of *raw* 615-column rows
(:func:`hoibench.evaluator.interact_features.interact_rows`: markers + BPS deltas), normalised
here as ``(row - mean) / std``, and ``embed_text(captions) -> (N, 256)``. Embeddings are the
``.loc`` (mean) outputs, not L2-normalised (InterAct's metrics use them as they are).
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np
import torch

from ..core.io import read_regular_file
from .card import WEIGHTS, CARD, FORMAT, check_safetensors, compute_id, changed_parts
from .embed import EMBED_THREADS, as_clip_list, deterministic, embed_captions
from .errors import CorruptEvaluatorFile, EvaluatorIntegrityError
from .interact_features import ROW_WIDTH, clip_rows
from .interact_model import MotionEncoder, TextEncoder

BACKEND = "interact"
TOKENIZER_DIR = "tokenizer"
REPRESENTATION = "interact-markers-bps"
MAX_CARD_BYTES = 16 << 20
MAX_WEIGHTS_BYTES = 4 << 30


def build_text_encoder(config: dict, pos_len: int) -> TextEncoder:
    """A :class:`TextEncoder` around a DistilBERT built from ``config`` (``config.json`` dict)."""
    from transformers import DistilBertConfig, DistilBertModel
    cfg = DistilBertConfig(**{k: v for k, v in config.items() if k not in ("architectures", "transformers_version")})
    return TextEncoder(DistilBertModel(cfg), int(cfg.dim), max_len=pos_len)


def build_motion_encoder(pos_len: int) -> MotionEncoder:
    return MotionEncoder(ROW_WIDTH, max_len=pos_len)


def _verify(folder: Path) -> tuple[dict, bytes]:
    """(card, weights bytes) of an interact folder whose id and tokenizer hashes check out."""
    from ..core.io import load_json_bytes, read_regular_file
    from .card import _sha256
    try:
        card = load_json_bytes(read_regular_file(folder / CARD, MAX_CARD_BYTES, "evaluator card"), folder / CARD)
        data = read_regular_file(folder / WEIGHTS, MAX_WEIGHTS_BYTES, "evaluator weights")
    except (ValueError, OSError) as exc:
        raise CorruptEvaluatorFile(str(exc).splitlines()[0] if str(exc) else f"{folder}: unreadable") from None
    if not isinstance(card, dict) or card.get("backend") != BACKEND or card.get("format") != FORMAT:
        raise EvaluatorIntegrityError(f"{folder / CARD}: not an interact evaluator card (backend/format fields)")
    check_safetensors(data, folder / WEIGHTS)
    if compute_id(data, card) != card.get("evaluator_id"):
        parts = changed_parts(card, data, WEIGHTS, CARD) or [f"{CARD} field evaluator_id or integrity was modified"]
        raise EvaluatorIntegrityError(f"{folder}: evaluator id mismatch: {'; '.join(parts)} after import; "
                                      f"import the evaluator again")
    files = card.get("text_model", {}).get("tokenizer_files", {})
    if not isinstance(files, dict) or not files:
        raise EvaluatorIntegrityError(f"{folder / CARD}: field text_model.tokenizer_files is missing")
    for name, digest in sorted(files.items()):
        path = folder / TOKENIZER_DIR / name
        if not path.is_file():
            raise EvaluatorIntegrityError(f"{path}: missing (the tokenizer files are part of the evaluator)")
        if _sha256(read_regular_file(path, 64 << 20, "tokenizer file")) != digest:
            raise EvaluatorIntegrityError(f"{path}: sha256 differs from card field text_model.tokenizer_files.{name}")
    return card, data


class InteractEvaluator:
    """InterAct's evaluator, loaded from an ``interact`` folder (:func:`load_interact`)."""

    def __init__(self, card: dict, text: TextEncoder, motion: MotionEncoder, tokenizer, mean: np.ndarray,
                 std: np.ndarray, basis: np.ndarray, threads: int | None = None, device: str = "cpu"):
        self.card = card
        self.device = torch.device(device)
        self.text = text.to(self.device).eval()
        self.motion = motion.to(self.device).eval()
        self.tokenizer = tokenizer
        self.mean = np.asarray(mean, np.float32)
        self.std = np.asarray(std, np.float32)
        self.basis = np.asarray(basis, np.float64)
        self.threads = EMBED_THREADS if threads is None else threads

    @property
    def id(self) -> str | None:
        return self.card.get("evaluator_id")

    @property
    def representation(self) -> str:
        return REPRESENTATION

    @property
    def variant(self) -> str:
        """What its motion branch reads (recorded in results)."""
        return "interact"

    @property
    def embed_dim(self) -> int:
        return int(self.motion.mu_token.shape[0])

    def embed_motion(self, features, lengths=None, batch_size: int = 64) -> np.ndarray:
        """(N, 256) float32 ``.loc`` embeddings of raw (T, 615) rows (padded (N, T, 615) with
        ``lengths``, or a list)."""
        clips = as_clip_list(features, lengths)
        for i, c in enumerate(clips):
            if c.shape[1] != ROW_WIDTH:
                raise ValueError(f"interact evaluator: features[{i}] has {c.shape[1]} columns, expected {ROW_WIDTH} "
                                 f"(77 markers x 3 + 128 BPS deltas x 3)")
        out = np.zeros((len(clips), self.embed_dim), np.float32)
        with deterministic(self.threads), torch.inference_mode():
            for s in range(0, len(clips), batch_size):
                chunk = clips[s:s + batch_size]
                T = max(len(c) for c in chunk)
                x = np.zeros((len(chunk), T, ROW_WIDTH), np.float32)
                for i, c in enumerate(chunk):
                    x[i, :len(c)] = (np.asarray(c, np.float32) - self.mean) / self.std
                lens = torch.tensor([len(c) for c in chunk], device=self.device)
                out[s:s + len(chunk)] = self.motion(torch.from_numpy(x).to(self.device), lens).cpu().numpy()
        return out

    def embed(self, features, lengths=None, batch_size: int = 64) -> np.ndarray:
        return self.embed_motion(features, lengths, batch_size)

    # ------------------------------------------------------------------ rows for scoring
    _CLIP_KEYS = ("markers", "obj_rot", "obj_trans", "object_sample_points", "object_origin")

    def store_rows(self, store, clip_id: str) -> np.ndarray:
        """(T, 615) rows of a stored clip (what ``hoibench prepare interact`` stores)."""
        try:
            return clip_rows(store.load(clip_id, keys=self._CLIP_KEYS), self.basis)
        except ValueError as exc:
            raise ValueError(f"{store.root}: clip {clip_id}: {exc}; prepare the store with "
                             f"`hoibench prepare interact`") from None

    def sample_rows(self, arrays: dict, k: int, store, clip_id: str) -> np.ndarray:
        """(T, 615) rows of sample ``k`` of a submission file (``markers``, ``obj_rot`` or
        ``obj_rotvec``, ``obj_trans``), with the ground-truth clip's object points and origin."""
        gt = store.load(clip_id, keys=("object_sample_points", "object_origin"))
        sample = {key: v for key, v in arrays.items() if key in ("markers", "obj_rot", "obj_rotvec", "obj_trans")}
        try:
            return clip_rows({**sample, **gt}, self.basis, k)
        except ValueError as exc:
            raise ValueError(f"{clip_id}: {exc}") from None

    def embed_text(self, texts: Sequence[str], tokens=None, batch_size: int = 128) -> np.ndarray:
        """(N, 256) float32 ``.loc`` embeddings of captions (``tokens`` is not used: the
        DistilBERT tokenizer reads the caption itself; no truncation, as in InterAct)."""
        return embed_captions(texts, self.embed_dim, self.threads, batch_size, self._encode_captions)

    def _encode_captions(self, chunk: list[str]) -> torch.Tensor:
        enc = self.tokenizer(chunk, return_tensors="pt", padding=True)
        return self.text(enc["input_ids"].to(self.device), enc["attention_mask"].to(self.device))


def split_state(tensors: dict) -> tuple[dict, dict, dict]:
    """(text state, motion state, other tensors) of a folder's tensors."""
    text = {k[len("textencoder."):]: v for k, v in tensors.items() if k.startswith("textencoder.")}
    motion = {k[len("motionencoder."):]: v for k, v in tensors.items() if k.startswith("motionencoder.")}
    rest = {k: v for k, v in tensors.items() if not k.startswith(("textencoder.", "motionencoder."))}
    return text, motion, rest


def show_interact(folder: str | Path) -> tuple[str, dict]:
    """(summary, card) of a verified ``interact`` folder, for ``hoibench evaluator show``."""
    folder = Path(folder)
    card, _ = _verify(folder)
    src, m, tm = card.get("source", {}), card.get("motion", {}), card.get("text_model", {}).get("config", {})
    text = (f"interact evaluator {card['evaluator_id']} (verified)\n"
            f"  imported from {src.get('checkpoint')} (sha256 {str(src.get('checkpoint_sha256'))[:12]}...)\n"
            f"  motion: {m.get('nfeats')} inputs (77 markers + {m.get('bps_points')} BPS deltas), latent "
            f"{m.get('latent')}, {m.get('layers')} layers, embedding = {m.get('embedding')}\n"
            f"  text: DistilBERT dim {tm.get('dim')}, {tm.get('n_layers')} layers, vocabulary {tm.get('vocab_size')}\n"
            f"  scores: dataset {card.get('dataset', {}).get('name')} at {card.get('dataset', {}).get('fps')} fps")
    return text, card


def load_interact(folder: str | Path, *, threads: int | None = None, device: str = "cpu", **_ignored
                  ) -> InteractEvaluator:
    """Load and verify an ``interact`` evaluator folder (one-line errors naming the file)."""
    from safetensors.torch import load as load_tensors
    from transformers import AutoTokenizer
    folder = Path(folder)
    if not (folder / CARD).is_file():
        raise EvaluatorIntegrityError(f"{folder}: not an evaluator folder (no {CARD}); make one with "
                                      f"`hoibench evaluator import interact ...`")
    card, data = _verify(folder)
    tensors = load_tensors(data)
    text_sd, motion_sd, rest = split_state(tensors)
    pos = int(card["motion"]["pos_len"])
    text = build_text_encoder(card["text_model"]["config"], pos)
    motion = build_motion_encoder(pos)
    text.load_state_dict(text_sd, strict=True)
    motion.load_state_dict(motion_sd, strict=True)
    tok_class = card["text_model"].get("tokenizer_class")
    if isinstance(tok_class, str):
        from .text import load_tokenizer
        try:
            tokenizer = load_tokenizer(folder / TOKENIZER_DIR, tok_class)
        except ValueError as exc:
            raise EvaluatorIntegrityError(str(exc)) from None
    else:                  # folders imported before the class was recorded
        tokenizer = AutoTokenizer.from_pretrained(str(folder / TOKENIZER_DIR), local_files_only=True)
    return InteractEvaluator(card, text, motion, tokenizer, rest["normalization.mean"].numpy(),
                             rest["normalization.std"].numpy(), rest["bps.basis"].numpy(), threads=threads,
                             device=device)





__all__ = ["BACKEND", "REPRESENTATION", "InteractEvaluator", "load_interact", "show_interact", "build_text_encoder",
           "build_motion_encoder", "split_state"]
