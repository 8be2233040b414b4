"""CATMO as one module: the two VQ-VAEs, the text and movement encoders, the intertwined GPT
and, on the HOI tracks, hoibench's object extension (point encoder + object head).

The object extension is hoibench's, not the paper's (the paper conditions the GPT on a
pretrained Point Transformer feature for static scenes only): the GPT's condition is
``Linear([Z_t; g])`` with ``g`` the max over the point encoder's tokens of the object's
surface samples, and :class:`ObjectHead` predicts the object trajectory (normalised hoi269
object axis-angle and translation, 6 channels per row) from the decoded motion rows, the
decoded contact probabilities and ``g``: residual dilated Conv1D layers.
"""
from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from ...representations import hml263
from ..layers import PointEncoder
from .config import CatmoConfig
from .gpt import IntertwinedGPT
from .textmatch import InteractionTextEncoder, MovementEncoder
from .vqvae import VQVAE

CONTACT_CHANNELS = 22
OBJECT_CHANNELS = 6


class ObjectHead(nn.Module):
    def __init__(self, obj_dim: int, width: int, layers: int):
        super().__init__()
        self.inp = nn.Conv1d(hml263.DIM + CONTACT_CHANNELS + obj_dim, width, 3, padding=1)
        self.blocks = nn.ModuleList([nn.Conv1d(width, width, 3, padding=2 ** k, dilation=2 ** k)
                                     for k in range(layers)])
        self.out = nn.Conv1d(width, OBJECT_CHANNELS, 3, padding=1)

    def forward(self, motion: torch.Tensor, contact_prob: torch.Tensor, obj: torch.Tensor,
                rows: torch.Tensor | None = None) -> torch.Tensor:
        """(B, L, 6) normalised object rows from (B, L, 263) motion, (B, L, 22) contact
        probabilities and (B, obj_dim) object features; ``rows`` (B, L): the valid rows of a
        zero-padded batch (padded rows are reset before every convolution reads them)."""
        L = motion.shape[1]
        keep = torch.ones_like(motion[:, None, :, 0]) if rows is None else rows[:, None].to(motion.dtype)
        x = torch.cat([motion, contact_prob, obj[:, None].expand(-1, L, -1)], -1).transpose(1, 2) * keep
        h = F.relu(self.inp(x)) * keep
        for conv in self.blocks:
            h = (h + F.relu(conv(h))) * keep
        return (self.out(h) * keep).transpose(1, 2)


class CATMO(nn.Module):
    def __init__(self, cfg: CatmoConfig, vocab: int, text_width: int, with_object: bool):
        super().__init__()
        v, t, g = cfg.vq, cfg.text, cfg.gpt
        self.cfg, self.with_object = cfg, with_object
        self.motion_vq = VQVAE(hml263.DIM, v.motion_codes, v.width, v.code_dim, v.down_t, v.depth, v.dilation_growth,
                               v.ema_mu)
        self.contact_vq = VQVAE(CONTACT_CHANNELS, v.contact_codes, v.width, v.code_dim, v.down_t, v.depth,
                                v.dilation_growth, v.ema_mu)
        self.text = InteractionTextEncoder(t.encoder, vocab, text_width, t.hidden, t.width)
        self.movement = MovementEncoder(hml263.DIM, t.hidden, t.width)
        cond_dim = t.width
        if with_object:
            self.points = PointEncoder(t.width, g.object_tokens, g.object_knn)
            self.object_head = ObjectHead(t.width, cfg.object.width, cfg.object.layers)
            cond_dim += t.width
        self.gpt = IntertwinedGPT(v.motion_codes, v.contact_codes, cond_dim, g.width, g.layers, g.heads, g.ff_mult,
                                  g.dropout, g.max_units)

    def object_feature(self, points: torch.Tensor) -> torch.Tensor:
        """(B, width) max over the point encoder's tokens of (B, P, 3) surface points."""
        return self.points(points).max(1).values

    def condition(self, text_emb: torch.Tensor, obj_feat: torch.Tensor | None) -> torch.Tensor:
        return text_emb if obj_feat is None else torch.cat([text_emb, obj_feat], -1)

    def stage_modules(self, stage: str) -> list[nn.Module]:
        """The modules a training stage optimises."""
        points = [self.points] if self.with_object else []
        if stage == "object":                  # the point encoder stays as the GPT left it
            return [self.object_head]
        return {"motion_vq": [self.motion_vq], "contact_vq": [self.contact_vq],
                "movement_ae": [self.movement.conv, self.movement.deconv],
                "text_match": [self.text, self.movement.head], "gpt": [self.gpt] + points}[stage]
