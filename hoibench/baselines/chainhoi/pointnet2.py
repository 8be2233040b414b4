"""PointNet++ with multi-scale grouping (Qi et al. 2017) in plain PyTorch: the object encoder
of the released ChainHOI (its ``PointNet2SemSegMSG``: four set-abstraction levels and one
feature-propagation level), without CUDA operators.

- Set abstraction (level l): farthest-point sampling of ``npoint`` centres (starting at point
  0; when ``npoint`` exceeds the input, the surplus centres repeat point 0); per radius, a
  ball query keeps the first ``nsample`` points (input order) with ``|p - c|^2 < r^2`` and
  fills the rest with the first one found; ``[p - c; features]`` pass a shared MLP (1x1
  conv without bias, BatchNorm, ReLU per layer), max over the group; radii outputs concatenated.
- Levels (npoint, radii, MLPs): (1024, 0.05/0.1, [16,16,32]/[32,32,64]), (256, 0.1/0.2,
  [64,64,128]/[64,96,128]), (16, 0.2/0.4, [128,196,256] x 2), (16, 0.4/0.8,
  [256,256,512]/[256,384,512]).
- Feature propagation: level-4 features interpolated onto level 3 (inverse-distance weights
  over the 3 nearest, ``1 / (d + 1e-8)``), concatenated with level 3's, MLP [1536, 512, 512].
- Output: (B, 16, 512) object tokens.

State-dict keys follow the released ``objEmbedding`` (``SA_modules.<l>.mlps.<s>.<layer>``,
``FP_modules.3.mlp.<layer>``). The CUDA FPS kernel of the public code also skips points
within 0.032 m of the origin; this implementation does not.
"""
from __future__ import annotations

import hashlib

import torch
from torch import nn

from ..layers import farthest_point_sample

LEVELS = (
    (1024, (0.05, 0.1), (16, 32), ((16, 16, 32), (32, 32, 64))),
    (256, (0.1, 0.2), (16, 32), ((64, 64, 128), (64, 96, 128))),
    (16, (0.2, 0.4), (16, 32), ((128, 196, 256), (128, 196, 256))),
    (16, (0.4, 0.8), (16, 32), ((256, 256, 512), (256, 384, 512))),
)
OUT_DIM = 512


def shared_mlp(widths: list[int]) -> nn.Sequential:
    layers: list[nn.Module] = []
    for a, b in zip(widths[:-1], widths[1:]):
        layers += [nn.Conv2d(a, b, 1, bias=False), nn.BatchNorm2d(b), nn.ReLU(True)]
    return nn.Sequential(*layers)


def ball_query(xyz: torch.Tensor, centres: torch.Tensor, radius: float, nsample: int) -> torch.Tensor:
    """(B, S, nsample) indices of the first ``nsample`` points within ``radius`` of each centre."""
    N = xyz.shape[1]
    inside = torch.cdist(centres, xyz) ** 2 < radius ** 2
    order = torch.where(inside, torch.arange(N, device=xyz.device), torch.full_like(inside, N, dtype=torch.long))
    first = order.sort(-1).values[..., :nsample]
    if first.shape[-1] < nsample:
        first = torch.cat([first, first.new_full(first.shape[:-1] + (nsample - first.shape[-1],), N)], -1)
    head = first[..., :1]
    head = torch.where(head == N, torch.zeros_like(head), head)
    return torch.where(first == N, head, first)


def _gather(x: torch.Tensor, idx: torch.Tensor) -> torch.Tensor:
    """x (B, N, C), idx (B, ...) -> (B, ..., C)."""
    B = x.shape[0]
    flat = idx.reshape(B, -1)
    return x[torch.arange(B, device=x.device)[:, None], flat].reshape(*idx.shape, x.shape[-1])


class SetAbstractionMSG(nn.Module):
    def __init__(self, npoint: int, radii, nsamples, mlps, c_in: int):
        super().__init__()
        self.npoint, self.radii, self.nsamples = npoint, radii, nsamples
        self.mlps = nn.ModuleList(shared_mlp([c_in + 3, *m]) for m in mlps)

    @torch.no_grad()
    def grouping(self, xyz: torch.Tensor) -> tuple[torch.Tensor, list[torch.Tensor]]:
        """(centre indices (B, S), [ball indices (B, S, k) per radius]) of xyz (B, N, 3)."""
        c = farthest_point_sample(xyz, self.npoint)
        centres = _gather(xyz, c)
        return c, [ball_query(xyz, centres, r, k) for r, k in zip(self.radii, self.nsamples)]

    def forward(self, xyz: torch.Tensor, feats: torch.Tensor | None, groups):
        """xyz (B, N, 3), feats (B, N, C) or None -> centres (B, S, 3), features (B, S, sum C_out)."""
        c, balls = groups
        centres = _gather(xyz, c)
        outs = []
        for idx, mlp in zip(balls, self.mlps):
            g = _gather(xyz, idx) - centres[:, :, None]
            if feats is not None:
                g = torch.cat([g, _gather(feats, idx)], -1)
            outs.append(mlp(g.permute(0, 3, 1, 2)).amax(-1))                 # (B, C, S)
        return centres, torch.cat(outs, 1).transpose(1, 2)


class FeaturePropagation(nn.Module):
    def __init__(self, widths: list[int]):
        super().__init__()
        self.mlp = shared_mlp(widths)

    def forward(self, xyz, known_xyz, feats, known_feats):
        d = torch.cdist(xyz, known_xyz)
        dist, idx = d.topk(3, dim=-1, largest=False)
        w = 1.0 / (dist + 1e-8)
        w = w / w.sum(-1, keepdim=True)
        interp = (_gather(known_feats, idx) * w[..., None]).sum(2)             # (B, n, C2)
        h = torch.cat([interp, feats], -1).transpose(1, 2)[..., None]
        return self.mlp(h)[..., 0].transpose(1, 2)


class PointNet2MSG(nn.Module):
    """(B, P, 3) points -> (B, 16, 512) object tokens."""

    def __init__(self):
        super().__init__()
        sa, c = [], 0
        for npoint, radii, ns, mlps in LEVELS:
            sa.append(SetAbstractionMSG(npoint, radii, ns, mlps, c))
            c = sum(m[-1] for m in mlps)
        self.SA_modules = nn.ModuleList(sa)
        c3 = sum(m[-1] for m in LEVELS[2][3])
        self.FP_modules = nn.ModuleList([nn.Identity(), nn.Identity(), nn.Identity(),
                                         FeaturePropagation([c + c3, OUT_DIM, OUT_DIM])])
        self._cache: dict[str, list] = {}

    def groupings(self, points: torch.Tensor) -> list:
        """Per level (centre indices, ball indices): geometry only, so computed once per
        distinct point set (objects are templates: a batch repeats a few) and cached."""
        rows, keys = [], [hashlib.sha1(p.detach().cpu().numpy().tobytes()).hexdigest() for p in points]
        for b, key in enumerate(keys):
            if key not in self._cache:
                if len(self._cache) >= 256:
                    self._cache.clear()
                xyz, levels = points[b:b + 1].detach(), []
                for sa in self.SA_modules:
                    c, balls = sa.grouping(xyz)
                    levels.append((c, balls))
                    xyz = _gather(xyz, c)
                self._cache[key] = levels
            rows.append(self._cache[key])
        return [(torch.cat([r[l][0] for r in rows]), [torch.cat([r[l][1][s] for r in rows]) for s in range(2)])
                for l in range(len(self.SA_modules))]

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        xyz, feats = [points], [None]
        for sa, groups in zip(self.SA_modules, self.groupings(points)):
            x, f = sa(xyz[-1], feats[-1], groups)
            xyz.append(x)
            feats.append(f)
        return self.FP_modules[3](xyz[-2], xyz[-1], feats[-2], feats[-1])
