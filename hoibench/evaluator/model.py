"""The contrastive text-motion model: motion branch, text branch, learned temperature, loss.

Motion branch: each normalised hml263 row is a token (``Linear(263, width)`` plus a
sinusoidal position code of its frame index); a learned CLS token is prepended; the ``hoi``
variant appends one more token per row for the object-relative features
(:mod:`hoibench.evaluator.features`, ``Linear(15, width)``, the same position code, and a
learned type embedding per stream). A pre-LayerNorm transformer encoder runs over the
sequence with a key padding mask, so padded rows never influence the CLS output; the CLS
output goes through LayerNorm and ``Linear(width, 512)`` and is L2-normalised.

Text branch: a pretrained sentence encoder (:mod:`hoibench.evaluator.text`), pooled as its
sentence-transformers config says, then an MLP ``Linear(h, h) - GELU - Dropout - Linear(h,
512)`` and L2 normalisation. While the encoder is frozen it stays in eval mode (no
dropout), so cached pooled outputs are exactly what it would compute.

Loss: CLIP's symmetric cross-entropy over the batch, ``logits = s * T M^T`` with ``s =
exp(logit_scale)`` learned (initial temperature 0.07, ``s`` clamped to 100). Pairs whose
captions are identical strings are not used as negatives for each other
(``negatives="mask_same_caption"``): on data with template texts several clips share a
caption and pushing them apart would train on label noise.
"""
from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn

from ..representations import hml263
from .config import ModelConfig
from .features import OBJ_DIM


def sinusoidal_positions(length: int, width: int, device=None) -> torch.Tensor:
    """(length, width) sine/cosine position codes (Vaswani et al.)."""
    pos = torch.arange(length, dtype=torch.float32, device=device)[:, None]
    div = torch.exp(torch.arange(0, width, 2, dtype=torch.float32, device=device) * (-math.log(10000.0) / width))
    pe = torch.zeros(length, width, device=device)
    pe[:, 0::2] = torch.sin(pos * div)
    pe[:, 1::2] = torch.cos(pos * div[: width // 2])
    return pe


def padding_mask(lengths: torch.Tensor, length: int) -> torch.Tensor:
    """(B, length) bool, True where a row is padding."""
    return torch.arange(length, device=lengths.device)[None, :] >= lengths[:, None]


class MotionEncoder(nn.Module):
    def __init__(self, cfg: ModelConfig):
        super().__init__()
        self.cfg = cfg
        w = cfg.width
        self.body_proj = nn.Linear(hml263.DIM, w)
        self.hoi = cfg.variant == "hoi"
        if self.hoi:
            self.obj_proj = nn.Linear(OBJ_DIM, w)
            self.stream = nn.Parameter(torch.zeros(2, w))
        self.cls = nn.Parameter(torch.randn(1, 1, w) * 0.02)
        self.in_drop = nn.Dropout(cfg.dropout)
        layer = nn.TransformerEncoderLayer(w, cfg.heads, cfg.ff_dim, cfg.dropout, activation="gelu",
                                           batch_first=True, norm_first=True)
        self.encoder = nn.TransformerEncoder(layer, cfg.layers, enable_nested_tensor=False)
        self.norm = nn.LayerNorm(w)
        self.head = nn.Linear(w, cfg.embed_dim)

    def forward(self, body: torch.Tensor, lengths: torch.Tensor, obj: torch.Tensor | None = None) -> torch.Tensor:
        """body (B, T, 263) normalised rows, lengths (B,), obj (B, T, 15) for ``hoi`` -> (B, 512)."""
        B, T, _ = body.shape
        pad = padding_mask(lengths, T)
        keep = (~pad)[..., None].to(body.dtype)
        pe = sinusoidal_positions(T, self.cfg.width, body.device)
        x = self.body_proj(body * keep) + pe
        tokens, masks = [self.cls.expand(B, -1, -1), x], [torch.zeros(B, 1, dtype=torch.bool, device=body.device), pad]
        if self.hoi:
            if obj is None:
                raise ValueError("obj: the hoi variant needs the object-relative rows")
            tokens[1] = x + self.stream[0]
            tokens.append(self.obj_proj(obj * keep) + pe + self.stream[1])
            masks.append(pad)
        seq = self.in_drop(torch.cat(tokens, dim=1))
        h = self.encoder(seq, src_key_padding_mask=torch.cat(masks, dim=1))
        return F.normalize(self.head(self.norm(h[:, 0])), dim=-1)


class TextBranch(nn.Module):
    """Pretrained transformer + pooling + projection. ``frozen``: the transformer gets no
    gradients and stays in eval mode."""

    def __init__(self, transformer: nn.Module, pooling: str, embed_dim: int, dropout: float):
        super().__init__()
        self.transformer = transformer
        self.pooling = pooling
        h = int(transformer.config.hidden_size)
        self.hidden = h
        self.proj = nn.Sequential(nn.Linear(h, h), nn.GELU(), nn.Dropout(dropout), nn.Linear(h, embed_dim))
        self.frozen = True
        self.set_frozen(True)

    def finetuned_names(self, layers: int) -> list[str]:
        """Parameter names of the transformer that fine-tuning updates: all (``layers == 0``)
        or those of its top ``layers`` encoder layers (BERT/RoBERTa ``encoder.layer``)."""
        names = [n for n, _ in self.transformer.named_parameters()]
        blocks = getattr(getattr(self.transformer, "encoder", None), "layer", None)
        if layers <= 0 or blocks is None or layers >= len(blocks):
            return names
        keep = tuple(f"encoder.layer.{i}." for i in range(len(blocks) - layers, len(blocks)))
        return [n for n in names if n.startswith(keep)]

    def set_frozen(self, frozen: bool, layers: int = 0) -> None:
        """Freeze the transformer, or unfreeze (all, or the top ``layers`` encoder layers)."""
        self.frozen = frozen
        trainable = set() if frozen else set(self.finetuned_names(layers))
        for n, p in self.transformer.named_parameters():
            p.requires_grad_(n in trainable)
        if frozen:
            self.transformer.eval()

    def train(self, mode: bool = True):
        super().train(mode)
        if self.frozen:
            self.transformer.eval()
        return self

    def pooled(self, batch: dict) -> torch.Tensor:
        """(B, h) pooled transformer outputs of a tokenised batch."""
        with torch.set_grad_enabled(torch.is_grad_enabled() and not self.frozen):
            out = self.transformer(**batch).last_hidden_state
        if self.pooling == "cls":
            return out[:, 0]
        m = batch["attention_mask"].unsqueeze(-1).to(out.dtype)
        return (out * m).sum(1) / m.sum(1).clamp(min=1e-9)

    def project(self, pooled: torch.Tensor) -> torch.Tensor:
        return F.normalize(self.proj(pooled), dim=-1)


class TextMotionModel(nn.Module):
    def __init__(self, cfg: ModelConfig, transformer: nn.Module, pooling: str):
        super().__init__()
        self.cfg = cfg
        self.motion = MotionEncoder(cfg)
        self.text = TextBranch(transformer, pooling, cfg.embed_dim, cfg.dropout)
        self.logit_scale = nn.Parameter(torch.tensor(math.log(1.0 / cfg.init_temperature)))

    def scale(self) -> torch.Tensor:
        return self.logit_scale.clamp(max=math.log(self.cfg.max_logit_scale)).exp()

    def own_state_dict(self, text_layers: int | None) -> dict[str, torch.Tensor]:
        """Tensors saved in an evaluator folder or checkpoint: the motion branch, the text
        projection and the temperature, plus the fine-tuned transformer parameters
        (``text_layers`` as in :meth:`TextBranch.finetuned_names`; ``None`` = none, the
        transformer is the pretrained one, named by hash)."""
        keep = (set() if text_layers is None
                else {"text.transformer." + n for n in self.text.finetuned_names(text_layers)})
        return {k: v.detach().contiguous().clone() for k, v in self.state_dict().items()
                if not k.startswith("text.transformer.") or k in keep}


def contrastive_loss(text: torch.Tensor, motion: torch.Tensor, scale: torch.Tensor,
                     same: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """Symmetric InfoNCE. ``same`` (B, B) bool marks pairs with identical captions: they are
    excluded as negatives (the diagonal stays). Returns (loss, in-batch top-1 accuracy)."""
    logits = scale * text @ motion.t()
    if same is not None:
        off = same & ~torch.eye(len(text), dtype=torch.bool, device=text.device)
        logits = logits.masked_fill(off, float("-inf"))
    target = torch.arange(len(text), device=text.device)
    loss = 0.5 * (F.cross_entropy(logits, target) + F.cross_entropy(logits.t(), target))
    acc = (logits.argmax(1) == target).float().mean()
    return loss, acc
