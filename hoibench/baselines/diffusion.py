"""The diffusion core every hoibench diffusion baseline shares (ChainHOI, EJIM).

- Forward process (DDPM, Ho et al. 2020): ``q(x_t | x_0) = N(sqrt(abar_t) x_0, (1 - abar_t) I)``
  with ``abar_t = prod_{s<=t} (1 - beta_s)``, ``beta`` linear from ``beta_start`` to
  ``beta_end`` over ``steps`` (1e-4 .. 0.02 over 1000 steps, as ChainHOI, appendix B.1).
  Timesteps are 0-based: ``t = 0`` is the first noising step.
- x0 parameterisation: the network predicts the clean sample ``x_0`` (as MDM and ChainHOI);
  the diffusion loss is the masked mean squared error to ``x_0``.
- DDIM sampling (Song et al. 2021) over ``ddim_steps`` evenly spaced timesteps
  ``t_i = i * steps // ddim_steps`` (i = 0..n-1, visited from the last), eta = 0
  (deterministic given the initial noise): ``eps = (x_t - sqrt(abar_t) x0) / sqrt(1 - abar_t)``,
  ``x_prev = sqrt(abar_prev) x0 + sqrt(1 - abar_prev - sigma^2) eps + sigma z``.
- Classifier-free guidance (Ho & Salimans 2022) on the x0 prediction:
  ``x0 = x0_uncond + s (x0_cond - x0_uncond)``; s = 1 is the conditional prediction.
  Training drops the condition with probability ``cond_drop`` per sample.
- EMA of the weights: ``ema = decay * ema + (1 - decay) * w`` after each optimiser step.

Imports only torch (and numpy), so it runs on a machine that has nothing else.
"""
from __future__ import annotations

import copy
from dataclasses import asdict, dataclass
from typing import Callable

import torch


@dataclass(frozen=True)
class DiffusionConfig:
    steps: int = 1000               # T
    beta_start: float = 1e-4
    beta_end: float = 0.02
    ddim_steps: int = 50
    ddim_eta: float = 0.0
    guidance: float = 2.0           # classifier-free guidance scale at sampling
    cond_drop: float = 0.2          # probability of dropping the text in training

    def __post_init__(self) -> None:
        if not (isinstance(self.steps, int) and self.steps >= 2):
            raise ValueError(f"diffusion.steps: expected an integer >= 2, got {self.steps!r}")
        if not 0 < self.beta_start <= self.beta_end < 1:
            raise ValueError(f"diffusion.beta_start/beta_end: expected 0 < start <= end < 1, got "
                             f"{self.beta_start}, {self.beta_end}")
        if not (isinstance(self.ddim_steps, int) and 1 <= self.ddim_steps <= self.steps):
            raise ValueError(f"diffusion.ddim_steps: expected an integer in [1, {self.steps}], got {self.ddim_steps!r}")
        if not 0 <= self.cond_drop < 1:
            raise ValueError(f"diffusion.cond_drop: expected a probability in [0, 1), got {self.cond_drop!r}")
        if not self.ddim_eta >= 0:
            raise ValueError(f"diffusion.ddim_eta: expected >= 0, got {self.ddim_eta!r}")

    def to_dict(self) -> dict:
        return asdict(self)


#: model(x_t, t, cond_mask) -> x0 prediction; ``cond_mask`` (B,) bool: True = condition kept
X0Model = Callable[[torch.Tensor, torch.Tensor, torch.Tensor], torch.Tensor]


class GaussianDiffusion:
    """Schedule, noising, x0-parameterised DDIM sampling with classifier-free guidance."""

    def __init__(self, config: DiffusionConfig | None = None):
        self.config = config or DiffusionConfig()
        c = self.config
        self.betas = torch.linspace(c.beta_start, c.beta_end, c.steps, dtype=torch.float64)
        self.alphas_cumprod = torch.cumprod(1.0 - self.betas, dim=0)

    @property
    def steps(self) -> int:
        return self.config.steps

    def _abar(self, t: torch.Tensor, like: torch.Tensor) -> torch.Tensor:
        a = self.alphas_cumprod.to(like.device)[t.long().to(like.device)].to(like.dtype)
        return a.view(-1, *([1] * (like.dim() - 1)))

    def q_sample(self, x0: torch.Tensor, t: torch.Tensor, noise: torch.Tensor) -> torch.Tensor:
        """``x_t = sqrt(abar_t) x0 + sqrt(1 - abar_t) noise`` (t: (B,) integer timesteps)."""
        a = self._abar(t, x0)
        return a.sqrt() * x0 + (1.0 - a).sqrt() * noise

    def sample_timesteps(self, batch: int, generator: torch.Generator | None = None,
                         device=None) -> torch.Tensor:
        return torch.randint(0, self.steps, (batch,), generator=generator, device=device)

    def ddim_timesteps(self, n: int | None = None) -> list[int]:
        """The n timesteps DDIM visits, in visiting order (descending)."""
        n = self.config.ddim_steps if n is None else n
        if not 1 <= n <= self.steps:
            raise ValueError(f"ddim steps: expected 1..{self.steps}, got {n}")
        return [i * self.steps // n for i in range(n)][::-1]

    @staticmethod
    def guided(model: X0Model, x: torch.Tensor, t: torch.Tensor, scale: float) -> torch.Tensor:
        """Classifier-free guided x0 prediction: one forward over the batch twice (condition
        kept, condition dropped), ``x0_u + scale (x0_c - x0_u)``."""
        B = x.shape[0]
        keep = torch.cat([torch.ones(B, dtype=torch.bool), torch.zeros(B, dtype=torch.bool)]).to(x.device)
        out = model(torch.cat([x, x]), torch.cat([t, t]), keep)
        cond, uncond = out[:B], out[B:]
        return uncond + scale * (cond - uncond)

    @torch.no_grad()
    def ddim_sample(self, model: X0Model, shape: tuple[int, ...], generator: torch.Generator | None = None,
                    device=None, steps: int | None = None, guidance: float | None = None,
                    eta: float | None = None, noise: torch.Tensor | None = None,
                    progress: Callable[[int, int], None] | None = None) -> torch.Tensor:
        """x0 samples of ``shape`` by DDIM from Gaussian noise (drawn from ``generator`` on
        the CPU, then moved to ``device``, so a seed gives the same start on every device)."""
        scale = self.config.guidance if guidance is None else float(guidance)
        eta = self.config.ddim_eta if eta is None else float(eta)
        if noise is None:
            noise = torch.randn(shape, generator=generator, dtype=torch.float32)
        x = noise.to(device) if device is not None else noise
        ts = self.ddim_timesteps(steps)
        abar = self.alphas_cumprod
        x0 = x
        for i, t in enumerate(ts):
            tt = torch.full((shape[0],), t, dtype=torch.long, device=x.device)
            x0 = self.guided(model, x, tt, scale) if scale != 0 else \
                model(x, tt, torch.zeros(shape[0], dtype=torch.bool, device=x.device))
            if i == len(ts) - 1:
                break
            a_t, a_prev = float(abar[t]), float(abar[ts[i + 1]])
            eps = (x - a_t ** 0.5 * x0) / (1.0 - a_t) ** 0.5
            sigma = eta * ((1 - a_prev) / (1 - a_t) * (1 - a_t / a_prev)) ** 0.5
            x = a_prev ** 0.5 * x0 + max(1.0 - a_prev - sigma ** 2, 0.0) ** 0.5 * eps
            if sigma > 0:
                z = torch.randn(shape, generator=generator, dtype=torch.float32).to(x.device)
                x = x + sigma * z
            if progress is not None:
                progress(i + 1, len(ts))
        return x0


def drop_condition(batch: int, p: float, generator: torch.Generator | None = None) -> torch.Tensor:
    """(B,) bool, True where the condition is kept (each dropped with probability ``p``)."""
    return torch.rand(batch, generator=generator) >= p


def masked_mse(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Mean of ``(pred - target)^2`` over the entries where ``mask`` (broadcastable, leading
    dims of ``pred``) is true."""
    m = mask.to(pred.dtype)
    while m.dim() < pred.dim():
        m = m.unsqueeze(-1)
    m = m.expand_as(pred)
    return ((pred - target) ** 2 * m).sum() / m.sum().clamp(min=1.0)


class EMA:
    """Exponential moving average of a module's floating-point parameters and buffers."""

    def __init__(self, model: torch.nn.Module, decay: float = 0.999):
        if not 0 <= decay < 1:
            raise ValueError(f"ema decay: expected [0, 1), got {decay}")
        self.decay = decay
        self.shadow = copy.deepcopy(model).eval()
        for p in self.shadow.parameters():
            p.requires_grad_(False)

    @torch.no_grad()
    def update(self, model: torch.nn.Module) -> None:
        src = model.state_dict()
        for k, v in self.shadow.state_dict().items():
            if v.dtype.is_floating_point:
                v.mul_(self.decay).add_(src[k].detach(), alpha=1.0 - self.decay)
            else:
                v.copy_(src[k])

    def state_dict(self) -> dict:
        return self.shadow.state_dict()

    def load_state_dict(self, state: dict) -> None:
        self.shadow.load_state_dict(state)
