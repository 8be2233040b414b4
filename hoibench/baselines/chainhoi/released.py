"""The ChainHOI denoiser as released (``Huanggh531/ChainHOI`` commit 4990160, ``ChainHOI`` in
``src/models/nets/chainhoi.py`` with the BEHAVE settings of ``scripts/train_behave.sh``).

hoibench's own implementation; its state-dict keys are the public denoiser's (``gcn_denoiser.``
stripped), so released weights load as they are. Tensors: ``h`` (B, C, L, V) with V = 24 graph
nodes; ``valid`` (B, L) bool.

- Input: four 1x1 convolutions + GroupNorm(4) for the root (node 0), the joints 1..21, the
  foot node 22 and the object node 23.
- Conditions: ``tau = Linear(timestep_embedding(t))`` (cos then sin, 256 -> 512); text memory
  ``[tau; text tokens]``, object memory ``[tau; 16 PointNet++ tokens]``.
- Block (width ``c``; ``c`` doubles at blocks 2 and 4): ``r = GN1(ReLU(Conv1x1(h)))``;
  ST-GCN ``s = ReLU(TCN(GCN(r)) + r)`` with ``GCN(r) = ReLU(GN(sum_k A_k-gather(Conv_k r)) + r)``
  over a learnable ``A`` (3, 24, 24) initialised from the identity, "In" (a parent averages
  its children; node 22 its feet; node 23 the interaction joints) and "Out" (the reverse);
  TCN: branches 1x1-GN-ReLU-dilated conv (k 3, dilations 1..4), 1x1-GN-ReLU-maxpool(3), 1x1;
  concatenated, GN-ReLU-1x1 (the transform), GN.
  Semantic module: HOI token ``Conv(c, c, (1, 24))(r)`` (one linear over the 24 nodes'
  features), + sinusoidal positions, a text decoder and an object decoder (4 post-norm layers
  each, ReLU) in parallel, summed, ``SiLU(Linear)``.
  KIM: ``u = Conv1x1([s; token])``; node tokens ``n = Linear(u)`` (model_dim); six chain
  tokens through a text and an object context decoder (GELU) in parallel, summed,
  ``Linear``; then per frame the text decoder's layers again with the chain tokens as queries
  and the frame's node tokens as memory under the chain mask; ``FC(6 * d -> 24 * c)`` plus
  ``Linear(n)``. Output ``h' = GN1(r + KIM) + r``.
- Output: ``Conv1x1(c -> 12)``.

``padding="reference"`` is the released arithmetic exactly: its GroupNorms average over every
frame of the padded batch and its temporal convolutions read padded frames, so a sequence's
output depends on the padding. ``padding="masked"`` (hoibench's default) takes GroupNorm
statistics over valid frames only and zeroes padded frames before the temporal convolutions and
the max-pool: a padded batch gives the outputs of its unpadded sequences.
"""
from __future__ import annotations

import math

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from ...core import skeleton as sk
from .graph import NODES, chain_membership
from .released_config import ReleasedConfig

WIDTH = 12
CHAINS = 6
MAX_FRAMES = 256          # positional table length of the semantic module


# ------------------------------------------------------------------------------ graph
def gather_edges() -> list[tuple[int, int]]:
    """(gatherer, source) pairs of the released "In" partition: every parent gathers its
    children, node 22 the feet (7, 8, 10, 11), node 23 the interaction joints."""
    edges = list(sk.bone_edges())
    edges += [(sk.FOOT_CONTACT_NODE, j) for j in sk.FOOT_NODE_NEIGHBOURS]
    edges += [(sk.OBJECT_NODE, j) for j in sk.OBJECT_NODE_NEIGHBOURS]
    return edges


def released_partitions() -> np.ndarray:
    """(3, 24, 24) float32 ``A[k, v, w]``: weight with which node w gathers node v (identity,
    In, Out); each gatherer averages over its sources (column-normalised)."""
    inward = np.zeros((NODES, NODES), np.float64)
    for w, v in gather_edges():
        inward[v, w] = 1.0
    outward = inward.T.copy()

    def colnorm(a):
        d = a.sum(0, keepdims=True)
        return np.divide(a, d, out=np.zeros_like(a), where=d > 0)
    return np.stack([np.eye(NODES), colnorm(inward), colnorm(outward)]).astype(np.float32)


# ------------------------------------------------------------------------------ helpers
def timestep_embedding(t: torch.Tensor, dim: int) -> torch.Tensor:
    """(B, dim): ``[cos(t f_i), sin(t f_i)]``, ``f_i = 10000^(-i / (dim/2))``."""
    half = dim // 2
    f = torch.exp(-math.log(10000.0) * torch.arange(half, dtype=torch.float32, device=t.device) / half)
    a = t.float()[:, None] * f[None]
    return torch.cat([torch.cos(a), torch.sin(a)], -1)


def sincos_table(length: int, dim: int) -> torch.Tensor:
    """(length, 1, dim): even channels ``sin(p w_i)``, odd ``cos(p w_i)``, ``w_i = 10000^(-2i/dim)``."""
    pe = torch.zeros(length, dim)
    pos = torch.arange(length, dtype=torch.float32)[:, None]
    w = torch.exp(torch.arange(0, dim, 2, dtype=torch.float32) * -(math.log(10000.0) / dim))
    pe[:, 0::2] = torch.sin(pos * w)
    pe[:, 1::2] = torch.cos(pos * w)
    return pe[:, None]


class MaskedGroupNorm(nn.GroupNorm):
    """GroupNorm over (B, C, L, V) whose statistics use only the valid frames when ``valid``
    is given (``None``: plain GroupNorm over every frame)."""

    def forward(self, x: torch.Tensor, valid: torch.Tensor | None = None) -> torch.Tensor:
        if valid is None:
            return super().forward(x)
        B, C, L, V = x.shape
        g = x.view(B, self.num_groups, C // self.num_groups, L, V)
        m = valid.to(x.dtype)[:, None, None, :, None]
        n = m.sum((2, 3, 4), keepdim=True) * (C // self.num_groups) * V
        mean = (g * m).sum((2, 3, 4), keepdim=True) / n
        var = (((g - mean) * m) ** 2).sum((2, 3, 4), keepdim=True) / n
        y = ((g - mean) / torch.sqrt(var + self.eps)).view(B, C, L, V)
        return y * self.weight[:, None, None] + self.bias[:, None, None]


def _gn(groups: int, ch: int) -> MaskedGroupNorm:
    return MaskedGroupNorm(groups, ch)


def _zero_pad(x: torch.Tensor, valid: torch.Tensor | None) -> torch.Tensor:
    return x if valid is None else x * valid.to(x.dtype)[:, None, :, None]


class _Conv(nn.Module):
    """Holds the temporal convolution as ``.conv`` (kernel (k, 1), dilation d, 'same' padding)."""

    def __init__(self, ch: int, dilation: int, k: int = 3):
        super().__init__()
        self.conv = nn.Conv2d(ch, ch, (k, 1), padding=(dilation * (k - 1) // 2, 0), dilation=(dilation, 1))

    def forward(self, x):
        return self.conv(x)


class _PositionTable(nn.Module):
    """Fixed sinusoidal positions (a non-trainable parameter, as released) + dropout."""

    def __init__(self, dim: int, dropout: float):
        super().__init__()
        self.embed = nn.Parameter(sincos_table(MAX_FRAMES, dim), requires_grad=False)
        self.dropout = nn.Dropout(dropout)

    def forward(self, x):                                   # (B, L, C)
        L = x.shape[1]
        table = self.embed[:, 0] if L <= self.embed.shape[0] else sincos_table(L, x.shape[-1])[:, 0].to(x)
        return self.dropout(x + table[:L][None])


class _TimeMLP(nn.Module):
    """Present in the released denoiser (and in its parameter count) but never called."""

    def __init__(self, dim: int):
        super().__init__()
        self.linear_1, self.linear_2 = nn.Linear(dim, dim), nn.Linear(dim, dim)


def _decoder(width: int, heads: int, layers: int, dropout: float, act: str) -> nn.TransformerDecoder:
    layer = nn.TransformerDecoderLayer(width, heads, 2 * width, dropout, activation=act, batch_first=True)
    return nn.TransformerDecoder(layer, layers)


# ------------------------------------------------------------------------------ ST-GCN
class GraphConv(nn.Module):
    """``ReLU(GN(sum_k gather_k(Conv_k x)) + x)`` over a learnable adjacency ``A`` (3, V, V)."""

    def __init__(self, ch: int, groups: int):
        super().__init__()
        self.A = nn.Parameter(torch.from_numpy(released_partitions()))
        self.bn = _gn(groups, ch)
        self.conv = nn.Conv2d(ch, 3 * ch, 1)

    def forward(self, x, valid):
        B, C, L, V = x.shape
        y = self.conv(x).view(B, 3, C, L, V)
        y = torch.einsum("bkclv,kvw->bclw", y, self.A)
        return F.relu(self.bn(y, valid) + x)


class TemporalConv(nn.Module):
    """Six branches (dilated k=3 convs with dilations 1..4, max-pool, 1x1), concatenated,
    GN-ReLU-1x1 transform, GN. Branch 0 takes the remainder of the width."""

    def __init__(self, ch: int):
        super().__init__()
        mid = ch // 6
        widths = [ch - 5 * mid] + [mid] * 5
        br = [nn.Sequential(nn.Conv2d(ch, w, 1), _gn(1, w), nn.ReLU(), _Conv(w, d))
              for w, d in zip(widths[:4], (1, 2, 3, 4))]
        br.append(nn.Sequential(nn.Conv2d(ch, widths[4], 1), _gn(1, widths[4]), nn.ReLU(),
                                nn.MaxPool2d((3, 1), stride=1, padding=(1, 0))))
        br.append(nn.Conv2d(ch, widths[5], 1))
        self.branches = nn.ModuleList(br)
        self.transform = nn.Sequential(_gn(1, ch), nn.ReLU(), nn.Conv2d(ch, ch, 1))
        self.bn = _gn(1, ch)

    def forward(self, x, valid):
        outs = []
        for b in self.branches[:5]:
            h = F.relu(b[1](b[0](x), valid))
            outs.append(b[3](_zero_pad(h, valid)))        # padded frames are zero for the conv / max-pool
        outs.append(self.branches[5](x))
        h = torch.cat(outs, 1)
        h = self.transform[2](F.relu(self.transform[0](h, valid)))
        return self.bn(h, valid)


class STGCN(nn.Module):
    def __init__(self, ch: int, groups: int):
        super().__init__()
        self.gcn = GraphConv(ch, groups)
        self.tcn = TemporalConv(ch)

    def forward(self, x, valid):
        return F.relu(self.tcn(self.gcn(x, valid), valid) + x)


# ------------------------------------------------------------------------------ semantic module, KIM
class SemanticModule(nn.Module):
    """HOI token per frame, text and object decoders in parallel (summed), SiLU(Linear)."""

    def __init__(self, ch: int, cfg: ReleasedConfig):
        super().__init__()
        self.norm = nn.LayerNorm(ch)                                   # released but unused
        self.input_proj = nn.Sequential(nn.Conv2d(ch, ch, (1, NODES), (1, NODES)))
        self.text_proj = nn.Sequential(nn.Linear(cfg.cond_dim, ch), nn.SiLU())
        self.obj_proj = nn.Sequential(nn.Linear(cfg.cond_dim, ch), nn.SiLU())
        self.pos_emb, self.pos_emb2 = _PositionTable(ch, cfg.dropout), _PositionTable(ch, cfg.dropout)
        self.decoder = _decoder(ch, cfg.heads, cfg.decoder_layers, cfg.dropout, "relu")
        self.decoder2 = _decoder(ch, cfg.heads, cfg.decoder_layers, cfg.dropout, "relu")
        self.post_proj = nn.Sequential(nn.Linear(ch, ch), nn.SiLU())

    def forward(self, r, valid, text, text_valid, obj, obj_valid):
        tok = self.input_proj(r)[..., 0].transpose(1, 2)                # (B, L, C)
        a = self.decoder(self.pos_emb(tok), self.text_proj(text), tgt_key_padding_mask=~valid,
                         memory_key_padding_mask=~text_valid)
        b = self.decoder2(self.pos_emb2(tok), self.obj_proj(obj), tgt_key_padding_mask=~valid,
                          memory_key_padding_mask=~obj_valid)
        return self.post_proj(a + b)


class KIM(nn.Module):
    """Chain tokens from the context decoders, then per frame the text decoder's layers over
    the frame's node tokens under the chain mask; ``FC(flatten) + Linear(nodes)``."""

    def __init__(self, ch: int, cfg: ReleasedConfig):
        super().__init__()
        d = cfg.model_dim
        self.limb_token = nn.Parameter(torch.randn(CHAINS, ch))
        self.input_proj = nn.Sequential(nn.Conv2d(2 * ch, ch, 1))
        self.transformer_decoder = _decoder(d, cfg.heads, cfg.decoder_layers, cfg.dropout, "gelu")
        self.transformer_decoder2 = _decoder(d, cfg.heads, cfg.decoder_layers, cfg.dropout, "gelu")
        self.ske_proj = nn.Linear(ch, d)
        self.query_proj = nn.Linear(d, d)
        self.text_proj = nn.Linear(cfg.cond_dim, d)
        self.text_proj2 = nn.Linear(cfg.cond_dim, d)
        self.x_cur_proj = nn.Linear(ch, d)
        self.x_cur_proj2 = nn.Linear(ch, d)
        self.proj_after_cross_att = nn.Linear(CHAINS * d, NODES * ch)
        self.m_output_proj = nn.Linear(d, ch)
        member = torch.from_numpy(chain_membership())
        # "released": the float (1 - membership) added to the scores; "paper": boolean, True = masked
        self.register_buffer("mask", (1.0 - member.float()) if cfg.mask == "released" else ~member,
                             persistent=False)

    def forward(self, s, tok, text, text_valid, obj, obj_valid):
        B, C, L, V = s.shape
        u = self.input_proj(torch.cat([s, tok.transpose(1, 2)[..., None].expand(B, C, L, V)], 1))
        nodes = self.ske_proj(u.permute(0, 2, 3, 1).reshape(B * L, V, C))            # (B L, 24, d)
        q = self.limb_token[None].expand(B, -1, -1)
        a = self.transformer_decoder(self.x_cur_proj(q), self.text_proj(text), memory_key_padding_mask=~text_valid)
        b = self.transformer_decoder2(self.x_cur_proj2(q), self.text_proj2(obj), memory_key_padding_mask=~obj_valid)
        d = a.shape[-1]
        chains = self.query_proj((a + b)[:, None].expand(B, L, CHAINS, d).reshape(B * L, CHAINS, d))
        chains = self.transformer_decoder(chains, nodes, memory_mask=self.mask)       # the text decoder's weights
        fused = self.proj_after_cross_att(chains.reshape(B, L, CHAINS * d)).view(B, L, V, C)
        out = self.m_output_proj(nodes).view(B, L, V, C) + fused
        return out.permute(0, 3, 1, 2)


class Block(nn.Module):
    def __init__(self, cin: int, ch: int, cfg: ReleasedConfig):
        super().__init__()
        self.input_proj = nn.Sequential(nn.Conv2d(cin, ch, 1), nn.ReLU(), _gn(1, ch))
        self.gcn_block = STGCN(ch, cfg.gn_groups * (ch // cfg.base_dim))
        self.temp_block = SemanticModule(ch, cfg)
        self.joint_block = KIM(ch, cfg)
        self.norm = nn.Sequential(_gn(1, ch))

    def forward(self, h, valid, gn_valid, text, text_valid, obj, obj_valid):
        r = self.input_proj[2](F.relu(self.input_proj[0](h)), gn_valid)
        r = _zero_pad(r, gn_valid)
        s = self.gcn_block(r, gn_valid)
        tok = self.temp_block(r, valid, text, text_valid, obj, obj_valid)
        j = self.joint_block(s, tok, text, text_valid, obj, obj_valid)
        return _zero_pad(self.norm[0](r + j, gn_valid) + r, gn_valid)


class ReleasedDenoiser(nn.Module):
    """x0 predictor: ``forward(x (B, L, 24, 12), valid (B, L), t (B,), text (B, Lt, cond_dim),
    text_valid (B, Lt), obj (B, n, cond_dim)) -> (B, L, 24, 12)``."""

    def __init__(self, cfg: ReleasedConfig):
        super().__init__()
        self.cfg = cfg
        b, g = cfg.base_dim, cfg.gn_groups
        self.alpha = nn.Parameter(torch.tensor(0.5))                   # released but unused
        self.time_emb = _TimeMLP(cfg.time_dim)                         # released but unused
        for part in ("root_joint", "skeleton_joint", "extra_joint", "obj_joint"):
            setattr(self, f"{part}_proj", nn.Conv2d(WIDTH, b, 1))
            setattr(self, f"{part}_norm", _gn(g, b))
        blocks, ch = [], b
        for i in range(cfg.blocks):
            cin = ch
            ch = 2 * ch if i + 1 in cfg.up_blocks else ch
            blocks.append(Block(cin, ch, cfg))
        self.blocks = nn.ModuleList(blocks)
        self.output_proj = nn.Conv2d(ch, WIDTH, 1)
        self.time_proj = nn.Linear(cfg.time_dim, cfg.cond_dim)
        self.text_proj = nn.Linear(cfg.cond_dim, cfg.cond_dim)        # released but unused
        self.obj_proj = nn.Linear(cfg.cond_dim, cfg.cond_dim)         # released but unused

    def _inputs(self, x, gn_valid):
        parts = (("root_joint", slice(0, 1)), ("skeleton_joint", slice(1, 22)), ("extra_joint", slice(22, 23)),
                 ("obj_joint", slice(23, 24)))
        return torch.cat([getattr(self, f"{p}_norm")(getattr(self, f"{p}_proj")(x[..., sl]), gn_valid)
                          for p, sl in parts], -1)

    def forward(self, x, valid, t, text, text_valid, obj):
        gn_valid = None if self.cfg.padding == "reference" else valid
        h = _zero_pad(self._inputs(x.permute(0, 3, 1, 2), gn_valid), gn_valid)
        tau = self.time_proj(timestep_embedding(t, self.cfg.time_dim))[:, None]
        ones = torch.ones(x.shape[0], 1, dtype=torch.bool, device=x.device)
        text, text_valid = torch.cat([tau, text], 1), torch.cat([ones, text_valid], 1)
        obj = torch.cat([tau, obj], 1)
        obj_valid = torch.ones(obj.shape[:2], dtype=torch.bool, device=x.device)
        for blk in self.blocks:
            h = blk(h, valid, gn_valid, text, text_valid, obj, obj_valid)
        return _zero_pad(self.output_proj(h), gn_valid).permute(0, 2, 3, 1)


# ------------------------------------------------------------------------------ full model
class ReleasedChainHOI(nn.Module):
    """Text input, PointNet++ object encoder and the released denoiser behind the interface
    every hoibench baseline model has (``encode_text``, ``encode_object``, ``forward``).

    ``denoiser.*`` and ``points.*`` hold the public ``gcn_denoiser.*`` and ``objEmbedding.*``
    weights under the same keys. Text: the public code feeds frozen CLIP token states (512);
    here sentence-encoder token states pass ``Linear(text_width, cond_dim)`` (``minilm``), or a
    trainable word-token encoder of width ``cond_dim`` (``tokens``). A dropped text (``keep``
    False) leaves only the time token in the text memory.
    """

    def __init__(self, cfg: ReleasedConfig, vocab: int = 0, text_width: int = 0):
        super().__init__()
        from ..layers import TokenTextEncoder
        from .pointnet2 import PointNet2MSG
        self.cfg = cfg
        if cfg.text_encoder == "tokens":
            if vocab < 2:
                raise ValueError("ChainHOI: the 'tokens' text encoder needs a vocabulary (>= 2 entries)")
            self.text_tokens = TokenTextEncoder(vocab, cfg.cond_dim, cfg.heads, cfg.text_layers, cfg.dropout)
            self.text_proj = nn.Identity()
        else:
            if text_width < 1:
                raise ValueError("ChainHOI: the 'minilm' text encoder needs text_width (its hidden size)")
            self.text_tokens = None
            self.text_proj = nn.Linear(text_width, cfg.cond_dim)
        self.points = PointNet2MSG()
        self.denoiser = ReleasedDenoiser(cfg)

    def encode_text(self, text: torch.Tensor, text_pad: torch.Tensor) -> torch.Tensor:
        return self.text_tokens(text, text_pad) if self.text_tokens is not None else self.text_proj(text)

    def encode_object(self, points: torch.Tensor) -> torch.Tensor:
        """(B, 16, 512) tokens from (B, P, 3) template vertices."""
        return self.points(points)

    def forward(self, x: torch.Tensor, t: torch.Tensor, keep: torch.Tensor, text_tokens: torch.Tensor,
                text_pad: torch.Tensor, obj_tokens: torch.Tensor, valid: torch.Tensor | None = None) -> torch.Tensor:
        if valid is None:
            valid = torch.ones(x.shape[:2], dtype=torch.bool, device=x.device)
        text_valid = ~text_pad & keep[:, None]
        return self.denoiser(x, valid, t, text_tokens, text_valid, obj_tokens)
