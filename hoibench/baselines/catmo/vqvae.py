"""CATMO's motion and contact VQ-VAEs (CATMO sec. 4.1, supp. 1.1), on T2M-GPT's design.

Encoder: Conv1D(in -> width, k 3), ReLU, then ``down_t`` stages of [stride-2 Conv1D (k 4),
residual stack], then Conv1D(width -> code_dim). Residual block: ``x + Conv1x1(ReLU(
Conv_k3,dilation d(ReLU(x))))`` with dilations ``growth^k`` (deepest first in the encoder).
Decoder mirrors it with nearest-neighbour x2 upsampling. ``L`` rows -> ``L / 2^down_t``
latent vectors; lengths must be multiples of ``2^down_t``.

Quantiser (:class:`EMAQuantizer`): nearest codebook vector ``argmin_k ||z - b_k||^2``;
straight-through gradient ``z + sg(z_q - z)``; codebook updated by exponential moving
averages of the assigned vectors' sums and counts (decay ``mu``) instead of the embedding
loss ``L_e`` (so only ``L_c = ||z - sg(z_q)||^2`` enters the loss), and codes whose EMA
count falls below 1 are reset to encoder outputs of the current batch (dead-code reset).
Perplexity ``exp(-sum_k p_k log p_k)`` of the batch's code frequencies measures usage.

Padding: given the valid rows of a zero-padded batch, every convolution stack resets the
padded positions after each layer (:func:`masked_stack`), so a clip's valid latents and rows
equal those it gets alone.
"""
from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn


class ResBlock1D(nn.Module):
    def __init__(self, width: int, dilation: int):
        super().__init__()
        self.conv = nn.Conv1d(width, width, 3, padding=dilation, dilation=dilation)
        self.proj = nn.Conv1d(width, width, 1)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x + self.proj(F.relu(self.conv(F.relu(x))))


def _leaves(layers: nn.Module):
    for layer in layers:
        if isinstance(layer, nn.Sequential):
            yield from _leaves(layer)
        else:
            yield layer


def masked_stack(layers: nn.Sequential, h: torch.Tensor, rows: torch.Tensor | None, rate: int = 1) -> torch.Tensor:
    """Run ``layers`` over (B, C, T) ``h`` whose positions each cover ``rate`` rows; with
    ``rows`` (B, T * rate) bool, the positions of padded rows are reset to 0 after every layer
    (the zero a convolution's own padding supplies past the end), so valid positions equal
    those of the unpadded sequence (valid lengths multiples of the coarsest rate). Strided
    convolutions multiply ``rate`` by their stride, upsampling and transposed convolutions
    divide it."""
    for layer in _leaves(layers):
        h = layer(h)
        if isinstance(layer, nn.ConvTranspose1d):
            rate //= layer.stride[0]
        elif isinstance(layer, nn.Conv1d):
            rate *= layer.stride[0]
        elif isinstance(layer, nn.Upsample):
            rate //= int(layer.scale_factor)
        if rows is not None:
            h = h * rows[:, rate - 1::rate][:, None].to(h.dtype)
    return h


def res_stack(width: int, depth: int, growth: int, deepest_first: bool) -> nn.Sequential:
    dil = [growth ** k for k in range(depth)]
    return nn.Sequential(*[ResBlock1D(width, d) for d in (dil[::-1] if deepest_first else dil)])


class Encoder(nn.Module):
    def __init__(self, channels: int, width: int, code_dim: int, down_t: int, depth: int, growth: int):
        super().__init__()
        layers: list[nn.Module] = [nn.Conv1d(channels, width, 3, padding=1), nn.ReLU()]
        for _ in range(down_t):
            layers += [nn.Conv1d(width, width, 4, stride=2, padding=1), res_stack(width, depth, growth, True)]
        layers.append(nn.Conv1d(width, code_dim, 3, padding=1))
        self.net = nn.Sequential(*layers)

    def forward(self, x: torch.Tensor, rows: torch.Tensor | None = None) -> torch.Tensor:
        """(B, L, channels) -> (B, L / 2^down_t, code_dim); ``rows`` (B, L): valid rows."""
        if rows is not None:
            x = x * rows[..., None].to(x.dtype)
        return masked_stack(self.net, x.transpose(1, 2), rows).transpose(1, 2)


class Decoder(nn.Module):
    def __init__(self, channels: int, width: int, code_dim: int, down_t: int, depth: int, growth: int):
        super().__init__()
        self.unit = 2 ** down_t
        layers: list[nn.Module] = [nn.Conv1d(code_dim, width, 3, padding=1), nn.ReLU()]
        for _ in range(down_t):
            layers += [res_stack(width, depth, growth, True), nn.Upsample(scale_factor=2, mode="nearest"),
                       nn.Conv1d(width, width, 3, padding=1)]
        layers += [nn.Conv1d(width, width, 3, padding=1), nn.ReLU(), nn.Conv1d(width, channels, 3, padding=1)]
        self.net = nn.Sequential(*layers)

    def forward(self, z: torch.Tensor, units: torch.Tensor | None = None) -> torch.Tensor:
        """(B, U, code_dim) -> (B, U * 2^down_t, channels); ``units`` (B, U): valid latents."""
        rows = None if units is None else units.repeat_interleave(self.unit, 1)
        if units is not None:
            z = z * units[..., None].to(z.dtype)
        return masked_stack(self.net, z.transpose(1, 2), rows, self.unit).transpose(1, 2)


class EMAQuantizer(nn.Module):
    """Codebook of ``codes`` vectors of size ``dim`` with EMA updates and dead-code reset."""

    def __init__(self, codes: int, dim: int, mu: float):
        super().__init__()
        self.codes, self.dim, self.mu = codes, dim, mu
        self.register_buffer("codebook", torch.zeros(codes, dim))
        self.register_buffer("ema_sum", torch.zeros(codes, dim))
        self.register_buffer("ema_count", torch.zeros(codes))
        self.register_buffer("initialised", torch.zeros((), dtype=torch.bool))

    def indices(self, z: torch.Tensor) -> torch.Tensor:
        """(...,) nearest code of each (..., dim) vector (ties: the lowest index)."""
        flat = z.reshape(-1, self.dim)
        d = (flat.pow(2).sum(-1, keepdim=True) - 2 * flat @ self.codebook.t()
             + self.codebook.pow(2).sum(-1)[None])
        return d.argmin(-1).reshape(z.shape[:-1])

    def lookup(self, idx: torch.Tensor) -> torch.Tensor:
        return F.embedding(idx, self.codebook)

    def _draw(self, flat: torch.Tensor, generator: torch.Generator | None) -> torch.Tensor:
        """``codes`` rows of the batch's vectors in a random order (tiled when the batch is smaller)."""
        n = flat.shape[0]
        reps = -(-self.codes // n)
        pool = flat.repeat(reps, 1) if reps > 1 else flat
        order = torch.randperm(pool.shape[0], generator=generator).to(flat.device)
        return pool[order[:self.codes]]

    @torch.no_grad()
    def initialise(self, flat: torch.Tensor, generator: torch.Generator | None = None) -> None:
        """Codebook = random vectors of the first training batch (N, dim)."""
        self.codebook.copy_(self._draw(flat, generator))
        self.ema_sum.copy_(self.codebook)
        self.ema_count.fill_(1.0)
        self.initialised.fill_(True)

    @torch.no_grad()
    def update(self, flat: torch.Tensor, idx: torch.Tensor, generator: torch.Generator | None = None) -> None:
        """One EMA step on (N, dim) encoder outputs assigned to ``idx`` (N,), then reset the
        codes whose EMA count is below 1 to random batch vectors:
        ``S_k <- mu S_k + (1 - mu) sum_{i: idx_i = k} z_i``, ``n_k <- mu n_k + (1 - mu) |{i: idx_i = k}|``,
        ``b_k = S_k / n_k`` if ``n_k >= 1`` else a batch vector (with ``S_k = b_k``, ``n_k = 1``)."""
        onehot = F.one_hot(idx, self.codes).to(flat.dtype)            # (N, codes)
        self.ema_sum.mul_(self.mu).add_(onehot.t() @ flat, alpha=1 - self.mu)
        self.ema_count.mul_(self.mu).add_(onehot.sum(0), alpha=1 - self.mu)
        used = (self.ema_count >= 1.0)[:, None]
        fresh = self._draw(flat, generator)
        self.codebook.copy_(torch.where(used, self.ema_sum / self.ema_count.clamp_min(1e-6)[:, None], fresh))
        self.ema_sum.copy_(torch.where(used, self.ema_sum, fresh))
        self.ema_count.copy_(torch.where(used[:, 0], self.ema_count, torch.ones_like(self.ema_count)))

    def forward(self, z: torch.Tensor, valid: torch.Tensor | None = None, generator: torch.Generator | None = None
                ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """(z_q with straight-through gradient, indices, commitment loss, perplexity) of
        (B, U, dim) ``z``; ``valid`` (B, U) marks the latents that count (padding excluded).
        In training mode the codebook takes one EMA step after quantising."""
        flat = z.reshape(-1, self.dim)
        keep = valid.reshape(-1) if valid is not None else torch.ones(flat.shape[0], dtype=torch.bool, device=z.device)
        if self.training and not bool(self.initialised):
            self.initialise(flat.detach()[keep], generator)
        idx = self.indices(z.detach())
        zq = self.lookup(idx).clone()
        if self.training:          # quantise with the codebook before this step's update (T2M-GPT's order)
            self.update(flat.detach()[keep], idx.reshape(-1)[keep], generator)
        err = (z - zq.detach()).pow(2).mean(-1).reshape(-1)
        commit = (err * keep).sum() / keep.sum().clamp_min(1)
        counts = torch.bincount(idx.reshape(-1)[keep], minlength=self.codes).float()
        p = counts / counts.sum().clamp_min(1)
        perplexity = torch.exp(-(p * torch.log(p.clamp_min(1e-10))).sum())
        return z + (zq - z).detach(), idx, commit, perplexity


class VQVAE(nn.Module):
    """Encoder, EMA quantiser and decoder over (B, L, channels) sequences."""

    def __init__(self, channels: int, codes: int, width: int, code_dim: int, down_t: int, depth: int, growth: int,
                 mu: float):
        super().__init__()
        self.channels, self.unit = channels, 2 ** down_t
        self.encoder = Encoder(channels, width, code_dim, down_t, depth, growth)
        self.quantizer = EMAQuantizer(codes, code_dim, mu)
        self.decoder = Decoder(channels, width, code_dim, down_t, depth, growth)

    def forward(self, x: torch.Tensor, valid_units: torch.Tensor | None = None,
                generator: torch.Generator | None = None) -> dict[str, torch.Tensor]:
        rows = None if valid_units is None else valid_units.repeat_interleave(self.unit, 1)
        z = self.encoder(x, rows)
        zq, idx, commit, perplexity = self.quantizer(z, valid_units, generator)
        if valid_units is not None:
            # padded latents carry nothing to the decoder and get no gradient (unconstrained by
            # the commitment loss, they would drift without bound through the straight-through path)
            zq = zq * valid_units[..., None].to(zq.dtype)
        return {"out": self.decoder(zq, valid_units), "indices": idx, "commit": commit, "perplexity": perplexity}

    @torch.no_grad()
    def encode(self, x: torch.Tensor) -> torch.Tensor:
        """(B, U) code indices of (B, U * unit, channels)."""
        return self.quantizer.indices(self.encoder(x))

    def decode(self, idx: torch.Tensor) -> torch.Tensor:
        """(B, U * unit, channels) from (B, U) indices."""
        return self.decoder(self.quantizer.lookup(idx))

    def decode_soft(self, probs: torch.Tensor, valid_units: torch.Tensor | None = None) -> torch.Tensor:
        """Differentiable decode of (B, U, codes) code probabilities: the decoder applied to
        the expected codebook vectors ``probs @ codebook`` (the alignment loss's path)."""
        return self.decoder(probs @ self.quantizer.codebook, valid_units)
