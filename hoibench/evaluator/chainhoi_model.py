"""ChainHOI's MotionCLIP evaluator: the network and its embedding API.

The evaluator ChainHOI (Zeng et al., CVPR 2025) scores with, as its public code defines it
(``src/models/evaluator/MotionCLIP``; sizes in :data:`RELEASED_SIZES`):

* motion branch: rows normalised with the dataset's ``Mean_local``/``Std_local``
  (first 263 columns) -> ``Conv1d(263, d, kernel 1, no bias)`` per frame -> a learned
  class token before the frames -> ``+ pos_embedding[:T + 1]`` (learned, 256 positions)
  -> LayerNorm -> pre-LN Transformer encoder (``d`` wide, 8 heads, feed-forward ``4 d``,
  GELU; frames past the clip's length masked as keys) -> LayerNorm of the class token
  -> ``@ motion_proj`` (``d x 512``);
* text branch: RoBERTa tokens (padded and cut to 32) -> ``pooler_output`` (tanh of a
  dense layer on the first token) -> ``@ text_proj`` (``768 x 512``);
* both outputs divided by their Euclidean norm: cosine geometry, 512 wide.

:class:`ChainHOIEvaluator` wraps a loaded network with the interface the scorer uses
(``id``, ``card``, ``embed_motion``, ``embed_text``); build it with
:func:`hoibench.evaluator.published_chainhoi.load_chainhoi`.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
import torch
from torch import nn

from .embed import EMBED_THREADS, CardBacked, as_clip_list, deterministic, embed_captions

#: the human feature columns the motion branch reads (hml263)
MOTION_DIM = 263
#: RoBERTa tokens per caption (the evaluator pads and truncates to this length)
TEXT_MAX_TOKENS = 32
#: attention heads (fixed in both released classes; not visible in the weights' shapes)
HEADS = 8
#: frames embedded at most: the evaluation datamodule keeps ``motion[:199]`` and floors the
#: length to a multiple of 4 (``max_motion_length: 196`` in configs/data)
MAX_FRAMES = 196
#: (model width, layers) of the two released evaluators: ``MotionCLIP`` (BEHAVE) and
#: ``MotionCLIP2`` (OMOMO)
RELEASED_SIZES = {"behave": (384, 8), "omomo": (512, 6)}

__all__ = ["MOTION_DIM", "TEXT_MAX_TOKENS", "HEADS", "MAX_FRAMES", "RELEASED_SIZES", "MotionTransformer",
           "ChainHOINet", "ChainHOIEvaluator"]


def lengths_mask(lengths: torch.Tensor, width: int) -> torch.Tensor:
    """(B, width) bool: True on the first ``lengths[b]`` positions of row b."""
    return torch.arange(width, device=lengths.device)[None, :] < lengths[:, None]


class MotionTransformer(nn.Module):
    """Motion branch up to the class token's LayerNorm: (B, T, 263) normalised rows and
    lengths (B,) -> (B, d). ``T`` must equal ``max(lengths)`` (a batch padded to its longest
    clip) and ``T + 1 <= max_positions``."""

    def __init__(self, width: int, layers: int, heads: int = HEADS, ff: int | None = None,
                 max_positions: int = 256, motion_dim: int = MOTION_DIM, dropout: float = 0.0):
        super().__init__()
        self.conv = nn.Conv1d(motion_dim, width, kernel_size=1, stride=1, bias=False)
        self.class_token = nn.Parameter(torch.zeros(width))
        self.pos_embedding = nn.Parameter(torch.zeros(max_positions, width))
        self.ln_pre = nn.LayerNorm(width)
        layer = nn.TransformerEncoderLayer(width, heads, dim_feedforward=ff or 4 * width, dropout=dropout,
                                           activation="gelu", batch_first=True, norm_first=True)
        self.transformer = nn.TransformerEncoder(layer, num_layers=layers, enable_nested_tensor=False)
        self.ln_post = nn.LayerNorm(width)

    def forward(self, x: torch.Tensor, lengths: torch.Tensor) -> torch.Tensor:
        B, T, _ = x.shape
        keep = torch.cat([torch.ones(B, 1, dtype=torch.bool, device=x.device), lengths_mask(lengths, T)], dim=1)
        h = self.conv(x.transpose(1, 2)).transpose(1, 2)                       # (B, T, d)
        h = torch.cat([self.class_token.expand(B, 1, -1), h], dim=1)            # (B, T + 1, d)
        h = self.ln_pre(h + self.pos_embedding[:T + 1])
        h = self.transformer(h, src_key_padding_mask=~keep)
        return self.ln_post(h[:, 0])


class ChainHOINet(nn.Module):
    """Both branches and their projections; outputs are L2-normalised (x / ||x||)."""

    def __init__(self, motion: MotionTransformer, text_model: nn.Module, output_dim: int, text_dim: int):
        super().__init__()
        width = motion.ln_post.normalized_shape[0]
        self.motion_encoder = motion
        self.text_encoder = text_model
        self.motion_proj = nn.Parameter(torch.zeros(width, output_dim))
        self.text_proj = nn.Parameter(torch.zeros(text_dim, output_dim))

    @staticmethod
    def _unit(x: torch.Tensor) -> torch.Tensor:
        return x / x.norm(dim=1, keepdim=True)

    def motion(self, x: torch.Tensor, lengths: torch.Tensor) -> torch.Tensor:
        return self._unit(self.motion_encoder(x, lengths) @ self.motion_proj)

    def text(self, batch: dict) -> torch.Tensor:
        return self._unit((self.text_encoder(**batch)["pooler_output"] @ self.text_proj).float())


class ChainHOIEvaluator(CardBacked):
    """ChainHOI's evaluator with hoibench's embedding interface.

    ``embed_motion(features, lengths)``: raw hml263 rows (or hoi269 rows: their first 263
    columns), the first :data:`MAX_FRAMES` rows of each clip, normalised as
    ``(x - mean) / std`` in the statistics' own dtype (as the reference's numpy code does)
    and cast to float32; batches are zero-padded to their longest clip (padded frames are
    masked). ``embed_text(captions, tokens=None)``: RoBERTa on the captions (``tokens``, the
    HumanML3D word/POS lists other evaluators read, is accepted and ignored). Both return
    (N, 512) float32 arrays of unit rows, computed in eval mode with a fixed CPU thread count
    (:func:`hoibench.evaluator.embed.deterministic`)."""

    variant = "human"

    def __init__(self, net: ChainHOINet, tokenizer, mean: np.ndarray, std: np.ndarray, card: dict,
                 max_frames: int = MAX_FRAMES, text_max_tokens: int = TEXT_MAX_TOKENS,
                 threads: int | None = None, device: str | torch.device = "cpu"):
        self.device = torch.device(device)
        self.net = net.to(self.device).eval()
        self.tokenizer = tokenizer
        self.mean, self.std = mean, std
        self.card = card
        self.max_frames = int(max_frames)
        self.text_max_tokens = int(text_max_tokens)
        self.threads = EMBED_THREADS if threads is None else threads

    @property
    def embed_dim(self) -> int:
        return int(self.net.motion_proj.shape[1])

    def normalise(self, clip: np.ndarray) -> np.ndarray:
        """(T, D >= 263) raw rows -> (min(T, max_frames), 263) float32 normalised rows."""
        rows = np.asarray(clip)[:self.max_frames]
        if rows.ndim != 2 or rows.shape[1] < MOTION_DIM:
            raise ValueError(f"features: expected (T, >= {MOTION_DIM}) rows, got shape {rows.shape}")
        return ((rows[:, :MOTION_DIM].astype(np.float32) - self.mean) / self.std).astype(np.float32)

    def _batch(self, clips: Sequence[np.ndarray]) -> tuple[torch.Tensor, torch.Tensor]:
        rows = [self.normalise(c) for c in clips]
        lengths = np.array([len(r) for r in rows], np.int64)
        x = np.zeros((len(rows), int(lengths.max()), MOTION_DIM), np.float32)
        for i, r in enumerate(rows):
            x[i, :len(r)] = r
        return torch.from_numpy(x).to(self.device), torch.from_numpy(lengths).to(self.device)

    def embed_motion(self, features, lengths=None, batch_size: int = 64) -> np.ndarray:
        """(N, 512) float32 unit embeddings of raw feature rows (a padded (N, T, D) array
        with ``lengths``, or a list of (T_i, D) arrays)."""
        clips = as_clip_list(features, lengths)
        out = np.zeros((len(clips), self.embed_dim), np.float32)
        with deterministic(self.threads), torch.inference_mode():
            for s in range(0, len(clips), batch_size):
                x, lens = self._batch(clips[s:s + batch_size])
                out[s:s + len(lens)] = self.net.motion(x, lens).float().cpu().numpy()
        return out

    def embed(self, features, lengths=None, batch_size: int = 64) -> np.ndarray:
        return self.embed_motion(features, lengths, batch_size)

    def tokenize(self, texts: Sequence[str]) -> dict:
        b = self.tokenizer(list(texts), return_tensors="pt", padding="max_length", truncation=True,
                           max_length=self.text_max_tokens)
        return {k: v.to(self.device) for k, v in b.items()}

    def embed_text(self, texts: Sequence[str], tokens=None, batch_size: int = 128) -> np.ndarray:
        """(N, 512) float32 unit embeddings of captions (``tokens`` is ignored)."""
        return embed_captions(texts, self.embed_dim, self.threads, batch_size,
                              lambda chunk: self.net.text(self.tokenize(chunk)))
