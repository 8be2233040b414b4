"""Selective scan (Mamba's S6 recurrence) in pure PyTorch, parallel over time.

The recurrence ``h_t = a_t * h_{t-1} + b_t`` (``h_{-1} = 0``, elementwise) is an associative
scan over pairs ``(a, b)`` with ``(a1, b1) . (a2, b2) = (a1 a2, a2 b1 + b2)``.
:func:`linear_scan` evaluates it by recursive doubling (Hillis & Steele): ``ceil(log2 L)``
vectorised steps, each combining every position with the one ``2^k`` earlier; no Python loop
over time. Only products of factors ``a`` in (0, 1] occur (``a = exp(delta * A)`` with
``A < 0``), so it is stable in float32 for any length, unlike the log-space cumulative-sum
form, whose ``exp(-cumsum(log a))`` overflows on long sequences.

The backward pass is the adjoint recurrence, itself a scan in reverse time:
``g_t = dL/dh_t + a_{t+1} g_{t+1}``, ``dL/db_t = g_t``, ``dL/da_t = g_t h_{t-1}``; autograd
therefore saves only ``a`` and ``h`` (not the log L intermediate levels).

:func:`selective_scan` is Mamba's S6 with zero-order-hold ``A`` and the simplified (Euler)
``B`` of Mamba-1: ``a = exp(delta A)``, ``b = delta B u``, ``y_t = C_t . h_t + D u_t``.
"""
from __future__ import annotations

import torch


def _doubling_scan(a: torch.Tensor, b: torch.Tensor, reverse: bool = False) -> torch.Tensor:
    """h along dim 1 (no autograd): recursive doubling."""
    if reverse:
        a, b = a.flip(1), b.flip(1)
    A, H = a.clone(), b.clone()
    L = a.shape[1]
    k = 1
    while k < L:
        # combine position t with t - k: H_t += A_t * H_{t-k}; A_t *= A_{t-k}
        H_prev = H[:, :-k]
        A_prev = A[:, :-k]
        H = torch.cat([H[:, :k], H[:, k:] + A[:, k:] * H_prev], 1)
        A = torch.cat([A[:, :k], A[:, k:] * A_prev], 1)
        k *= 2
    return H.flip(1) if reverse else H


class _LinearScan(torch.autograd.Function):
    @staticmethod
    def forward(ctx, a, b):
        h = _doubling_scan(a, b)
        ctx.save_for_backward(a, h)
        return h

    @staticmethod
    def backward(ctx, grad_h):
        a, h = ctx.saved_tensors
        # g_t = grad_t + a_{t+1} g_{t+1}: a reverse scan with factors a shifted one step left
        a_next = torch.cat([a[:, 1:], torch.zeros_like(a[:, :1])], 1)
        g = _doubling_scan(a_next, grad_h, reverse=True)
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
    return _doubling_scan(a, b)


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
