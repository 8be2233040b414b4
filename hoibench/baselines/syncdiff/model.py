"""SyncDiff's denoiser (paper 004, section 3.4, appendix D.2): one transformer over the
padded high-order representation, predicting the clean sample (x0).

Condition vector (per clip): action-label and object-label features (offline text encoder
-> 2-layer MLP; CLIP in the paper), object geometry (BPS -> 2-layer MLP, one slot per
object), skeleton shapes (bone lengths) and the 0/1 column mask of the clip's layout. It is
replicated over the tokens and concatenated with each token's values and 0/1 padding mask.

With decomposition, the noised ``x_t`` of each clip (its own frames only) is split
(:mod:`.frequency`) into its low part (``T`` time-domain tokens) and the coefficients of its
high part (``2 (cutoff - low)`` frequency-domain tokens); each stream has its own encoder
(a kernel-1 Conv1D: a linear map per token) and decoder; both streams share the
transformer, with the timestep embedding added to every token. The output is
``x0 = x0_low + synthesize(X0_high)``. Without decomposition one time-domain stream carries
``x_t`` itself. Padded frames, rows and columns are zeroed at the input and masked out of
attention, so a padded batch gives each clip what it gets alone.
"""
from __future__ import annotations

import torch
from torch import nn

from ..layers import sinusoidal
from . import frequency as F


def _mlp(i: int, h: int, o: int) -> nn.Sequential:
    return nn.Sequential(nn.Linear(i, h), nn.ReLU(), nn.Linear(h, o))


class SyncDiffNet(nn.Module):
    def __init__(self, cfg, sync, width: int, vocab: int, text_width: int, max_objects: int, max_skeletons: int,
                 shape_width: int):
        super().__init__()
        m = cfg
        self.width, self.decompose = width, bool(sync.decompose)
        self.low, self.cutoff = int(sync.low), int(sync.cutoff)
        self.rows = F.coefficient_rows(self.low, self.cutoff)
        self.freq_position = getattr(sync, "freq_position", "index")
        self.groups = int(getattr(sync, "high_groups", 1))
        self.group_width = -(-width // self.groups)               # columns per high-part token
        self.tokens = m.text_encoder == "tokens"
        tw = m.cond_width if self.tokens else text_width
        if self.tokens:
            self.embed = nn.Embedding(max(vocab, 2), m.cond_width, padding_idx=0)
        self.action_mlp = _mlp(tw, m.cond_width, m.cond_width)
        self.object_mlp = _mlp(tw, m.cond_width, m.cond_width)
        self.geo_mlp = _mlp(m.bps_points + 1, m.cond_width, m.cond_width)
        cond = 2 * m.cond_width + max_objects * m.cond_width + max_skeletons * shape_width + width
        self.cond_dim = cond
        self.enc_low = nn.Conv1d(width + 1 + cond, m.latent, 1)
        self.dec_low = nn.Linear(m.latent, width)
        if self.decompose:
            G, gw = self.groups, self.group_width
            # one encoder and one decoder per column group (grouped kernel-1 convolutions), so a
            # token knows which columns it carries; G = 1 is the single per-row encoder
            self.enc_high = nn.Conv1d(G * (gw + 1 + cond), G * m.latent, 1, groups=G)
            self.dec_high = (nn.Linear(m.latent, gw) if G == 1 else
                             nn.Conv1d(G * m.latent, G * gw, 1, groups=G))
            self.stream = nn.Parameter(torch.zeros(2, m.latent))
            if self.freq_position == "rate":
                self.parity = nn.Parameter(torch.randn(2, m.latent) * 0.02)   # a_k (cos) / b_k (sin) rows
            if self.groups > 1:
                self.group = nn.Parameter(torch.randn(self.groups, m.latent) * 0.02)
        self.time = nn.Sequential(nn.Linear(m.time_width, m.latent), nn.GELU(), nn.Linear(m.latent, m.latent))
        self.time_width, self.latent = m.time_width, m.latent
        layer = nn.TransformerEncoderLayer(m.latent, m.heads, m.ff_mult * m.latent, m.dropout, batch_first=True,
                                           activation="gelu")
        self.backbone = nn.TransformerEncoder(layer, m.layers, enable_nested_tensor=False)

    # ------------------------------------------------------------------ conditions
    def _text(self, tt: torch.Tensor, pad: torch.Tensor) -> torch.Tensor:
        h = self.embed(tt) if self.tokens else tt
        keep = (~pad).to(h.dtype)[..., None]
        return (h * keep).sum(1) / keep.sum(1).clamp(min=1.0)

    def condition(self, action: tuple, objects: tuple, geo: torch.Tensor, shapes: torch.Tensor,
                  cols: torch.Tensor) -> torch.Tensor:
        """(B, cond_dim) condition vector; ``action`` / ``objects``: (text input, pad)."""
        a = self.action_mlp(self._text(*action))
        o = self.object_mlp(self._text(*objects))
        g = self.geo_mlp(geo) * geo[..., -1:]                      # absent object slots: zero
        return torch.cat([a, o, g.flatten(1), shapes.flatten(1), cols], -1)

    # ------------------------------------------------------------------ streams
    def split(self, x: torch.Tensor, lengths: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(low (B, T, D), high coefficients (B, R, D), row mask (B, R)) of padded ``x``."""
        low, high = torch.zeros_like(x), x.new_zeros((x.shape[0], self.rows, x.shape[2]))
        rmask = torch.zeros((x.shape[0], self.rows), dtype=torch.bool, device=x.device)
        for b, n in enumerate(lengths.tolist()):
            lo_b, hi_b = F.split(x[b, :n], self.low, self.cutoff)
            low[b, :n], high[b] = lo_b, hi_b
            usable = 2 * max(0, F.clamp(n, self.cutoff) - F.clamp(n, self.low))
            rmask[b, :usable] = True
        return low, high, rmask

    def recompose(self, low: torch.Tensor, high: torch.Tensor, lengths: torch.Tensor) -> torch.Tensor:
        out = low.clone()
        for b, n in enumerate(lengths.tolist()):
            out[b, :n] = low[b, :n] + F.high_frames(high[b], n, self.low)
        return out

    def frequency_positions(self, lengths: torch.Tensor) -> torch.Tensor:
        """(1 or B, R, latent) position codes of the high part's rows: the row index, or
        (``rate``) the rate ``k / n`` cycles per frame of row ``(a_k | b_k)`` in a clip of ``n``
        frames (scaled by 1000 into the sinusoid's range) plus a learned cos/sin code."""
        rows = torch.arange(self.rows, device=lengths.device)
        if self.freq_position == "index":
            return sinusoidal(rows, self.latent)[None]
        k = (self.low + 1 + rows // 2).to(torch.float32)
        rate = k[None] / lengths.to(torch.float32).clamp(min=1.0)[:, None]
        return sinusoidal(1000.0 * rate, self.latent) + self.parity[rows % 2][None]

    def _encode(self, enc, vals: torch.Tensor, mask: torch.Tensor, cond: torch.Tensor, cols: torch.Tensor):
        m = mask.to(vals.dtype)[..., None]
        inp = torch.cat([vals * cols[:, None], m, cond[:, None].expand(-1, vals.shape[1], -1)], -1) * m
        return enc(inp.transpose(1, 2)).transpose(1, 2)

    def _encode_high(self, high: torch.Tensor, rmask: torch.Tensor, cond: torch.Tensor, cols: torch.Tensor
                     ) -> tuple[torch.Tensor, torch.Tensor]:
        """(tokens (B, R G, latent), mask (B, R G)) of the high part's coefficients (B, R, D):
        row r's columns in G groups, one token per (row, group); a group of padding columns
        only is masked out."""
        B, R, D = high.shape
        G, gw = self.groups, self.group_width
        extra = G * gw - D
        vals = nn.functional.pad(high * cols[:, None], (0, extra)).reshape(B, R * G, gw)
        gvalid = nn.functional.pad(cols, (0, extra)).reshape(B, G, gw).sum(-1) > 0
        tmask = (rmask[:, :, None] & gvalid[:, None, :]).reshape(B, R * G)
        m = tmask.to(high.dtype)[..., None]
        inp = (torch.cat([vals, m, cond[:, None].expand(-1, R * G, -1)], -1) * m).reshape(B, R, -1)
        h = self.enc_high(inp.transpose(1, 2)).transpose(1, 2).reshape(B, R * G, -1)
        if G > 1:
            h = h + self.group.repeat(R, 1)[None]
        return h, tmask

    def _decode_high(self, h: torch.Tensor, cols: torch.Tensor, rmask: torch.Tensor) -> torch.Tensor:
        B, D = cols.shape
        if self.groups == 1:
            out = self.dec_high(h)
        else:                                                      # (B, R G, latent) -> (B, R, G gw)
            out = self.dec_high(h.reshape(B, self.rows, -1).transpose(1, 2)).transpose(1, 2)
        out = out.reshape(B, self.rows, self.groups * self.group_width)[..., :D]
        return out * cols[:, None] * rmask[..., None]

    def forward(self, x_t: torch.Tensor, t: torch.Tensor, frames: torch.Tensor, cols: torch.Tensor,
                cond: torch.Tensor) -> dict[str, torch.Tensor]:
        """x0 prediction for noised ``x_t`` (B, T, D); ``frames`` (B, T) bool, ``cols`` (B, D)
        0/1, ``cond`` (B, cond_dim). Returns ``x0`` and, with decomposition, ``low`` (B, T, D)
        and ``high`` (B, R, D) coefficients."""
        lengths = frames.sum(1)
        temb = self.time(sinusoidal(t, self.time_width))[:, None]
        pos = sinusoidal(torch.arange(x_t.shape[1], device=x_t.device), self.latent)[None]
        if not self.decompose:
            h = self._encode(self.enc_low, x_t, frames, cond, cols) + pos + temb
            h = self.backbone(h, src_key_padding_mask=~frames)
            return {"x0": self.dec_low(h) * cols[:, None] * frames[..., None]}
        low, high, rmask = self.split(x_t, lengths)
        hpos = self.frequency_positions(lengths)
        h_low = self._encode(self.enc_low, low, frames, cond, cols) + pos + self.stream[0] + temb
        h_high, hmask = self._encode_high(high, rmask, cond, cols)
        h_high = h_high + hpos.repeat_interleave(self.groups, dim=1) + self.stream[1] + temb
        T = x_t.shape[1]
        h = self.backbone(torch.cat([h_low, h_high], 1), src_key_padding_mask=~torch.cat([frames, hmask], 1))
        p_low = self.dec_low(h[:, :T]) * cols[:, None] * frames[..., None]
        p_high = self._decode_high(h[:, T:], cols, rmask)
        return {"x0": self.recompose(p_low, p_high, lengths), "low": p_low, "high": p_high, "rows": rmask}
