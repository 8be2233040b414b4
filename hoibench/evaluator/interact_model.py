"""The networks of InterAct's text-to-interaction evaluator (a TMR/TEMOS-style pair).

Both encoders are "actor-agnostic" transformer VAE encoders: two learned tokens
(``mu_token``, ``logvar_token``, each ``(latent,)``) are put in front of the sequence, a
sinusoidal table ``sequence_pos_encoding.pe`` ``(max_len, 1, latent)`` is added, a
post-norm GELU ``nn.TransformerEncoder`` (``latent`` = 256, 4 heads, feed-forward 1024,
4 layers) runs with padded positions masked, and the embedding is the output at the
``mu_token`` position (the mean, ``.loc``, of the encoder's Gaussian; the ``logvar``
output is not used for scoring).

* motion: ``skel_embedding`` Linear(615 -> 256) of the normalised marker + BPS rows;
* text: a DistilBERT (``text_model``, frozen in InterAct) gives the last hidden state of
  the tokenised caption, ``projection`` = ReLU then Linear(hidden -> 256), padding tokens
  masked.

Parameter names follow the checkpoint's, so a ``textencoder.`` / ``motionencoder.`` slice of
its ``state_dict`` loads as is.
"""
from __future__ import annotations

import torch
from torch import nn

LATENT = 256
FF_SIZE = 1024
LAYERS = 4
HEADS = 4


class _Sinusoid(nn.Module):
    """Holds the checkpoint's ``pe`` table ``(max_len, 1, latent)``; adds ``pe[:S]`` to (S, B, D)."""

    def __init__(self, max_len: int, latent: int):
        super().__init__()
        self.register_buffer("pe", torch.zeros(max_len, 1, latent))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if x.shape[0] > self.pe.shape[0]:
            raise ValueError(f"interact evaluator: a sequence of {x.shape[0] - 2} frames/tokens is longer than the "
                             f"positional table ({self.pe.shape[0] - 2})")
        return x + self.pe[: x.shape[0]]


class AgnosticEncoder(nn.Module):
    """The shared transformer head: tokens + positions + masked encoder -> mu output (B, latent)."""

    def __init__(self, latent: int = LATENT, ff_size: int = FF_SIZE, layers: int = LAYERS, heads: int = HEADS,
                 max_len: int = 5000):
        super().__init__()
        self.mu_token = nn.Parameter(torch.zeros(latent))
        self.logvar_token = nn.Parameter(torch.zeros(latent))
        self.sequence_pos_encoding = _Sinusoid(max_len, latent)
        layer = nn.TransformerEncoderLayer(d_model=latent, nhead=heads, dim_feedforward=ff_size, dropout=0.0,
                                           activation="gelu")
        self.seqTransEncoder = nn.TransformerEncoder(layer, num_layers=layers, enable_nested_tensor=False)

    def encode(self, x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """``x`` (B, S, latent) embedded inputs, ``mask`` (B, S) True where valid -> (B, latent)."""
        bs = x.shape[0]
        tokens = torch.stack([self.mu_token, self.logvar_token])[:, None, :].expand(2, bs, -1)
        seq = torch.cat([tokens, x.permute(1, 0, 2)], 0)
        valid = torch.cat([torch.ones(bs, 2, dtype=torch.bool, device=x.device), mask], 1)
        out = self.seqTransEncoder(self.sequence_pos_encoding(seq), src_key_padding_mask=~valid)
        return out[0]


class MotionEncoder(AgnosticEncoder):
    """Motion branch: (B, T, nfeats) normalised rows + lengths -> (B, latent)."""

    def __init__(self, nfeats: int = 615, **kw):
        super().__init__(**kw)
        self.skel_embedding = nn.Linear(nfeats, self.mu_token.shape[0])

    def forward(self, rows: torch.Tensor, lengths: torch.Tensor) -> torch.Tensor:
        T = rows.shape[1]
        mask = torch.arange(T, device=rows.device)[None, :] < lengths[:, None]
        return self.encode(self.skel_embedding(rows), mask)


class TextEncoder(AgnosticEncoder):
    """Text branch: DistilBERT last hidden state -> ReLU -> Linear -> transformer -> (B, latent)."""

    def __init__(self, text_model: nn.Module, hidden: int, **kw):
        super().__init__(**kw)
        self.text_model = text_model
        self.projection = nn.Sequential(nn.ReLU(), nn.Linear(hidden, self.mu_token.shape[0]))

    def forward(self, input_ids: torch.Tensor, attention_mask: torch.Tensor) -> torch.Tensor:
        hidden = self.text_model(input_ids=input_ids, attention_mask=attention_mask).last_hidden_state
        return self.encode(self.projection(hidden), attention_mask.bool())


__all__ = ["LATENT", "FF_SIZE", "LAYERS", "HEADS", "AgnosticEncoder", "MotionEncoder", "TextEncoder"]
