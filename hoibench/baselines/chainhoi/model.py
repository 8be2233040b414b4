"""The ChainHOI denoiser (Zeng et al., CVPR 2025): N blocks of GST-GCN + KIM over the HOI graph.

Input: a noisy joint-level sequence ``x_t`` (B, L, 24, 12) (normalised), the timestep, the
text condition and the object's surface points; output: the predicted clean sequence x0.

Per block (``z``: (B, L, 24, D_m)):

- **ST-GCN** (short term): spatial graph convolution ``sum_k A_k z W_k`` over the identity,
  inward and outward partitions (:mod:`.graph`), then a multi-branch temporal convolution
  (dilated convolutions, a max-pool branch and a 1x1 branch, concatenated), residual;
  padded frames are reset after every operator that can write them, so a padded batch
  gives each clip what it gives alone.
- **Semantic-consistent Module** (long term): HOI tokens ``mean_nodes(Linear(z))`` (B, L, D_t)
  are the queries of two transformer decoders, the first attending to the text tokens
  (with the timestep token), the second to the object-geometry tokens; ``z^l`` is mapped
  back to D_m, repeated over the nodes and fused: ``y = Linear([z^l; z^s])``.
- **KIM**: six learnable kinetic-chain tokens pass a Context-aware Decoder (same structure,
  queries = the tokens), then per frame a Kinematic-aware Decoder: self-attention among the
  chain tokens, cross-attention to the frame's node tokens ``Linear(y_i)`` (B L, 24, D_t)
  under the chain mask (each token sees only its chain's nodes), feed-forward. Fusion:
  ``v'' = reshape(FC(flatten(v')))`` (24, D_t), ``y_hat = Linear([v''; ybar])``, residual.

``mask="paper"`` uses the boolean chain mask (attention outside the chain is exactly zero).
``mask="released"`` reproduces the released code, which passes the float ``1 - mask`` as
an additive mask: scores outside the chain get +1 and inside +0, so nothing is masked
(see docs/baselines.md for the measured difference).

Object geometry: a pure-PyTorch point encoder (farthest-point sampling of 16 centres, kNN
grouping, a shared MLP on centre-relative coordinates, max-pool) -- no CUDA operators.
"""
from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from ..layers import ConditionEncoders, sinusoidal
from .config import ModelConfig
from .graph import NODES, chain_mask, partitions

WIDTH = 12            # channels per node (joint_level)
CHAINS = 6


# ------------------------------------------------------------------------------ blocks
def _decoder_layer(width: int, heads: int, ff: int, dropout: float) -> nn.TransformerDecoderLayer:
    return nn.TransformerDecoderLayer(width, heads, ff, dropout, batch_first=True, norm_first=True)


class DecoderPair(nn.Module):
    """Two transformer decoders: queries attend to the text tokens, then to the object tokens
    (the Semantic-consistent Module and the Context-aware Decoder share this structure)."""

    def __init__(self, width: int, heads: int, ff: int, dropout: float):
        super().__init__()
        self.text = _decoder_layer(width, heads, ff, dropout)
        self.object = _decoder_layer(width, heads, ff, dropout)

    def forward(self, q, q_pad, text, text_pad, obj):
        q = self.text(q, text, tgt_key_padding_mask=q_pad, memory_key_padding_mask=text_pad)
        return self.object(q, obj, tgt_key_padding_mask=q_pad)


class STGCN(nn.Module):
    """Spatial graph convolution over three partitions + multi-branch temporal convolution."""

    def __init__(self, width: int, kernel: int, dilations: tuple[int, ...], dropout: float):
        super().__init__()
        self.register_buffer("A", torch.from_numpy(partitions()), persistent=False)
        self.spatial = nn.Linear(width, width * 3)
        self.norm1 = nn.LayerNorm(width)
        nb = len(dilations) + 2
        bw = [width // nb + (1 if i < width % nb else 0) for i in range(nb)]
        self.branches = nn.ModuleList()
        for d, w in zip(dilations, bw):
            self.branches.append(nn.Sequential(nn.Conv1d(width, w, 1), nn.GELU(),
                                               nn.Conv1d(w, w, kernel, padding=d * (kernel - 1) // 2, dilation=d)))
        self.branches.append(nn.Sequential(nn.Conv1d(width, bw[-2], 1), nn.GELU(),
                                           nn.MaxPool1d(3, stride=1, padding=1)))
        self.branches.append(nn.Conv1d(width, bw[-1], 1))
        self.norm2 = nn.LayerNorm(width)
        self.drop = nn.Dropout(dropout)

    def forward(self, z: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
        B, L, N, D = z.shape
        parts = self.spatial(z).view(B, L, N, 3, D)
        s = torch.einsum("kij,bljkd->blid", self.A, parts)              # sum_k A_k z W_k
        z = z + self.drop(F.gelu(self.norm1(s)))
        z = z * valid[:, :, None, None]                                  # padding never leaks in time
        t = z.permute(0, 2, 3, 1).reshape(B * N, D, L)
        keep = valid[:, None, None, :].expand(B, N, 1, L).reshape(B * N, 1, L)
        t = self.temporal(t, keep).view(B, N, D, L).permute(0, 3, 1, 2)
        return (z + self.drop(F.gelu(self.norm2(t)))) * valid[:, :, None, None]

    def temporal(self, t: torch.Tensor, keep: torch.Tensor) -> torch.Tensor:
        """(B N, D, L) -> (B N, D, L): the branches concatenated; ``keep`` (B N, 1, L) bool.
        A branch's 1x1 convolution carries a bias, so its padded frames are reset before the
        temporal operator reads them: to 0 before a dilated convolution (what its own zero
        padding supplies past the end), to -inf before the max-pool (what its padding
        supplies). Valid frames then equal those of the unpadded sequence."""
        out = []
        for b in self.branches:
            if not isinstance(b, nn.Sequential):                         # the bare 1x1 branch
                out.append(b(t))
            elif isinstance(b[2], nn.MaxPool1d):
                out.append(b[2](b[1](b[0](t)).masked_fill(~keep, float("-inf"))).masked_fill(~keep, 0.0))
            else:
                out.append(b[2](b[1](b[0](t)) * keep))
        return torch.cat(out, 1)


class GSTGCN(nn.Module):
    def __init__(self, cfg: ModelConfig):
        super().__init__()
        dm, dt = cfg.d_model, cfg.d_text
        self.stgcn = STGCN(dm, cfg.temporal_kernel, cfg.temporal_dilations, cfg.dropout)
        self.to_tokens = nn.Linear(dm, dt)
        self.scm = DecoderPair(dt, cfg.heads, cfg.ff_mult * dt, cfg.dropout)
        self.from_tokens = nn.Linear(dt, dm)
        self.fuse = nn.Linear(2 * dm, dm)

    def forward(self, z, valid, text, text_pad, obj):
        zs = self.stgcn(z, valid)
        tok = self.to_tokens(z).mean(2)                                   # (B, L, D_t)
        tok = tok + sinusoidal(torch.arange(z.shape[1], device=z.device), tok.shape[-1])
        zl = self.scm(tok, ~valid, text, text_pad, obj)
        zl = self.from_tokens(zl)[:, :, None].expand_as(zs)
        return self.fuse(torch.cat([zl, zs], -1))


class KinematicDecoderLayer(nn.Module):
    """Chain tokens: self-attention (inter-chain), masked cross-attention to one frame's
    node tokens (intra-chain), feed-forward; pre-norm residuals."""

    def __init__(self, width: int, heads: int, ff: int, dropout: float, mask: str):
        super().__init__()
        self.self_attn = nn.MultiheadAttention(width, heads, dropout=dropout, batch_first=True)
        self.cross_attn = nn.MultiheadAttention(width, heads, dropout=dropout, batch_first=True)
        self.ff = nn.Sequential(nn.Linear(width, ff), nn.GELU(), nn.Dropout(dropout), nn.Linear(ff, width))
        self.n1, self.n2, self.n3 = nn.LayerNorm(width), nn.LayerNorm(width), nn.LayerNorm(width)
        self.drop = nn.Dropout(dropout)
        m = torch.from_numpy(chain_mask())
        # "paper": boolean, True = not allowed; "released": the float (1 - membership) added to scores
        self.register_buffer("mask", m if mask == "paper" else m.float(), persistent=False)
        self.last_attention: torch.Tensor | None = None
        self.keep_attention = False

    def forward(self, kt: torch.Tensor, nodes: torch.Tensor) -> torch.Tensor:
        h = self.n1(kt)
        kt = kt + self.drop(self.self_attn(h, h, h, need_weights=False)[0])
        h = self.n2(kt)
        out, w = self.cross_attn(h, nodes, nodes, attn_mask=self.mask, need_weights=self.keep_attention,
                                 average_attn_weights=False)
        if self.keep_attention:
            self.last_attention = w.detach()
        kt = kt + self.drop(out)
        return kt + self.drop(self.ff(self.n3(kt)))


class KIM(nn.Module):
    def __init__(self, cfg: ModelConfig):
        super().__init__()
        dm, dt = cfg.d_model, cfg.d_text
        self.tokens = nn.Parameter(torch.randn(CHAINS, dt) * 0.02)
        self.context = DecoderPair(dt, cfg.heads, cfg.ff_mult * dt, cfg.dropout)
        self.to_nodes = nn.Linear(dm, dt)
        self.kinematic = KinematicDecoderLayer(dt, cfg.heads, cfg.ff_mult * dt, cfg.dropout, cfg.mask)
        self.expand = nn.Linear(CHAINS * dt, NODES * dt)
        self.fuse = nn.Linear(2 * dt, dm)

    def forward(self, y, text, text_pad, obj):
        B, L, N, _ = y.shape
        kt = self.context(self.tokens[None].expand(B, -1, -1), None, text, text_pad, obj)   # (B, 6, D_t)
        ybar = self.to_nodes(y)                                                               # (B, L, 24, D_t)
        dt = ybar.shape[-1]
        kt = kt[:, None].expand(B, L, CHAINS, dt).reshape(B * L, CHAINS, dt)
        v = self.kinematic(kt, ybar.reshape(B * L, N, dt))                                    # (B L, 6, D_t)
        v2 = self.expand(v.reshape(B * L, CHAINS * dt)).view(B, L, N, dt)
        return y + self.fuse(torch.cat([v2, ybar], -1))


class Block(nn.Module):
    def __init__(self, cfg: ModelConfig):
        super().__init__()
        self.gst = GSTGCN(cfg)
        self.kim = KIM(cfg)

    def forward(self, z, valid, text, text_pad, obj):
        y = self.gst(z, valid, text, text_pad, obj)
        return self.kim(y, text, text_pad, obj) * valid[:, :, None, None]


class ChainHOI(ConditionEncoders):
    """x0-predicting denoiser. ``text_width``: width of the text-token inputs (the sentence
    encoder's hidden size), or ``vocab`` for the trainable ``tokens`` encoder."""

    def __init__(self, cfg: ModelConfig, vocab: int = 0, text_width: int = 0):
        super().__init__("ChainHOI", cfg.text_encoder, cfg.d_text, vocab, text_width, cfg.heads, cfg.text_layers,
                         cfg.dropout, cfg.object_tokens, cfg.object_knn)
        self.cfg = cfg
        dm, dt = cfg.d_model, cfg.d_text
        self.time_text = nn.Sequential(nn.Linear(dt, dt), nn.SiLU(), nn.Linear(dt, dt))
        self.time_motion = nn.Sequential(nn.Linear(dt, dm), nn.SiLU(), nn.Linear(dm, dm))
        self.null_text = nn.Parameter(torch.zeros(dt))
        self.in_proj = nn.Linear(WIDTH, dm)
        self.node_embed = nn.Parameter(torch.randn(NODES, dm) * 0.02)
        self.blocks = nn.ModuleList(Block(cfg) for _ in range(cfg.blocks))
        self.out_proj = nn.Linear(dm, WIDTH)

    def forward(self, x: torch.Tensor, t: torch.Tensor, keep: torch.Tensor, text_tokens: torch.Tensor,
                text_pad: torch.Tensor, obj_tokens: torch.Tensor, valid: torch.Tensor | None = None) -> torch.Tensor:
        """x (B, L, 24, 12), t (B,), keep (B,) bool (False: text dropped), text_tokens (B, Lt,
        D_t) from :meth:`encode_text`, text_pad (B, Lt) bool, obj_tokens (B, n, D_t) from
        :meth:`encode_object`, valid (B, L) bool -> x0 (B, L, 24, 12)."""
        B, L = x.shape[:2]
        if valid is None:
            valid = torch.ones(B, L, dtype=torch.bool, device=x.device)
        temb = sinusoidal(t, self.cfg.d_text)
        ttok = self.time_text(temb) + (~keep)[:, None].float() * self.null_text
        text = torch.cat([ttok[:, None], text_tokens], 1)
        pad = torch.cat([torch.zeros(B, 1, dtype=torch.bool, device=x.device),
                         text_pad | ~keep[:, None]], 1)                 # dropped text: only the time token
        z = self.in_proj(x) + self.node_embed + self.time_motion(temb)[:, None, None]
        z = z * valid[:, :, None, None]
        for blk in self.blocks:
            z = blk(z, valid, text, pad, obj_tokens)
        return self.out_proj(z) * valid[:, :, None, None]
