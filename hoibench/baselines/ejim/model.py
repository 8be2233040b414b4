"""The EJIM denoiser (Huang et al., ICME 2025): joint tokens, dual-branch HOI Mamba, condition
injector, dynamic interaction blocks with progressive masking.

Tokens per frame: 23 human tokens (nodes 0-21 and the virtual foot-ground node 22 of the
joint-level layout) and one object token (node 23), embedded by linear encoders (plus a
learned joint embedding, so the shared encoder knows which joint it reads). Each of N
Joint-level Interaction Modules runs

1. **DHM** (dual-branch HOI Mamba): human temporal Mamba (each joint over time), object
   temporal Mamba (the object over time), then the limb-guided spatial Mamba: per frame, the
   human tokens reordered by limb with a learnable separator token before each group
   (torso, left leg, right leg, left arm, right arm; the foot node in both leg groups, its
   two outputs averaged), 29 tokens;
2. **DIB #1**: per frame, attention over [object; 23 human tokens] with the current mask;
3. **DCI** (dual-branch condition injector): the condition tokens (timestep, pooled text,
   16 object-geometry tokens) are prepended to each joint's and the object's temporal
   sequence, scanned, and dropped again;
4. **DIB #2**, whose object-to-joint attention scores update the mask for the next module
   (the scores are the attention weights without dropout, so training and sampling choose
   joints by the same rule).

**Progressive masking** (:func:`update_mask`): per sample and frame, the ``mask_k`` visible
human joints with the lowest object-to-joint attention in DIB #2 are masked, cumulatively
(all visible at the start; after 5 of 6 modules with k = 3, 8 joints stay visible, the number
of interaction joints HOI-Diff and ChainHOI use). A masked joint is excluded as a key in
every later DIB (it receives no attention) and its token is not updated by a DIB; the Mamba
scans still carry all joints. The object token is never masked.

Every Mamba sub-module is a :class:`~.mamba.BiMamba` (a forward and a backward block). What
the paper leaves open and hoibench chose is listed in docs/baselines.md.
"""
from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn

from ..layers import ConditionEncoders, sinusoidal
from .config import ModelConfig
from .mamba import BiMamba

HUMAN = 23            # nodes 0..22 (22 = virtual foot-ground node)
WIDTH = 12
#: limb groups of the spatial scan, each read after its own learnable separator token
LIMB_GROUPS: tuple[tuple[int, ...], ...] = (
    (0, 3, 6, 9, 12, 15),        # torso and head
    (1, 4, 7, 10, 22),           # left leg + foot-ground node
    (2, 5, 8, 11, 22),           # right leg + foot-ground node
    (13, 16, 18, 20),            # left arm
    (14, 17, 19, 21),            # right arm
)


def limb_order() -> tuple[list[int], list[int]]:
    """(sequence, separator positions): the spatial scan's token order as indices into the 23
    human tokens, -1 for a separator; and where each group's separator sits."""
    seq, seps = [], []
    for g in LIMB_GROUPS:
        seps.append(len(seq))
        seq.append(-1)
        seq.extend(g)
    return seq, seps


def update_mask(masked: torch.Tensor, scores: torch.Tensor, k: int, keep_visible: int = 1) -> torch.Tensor:
    """Progressive masking: mask the ``k`` visible joints with the lowest ``scores`` (per row,
    ties broken by joint index), keeping at least ``keep_visible`` joints visible.
    ``masked``, ``scores``: (..., 23); returns the new bool mask (True = masked)."""
    if k <= 0:
        return masked
    visible = (~masked).sum(-1, keepdim=True)
    n = (visible - keep_visible).clamp(min=0).clamp(max=k)             # how many to mask per row
    s = scores.masked_fill(masked, float("inf"))
    order = torch.argsort(s, dim=-1, stable=True)
    rank = torch.empty_like(order)
    rank.scatter_(-1, order, torch.arange(order.shape[-1], device=order.device).expand_as(order))
    return masked | (rank < n)


class DIB(nn.Module):
    """Dynamic Interaction Block: per-frame attention over [object; human tokens], masked joints
    excluded as keys and left unchanged; pre-norm, residual, feed-forward on visible tokens."""

    def __init__(self, d: int, heads: int, dropout: float):
        super().__init__()
        self.norm = nn.LayerNorm(d)
        self.attn = nn.MultiheadAttention(d, heads, dropout=dropout, batch_first=True)
        self.ff = nn.Sequential(nn.LayerNorm(d), nn.Linear(d, 2 * d), nn.GELU(), nn.Linear(2 * d, d))

    def forward(self, h: torch.Tensor, o: torch.Tensor, masked: torch.Tensor):
        """h (B, L, 23, d), o (B, L, d), masked (B, L, 23) -> (h, o, object-to-joint scores (B, L, 23))."""
        B, L, J, d = h.shape
        tok = torch.cat([o[:, :, None], h], 2).reshape(B * L, J + 1, d)
        keymask = torch.cat([torch.zeros(B, L, 1, dtype=torch.bool, device=h.device), masked], 2).reshape(B * L, J + 1)
        x = self.norm(tok)
        upd, scores = self.attend(x, keymask)
        scores = scores.reshape(B, L, J)
        if bool(masked.any()):
            live = (~keymask)[..., None].to(tok.dtype)                     # masked tokens: no update
            tok = tok + upd * live
            tok = tok + self.ff(tok) * live
        else:
            tok = tok + upd
            tok = tok + self.ff(tok)
        tok = tok.reshape(B, L, J + 1, d)
        return tok[:, :, 1:], tok[:, :, 0], scores

    def attend(self, x: torch.Tensor, keymask: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``self.attn``'s self-attention over x (N, T, d) with ``keymask`` (N, T) keys excluded
        (the packed in-projection, scaled dot-product attention with attention dropout in
        training, the out-projection), and the object query's scores (N, T - 1):
        ``mean_h softmax_k(q_h . k_h / sqrt(d_h))`` over the joint keys, from the same q and k
        but without attention dropout (``nn.MultiheadAttention`` returns its weights after
        dropout in training, which would make the progressive mask a dropout draw)."""
        a = self.attn
        N, T, d = x.shape
        H = a.num_heads
        W, b = a.in_proj_weight, a.in_proj_bias                  # the packed projection's thirds, contiguous
        q, k, v = (F.linear(x, W[i * d:(i + 1) * d], b[i * d:(i + 1) * d]).view(N, T, H, d // H).transpose(1, 2)
                   for i in range(3))
        bias = torch.zeros(N, 1, 1, T, dtype=x.dtype, device=x.device).masked_fill_(keymask[:, None, None],
                                                                                   float("-inf"))
        out = F.scaled_dot_product_attention(q, k, v, bias, dropout_p=a.dropout if a.training else 0.0)
        upd = a.out_proj(out.transpose(1, 2).reshape(N, T, d))
        with torch.no_grad():
            logits = (q[:, :, :1] @ k.transpose(-1, -2)) / math.sqrt(d // H)          # (N, H, 1, T)
            scores = logits.masked_fill(keymask[:, None, None], float("-inf")).softmax(-1).mean(1)[:, 0, 1:]
        return upd, scores


class Module(nn.Module):
    """One Joint-level Interaction Module: DHM -> DIB #1 -> DCI -> DIB #2 (+ mask update)."""

    def __init__(self, cfg: ModelConfig):
        super().__init__()
        d = cfg.d_model
        mk = lambda: BiMamba(d, cfg.d_state, cfg.expand, cfg.d_conv, cfg.dropout)   # noqa: E731
        self.human_time, self.object_time, self.limb_space = mk(), mk(), mk()
        self.separators = nn.Parameter(torch.randn(len(LIMB_GROUPS), d) * 0.02)
        self.dib1, self.dib2 = DIB(d, cfg.heads, cfg.dropout), DIB(d, cfg.heads, cfg.dropout)
        self.human_cond, self.object_cond = mk(), mk()
        seq, seps = limb_order()
        self.register_buffer("seq", torch.tensor([max(i, 0) for i in seq]), persistent=False)
        self.register_buffer("sep_pos", torch.tensor(seps), persistent=False)
        # back from the 29-token order to the 23 tokens: each joint's first position; the
        # foot-ground node's two outputs are averaged
        first = [seq.index(j) for j in range(HUMAN)]
        self.register_buffer("first", torch.tensor(first), persistent=False)
        self.foot_pos = tuple(p for p, j in enumerate(seq) if j == HUMAN - 1)

    def spatial(self, h: torch.Tensor) -> torch.Tensor:
        """h (L, B, 23, d) -> (L, B, 23, d): the limb-guided scan over each frame's 29 tokens."""
        L, B, J, d = h.shape
        x = h.reshape(L * B, J, d).transpose(0, 1)[self.seq]               # (29, LB, d): token-major
        x[self.sep_pos] = self.separators[:, None, :].to(x.dtype)
        y = self.limb_space.forward_tm(x).transpose(0, 1)                 # (LB, 29, d)
        out = y[:, self.first]
        p, q = self.foot_pos
        out[:, HUMAN - 1] = y[:, p] * 0.5 + y[:, q] * 0.5
        return out.reshape(L, B, J, d)

    def forward(self, h, o, cond, valid, masked, k: int):
        """Time-major: h (L, B, 23, d), o (L, B, d), cond (B, nc, d), valid (L, B), masked
        (L, B, 23) -> (h, o, new mask)."""
        L, B, J, d = h.shape
        vj = valid[:, :, None].expand(L, B, J).reshape(L, B * J)
        h = self.human_time.forward_tm(h.reshape(L, B * J, d), vj).reshape(L, B, J, d)
        o = self.object_time.forward_tm(o, valid)
        h = self.spatial(h)
        h, o, _ = self.dib1(h, o, masked)
        nc = cond.shape[1]
        ones = torch.ones(nc, B, dtype=torch.bool, device=h.device)
        ct = cond.transpose(0, 1)                                          # (nc, B, d)
        hc = torch.cat([ct[:, :, None].expand(nc, B, J, d), h], 0).view(nc + L, B * J, d)
        vjc = torch.cat([ones[:, :, None].expand(nc, B, J).reshape(nc, B * J), vj], 0)
        h = self.human_cond.forward_tm(hc, vjc, prefix=nc)[nc:].reshape(L, B, J, d)
        o = self.object_cond.forward_tm(torch.cat([ct, o], 0), torch.cat([ones, valid], 0), prefix=nc)[nc:]
        h, o, scores = self.dib2(h, o, masked)
        with torch.no_grad():
            new_mask = update_mask(masked, scores.detach(), k)
        return h * valid[..., None, None], o * valid[..., None], new_mask


class EJIM(ConditionEncoders):
    """x0-predicting denoiser with the shared baseline interface (see :mod:`..registry`)."""

    def __init__(self, cfg: ModelConfig, vocab: int = 0, text_width: int = 0):
        d = cfg.d_model
        super().__init__("EJIM", cfg.text_encoder, d, vocab, text_width, next(n for n in (4, 2, 1) if d % n == 0),
                         cfg.text_layers, cfg.dropout, cfg.object_tokens, cfg.object_knn)
        self.cfg = cfg
        self.time = nn.Sequential(nn.Linear(d, d), nn.SiLU(), nn.Linear(d, d))
        self.null_text = nn.Parameter(torch.zeros(d))
        self.enc_h, self.enc_o = nn.Linear(WIDTH, d), nn.Linear(WIDTH, d)
        self.joint_embed = nn.Parameter(torch.randn(HUMAN, d) * 0.02)
        self.modules_ = nn.ModuleList(Module(cfg) for _ in range(cfg.modules))
        self.dec_h, self.dec_o = nn.Linear(d, WIDTH), nn.Linear(d, WIDTH)
        self.last_masks: list[torch.Tensor] = []

    def forward(self, x: torch.Tensor, t: torch.Tensor, keep: torch.Tensor, text_tokens: torch.Tensor,
                text_pad: torch.Tensor, obj_tokens: torch.Tensor, valid: torch.Tensor | None = None) -> torch.Tensor:
        B, L = x.shape[:2]
        if valid is None:
            valid = torch.ones(B, L, dtype=torch.bool, device=x.device)
        w = (~text_pad)[..., None].to(text_tokens.dtype)
        pooled = (text_tokens * w).sum(1) / w.sum(1).clamp(min=1.0)
        text = torch.where(keep[:, None], pooled, self.null_text.expand_as(pooled))
        cond = torch.cat([self.time(sinusoidal(t, self.cfg.d_model))[:, None], text[:, None], obj_tokens], 1)
        xt, vt = x.transpose(0, 1), valid.t()                              # time-major: (L, B, ...)
        h = (self.enc_h(xt[:, :, :HUMAN]) + self.joint_embed) * vt[..., None, None]
        o = self.enc_o(xt[:, :, HUMAN]) * vt[..., None]
        masked = torch.zeros(L, B, HUMAN, dtype=torch.bool, device=x.device)
        self.last_masks = []
        for mod in self.modules_:
            h, o, masked = mod(h, o, cond, vt, masked, self.cfg.mask_k)
            self.last_masks.append(masked.transpose(0, 1))
        out = torch.cat([self.dec_h(h), self.dec_o(o)[:, :, None]], 2).transpose(0, 1)
        return (out * valid[..., None, None]).contiguous()
