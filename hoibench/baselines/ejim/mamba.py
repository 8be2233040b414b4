"""A Mamba-1 block in pure PyTorch (Gu & Dao 2023), with padding and direction handled exactly.

``x -> LayerNorm -> in_proj -> (u, z)``; ``u -> depthwise causal conv (width d_conv) -> SiLU``;
``delta = softplus(dt_proj(x_proj(u)))``, ``B, C = x_proj(u)``; ``y = S6(u, delta, A, B, C, D)``
(:func:`hoibench.baselines.scan.selective_scan`, parallel over time); ``out = out_proj(y *
SiLU(z))``; residual. ``A = -exp(A_log)`` with ``A_log = log(1..d_state)`` (S4D-real),
``dt`` bias initialised so that ``softplus(bias)`` is log-uniform in [1e-3, 1e-1].

Exactness with padding and direction:

- ``valid`` (b, L): padded positions are zeroed after ``in_proj`` and get ``delta = 0``, so
  they neither feed the convolution nor change the state (``exp(0 A) = 1``, input 0).
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

from ..scan import selective_scan


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
