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
from hoibench.baselines import scan as _scan
from hoibench.baselines.ejim import mamba as _mamba
from hoibench.baselines.ejim import model as _model
from hoibench.baselines.layers import ConditionEncoders, sinusoidal

# unchanged by the fused scan: taken from the package (their code is the reference's)
linear_scan, linear_scan_reference = _scan.linear_scan, _scan.linear_scan_reference
HUMAN, WIDTH, LIMB_GROUPS, limb_order, update_mask = (_model.HUMAN, _model.WIDTH, _model.LIMB_GROUPS,
                                                      _model.limb_order, _model.update_mask)

# ---------------------------------------------------------------- scan (hoibench/baselines/scan.py)
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


class MambaBlock(_mamba.MambaBlock):
    """The package's parameters (one state dict loads into both); the forward before the
    fused scan."""

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
