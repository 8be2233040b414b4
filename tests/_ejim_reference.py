"""A frozen copy of EJIM's forward as it was before the fused selective scan: the Blelloch
scan that materialises (sequences, frames, width, state) tensors, the Mamba block, the
module and the denoiser, verbatim (parameter names equal the package's, so one state dict
loads into both). The tests and ``benchmarks/ejim_step.py`` compare the package against it.
"""
from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn

from hoibench.baselines.ejim.config import ModelConfig
from hoibench.baselines.layers import ConditionEncoders, sinusoidal

# ---------------------------------------------------------------- scan (hoibench/baselines/scan.py)
def _blelloch_scan(a: torch.Tensor, b: torch.Tensor, reverse: bool = False) -> torch.Tensor:
    """h along dim 1 (no autograd): Blelloch's work-efficient scan, in place on strided views.

    Up-sweep: for step = 1, 2, 4, ... combine each block end ``i`` (``(i + 1) % 2 step == 0``)
    with the end of the block before it, ``i - step``; afterwards position ``i`` holds the
    aggregate of the block of size lowbit(i + 1) ending at ``i``. Down-sweep: for step = n/4,
    ..., 1 complete every position ``i`` with ``(i + 1)`` an odd multiple (>= 3) of ``step``
    from the finished prefix at ``i - step``. The length is padded to a power of two with
    identity pairs (a = 1, b = 0), which leaves the earlier prefixes unchanged.
    """
    if reverse:
        a, b = a.flip(1), b.flip(1)
    L = a.shape[1]
    n = 1 << max(L - 1, 0).bit_length()
    if n != L:
        pad = list(a.shape)
        pad[1] = n - L
        A, H = torch.cat([a, a.new_ones(pad)], 1), torch.cat([b, b.new_zeros(pad)], 1)
    else:
        A, H = a.clone(), b.clone()
    step = 1
    while step < n:
        left, right = slice(step - 1, n, 2 * step), slice(2 * step - 1, n, 2 * step)
        H[:, right] += A[:, right] * H[:, left]
        A[:, right] *= A[:, left]
        step *= 2
    step = n // 4
    while step >= 1:
        src, dst = slice(2 * step - 1, n - step, 2 * step), slice(3 * step - 1, n, 2 * step)
        H[:, dst] += A[:, dst] * H[:, src]
        step //= 2
    H = H[:, :L]
    return H.flip(1) if reverse else H


class _LinearScan(torch.autograd.Function):
    @staticmethod
    def forward(ctx, a, b):
        h = _blelloch_scan(a, b)
        ctx.save_for_backward(a, h)
        return h

    @staticmethod
    def backward(ctx, grad_h):
        a, h = ctx.saved_tensors
        # g_t = grad_t + a_{t+1} g_{t+1}: a reverse scan with factors a shifted one step left
        a_next = torch.cat([a[:, 1:], torch.zeros_like(a[:, :1])], 1)
        g = _blelloch_scan(a_next, grad_h, reverse=True)
        h_prev = torch.cat([torch.zeros_like(h[:, :1]), h[:, :-1]], 1)
        return g * h_prev, g


def linear_scan(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """``h_t = a_t h_{t-1} + b_t`` along dim 1 of (B, L, ...) tensors (parallel, differentiable)."""
    if a.shape != b.shape:
        raise ValueError(f"linear_scan: a {tuple(a.shape)} and b {tuple(b.shape)} differ in shape")
    if a.shape[1] == 0:
        return b.clone()
    if torch.is_grad_enabled() and (a.requires_grad or b.requires_grad):
        return _LinearScan.apply(a, b)
    return _blelloch_scan(a, b)


def linear_scan_reference(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """The same recurrence step by step (a Python loop over time): the tests' reference."""
    h = torch.zeros_like(b[:, 0])
    out = []
    for t in range(a.shape[1]):
        h = a[:, t] * h + b[:, t]
        out.append(h)
    return torch.stack(out, 1)


def selective_scan(u: torch.Tensor, delta: torch.Tensor, A: torch.Tensor, B: torch.Tensor, C: torch.Tensor,
                   D: torch.Tensor | None = None, scan=linear_scan) -> torch.Tensor:
    """Mamba-1 S6. u, delta: (b, L, d); A: (d, n) (negative); B, C: (b, L, n); D: (d,).
    Returns y (b, L, d): ``h_t = exp(delta_t A) h_{t-1} + delta_t B_t u_t``, ``y_t = C_t h_t + D u_t``."""
    dA = torch.exp(delta[..., None] * A)                          # (b, L, d, n)
    dBu = (delta * u)[..., None] * B[:, :, None, :]               # (b, L, d, n)
    h = scan(dA, dBu)
    y = (h * C[:, :, None, :]).sum(-1)
    return y if D is None else y + u * D


# ---------------------------------------------------------------- Mamba (hoibench/baselines/ejim/mamba.py)
def reversal_index(valid: torch.Tensor, prefix: int = 0) -> torch.Tensor:
    """(b, L) gather index that reverses positions ``prefix .. prefix + n_b - 1`` of each row
    (``n_b`` valid positions after the prefix) and leaves the prefix and the padding in place.
    Its own inverse."""
    b, L = valid.shape
    pos = torch.arange(L, device=valid.device).expand(b, L)
    n = valid[:, prefix:].sum(1, keepdim=True) if L > prefix else torch.zeros(b, 1, dtype=torch.long,
                                                                              device=valid.device)
    inside = (pos >= prefix) & (pos < prefix + n)
    return torch.where(inside, 2 * prefix + n - 1 - pos, pos)


def _gather(x: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
    return torch.gather(x, 1, index[..., None].expand_as(x))


class MambaBlock(nn.Module):
    def __init__(self, d_model: int, d_state: int = 16, expand: int = 2, d_conv: int = 4, dropout: float = 0.0):
        super().__init__()
        inner = expand * d_model
        self.dt_rank = math.ceil(d_model / 16)
        self.d_state = d_state
        self.norm = nn.LayerNorm(d_model)
        self.in_proj = nn.Linear(d_model, 2 * inner)
        self.conv = nn.Conv1d(inner, inner, d_conv, groups=inner, padding=d_conv - 1)
        self.x_proj = nn.Linear(inner, self.dt_rank + 2 * d_state, bias=False)
        self.dt_proj = nn.Linear(self.dt_rank, inner)
        dt = torch.exp(torch.rand(inner) * (math.log(0.1) - math.log(1e-3)) + math.log(1e-3)).clamp(min=1e-4)
        with torch.no_grad():
            self.dt_proj.bias.copy_(dt + torch.log(-torch.expm1(-dt)))        # softplus^-1(dt)
        self.A_log = nn.Parameter(torch.log(torch.arange(1, d_state + 1, dtype=torch.float32)).repeat(inner, 1))
        self.D = nn.Parameter(torch.ones(inner))
        self.out_proj = nn.Linear(inner, d_model)
        self.drop = nn.Dropout(dropout)

    def forward(self, x: torch.Tensor, valid: torch.Tensor | None = None, reverse: bool = False,
                prefix: int = 0) -> torch.Tensor:
        """x (b, L, d) -> (b, L, d); ``valid`` (b, L) bool (True = real position)."""
        b, L, _ = x.shape
        if valid is None:
            valid = torch.ones(b, L, dtype=torch.bool, device=x.device)
        index = reversal_index(valid, prefix) if reverse else None
        h = self.norm(_gather(x, index) if reverse else x)
        m = valid[..., None].to(h.dtype)
        u, z = (self.in_proj(h) * m).chunk(2, dim=-1)
        u = F.silu(self.conv(u.transpose(1, 2))[..., :L].transpose(1, 2)) * m
        dbc = self.x_proj(u)
        dt, B, C = dbc.split([self.dt_rank, self.d_state, self.d_state], dim=-1)
        delta = F.softplus(self.dt_proj(dt)) * m
        y = selective_scan(u, delta, -torch.exp(self.A_log), B, C, self.D)
        out = self.drop(self.out_proj(y * F.silu(z))) * m
        if reverse:
            out = _gather(out, index)
        return x + out


class BiMamba(nn.Module):
    """Two Mamba blocks, the second reading the sequence backwards (EJIM's "two Mamba blocks
    per sub-module"; a denoiser of whole sequences needs both directions)."""

    def __init__(self, d_model: int, d_state: int, expand: int, d_conv: int, dropout: float):
        super().__init__()
        self.fwd = MambaBlock(d_model, d_state, expand, d_conv, dropout)
        self.bwd = MambaBlock(d_model, d_state, expand, d_conv, dropout)

    def forward(self, x, valid=None, prefix: int = 0):
        return self.bwd(self.fwd(x, valid, prefix=prefix), valid, reverse=True, prefix=prefix)


# ---------------------------------------------------------------- model (hoibench/baselines/ejim/model.py)
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
        upd = self.attn(x, x, x, key_padding_mask=keymask, need_weights=False)[0]
        scores = self.object_scores(x, keymask).reshape(B, L, J)
        live = (~keymask)[..., None].to(tok.dtype)                         # masked tokens: no update
        tok = tok + upd * live
        tok = tok + self.ff(tok) * live
        tok = tok.reshape(B, L, J + 1, d)
        return tok[:, :, 1:], tok[:, :, 0], scores

    def object_scores(self, x: torch.Tensor, keymask: torch.Tensor) -> torch.Tensor:
        """(N, J) attention of the object query (token 0) to the joint keys, averaged over
        heads: ``mean_h softmax_k(q_h . k_h / sqrt(d_h))`` with masked keys excluded, computed
        without attention dropout (``nn.MultiheadAttention`` returns its weights after
        dropout in training, which would make the progressive mask a dropout draw)."""
        a = self.attn
        N, T, d = x.shape
        H = a.num_heads
        q = F.linear(x[:, :1], a.in_proj_weight[:d], a.in_proj_bias[:d]).view(N, 1, H, d // H).transpose(1, 2)
        k = F.linear(x, a.in_proj_weight[d:2 * d], a.in_proj_bias[d:2 * d]).view(N, T, H, d // H).transpose(1, 2)
        logits = (q @ k.transpose(-1, -2)) / math.sqrt(d // H)              # (N, H, 1, T)
        logits = logits.masked_fill(keymask[:, None, None], float("-inf"))
        return logits.softmax(-1).mean(1)[:, 0, 1:]


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
        self.register_buffer("is_sep", torch.tensor([i < 0 for i in seq]), persistent=False)
        self.register_buffer("sep_pos", torch.tensor(seps), persistent=False)
        # back from the 29-token order to the 23 tokens: each joint's positions (22 appears twice)
        back = torch.zeros(HUMAN, len(seq))
        for p, j in enumerate(seq):
            if j >= 0:
                back[j, p] = 1.0
        self.register_buffer("back", back / back.sum(1, keepdim=True), persistent=False)

    def spatial(self, h: torch.Tensor) -> torch.Tensor:
        B, L, J, d = h.shape
        x = h.reshape(B * L, J, d)[:, self.seq]                            # (BL, 29, d)
        sep = torch.zeros_like(x)
        sep[:, self.sep_pos] = self.separators
        x = torch.where(self.is_sep[None, :, None], sep, x)
        y = self.limb_space(x)
        return torch.einsum("jp,npd->njd", self.back, y).reshape(B, L, J, d)

    def forward(self, h, o, cond, valid, masked, k: int):
        B, L, J, d = h.shape
        vj = valid[:, None].expand(B, J, L).reshape(B * J, L)
        h = self.human_time(h.permute(0, 2, 1, 3).reshape(B * J, L, d), vj).reshape(B, J, L, d).permute(0, 2, 1, 3)
        o = self.object_time(o, valid)
        h = self.spatial(h)
        h, o, _ = self.dib1(h, o, masked)
        nc = cond.shape[1]
        ones = torch.ones(B, nc, dtype=torch.bool, device=h.device)
        hc = torch.cat([cond[:, None].expand(B, J, nc, d).reshape(B * J, nc, d),
                        h.permute(0, 2, 1, 3).reshape(B * J, L, d)], 1)
        vjc = torch.cat([ones[:, None].expand(B, J, nc).reshape(B * J, nc), vj], 1)
        h = self.human_cond(hc, vjc, prefix=nc)[:, nc:].reshape(B, J, L, d).permute(0, 2, 1, 3)
        o = self.object_cond(torch.cat([cond, o], 1), torch.cat([ones, valid], 1), prefix=nc)[:, nc:]
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
        h = (self.enc_h(x[:, :, :HUMAN]) + self.joint_embed) * valid[..., None, None]
        o = self.enc_o(x[:, :, HUMAN]) * valid[..., None]
        masked = torch.zeros(B, L, HUMAN, dtype=torch.bool, device=x.device)
        self.last_masks = []
        for mod in self.modules_:
            h, o, masked = mod(h, o, cond, valid, masked, self.cfg.mask_k)
            self.last_masks.append(masked)
        out = torch.cat([self.dec_h(h), self.dec_o(o)[:, :, None]], 2)
        return out * valid[..., None, None]
