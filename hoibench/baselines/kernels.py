"""EJIM's two sequential inner loops compiled (numba; ``pip install hoibench[fast]``): the
selective scan (:mod:`.scan`) and the causal depthwise convolution
(:class:`.ejim.mamba._CausalConv`), forward and backward, the same sums as their PyTorch
versions.

The PyTorch versions dispatch a handful of operators per time step (scan) or per tap
(convolution), each streaming a whole (sequences, state, width) slice through memory; here one
loop walks each sequence once with its state in cache:

- scan: per step ``h = exp(delta A) h + delta B u`` and ``y = C . h + D u`` (forward), and the
  adjoint ``g_t = C_t dy_t + exp(delta_{t+1} A) g_{t+1}`` with every gradient of
  :class:`.scan._S6` (backward; training keeps the states h (L, b, n, d) for it);
- convolution: ``out_t = bias + sum_k w_k x_{t - (K - 1 - k)}`` and its gradients in one pass
  each.

``exp`` is computed as ``2^i 2^f`` (``i`` the rounded exponent, ``2^f`` a degree-7 polynomial,
the reduction in float64, rounded to float32) so that the loops vectorise; float32 only
(training's dtype; float64 runs the PyTorch versions). Work is split into fixed blocks of
:data:`BLOCK` sequences, run on ``torch.get_num_threads()`` threads (the loops release the GIL;
the threads live for one call, so nothing survives a fork); every sum over sequences
(``dL/dA``, ``dL/dD``) is taken afterwards in PyTorch, and the convolution's weight gradient
is summed in float64 per block and then over the blocks in order, so results do not depend on
the thread count. The loops are compiled at the first call and cached on disk (``cache=True``).
``HOIBENCH_KERNELS=torch`` keeps the PyTorch versions.

Layouts (time-major, contiguous): u, delta, x (L, b, d); ``At`` (n, d) = A transposed; B, C
(L, b, n); D, bias (d,); convolution weight (K, d) (transposed from ``nn.Conv1d``'s (d, 1, K)).
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import torch

try:                                                   # optional: pip install hoibench[fast]
    import numba
    import numpy as np
except ImportError:                                    # pragma: no cover - exercised without numba
    numba = None

#: ``HOIBENCH_KERNELS=torch`` keeps the PyTorch versions even where numba is installed
ENV = "HOIBENCH_KERNELS"


_CHOICES = {"": "auto", "auto": "auto", "numba": "auto", "compiled": "auto", "torch": "torch", "pytorch": "torch"}


def choice() -> str:
    """``HOIBENCH_KERNELS``: ``auto`` (unset, ``numba``, ``compiled``: the compiled loops where numba
    is installed) or ``torch`` (``pytorch``: the PyTorch loops); ValueError naming the variable otherwise."""
    raw = os.environ.get(ENV, "")
    try:
        return _CHOICES[raw.strip().lower()]
    except KeyError:
        raise ValueError(f"environment variable {ENV}={raw!r}: expected 'torch' (the PyTorch loops) or "
                         f"'numba' (compiled loops; the default where numba is installed)") from None


def available() -> bool:
    """numba is importable and not switched off by ``HOIBENCH_KERNELS=torch``."""
    return choice() == "auto" and numba is not None


def describe(device="cpu") -> str:
    """Which inner loops run on ``device``: ``compiled (numba X)`` (CPU only) or ``torch`` (run logs
    record it)."""
    return f"compiled (numba {numba.__version__})" if available() and torch.device(device).type == "cpu" \
        else "torch"


def usable(*tensors: torch.Tensor) -> bool:
    """The compiled loops take CPU float32 tensors (training's dtype; float64 runs the PyTorch loop)."""
    return available() and all(t.device.type == "cpu" and t.dtype == torch.float32 for t in tensors)


#: exp(x) = 2^(x log2 e) = 2^i 2^f (i = round(x log2 e), |f| <= 1/2), the reduction in float64;
#: 2^f = e^(f ln 2) by its degree-7 Taylor polynomial (truncation below 6e-9 relative), rounded
#: to float32 (half an ulp); 2^i added to the float's exponent bits. A loop of these vectorises,
#: where a call to the C library's exp per element does not.
_LOG2E = 1.4426950408889634
_P = (1.5252733804059838e-05, 0.00015403530393381606, 0.0013333558146428441, 0.009618129107628477, 0.055504108664821576, 0.2402265069591007, 0.6931471805599453, 1.0)


def _exp_row(x, a, out, bits):
    """``out[j] = exp(x[j] a[j])`` for float32 rows (the product in float32, as PyTorch forms it);
    ``bits`` is ``out`` viewed as int32. Exponents are clamped to [-125, 127] (factors under 2e-38 read
    as 2e-38; the scan's decays exp(delta A), A < 0, never reach the upper end)."""
    for j in range(out.shape[0]):
        v = min(max(np.float64(x[j] * a[j]) * _LOG2E, -125.0), 127.0)
        i = np.floor(v + 0.5)
        f = v - i
        p = _P[0]
        p = p * f + _P[1]
        p = p * f + _P[2]
        p = p * f + _P[3]
        p = p * f + _P[4]
        p = p * f + _P[5]
        p = p * f + _P[6]
        p = p * f + _P[7]
        out[j] = np.float32(p)
        bits[j] += np.int32(i) << 23


def _forward(u, delta, At, B, C, D, y, H, keep, s0, s1):
    L, b, d = u.shape
    n = At.shape[0]
    h = np.zeros((n, d), np.float32)
    du = np.empty(d, np.float32)
    e = np.empty(d, np.float32)
    ebits = e.view(np.int32)
    spare = np.empty(d, np.float32)                    # where the states go when none are kept
    for s in range(s0, s1):
        h[:] = 0.0
        for t in range(L):
            ut, dt, acc = u[t, s], delta[t, s], y[t, s]
            for j in range(d):
                du[j] = dt[j] * ut[j]
                acc[j] = D[j] * ut[j]
            for k in range(n):
                bk = B[t, s, k]
                ck = C[t, s, k]
                _exp_row(dt, At[k], e, ebits)
                hk = h[k]
                out = H[t, s, k] if keep else spare
                for j in range(d):
                    hv = e[j] * hk[j] + bk * du[j]
                    hk[j] = hv
                    out[j] = hv
                    acc[j] += ck * hv


def _backward(u, delta, At, B, C, D, H, dy, gu, gdelta, gA, gB, gC, s0, s1):
    L, b, d = u.shape
    n = At.shape[0]
    g = np.empty((n, d), np.float32)                   # the adjoint g_{t+1}
    e_next = np.empty((n, d), np.float32)              # exp(delta_{t+1} A)
    e = np.empty(d, np.float32)
    ebits = e.view(np.int32)
    zeros = np.zeros(d, np.float32)
    for s in range(s0, s1):
        g[:] = 0.0
        e_next[:] = 0.0
        ga = gA[s]
        for t in range(L - 1, -1, -1):
            ut, dt, dyt = u[t, s], delta[t, s], dy[t, s]
            GB, gdec = gu[t, s], gdelta[t, s]          # sum_n B_t g_t and sum_n A q_t, finished below
            GB[:] = 0.0
            gdec[:] = 0.0
            for k in range(n):
                bk = B[t, s, k]
                ck = C[t, s, k]
                _exp_row(dt, At[k], e, ebits)
                gk, enk, gak, Ak = g[k], e_next[k], ga[k], At[k]
                hk = H[t, s, k]
                hprev = H[t - 1, s, k] if t > 0 else zeros
                gb = np.float32(0.0)
                gc = np.float32(0.0)
                for j in range(d):
                    gv = ck * dyt[j] + enk[j] * gk[j]
                    gk[j] = gv
                    enk[j] = e[j]
                    q = gv * e[j] * hprev[j]                  # g_t h_{t-1} exp(delta_t A)
                    gak[j] += dt[j] * q
                    gdec[j] += Ak[j] * q
                    GB[j] += bk * gv
                    gb += gv * dt[j] * ut[j]
                    gc += dyt[j] * hk[j]
                gB[t, s, k] = gb
                gC[t, s, k] = gc
            for j in range(d):
                gv = GB[j]
                GB[j] = dt[j] * gv + D[j] * dyt[j]             # gu
                gdec[j] += ut[j] * gv                          # gdelta


def _conv_forward(x, wT, bias, out, s0, s1):
    L, b, d = x.shape
    K = wT.shape[0]
    for t in range(L):
        for s in range(s0, s1):
            o = out[t, s]
            o[:] = bias
            for k in range(K):
                src = t - (K - 1 - k)
                if src >= 0:
                    xs, wk = x[src, s], wT[k]
                    for j in range(d):
                        o[j] += wk[j] * xs[j]


def _conv_backward(x, wT, grad, gx, gw, s0, s1):
    """gx (L, b, d) and the block's gw (K, d) float64 (zeroed by the caller) for sequences s0..s1-1."""
    L, b, d = x.shape
    K = wT.shape[0]
    for t in range(L):
        for s in range(s0, s1):
            o = gx[t, s]
            o[:] = 0.0
            xt = x[t, s]
            for k in range(K):
                dst = t + (K - 1 - k)                  # the output this input feeds through tap k
                if dst < L:
                    gs, wk, gwk = grad[dst, s], wT[k], gw[k]
                    for j in range(d):
                        o[j] += wk[j] * gs[j]
                        gwk[j] += gs[j] * xt[j]


if numba is not None:                                  # compiled lazily, at the first call
    _jit = numba.njit(fastmath=True, cache=True, nogil=True)
    _exp_row = numba.njit(fastmath=True, cache=True, nogil=True, inline="always")(_exp_row)
    _forward = _jit(_forward)
    _backward = _jit(_backward)
    _conv_forward = _jit(_conv_forward)
    _conv_backward = _jit(_conv_backward)


def _np(x: torch.Tensor):
    return x.detach().numpy()


#: sequences per block: the unit of work of a thread, and of the convolution's weight-gradient sums
BLOCK = 32


def _blocks(b: int) -> list[tuple[int, int]]:
    return [(s, min(b, s + BLOCK)) for s in range(0, b, BLOCK)]


def _run(kernel, args: tuple, b: int) -> None:
    """``kernel(*args, s0, s1)`` over the fixed sequence blocks, on ``torch.get_num_threads()``
    threads (the loops release the GIL). Blocks are independent and fixed by ``b`` alone, so the
    result does not depend on the thread count."""
    blocks = _blocks(b)
    threads = min(torch.get_num_threads(), len(blocks))
    if threads <= 1:
        for s0, s1 in blocks:
            kernel(*args, s0, s1)
        return
    with ThreadPoolExecutor(threads) as pool:          # per call: nothing survives a fork
        list(pool.map(lambda blk: kernel(*args, *blk), blocks))


def s6_forward(u, delta, At, B, C, D, keep: bool):
    """y (L, b, d) with ``D u`` included, and the states H (L, b, n, d) when ``keep``."""
    L, b, d = u.shape
    n = At.shape[0]
    y = u.new_empty(L, b, d)
    H = u.new_empty(L, b, n, d) if keep else u.new_empty(1, 1, 1, 1)
    _run(_forward, (*map(_np, (u, delta, At, B, C, D, y, H)), keep), b)
    return y, (H if keep else None)


def s6_backward(u, delta, At, B, C, D, H, dy):
    """Gradients of :func:`s6_forward`'s y for u, delta, At, B and C (D's is the caller's)."""
    L, b, d = u.shape
    n = At.shape[0]
    gu, gdelta = u.new_empty(L, b, d), u.new_empty(L, b, d)
    gA = u.new_zeros(b, n, d)
    gB, gC = u.new_empty(L, b, n), u.new_empty(L, b, n)
    _run(_backward, tuple(map(_np, (u, delta, At, B, C, D, H, dy, gu, gdelta, gA, gB, gC))), b)
    return gu, gdelta, gA.sum(0), gB, gC


def conv_forward(x: torch.Tensor, weight: torch.Tensor, bias: torch.Tensor) -> torch.Tensor:
    """x (L, b, d), weight (d, K), bias (d,) -> the causal convolution (L, b, d)."""
    out = torch.empty_like(x)
    _run(_conv_forward, (_np(x), _np(weight.t().contiguous()), _np(bias), _np(out)), x.shape[1])
    return out


def conv_backward(x: torch.Tensor, weight: torch.Tensor, grad: torch.Tensor):
    """Gradients of :func:`conv_forward` for x and weight (d, K) (the bias's is the caller's); the
    weight gradient is summed in float64 per sequence block, then over the blocks in order."""
    b = x.shape[1]
    blocks = _blocks(b)
    gx = torch.empty_like(x)
    gw = torch.zeros(len(blocks), weight.shape[1], weight.shape[0], dtype=torch.float64)
    xs, wT, gs, gxs, gws = _np(x), _np(weight.t().contiguous()), _np(grad), _np(gx), _np(gw)

    def one(s0, s1):
        _conv_backward(xs, wT, gs, gxs, gws[s0 // BLOCK], s0, s1)

    _run(one, (), b)
    return gx, gw.sum(0).t().to(weight.dtype)
