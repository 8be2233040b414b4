"""Selective scan (Mamba's S6 recurrence) in pure PyTorch.

:func:`selective_scan` is Mamba-1's S6 with zero-order-hold ``A`` and the simplified (Euler)
``B``: ``h_t = exp(delta_t A) h_{t-1} + delta_t B_t u_t`` (``h_{-1} = 0``, per channel ``d`` and
state ``n``), ``y_t = C_t . h_t + D u_t``. It runs time-major as a loop over time chunks of
about ``CHUNK_ELEMENTS`` state entries (one step for many sequences, many steps for few):
per chunk ``exp(delta A)`` and ``delta B u`` for the chunk only, the recurrence one step at a
time in place, and the ``C`` contraction as one batched product, so no (sequences, frames,
width, state) tensor is streamed through memory again and again; the state sits as (state,
width) with the width contiguous, so every broadcast runs over the contiguous width.

Its backward is written out (:class:`_S6`): the adjoint ``g_t = dL/dh_t`` runs backwards in
time, ``g_t = C_t dy_t + exp(delta_{t+1} A) g_{t+1}``, and with ``q_t = g_t h_{t-1}
exp(delta_t A)``: ``dL/dA = sum_t delta_t q_t``, ``dL/ddelta_t = sum_n A q_t + u_t sum_n B_t
g_t``, ``dL/du_t = delta_t sum_n B_t g_t + D dy_t``, ``dL/dB_t = sum_d delta_t u_t g_t``,
``dL/dC_t = sum_d dy_t h_t``, ``dL/dD = sum_t dy_t u_t``. Training keeps each chunk's states h
and ``exp(delta A)`` for it (chunks of a few hundred KB: reused memory, where one tensor of
the whole scan would be a fresh memory mapping at every call); sampling keeps nothing.

With numba installed (``pip install hoibench[fast]``) float32 scans on the CPU run the same
recurrence and backward as compiled loops instead (:mod:`.kernels`, one pass per sequence;
``HOIBENCH_KERNELS=torch`` keeps this module's loop).

:func:`linear_scan` is the general ``h_t = a_t h_{t-1} + b_t`` over given tensors by
Blelloch's work-efficient parallel scan (``2 log2 L`` vectorised steps over strided views,
up-sweep and down-sweep, an adjoint reverse scan as its backward); :func:`linear_scan_reference`
is the same recurrence as a plain loop, the tests' reference. ``benchmarks/scan.py`` compares
them; EJIM used ``linear_scan`` under S6 before :func:`selective_scan` fused it.
"""
from __future__ import annotations

import torch

from . import kernels

#: state entries (frames x sequences x state x width) per time chunk: 128 Ki floats, 512 KiB
CHUNK_ELEMENTS = 1 << 17


def _chunks(L: int, per_step: int) -> list[tuple[int, int]]:
    step = max(1, CHUNK_ELEMENTS // max(per_step, 1))
    return [(t, min(L, t + step)) for t in range(0, L, step)]


def _s6_forward(u, delta, At, B, C, keep: bool):
    """Time-major S6 without ``D``: u, delta (L, b, d); At (n, d) = A transposed; B, C (L, b, n).

    Per time chunk: ``E = exp(delta A)`` and ``X = delta B u`` for the chunk (T, b, n, d), the
    recurrence ``h_t = E_t h_{t-1} + X_t`` step by step in place of X, ``y = C . h`` for the
    chunk. Returns y (L, b, d) and, with ``keep``, the chunks' (E, h) for the backward pass
    (chunks of about ``CHUNK_ELEMENTS`` entries: reused memory, not a fresh mapping per call)."""
    L, b, d = u.shape
    n = At.shape[0]
    du = delta * u
    y = u.new_empty(L, b, d)
    saved = []
    h = None
    for t0, t1 in _chunks(L, b * n * d):
        T = t1 - t0
        E = torch.mul(delta[t0:t1, :, None, :], At, out=u.new_empty(T, b, n, d)).exp_()
        X = torch.mul(B[t0:t1, :, :, None], du[t0:t1, :, None, :], out=u.new_empty(T, b, n, d))
        for i in range(T):
            if h is not None:
                X[i].addcmul_(E[i], h)
            h = X[i]
        torch.bmm(C[t0:t1].reshape(T * b, 1, n), X.view(T * b, n, d), out=y[t0:t1].view(T * b, 1, d))
        if keep:
            saved.append((E, X))
    return y, saved


def _s6_backward(u, delta, At, B, C, saved, dy):
    """Gradients of :func:`_s6_forward`'s y (time-major) for u, delta, At, B, C, chunk by
    chunk backwards in time: the adjoint ``g_t = C_t dy_t + E_{t+1} g_{t+1}`` step by step,
    the rest as products over the chunk."""
    L, b, d = u.shape
    n = At.shape[0]
    du = delta * u
    gdecay = u.new_empty(L, b, d)             # sum_n A q_t
    GB = u.new_empty(L, b, d)                 # sum_n B_t g_t
    gB, gC = u.new_empty(L, b, n), u.new_empty(L, b, n)
    gAt = At.new_zeros(At.shape)
    chunks = _chunks(L, b * n * d)
    g_next = E_next = None
    for k in range(len(chunks) - 1, -1, -1):
        t0, t1 = chunks[k]
        T = t1 - t0
        E, H = saved[k]
        G = torch.mul(C[t0:t1, :, :, None], dy[t0:t1, :, None, :], out=u.new_empty(T, b, n, d))
        for i in range(T - 1, -1, -1):
            if g_next is not None:
                G[i].addcmul_(E_next, g_next)
            g_next, E_next = G[i], E[i]
        q = torch.mul(H, dy[t0:t1, :, None, :], out=u.new_empty(T, b, n, d))
        torch.sum(q, -1, out=gC[t0:t1])
        torch.bmm(B[t0:t1].reshape(T * b, 1, n), G.view(T * b, n, d), out=GB[t0:t1].view(T * b, 1, d))
        torch.sum(torch.mul(G, du[t0:t1, :, None, :], out=q), -1, out=gB[t0:t1])
        # q_t = g_t h_{t-1} E_t (h_{-1} = 0)
        torch.mul(G[1:], H[:-1], out=q[1:])
        if k > 0:
            torch.mul(G[0], saved[k - 1][1][-1], out=q[0])
        else:
            q[0].zero_()
        q.mul_(E)
        gAt += (q * delta[t0:t1, :, None, :]).sum((0, 1))
        torch.sum(q.mul_(At), 2, out=gdecay[t0:t1])
    return delta * GB, gdecay.addcmul_(u, GB), gAt, gB, gC


class _S6(torch.autograd.Function):
    @staticmethod
    def forward(ctx, u, delta, At, B, C, D):
        ctx.compiled = kernels.usable(u, delta, At, B, C, D)
        if ctx.compiled:
            y, saved = kernels.s6_forward(u, delta, At, B, C, D, keep=True)
        else:
            y, saved = _s6_forward(u, delta, At, B, C, keep=True)
            y.addcmul_(u, D)
        ctx.save_for_backward(u, delta, At, B, C, D)
        ctx.states = saved
        return y

    @staticmethod
    def backward(ctx, dy):
        u, delta, At, B, C, D = ctx.saved_tensors
        saved = ctx.states
        del ctx.states
        dy = dy.contiguous()
        if ctx.compiled:                                   # D dy is inside the compiled gu
            gu, gdelta, gAt, gB, gC = kernels.s6_backward(u, delta, At, B, C, D, saved, dy)
        else:
            gu, gdelta, gAt, gB, gC = _s6_backward(u, delta, At, B, C, saved, dy)
            gu.addcmul_(dy, D)
        return gu, gdelta, gAt, gB, gC, (dy * u).reshape(-1, u.shape[-1]).sum(0)


def selective_scan_tm(u: torch.Tensor, delta: torch.Tensor, A: torch.Tensor, B: torch.Tensor, C: torch.Tensor,
                      D: torch.Tensor | None = None) -> torch.Tensor:
    """:func:`selective_scan` time-major: u, delta (L, b, d); B, C (L, b, n); returns y (L, b, d)."""
    args = (u.contiguous(), delta.contiguous(), A.t().contiguous(), B.contiguous(), C.contiguous(),
            u.new_zeros(u.shape[-1]) if D is None else D)
    if torch.is_grad_enabled() and any(x.requires_grad for x in args):
        return _S6.apply(*args)
    if kernels.usable(*args):
        return kernels.s6_forward(*args, keep=False)[0]
    return _s6_forward(*args[:5], keep=False)[0].addcmul_(args[0], args[5])


def selective_scan(u: torch.Tensor, delta: torch.Tensor, A: torch.Tensor, B: torch.Tensor, C: torch.Tensor,
                   D: torch.Tensor | None = None) -> torch.Tensor:
    """Mamba-1 S6. u, delta: (b, L, d); A: (d, n) (negative); B, C: (b, L, n); D: (d,).
    Returns y (b, L, d): ``h_t = exp(delta_t A) h_{t-1} + delta_t B_t u_t``, ``y_t = C_t h_t + D u_t``."""
    tm = lambda x: x.transpose(0, 1)            # noqa: E731  (time-major)
    return tm(selective_scan_tm(tm(u), tm(delta), A, tm(B), tm(C), D))


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
