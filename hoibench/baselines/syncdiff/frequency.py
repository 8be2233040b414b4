"""SyncDiff's frequency decomposition (paper 004, section 3.3, appendix B.1).

A trajectory ``x`` of ``n`` frames (any trailing columns) is written on the real Fourier
basis of its own length::

    x(t) = c_0 + sum_{k=1}^{n/2} [a_k cos(2 pi k t / n) + b_k sin(2 pi k t / n)]

Components with ``k > cutoff`` are discarded (mocap noise); the remainder splits into the
low part (``k <= low``, kept in the time domain) and the high part (``low < k <= cutoff``),
which the model sees and predicts as its coefficients ``(a_k, b_k)`` (``2 (cutoff - low)``
rows, the frequency-domain representation) and which :func:`synthesize` turns back into
frames. ``low + high`` is the clipped signal exactly (orthogonality of the basis for
integer ``k < n / 2``). Both limits are clamped to ``(n - 1) // 2`` for short clips, so the
Nyquist term never enters. Padding: every function takes the clip's own frames only.
"""
from __future__ import annotations

import math

import torch

__all__ = ["basis", "clamp", "analyze", "synthesize", "split", "coefficient_rows"]


def clamp(n: int, k: int) -> int:
    """The largest usable frequency index ``<= k`` for ``n`` frames (``(n - 1) // 2``)."""
    return max(0, min(int(k), (int(n) - 1) // 2))


def coefficient_rows(low: int, cutoff: int) -> int:
    """Rows of the high part's frequency representation: ``(a_k, b_k)`` per ``low < k <= cutoff``."""
    return 2 * max(0, cutoff - low)


def basis(n: int, k0: int, k1: int, dtype=torch.float64, device=None) -> torch.Tensor:
    """(n, 2 (k1 - k0)) columns ``cos(2 pi k t / n), sin(2 pi k t / n)`` for ``k0 < k <= k1``
    (interleaved: column ``2 j`` cos, ``2 j + 1`` sin of ``k = k0 + 1 + j``)."""
    t = torch.arange(n, dtype=dtype, device=device)[:, None]
    k = torch.arange(k0 + 1, k1 + 1, dtype=dtype, device=device)[None]
    ang = 2 * math.pi * k * t / n
    return torch.stack([torch.cos(ang), torch.sin(ang)], -1).reshape(n, -1)


def analyze(x: torch.Tensor, k0: int, k1: int) -> torch.Tensor:
    """(2 (k1 - k0), D) coefficients ``(a_k, b_k)`` of ``x`` (n, D), ``k0 < k <= k1``, k1 < n / 2:
    ``a_k = 2/n sum_t x cos``, ``b_k = 2/n sum_t x sin``."""
    n = x.shape[0]
    B = basis(n, k0, k1, x.dtype, x.device)
    return (2.0 / n) * B.T @ x


def synthesize(coef: torch.Tensor, n: int, k0: int) -> torch.Tensor:
    """(n, D) frames of coefficients (2 m, D) for ``k0 < k <= k0 + m``."""
    m = coef.shape[0] // 2
    return basis(n, k0, k0 + m, coef.dtype, coef.device) @ coef


def split(x: torch.Tensor, low: int, cutoff: int) -> tuple[torch.Tensor, torch.Tensor]:
    """(low part (n, D) in frames, high part's coefficients (2 (cutoff - low), D)) of ``x``
    (n, D), after clamping both limits for ``n`` frames (:func:`clamp`); the rows of
    frequencies clamped away are zero."""
    n = x.shape[0]
    lo, hi = clamp(n, low), clamp(n, cutoff)
    mean = x.mean(0, keepdim=True)
    x_low = mean + (synthesize(analyze(x, 0, lo), n, 0) if lo > 0 else 0.0)
    coef = x.new_zeros((coefficient_rows(low, cutoff), x.shape[1]))
    if hi > lo:
        coef[: 2 * (hi - lo)] = analyze(x, lo, hi)
    return x_low, coef


def high_frames(coef: torch.Tensor, n: int, low: int) -> torch.Tensor:
    """(n, D) time-domain high part of ``coef`` (:func:`split`'s second output) for a clip of
    ``n`` frames (rows beyond the clamped cutoff are ignored)."""
    lo = clamp(n, low)
    m = coef.shape[0] // 2
    usable = max(0, clamp(n, lo + m) - lo) if lo == low else 0
    if usable == 0:
        return coef.new_zeros((n, coef.shape[1]))
    return synthesize(coef[: 2 * usable], n, lo)
