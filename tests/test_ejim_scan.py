"""EJIM's fused selective scan and time-major blocks against independent references: a plain
time loop of the S6 recurrence (written here), ``F.conv1d`` for the causal convolution, and
the frozen pre-fusion implementation (``tests/_ejim_reference.py``) for whole models: same
weights and inputs, same outputs and parameter gradients; padding invariance; unchanged
parameter names and shapes. Each float32 check runs with the PyTorch loops and with the
compiled loops (``hoibench.baselines.kernels``, numba; skipped where it is not installed)."""
from __future__ import annotations

import pytest
import torch

import _ejim_reference as R
import torch.nn.functional as F

from hoibench.baselines import kernels, scan
from hoibench.baselines.ejim.config import preset
from hoibench.baselines.ejim.mamba import BiMamba
from hoibench.baselines.ejim.model import EJIM


def s6_loop(u, delta, A, B, C, D):
    """``h_t = exp(delta_t A) h_{t-1} + delta_t B_t u_t``, ``y_t = C_t . h_t + D u_t``, one
    step at a time: u, delta (b, L, d); A (d, n); B, C (b, L, n)."""
    b, L, d = u.shape
    h = u.new_zeros(b, d, A.shape[1])
    ys = []
    for t in range(L):
        h = torch.exp(delta[:, t, :, None] * A) * h + (delta[:, t] * u[:, t])[..., None] * B[:, t, None, :]
        ys.append((h * C[:, t, None, :]).sum(-1) + D * u[:, t])
    return torch.stack(ys, 1)


def s6_inputs(b, L, d, n, dtype, seed, lengths=None):
    g = torch.Generator().manual_seed(seed)
    u = torch.randn(b, L, d, generator=g, dtype=dtype)
    delta = torch.rand(b, L, d, generator=g, dtype=dtype) * 0.3
    if lengths is not None:                                 # padded tails: delta = 0, u = 0
        pad = torch.arange(L)[None] >= torch.tensor(lengths)[:, None]
        u[pad], delta[pad] = 0.0, 0.0
    A = -torch.exp(torch.randn(d, n, generator=g, dtype=dtype))
    B, C = torch.randn(b, L, n, generator=g, dtype=dtype), torch.randn(b, L, n, generator=g, dtype=dtype)
    D = torch.randn(d, generator=g, dtype=dtype)
    return [u, delta, A, B, C, D], torch.randn(b, L, d, generator=g, dtype=dtype)


@pytest.mark.parametrize("L,n,chunk_steps", [(1, 4, None), (7, 16, 3), (64, 8, 5), (196, 4, 1), (196, 16, None),
                                             (400, 6, 64)])
def test_selective_scan_equals_the_time_loop_forward_and_gradients(L, n, chunk_steps, monkeypatch):
    b, d = 3, 5
    if chunk_steps is not None:                             # several time chunks: their seams are tested
        monkeypatch.setattr(scan, "CHUNK_ELEMENTS", chunk_steps * b * n * d)
    lengths = [L, max(1, L - 3), max(1, L // 2)]
    args, w = s6_inputs(b, L, d, n, torch.float64, seed=L + n, lengths=lengths)
    xs = [x.clone().requires_grad_() for x in args]
    rs = [x.clone().requires_grad_() for x in args]
    y, ref = scan.selective_scan(*xs), s6_loop(*rs)
    torch.testing.assert_close(y, ref, rtol=1e-10, atol=1e-10)
    for got, want in zip(torch.autograd.grad((y * w).sum(), xs), torch.autograd.grad((ref * w).sum(), rs)):
        torch.testing.assert_close(got, want, rtol=1e-9, atol=1e-9)
    with torch.no_grad():                                   # sampling's path (no states kept)
        torch.testing.assert_close(scan.selective_scan(*args), ref.detach(), rtol=1e-10, atol=1e-10)


@pytest.fixture(params=["torch", "compiled"])
def backend(request, monkeypatch):
    """The PyTorch loops (``HOIBENCH_KERNELS=torch``) or the compiled ones (numba)."""
    if request.param == "compiled" and kernels.numba is None:
        pytest.skip("numba is not installed (pip install hoibench[fast])")
    monkeypatch.setenv(kernels.ENV, "torch" if request.param == "torch" else "")
    return request.param


def _spy(monkeypatch):
    """Count the calls reaching the compiled loops."""
    calls = []
    for name in ("s6_forward", "s6_backward", "conv_forward", "conv_backward"):
        real = getattr(kernels, name)
        monkeypatch.setattr(kernels, name, lambda *a, _r=real, _n=name, **k: calls.append(_n) or _r(*a, **k))
    return calls


@pytest.mark.parametrize("L,n", [(1, 4), (7, 16), (64, 8), (196, 4), (400, 6)])
def test_selective_scan_float32_matches_the_float64_loop_to_1e_5(L, n, backend, monkeypatch):
    calls = _spy(monkeypatch)
    b, d = 4, 16
    lengths = [L, max(1, L - 6), max(1, L // 2), 1]
    args, w = s6_inputs(b, L, d, n, torch.float64, seed=3 + L + n, lengths=lengths)
    rs = [x.clone().requires_grad_() for x in args]
    xs = [x.float().requires_grad_() for x in args]
    y, ref = scan.selective_scan(*xs), s6_loop(*rs)
    assert _max_rel(y.double(), ref) < 1e-5
    for name, got, want in zip("u delta A B C D".split(), torch.autograd.grad((y * w.float()).sum(), xs),
                               torch.autograd.grad((ref * w).sum(), rs)):
        assert _max_rel(got.double(), want) < 1e-5, name
    with torch.no_grad():                                   # sampling's path (no states kept)
        assert _max_rel(scan.selective_scan(*[x.float() for x in args]).double(), ref.detach()) < 1e-5
    assert (set(calls) == {"s6_forward", "s6_backward"}) == (backend == "compiled")


@pytest.mark.parametrize("L,K", [(1, 4), (3, 4), (50, 4), (9, 2)])
def test_causal_convolution_equals_conv1d_forward_and_gradients(L, K, backend, monkeypatch):
    from hoibench.baselines.ejim.mamba import _CausalConv
    calls = _spy(monkeypatch)
    g = torch.Generator().manual_seed(L + K)
    b, c = 5, 12
    x, wt, bias = torch.randn(L, b, c, generator=g), torch.randn(c, K, generator=g), torch.randn(c, generator=g)
    dy = torch.randn(L, b, c, generator=g)
    xs = [t.clone().requires_grad_() for t in (x, wt, bias)]
    rs = [t.double().requires_grad_() for t in (x, wt, bias)]
    out = _CausalConv.apply(*xs)
    # F.conv1d over (b, c, L) with K - 1 zeros on the left is the causal convolution
    ref = F.conv1d(F.pad(rs[0].permute(1, 2, 0), (K - 1, 0)), rs[1][:, None], rs[2], groups=c).permute(2, 0, 1)
    assert _max_rel(out.double(), ref) < 1e-6
    for name, got, want in zip(("x", "weight", "bias"), torch.autograd.grad((out * dy).sum(), xs),
                               torch.autograd.grad((ref * dy.double()).sum(), rs)):
        assert _max_rel(got.double(), want) < 1e-6, name
    assert (set(calls) == {"conv_forward", "conv_backward"}) == (backend == "compiled")


@pytest.fixture
def one_thread():
    """One torch thread for the model comparisons (two threads on shared cores wait on each other)."""
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


def _max_rel(a: torch.Tensor, b: torch.Tensor) -> float:
    return ((a - b).abs().max() / b.abs().max().clamp(min=1e-30)).item()


def _twin_models(over: dict):
    cfg = preset("tiny").replace(**{"model.object_points": 64, "model.object_knn": 8, **over}).model
    torch.manual_seed(0)
    new = EJIM(cfg, vocab=10)
    old = R.EJIM(cfg, vocab=10)
    old.load_state_dict(new.state_dict())                  # strict: the same names and shapes
    return cfg, new, old


@pytest.mark.parametrize("over", [{"model.d_model": 32},
                                  {"model.d_model": 16, "model.d_state": 16, "model.expand": 2, "model.modules": 3}])
def test_model_equals_the_frozen_reference_outputs_and_parameter_gradients(over, one_thread, backend):
    cfg, new, old = _twin_models(over)
    g = torch.Generator().manual_seed(1)
    B, L = 3, 21
    x = torch.randn(B, L, 24, 12, generator=g)
    valid = torch.arange(L)[None] < torch.tensor([L, 13, 4])[:, None]
    ids, pad = torch.randint(1, 10, (B, 4), generator=g), torch.tensor([[False] * 4, [False] * 2 + [True] * 2,
                                                                         [False] * 4])
    pts, w = torch.randn(B, cfg.object_points, 3, generator=g), torch.randn(B, L, 24, 12, generator=g)
    t, keep = torch.tensor([5, 500, 999]), torch.tensor([True, False, True])
    results = []
    for m in (new, old):
        m.train()
        out = m(x, t, keep, m.encode_text(ids, pad), pad, m.encode_object(pts), valid)
        (out * w).sum().backward()
        results.append((out.detach(), dict(m.named_parameters()), [k.clone() for k in m.last_masks]))
    (o1, p1, m1), (o0, p0, m0) = results
    assert _max_rel(o1, o0) < 1e-5
    assert all(torch.equal(a, b) for a, b in zip(m1, m0))                     # the same joints masked
    assert p1.keys() == p0.keys()
    for name in p0:
        assert _max_rel(p1[name].grad, p0[name].grad) < 1e-5, name


@pytest.mark.parametrize("name", ["tiny", "paper"])
def test_parameter_names_and_shapes_are_unchanged(name):
    cfg = preset(name).replace(**{"model.text_encoder": "tokens"}).model
    new, old = EJIM(cfg, vocab=20).state_dict(), R.EJIM(cfg, vocab=20).state_dict()
    assert {k: tuple(v.shape) for k, v in new.items()} == {k: tuple(v.shape) for k, v in old.items()}


def test_bimamba_padding_changes_neither_valid_outputs_nor_parameter_gradients(backend):
    torch.manual_seed(0)
    m = BiMamba(8, 4, 2, 4, 0.0)
    g = torch.Generator().manual_seed(2)
    x = torch.randn(3, 12, 8, generator=g)
    valid = torch.arange(12)[None] < torch.tensor([12, 9, 2])[:, None]
    w = torch.randn(3, 12, 8, generator=g) * valid[..., None]
    runs = []
    for garbage in (0.0, 1e3):
        xx = x.clone()
        xx[~valid] = garbage * torch.randn(int((~valid).sum()), 8, generator=g)
        m.zero_grad()
        out = m(xx, valid, prefix=3)
        (out * w).sum().backward()
        runs.append((out[valid].detach(), {k: p.grad.clone() for k, p in m.named_parameters()}))
    (o0, g0), (o1, g1) = runs
    torch.testing.assert_close(o1, o0, rtol=1e-6, atol=1e-6)
    for k in g0:
        torch.testing.assert_close(g1[k], g0[k], rtol=1e-5, atol=1e-6)


def test_the_kernels_variable_is_read_strictly(monkeypatch):
    for value, want in (("", "auto"), ("numba", "auto"), (" Torch ", "torch"), ("pytorch", "torch")):
        monkeypatch.setenv(kernels.ENV, value)
        assert kernels.choice() == want
    monkeypatch.setenv(kernels.ENV, "cuda")
    with pytest.raises(ValueError, match="HOIBENCH_KERNELS='cuda': expected 'torch'"):
        scan.selective_scan(*s6_inputs(1, 3, 2, 2, torch.float32, seed=0)[0])


def test_compiled_loops_give_the_same_bits_on_one_and_two_threads():
    if kernels.numba is None:
        pytest.skip("numba is not installed (pip install hoibench[fast])")
    from hoibench.baselines.ejim.mamba import _CausalConv
    b = 2 * kernels.BLOCK + 7                                # three sequence blocks, the last partial
    args, w = s6_inputs(b, 9, 8, 4, torch.float32, seed=5, lengths=[9, 4] * (b // 2) + [1])
    g = torch.Generator().manual_seed(6)
    conv = [torch.randn(9, b, 8, generator=g), torch.randn(8, 4, generator=g), torch.randn(8, generator=g)]
    n = torch.get_num_threads()
    runs = []
    try:
        for threads in (1, 2):
            torch.set_num_threads(threads)
            xs = [x.clone().requires_grad_() for x in args]
            y = scan.selective_scan(*xs)
            cs = [x.clone().requires_grad_() for x in conv]
            c = _CausalConv.apply(*cs)
            runs.append([y, c, *torch.autograd.grad((y * w).sum() + (c * c).sum(), xs + cs)])
    finally:
        torch.set_num_threads(n)
    assert all(torch.equal(a, b) for a, b in zip(*runs))


def test_a_bad_kernels_variable_stops_train_and_sample_before_anything_is_written(tmp_path, monkeypatch, capsys):
    from hoibench.cli import main
    monkeypatch.setenv(kernels.ENV, "gpu")
    for argv in (["baseline", "train", "ejim", str(tmp_path / "data"), "--out", str(tmp_path / "run"), "--steps", "0"],
                 ["baseline", "sample", "ejim", str(tmp_path / "run"), "--data", str(tmp_path / "data"),
                  "--out", str(tmp_path / "sub")]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "HOIBENCH_KERNELS='gpu'" in err[0]
    assert list(tmp_path.iterdir()) == []
