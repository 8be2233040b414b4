"""The shared diffusion core: schedule, noising, DDIM, classifier-free guidance, EMA."""
from __future__ import annotations

import math

import pytest
import torch

from hoibench.baselines.diffusion import EMA, DiffusionConfig, GaussianDiffusion, drop_condition, masked_mse


def test_linear_schedule_matches_its_definition():
    d = GaussianDiffusion()
    assert d.betas.shape == (1000,)
    assert float(d.betas[0]) == pytest.approx(1e-4) and float(d.betas[-1]) == pytest.approx(0.02)
    # abar_t = prod (1 - beta_s), computed independently in plain Python
    prod = 1.0
    for s in range(10):
        prod *= 1 - (1e-4 + s * (0.02 - 1e-4) / 999)
    assert float(d.alphas_cumprod[9]) == pytest.approx(prod, rel=1e-12)
    assert float(d.alphas_cumprod[-1]) < 1e-4          # T = 1000 ends near pure noise


def test_q_sample_is_the_closed_form():
    d = GaussianDiffusion()
    g = torch.Generator().manual_seed(0)
    x0, noise = torch.randn(3, 5, generator=g, dtype=torch.float64), torch.randn(3, 5, generator=g, dtype=torch.float64)
    t = torch.tensor([0, 499, 999])
    xt = d.q_sample(x0, t, noise)
    for i, ti in enumerate(t.tolist()):
        a = float(d.alphas_cumprod[ti])
        assert torch.allclose(xt[i], math.sqrt(a) * x0[i] + math.sqrt(1 - a) * noise[i], rtol=0, atol=1e-12)
    # float32 inputs: the same within float32 rounding
    x32 = d.q_sample(x0.float(), t, noise.float())
    assert torch.allclose(x32.double(), xt, rtol=1e-6, atol=1e-6)


def test_ddim_timesteps_are_fifty_evenly_spaced_descending():
    ts = GaussianDiffusion().ddim_timesteps()
    assert len(ts) == 50 and ts[0] == 980 and ts[-1] == 0
    assert all(a - b == 20 for a, b in zip(ts, ts[1:]))


def test_ddim_with_an_oracle_returns_the_oracle_sample():
    """A model that always predicts the same x0 must be sampled to exactly that x0."""
    target = torch.randn(2, 7, 3)
    d = GaussianDiffusion(DiffusionConfig(ddim_steps=10))
    out = d.ddim_sample(lambda x, t, keep: target.repeat(x.shape[0] // 2, 1, 1), (2, 7, 3),
                        generator=torch.Generator().manual_seed(0))
    assert torch.allclose(out, target, atol=1e-6)


def test_guidance_formula_and_scale_one_is_conditional():
    torch.manual_seed(0)
    net = torch.nn.Linear(4, 4)
    cond_shift = torch.randn(4)

    def model(x, t, keep):
        return net(x) + keep[:, None].float() * cond_shift

    x, t = torch.randn(3, 4), torch.zeros(3, dtype=torch.long)
    cond = model(x, t, torch.ones(3, dtype=torch.bool))
    uncond = model(x, t, torch.zeros(3, dtype=torch.bool))
    with torch.no_grad():
        assert torch.allclose(GaussianDiffusion.guided(model, x, t, 1.0), cond, atol=1e-6)
        assert torch.allclose(GaussianDiffusion.guided(model, x, t, 2.5), uncond + 2.5 * (cond - uncond), atol=1e-6)
        assert torch.allclose(GaussianDiffusion.guided(model, x, t, 0.0), uncond, atol=1e-6)


def test_condition_drop_rate_and_masked_mse():
    keep = drop_condition(20000, 0.2, torch.Generator().manual_seed(1))
    assert abs(1 - keep.float().mean().item() - 0.2) < 0.01
    pred, target = torch.zeros(2, 3, 1), torch.ones(2, 3, 1)
    target[0, 2] = 10.0                                   # a padded row must not count
    mask = torch.tensor([[True, True, False], [True, False, False]])
    assert masked_mse(pred, target, mask).item() == pytest.approx(1.0)


def test_ema_moves_toward_the_weights():
    net = torch.nn.Linear(2, 2, bias=False)
    ema = EMA(net, decay=0.9)
    before = ema.shadow.weight.clone()
    with torch.no_grad():
        net.weight.add_(1.0)
    ema.update(net)
    assert torch.allclose(ema.shadow.weight, 0.9 * before + 0.1 * net.weight)


@pytest.mark.parametrize("bad", [{"steps": 1}, {"beta_start": 0.0}, {"ddim_steps": 0}, {"ddim_steps": 2000},
                                 {"cond_drop": 1.0}])
def test_bad_config_is_refused_naming_the_field(bad):
    with pytest.raises(ValueError, match="diffusion."):
        DiffusionConfig(**bad)
