"""Exact, differentiable point-to-triangle-mesh distance in PyTorch (the ``exact`` ``L_h``).

:func:`closest_point_on_triangle` is the closest point of a triangle to a point (Ericson,
*Real-Time Collision Detection* 5.1.5: the Voronoi regions of the vertices, the edges and the
face), broadcast over leading axes. :func:`nearest_face` finds, without gradient and in chunks
of point-face pairs, the face each point is closest to; the squared distance to that face's
closest point is then differentiable in the point (its gradient is ``2 (p - c)``, the gradient
of the distance to the whole mesh wherever the closest face is unique).
"""
from __future__ import annotations

import torch


def _dot(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    return (a * b).sum(-1)


def closest_point_on_triangle(p: torch.Tensor, a: torch.Tensor, b: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
    """(..., 3) closest point of triangle (a, b, c) to ``p``; all (..., 3), broadcast."""
    ab, ac, ap, bp, cp = b - a, c - a, p - a, p - b, p - c
    d1, d2, d3, d4, d5, d6 = _dot(ab, ap), _dot(ac, ap), _dot(ab, bp), _dot(ac, bp), _dot(ab, cp), _dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2

    def ratio(num: torch.Tensor, den: torch.Tensor) -> torch.Tensor:        # 0/0 on unused branches -> 0
        return num / torch.where(den == 0, torch.ones_like(den), den)

    s = ratio(torch.ones_like(va), va + vb + vc)
    out = a + ab * (vb * s)[..., None] + ac * (vc * s)[..., None]               # face
    shape = out.shape
    cases = [  # later cases take precedence, as in Ericson's early returns (vertices first)
        ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), b + (c - b) * ratio(d4 - d3, (d4 - d3) + (d5 - d6))[..., None]),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + ac * ratio(d2, d2 - d6)[..., None]),
        ((d6 >= 0) & (d5 <= d6), c.expand(shape)),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + ab * ratio(d1, d1 - d3)[..., None]),
        ((d3 >= 0) & (d4 <= d3), b.expand(shape)),
        ((d1 <= 0) & (d2 <= 0), a.expand(shape)),
    ]
    for cond, point in cases:
        out = torch.where(cond[..., None], point, out)
    return out


@torch.no_grad()
def nearest_face(points: torch.Tensor, owner: torch.Tensor, meshes: torch.Tensor, chunk_points: int = 256
                 ) -> torch.Tensor:
    """(N,) index of the face of ``meshes[owner]`` closest to each of ``points`` (N, 3);
    ``meshes`` (B, F, 3, 3) triangles, ``owner`` (N,) the mesh of each point.

    Exact, with pruning: a face's distance is at least ``|p - centre| - radius`` (its bounding
    sphere about the centroid) and the mesh's at most ``min_f |p - centre_f|``, so only the
    faces whose lower bound is within that upper bound can be nearest; the exact closest
    point is computed for the ``k`` faces of smallest lower bound, ``k`` the largest
    candidate count of the chunk."""
    centre = meshes.mean(2)                                                        # (B, F, 3)
    radius = (meshes - centre[:, :, None]).norm(dim=-1).amax(-1)                  # (B, F)
    out = torch.empty(len(points), dtype=torch.long, device=points.device)
    for s in range(0, len(points), chunk_points):
        p, o = points[s:s + chunk_points], owner[s:s + chunk_points]
        dc = (p[:, None] - centre[o]).norm(dim=-1)                                # (n, F)
        lower = (dc - radius[o]).clamp_min(0)
        upper = dc.min(1, keepdim=True).values
        k = int((lower <= upper).sum(1).max())
        cand = lower.topk(k, dim=1, largest=False).indices                         # (n, k)
        t = meshes[o[:, None], cand]                                               # (n, k, 3, 3)
        c = closest_point_on_triangle(p[:, None], t[:, :, 0], t[:, :, 1], t[:, :, 2])
        best = ((p[:, None] - c) ** 2).sum(-1).argmin(1)
        out[s:s + chunk_points] = cand.gather(1, best[:, None])[:, 0]
    return out


def squared_distance(points: torch.Tensor, owner: torch.Tensor, meshes: torch.Tensor) -> torch.Tensor:
    """(N,) squared exact distance (m^2) of ``points`` (N, 3) to their meshes ``meshes[owner]``
    ((B, F, 3, 3) triangles; pad a mesh with copies of one of its faces), differentiable in
    the points (and the nearest face's vertices)."""
    if len(points) == 0:
        return points.sum(-1)
    idx = nearest_face(points.detach(), owner, meshes.detach())
    t = meshes[owner, idx]                                                        # (N, 3, 3)
    c = closest_point_on_triangle(points, t[:, 0], t[:, 1], t[:, 2])
    return ((points - c) ** 2).sum(-1)
