"""A Mamba-1 block in pure PyTorch (Gu & Dao 2023), with padding and direction handled exactly.

``x -> LayerNorm -> in_proj -> (u, z)``; ``u -> depthwise causal conv (width d_conv) -> SiLU``;
``delta = softplus(dt_proj(x_proj(u)))``, ``B, C = x_proj(u)``; ``y = S6(u, delta, A, B, C, D)``
(:func:`hoibench.baselines.scan.selective_scan_tm`); ``out = out_proj(y * SiLU(z))``;
residual. ``A = -exp(A_log)`` with ``A_log = log(1..d_state)`` (S4D-real), ``dt`` bias
initialised so that ``softplus(bias)`` is log-uniform in [1e-3, 1e-1].

The block computes time-major (:meth:`MambaBlock.forward_tm`, x (L, b, d)): every
projection is row-wise, the causal convolution is ``d_conv`` shifted multiply-adds along
the leading (time) axis (:class:`_CausalConv`, the same sum as ``nn.Conv1d`` with
``padding = d_conv - 1`` cut to L), and the scan reads one time step's rows at a time.
:meth:`MambaBlock.forward` takes (b, L, d).

Exactness with padding and direction:

- ``valid`` (b, L): padding sits at the end of every sequence (after the reversal below
  too), and every step of the block is row-wise or causal (convolution, scan), so a valid
  position never reads a padded one; the block's output is zeroed at padded positions, so
  the residual stream there is left as it came. Gradients reach no padded position (its
  output is zeroed and nothing valid reads it), so padding changes neither outputs nor
  parameter gradients.
- ``reverse``: each sequence's valid part is reversed in place (padding stays at the end),
  so the backward scan of a padded sequence equals that of the unpadded one.
- ``prefix``: the first ``prefix`` positions (condition tokens) are never reversed, so in
  both directions the sequence is read conditions first (EJIM's condition injector).
"""
from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn

from .. import kernels
from ..scan import selective_scan_tm


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


class _Rows(torch.autograd.Function):
    """``x.view(N, d)[rows]`` for a permutation ``rows`` that is its own inverse: the backward
    is the same row gather."""

    @staticmethod
    def forward(ctx, x, rows):
        ctx.save_for_backward(rows)
        return x.reshape(-1, x.shape[-1]).index_select(0, rows).view(x.shape)

    @staticmethod
    def backward(ctx, grad):
        rows, = ctx.saved_tensors
        return grad.reshape(-1, grad.shape[-1]).index_select(0, rows).view(grad.shape), None


def reversal_rows(valid_tm: torch.Tensor, prefix: int = 0) -> torch.Tensor:
    """Flat row index into a time-major (L, b, ...) tensor viewed as (L b, ...) that applies
    :func:`reversal_index` to every sequence; its own inverse."""
    L, b = valid_tm.shape
    src = reversal_index(valid_tm.t(), prefix).t()                              # (L, b) source time
    return (src * b + torch.arange(b, device=valid_tm.device)).reshape(-1)


class _CausalConv(torch.autograd.Function):
    """Depthwise causal convolution along dim 0 of x (L, b, c) with weight (c, K), bias (c):
    ``out_t = bias + sum_k w_k x_{t - (K - 1 - k)}`` (x before 0 reads as 0)."""

    @staticmethod
    def forward(ctx, x, weight, bias):
        ctx.compiled = kernels.usable(x, weight, bias)
        if ctx.compiled:                                   # one compiled pass (hoibench[fast])
            x = x.contiguous()
            ctx.save_for_backward(x, weight)
            return kernels.conv_forward(x, weight, bias)
        L, K = x.shape[0], weight.shape[1]
        out = bias.expand_as(x).clone()
        for k in range(K):
            s = K - 1 - k
            if s < L:
                out[s:].addcmul_(x[:L - s], weight[:, k])
        ctx.save_for_backward(x, weight)
        return out

    @staticmethod
    def backward(ctx, grad):
        x, weight = ctx.saved_tensors
        grad = grad.contiguous()
        if ctx.compiled:
            gx, gw = kernels.conv_backward(x, weight, grad)
        else:
            L, K = x.shape[0], weight.shape[1]
            gx = torch.zeros_like(x)
            gw = weight.new_zeros(weight.shape)
            for k in range(K):
                s = K - 1 - k
                if s < L:
                    gx[:L - s].addcmul_(grad[s:], weight[:, k])
                    gw[:, k] = (grad[s:] * x[:L - s]).reshape(-1, x.shape[-1]).sum(0)
        return gx, gw, grad.reshape(-1, grad.shape[-1]).sum(0)


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
        vt = None if valid is None else valid.t()
        return self.forward_tm(x.transpose(0, 1), vt, reverse, prefix).transpose(0, 1)

    def forward_tm(self, x: torch.Tensor, valid: torch.Tensor | None = None, reverse: bool = False,
                   prefix: int = 0, rows: torch.Tensor | None = None) -> torch.Tensor:
        """Time-major: x (L, b, d) -> (L, b, d); ``valid`` (L, b) bool; ``rows``: the
        :func:`reversal_rows` of ``valid`` and ``prefix`` when the caller has them."""
        L, b, _ = x.shape
        if valid is None:
            valid = torch.ones(L, b, dtype=torch.bool, device=x.device)
        if reverse and rows is None:
            rows = reversal_rows(valid, prefix)
        h = self.norm(_Rows.apply(x, rows) if reverse else x)
        W, bias, inner = self.in_proj.weight, self.in_proj.bias, self.D.shape[0]
        u, z = F.linear(h, W[:inner], bias[:inner]), F.linear(h, W[inner:], bias[inner:])   # in_proj's halves, contiguous
        u = F.silu(_CausalConv.apply(u, self.conv.weight[:, 0], self.conv.bias))
        dt, B, C = self.x_proj(u).split([self.dt_rank, self.d_state, self.d_state], dim=-1)
        delta = F.softplus(self.dt_proj(dt))
        y = selective_scan_tm(u, delta, -torch.exp(self.A_log), B, C, self.D)
        out = self.drop(self.out_proj(y * F.silu(z)))
        if not bool(valid.all()):
            out = out * valid[..., None].to(out.dtype)
        if reverse:
            out = _Rows.apply(out, rows)
        return x + out


class BiMamba(nn.Module):
    """Two Mamba blocks, the second reading the sequence backwards (EJIM's "two Mamba blocks
    per sub-module"; a denoiser of whole sequences needs both directions)."""

    def __init__(self, d_model: int, d_state: int, expand: int, d_conv: int, dropout: float):
        super().__init__()
        self.fwd = MambaBlock(d_model, d_state, expand, d_conv, dropout)
        self.bwd = MambaBlock(d_model, d_state, expand, d_conv, dropout)

    def forward(self, x, valid=None, prefix: int = 0):
        """x (b, L, d), valid (b, L)."""
        vt = None if valid is None else valid.t()
        return self.forward_tm(x.transpose(0, 1), vt, prefix).transpose(0, 1)

    def forward_tm(self, x, valid=None, prefix: int = 0):
        """Time-major: x (L, b, d), valid (L, b)."""
        return self.bwd.forward_tm(self.fwd.forward_tm(x, valid, prefix=prefix), valid, reverse=True, prefix=prefix)
