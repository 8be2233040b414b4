"""CATMO's interaction-aware text encoder and movement encoder (CATMO sec. 4.3, supp. 1.2).

- Movement encoder, part 1 (:class:`MovementConv`): Conv1D layers over normalised hml263 rows
  with two stride-2 stages (one vector per 4 rows), trained as an autoencoder with a
  smooth-L1 reconstruction loss (:class:`MovementDeconv` is its decoder), then frozen.
- Movement encoder, part 2 (:class:`MovementHead`): an MLP per latent and a masked mean
  over time -> (B, width).
- Text encoder (:class:`InteractionTextEncoder`): word embeddings (``tokens``) or frozen
  sentence-encoder states (``minilm``) -> Conv1D layers -> masked max over words -> MLP ->
  (B, width).

Text encoder and part 2 are trained together with the contrastive loss of CATMO supp.
eq. 1-3 (:func:`matching_loss`): ``D(Z_t, Z) + max(0, m - D(Z_t, Z'))`` averaged over the
batch, ``D`` the Euclidean distance and ``Z'`` the batch's motion embeddings rolled by a
random offset (a mismatched pair). The frozen text encoder then conditions the GPT, and the
frozen movement encoder embeds the GPT's predicted motion for the alignment loss.
"""
from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from .vqvae import masked_stack


class MovementConv(nn.Module):
    """(B, L, 263) -> (B, L / 4, hidden)."""

    def __init__(self, channels: int, hidden: int):
        super().__init__()
        self.net = nn.Sequential(nn.Conv1d(channels, hidden, 4, stride=2, padding=1), nn.LeakyReLU(0.2),
                                 nn.Conv1d(hidden, hidden, 4, stride=2, padding=1), nn.LeakyReLU(0.2))
        self.out = nn.Linear(hidden, hidden)

    def forward(self, x: torch.Tensor, rows: torch.Tensor | None = None) -> torch.Tensor:
        """``rows`` (B, L): valid rows of a zero-padded batch (padded positions reset per layer)."""
        return self.out(masked_stack(self.net, x.transpose(1, 2), rows).transpose(1, 2))


class MovementDeconv(nn.Module):
    """(B, L / 4, hidden) -> (B, L, 263): part 1's reconstruction head."""

    def __init__(self, channels: int, hidden: int):
        super().__init__()
        self.net = nn.Sequential(nn.ConvTranspose1d(hidden, hidden, 4, stride=2, padding=1), nn.LeakyReLU(0.2),
                                 nn.ConvTranspose1d(hidden, hidden, 4, stride=2, padding=1), nn.LeakyReLU(0.2))
        self.out = nn.Linear(hidden, channels)

    def forward(self, h: torch.Tensor, rows: torch.Tensor | None = None) -> torch.Tensor:
        """``rows`` (B, 4 U): valid rows of a zero-padded batch (padded positions reset per layer)."""
        if rows is not None:
            h = h * rows[:, 3::4, None].to(h.dtype)
        return self.out(masked_stack(self.net, h.transpose(1, 2), rows, 4).transpose(1, 2))


def masked_mean(h: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
    """(B, D) mean of (B, N, D) over the ``valid`` (B, N) positions."""
    w = valid.to(h.dtype)[..., None]
    return (h * w).sum(1) / w.sum(1).clamp_min(1.0)


class MovementHead(nn.Module):
    """Part 2: (B, U, hidden) latents and (B, U) validity -> (B, width) motion embedding."""

    def __init__(self, hidden: int, width: int):
        super().__init__()
        self.mlp = nn.Sequential(nn.Linear(hidden, hidden), nn.LeakyReLU(0.2), nn.Linear(hidden, width))

    def forward(self, h: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
        return masked_mean(self.mlp(h), valid)


class MovementEncoder(nn.Module):
    def __init__(self, channels: int, hidden: int, width: int):
        super().__init__()
        self.conv = MovementConv(channels, hidden)
        self.deconv = MovementDeconv(channels, hidden)
        self.head = MovementHead(hidden, width)

    def forward(self, x: torch.Tensor, valid_rows: torch.Tensor) -> torch.Tensor:
        """(B, width) embedding of (B, L, 263) normalised rows (L a multiple of 4)."""
        h = self.conv(x, valid_rows if valid_rows.shape[1] >= 4 else None)
        return self.head(h, valid_rows[:, 3::4] if valid_rows.shape[1] >= 4 else valid_rows[:, :1])


class InteractionTextEncoder(nn.Module):
    def __init__(self, encoder: str, vocab: int, text_width: int, hidden: int, width: int):
        super().__init__()
        if encoder == "tokens":
            if vocab < 2:
                raise ValueError("catmo: the 'tokens' text encoder needs a vocabulary (>= 2 entries)")
            self.embed: nn.Module = nn.Embedding(vocab, hidden, padding_idx=0)
        else:
            if text_width < 1:
                raise ValueError("catmo: the 'minilm' text encoder needs text_width (its hidden size)")
            self.embed = nn.Linear(text_width, hidden)
        self.convs = nn.ModuleList([nn.Conv1d(hidden, hidden, 3, padding=1) for _ in range(2)])
        self.mlp = nn.Sequential(nn.Linear(hidden, hidden), nn.LeakyReLU(0.2), nn.Linear(hidden, width))

    def forward(self, text: torch.Tensor, pad: torch.Tensor) -> torch.Tensor:
        h = self.embed(text)
        for conv in self.convs:
            h = h + F.leaky_relu(conv(h.transpose(1, 2)).transpose(1, 2), 0.2)
        h = h.masked_fill(pad[..., None], float("-inf")).max(1).values
        return self.mlp(torch.nan_to_num(h, neginf=0.0))


def matching_loss(text: torch.Tensor, motion: torch.Tensor, margin: float, offset: int) -> torch.Tensor:
    """CATMO supp. eq. 1-3: mean ``||t_i - m_i|| + max(0, margin - ||t_i - m_{i+offset}||)``."""
    pos = (text - motion).norm(dim=-1)
    neg = (text - motion.roll(offset, 0)).norm(dim=-1)
    return pos.mean() + F.relu(margin - neg).mean()
