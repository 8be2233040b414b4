"""Layers the diffusion baselines share: sinusoidal embeddings, the pure-PyTorch point encoder
(farthest-point sampling + kNN grouping, no CUDA operators) and the trainable token text encoder."""
from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn


def sinusoidal(positions: torch.Tensor, width: int) -> torch.Tensor:
    """(..., width) sinusoidal embedding of (...) positions or timesteps."""
    half = width // 2
    freq = torch.exp(-math.log(10000.0) * torch.arange(half, dtype=torch.float32, device=positions.device) / half)
    ang = positions.float()[..., None] * freq
    emb = torch.cat([ang.sin(), ang.cos()], -1)
    return F.pad(emb, (0, width - 2 * half))


# ------------------------------------------------------------------------------ object points
def farthest_point_sample(points: torch.Tensor, n: int) -> torch.Tensor:
    """(B, n) indices of ``n`` farthest points of (B, P, 3), starting from index 0
    (deterministic)."""
    B, P, _ = points.shape
    idx = torch.zeros(B, n, dtype=torch.long, device=points.device)
    dist = torch.full((B, P), float("inf"), device=points.device)
    cur = torch.zeros(B, dtype=torch.long, device=points.device)
    ar = torch.arange(B, device=points.device)
    for i in range(n):
        idx[:, i] = cur
        d = ((points - points[ar, cur][:, None]) ** 2).sum(-1)
        dist = torch.minimum(dist, d)
        cur = dist.argmax(-1)
    return idx


class PointEncoder(nn.Module):
    """(B, P, 3) surface points -> (B, tokens, out_dim): FPS centres, kNN groups, shared MLP
    on [p - c, c], max over the group (a one-level PointNet++ set abstraction)."""

    def __init__(self, out_dim: int, tokens: int = 16, knn: int = 32, hidden: int = 64):
        super().__init__()
        self.tokens, self.knn = tokens, knn
        self.mlp = nn.Sequential(nn.Linear(6, hidden), nn.GELU(), nn.Linear(hidden, hidden), nn.GELU(),
                                 nn.Linear(hidden, out_dim))

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        B = points.shape[0]
        centres_idx = farthest_point_sample(points, self.tokens)
        ar = torch.arange(B, device=points.device)[:, None]
        centres = points[ar, centres_idx]                              # (B, n, 3)
        d = torch.cdist(centres, points)                               # (B, n, P)
        nn_idx = d.topk(self.knn, dim=-1, largest=False).indices       # (B, n, k)
        groups = points[ar[..., None], nn_idx]                         # (B, n, k, 3)
        feats = torch.cat([groups - centres[:, :, None], centres[:, :, None].expand_as(groups)], -1)
        return self.mlp(feats).max(dim=2).values


# ------------------------------------------------------------------------------ text
class TokenTextEncoder(nn.Module):
    """Trainable word-embedding encoder: (B, Lt) ids -> (B, Lt, d) (id 0 = padding)."""

    def __init__(self, vocab: int, width: int, heads: int, layers: int, dropout: float):
        super().__init__()
        self.embed = nn.Embedding(vocab, width, padding_idx=0)
        layer = nn.TransformerEncoderLayer(width, heads, 2 * width, dropout, batch_first=True, norm_first=True)
        self.encoder = nn.TransformerEncoder(layer, layers, enable_nested_tensor=False)

    def forward(self, ids: torch.Tensor, pad: torch.Tensor) -> torch.Tensor:
        x = self.embed(ids) + sinusoidal(torch.arange(ids.shape[1], device=ids.device), self.embed.embedding_dim)
        return self.encoder(x, src_key_padding_mask=pad)


class ConditionEncoders(nn.Module):
    """Text and object-geometry encoders every baseline denoiser shares: ``encode_text``
    (trainable word tokens, or a projection of frozen sentence-encoder states) and
    ``encode_object`` (the point encoder), both to ``width``."""

    def __init__(self, name: str, text_encoder: str, width: int, vocab: int, text_width: int, heads: int,
                 text_layers: int, dropout: float, object_tokens: int, object_knn: int):
        super().__init__()
        if text_encoder == "tokens":
            if vocab < 2:
                raise ValueError(f"{name}: the 'tokens' text encoder needs a vocabulary (>= 2 entries)")
            self.text_tokens = TokenTextEncoder(vocab, width, heads, text_layers, dropout)
            self.text_proj = nn.Identity()
        else:
            if text_width < 1:
                raise ValueError(f"{name}: the 'minilm' text encoder needs text_width (its hidden size)")
            self.text_tokens = None
            self.text_proj = nn.Linear(text_width, width)
        self.points = PointEncoder(width, object_tokens, object_knn)

    def encode_text(self, text: torch.Tensor, text_pad: torch.Tensor) -> torch.Tensor:
        """(B, Lt, width) text tokens from ids (``tokens``) or sentence-encoder states (``minilm``)."""
        if self.text_tokens is not None:
            return self.text_tokens(text, text_pad)
        return self.text_proj(text)

    def encode_object(self, points: torch.Tensor) -> torch.Tensor:
        """(B, object_tokens, width) from (B, P, 3) surface points."""
        return self.points(points)
