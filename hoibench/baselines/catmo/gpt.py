"""CATMO's intertwined GPT (CATMO sec. 4.2): one causal transformer over interleaved motion
and contact indices.

Token ids share one table: motion codes ``0..Km-1``, contact codes ``Km..Km+Kc-1``, ``END =
Km+Kc`` and ``PAD = Km+Kc+1`` (input only). A clip of ``U`` units is the target sequence
``[m_1, c_1, m_2, c_2, ..., m_U, c_U, END]`` (:func:`interleave`); the input is the
condition vector followed by every target but the last, so position ``0`` (the condition)
predicts ``m_1``, the position of ``m_i`` predicts ``c_i`` and the position of ``c_i``
predicts ``m_{i+1}`` (or END): eq. 4's ``p(s_i | s_<i, s^c_<i, Z_t) p(s^c_i | s_<=i,
s^c_<i, Z_t)``. No flag says which kind comes next; the position's parity is the only cue.
Training uses cross-entropy over the whole table; sampling restricts each position to its
modality's codes (:meth:`IntertwinedGPT.sample`).

Multi-modal corruption (:func:`corrupt`): every input index is replaced, with probability
``rate`` and independently of the others, by a random index of its own modality
(``"token"``, CATMO's mixed-random strategy); ``"unit"`` corrupts ``m_i`` and ``c_i``
together (the standard strategy CATMO compares against).
"""
from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn


def vocab_layout(motion_codes: int, contact_codes: int) -> tuple[int, int, int]:
    """(END id, PAD id, output classes)."""
    end = motion_codes + contact_codes
    return end, end + 1, end + 1


def interleave(motion: torch.Tensor, contact: torch.Tensor, units: torch.Tensor, motion_codes: int,
               contact_codes: int) -> tuple[torch.Tensor, torch.Tensor]:
    """(targets (B, 2U+1), valid (B, 2U+1)) from (B, U) motion and contact indices and (B,)
    unit counts: ``[m_1, c_1 + Km, ..., m_u, c_u + Km, END, PAD...]``."""
    B, U = motion.shape
    end, pad, _ = vocab_layout(motion_codes, contact_codes)
    seq = torch.full((B, 2 * U + 1), pad, dtype=torch.long, device=motion.device)
    seq[:, 0:2 * U:2] = motion
    seq[:, 1:2 * U:2] = contact + motion_codes
    pos = torch.arange(2 * U + 1, device=motion.device)[None]
    n = 2 * units[:, None]
    seq = torch.where(pos < n, seq, torch.full_like(seq, pad))
    seq = torch.where(pos == n, torch.full_like(seq, end), seq)
    return seq, pos <= n


def corrupt(tokens: torch.Tensor, rate: float, motion_codes: int, contact_codes: int, mode: str,
            generator: torch.Generator | None = None) -> torch.Tensor:
    """Replace input indices (motion and contact slots, never END/PAD) by random indices of
    the same modality with probability ``rate`` (per index: ``token``; per unit: ``unit``)."""
    if rate <= 0:
        return tokens
    dev = tokens.device
    B, N = tokens.shape
    u = torch.rand(B, N, generator=generator)
    if mode == "unit":              # m_i (even position) and c_i (the next one) share a draw
        u = u[:, 0::2].repeat_interleave(2, 1)[:, :N]
    hit = (u < rate).to(dev)
    rand_m = torch.randint(0, motion_codes, (B, N), generator=generator).to(dev)
    rand_c = torch.randint(0, contact_codes, (B, N), generator=generator).to(dev) + motion_codes
    is_m = tokens < motion_codes
    is_c = (tokens >= motion_codes) & (tokens < motion_codes + contact_codes)
    out = torch.where(hit & is_m, rand_m, tokens)
    return torch.where(hit & is_c, rand_c, out)


class IntertwinedGPT(nn.Module):
    def __init__(self, motion_codes: int, contact_codes: int, cond_dim: int, width: int, layers: int, heads: int,
                 ff_mult: int, dropout: float, max_units: int):
        super().__init__()
        self.motion_codes, self.contact_codes, self.max_units = motion_codes, contact_codes, max_units
        self.end, self.pad, classes = vocab_layout(motion_codes, contact_codes)
        self.embed = nn.Embedding(classes + 1, width)
        self.cond = nn.Linear(cond_dim, width)
        self.pos = nn.Parameter(torch.zeros(1, 2 * max_units + 1, width))
        nn.init.normal_(self.pos, std=0.02)
        layer = nn.TransformerEncoderLayer(width, heads, ff_mult * width, dropout, batch_first=True, norm_first=True)
        self.blocks = nn.TransformerEncoder(layer, layers, enable_nested_tensor=False)
        self.norm = nn.LayerNorm(width)
        self.head = nn.Linear(width, classes)
        self.drop = nn.Dropout(dropout)

    def forward(self, cond: torch.Tensor, tokens: torch.Tensor) -> torch.Tensor:
        """(B, N + 1, classes) logits for (B, cond_dim) conditions and (B, N) input tokens."""
        x = torch.cat([self.cond(cond)[:, None], self.embed(tokens)], 1)
        n = x.shape[1]
        if n > self.pos.shape[1]:
            raise ValueError(f"catmo: {n} positions exceed the GPT's block of {self.pos.shape[1]} "
                             f"(gpt.max_units = {self.max_units})")
        x = self.drop(x + self.pos[:, :n])
        causal = torch.triu(torch.ones(n, n, dtype=torch.bool, device=x.device), 1)
        return self.head(self.norm(self.blocks(x, mask=causal, is_causal=True)))

    def legal(self, position: int) -> tuple[int, int]:
        """[lo, hi) of the ids a generated target position may take (even: motion, odd: contact)."""
        if position % 2 == 0:
            return 0, self.motion_codes
        return self.motion_codes, self.motion_codes + self.contact_codes

    def step(self, x: torch.Tensor, cache: list | None) -> tuple[torch.Tensor, list]:
        """Incremental forward (eval mode): logits (B, n, classes) of ``n`` new positions whose
        embeddings (with positions added) are ``x`` (B, n, width), attending to the keys and
        values cached for the earlier positions; returns the extended cache. Equals
        :meth:`forward` on the whole prefix (tested)."""
        start = 0 if not cache else cache[0][0].shape[2]
        n = x.shape[1]
        allowed = torch.ones(n, start + n, dtype=torch.bool, device=x.device).tril(start)
        new_cache = []
        for i, layer in enumerate(self.blocks.layers):
            attn = layer.self_attn
            H = attn.num_heads
            B, _, W = x.shape
            q, k, v = F.linear(layer.norm1(x), attn.in_proj_weight, attn.in_proj_bias).chunk(3, -1)
            q, k, v = (t.reshape(B, n, H, W // H).transpose(1, 2) for t in (q, k, v))
            if cache:
                k, v = torch.cat([cache[i][0], k], 2), torch.cat([cache[i][1], v], 2)
            o = F.scaled_dot_product_attention(q, k, v, attn_mask=allowed)
            x = x + attn.out_proj(o.transpose(1, 2).reshape(B, n, W))
            x = x + layer.linear2(layer.activation(layer.linear1(layer.norm2(x))))
            new_cache.append((k, v))
        return self.head(self.norm(x)), new_cache

    @torch.no_grad()
    def sample(self, cond: torch.Tensor, units: int, generator: torch.Generator, temperature: float = 1.0
               ) -> tuple[torch.Tensor, torch.Tensor]:
        """(motion (K, units), contact (K, units)) indices drawn for (K, cond_dim) conditions:
        ``units`` motion/contact pairs, END never drawn (the length is given), each draw from
        the softmax of the legal logits / ``temperature`` with ``generator`` (a CPU
        generator: the same draws on every device). Keys and values are cached, so each
        draw costs one position's pass.

        Longer than the positional table (``units > max_units``): a sliding window. When the
        next input would fall past the table, the oldest ``hop = max(1, max_units // 2)``
        units leave the window and the cache is rebuilt over the condition and the remaining
        tokens at positions 1, 2, ... (whole units leave, so a motion index always sits at an
        odd position as in training). Up to ``max_units`` units the draws are those of the
        plain cached pass."""
        if units < 1:
            raise ValueError(f"catmo: {units} units to generate; expected at least 1")
        block, hop = 2 * self.max_units, 2 * max(1, self.max_units // 2)
        head = self.cond(cond)[:, None] + self.pos[:, :1]
        drawn: list[torch.Tensor] = []
        start = 0                                          # index in ``drawn`` of the window's first token
        logits, cache = self.step(head, None)
        for j in range(2 * units):
            lo, hi = self.legal(j)
            probs = F.softmax(logits[:, -1, lo:hi].float().cpu() / temperature, -1)
            draw = torch.multinomial(probs, 1, generator=generator) + lo
            drawn.append(draw)
            if j + 1 == 2 * units:
                break
            if j + 1 - start > block:                      # drawn[j] would sit past the table: slide
                start += hop
                window = torch.cat(drawn[start:], 1).to(cond.device)
                x = torch.cat([head, self.embed(window) + self.pos[:, 1:window.shape[1] + 1]], 1)
                logits, cache = self.step(x, None)
            else:
                p = j + 1 - start
                logits, cache = self.step(self.embed(draw.to(cond.device)) + self.pos[:, p:p + 1], cache)
        tokens = torch.cat(drawn, 1).to(cond.device)
        return tokens[:, 0::2], tokens[:, 1::2] - self.motion_codes
