"""Losses of ChainHOI ``released`` (the public code's ``_step_network`` and ``calculate_dis_loss``):
``L = L_diff + 2 L_h + 1 L_o`` on an x0 prediction.

- ``L_diff``: squared error of the normalised rows, averaged over the 24 x 12 values of a
  frame, then over the valid frames.
- ``L_o``: the template vertices posed by the predicted object pose and by the GT pose
  (raw rows: ``R(aa) v + t``, m); squared error averaged over vertices and xyz per frame, zero
  on padded frames, then averaged over all B x L frames (the released code divides by the
  padded count too).
- ``L_h``: the 22 predicted joints (root = global root channels, joints = ``R_y(yaw)`` ric +
  root xz, :func:`joint_positions`) against the GT-posed mesh: squared exact point-to-triangle
  distance (m^2, :func:`point_triangle_distance`), averaged per clip over the (frame, joint)
  pairs labelled in contact, then summed over clips and divided by B (clips without contact
  add 0).
"""
from __future__ import annotations

import torch

from ...core.geometry import axis_angle_to_matrix
from ..diffusion import masked_mse
from ..joint_losses import denoise

CHUNK = 256           # query points per distance chunk (bounds the (points, faces, 3, 3) temporaries)


def joint_positions(rows: torch.Tensor) -> torch.Tensor:
    """(..., 22, 3) joint positions (m) from raw joint-level rows (..., 24, 12): the root is
    the global root (node 0, channels 8..10); joint j = ``(c x - s z, y, s x + c z)`` of its
    ric (x, y, z) with ``c, s = cos, sin(yaw)``, plus the root's x and z."""
    yaw, root = rows[..., 0, 7], rows[..., 0, 8:11]
    c, s = torch.cos(yaw)[..., None], torch.sin(yaw)[..., None]
    ric = rows[..., 1:22, 0:3]
    x = c * ric[..., 0] - s * ric[..., 2] + root[..., None, 0]
    z = s * ric[..., 0] + c * ric[..., 2] + root[..., None, 2]
    return torch.cat([root[..., None, :], torch.stack([x, ric[..., 1], z], -1)], -2)


def posed_vertices(rows: torch.Tensor, vertices: torch.Tensor) -> torch.Tensor:
    """(B, L, V, 3): template vertices (B, V, 3) posed by the object node of raw rows."""
    R = axis_angle_to_matrix(rows[..., 23, 0:3])
    return torch.einsum("blij,bvj->blvi", R, vertices) + rows[..., 23, 3:6][..., None, :]


def _segment_distance(p: torch.Tensor, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    ab = b - a
    t = ((p - a) * ab).sum(-1) / (ab * ab).sum(-1).clamp_min(1e-20)
    return (p - (a + t.clamp(0, 1)[..., None] * ab)).norm(dim=-1)


def point_triangle_distance(p: torch.Tensor, tri: torch.Tensor) -> torch.Tensor:
    """Exact Euclidean distance from points to triangles: p (..., 3), tri (..., 3, 3) ->
    (...,): the plane distance where the projection falls inside the triangle (barycentric
    coordinates >= 0), otherwise the nearest of the three edge segments."""
    a, b, c = tri[..., 0, :], tri[..., 1, :], tri[..., 2, :]
    n = torch.linalg.cross(b - a, c - a)
    area2 = n.norm(dim=-1)
    nhat = n / area2.clamp_min(1e-20)[..., None]
    h = ((p - a) * nhat).sum(-1)
    q = p - h[..., None] * nhat
    e0, e1, e2 = b - a, c - a, q - a
    d00, d01, d11 = (e0 * e0).sum(-1), (e0 * e1).sum(-1), (e1 * e1).sum(-1)
    d20, d21 = (e2 * e0).sum(-1), (e2 * e1).sum(-1)
    den = (d00 * d11 - d01 * d01).clamp_min(1e-30)
    v, w = (d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den
    inside = (v >= 0) & (w >= 0) & (v + w <= 1) & (area2 > 1e-12)
    edges = torch.minimum(torch.minimum(_segment_distance(p, a, b), _segment_distance(p, b, c)),
                          _segment_distance(p, c, a))
    return torch.where(inside, h.abs(), edges)


def mesh_distance(points: torch.Tensor, triangles: torch.Tensor) -> torch.Tensor:
    """(M,) distance from each point (M, 3) to the nearest of its own triangles (M, F, 3, 3)."""
    return point_triangle_distance(points[:, None], triangles).min(-1).values


def contact_loss(raw_pred: torch.Tensor, raw_gt: torch.Tensor, contacts: torch.Tensor, valid: torch.Tensor,
                 vertices: torch.Tensor, faces: torch.Tensor) -> torch.Tensor:
    """``L_h``: contacts (B, L, 22) bool, vertices (B, V, 3), faces (B, F, 3) int64."""
    B = raw_pred.shape[0]
    gate = contacts & valid[..., None]
    if not bool(gate.any()):
        return raw_pred.sum() * 0.0
    b, l, j = gate.nonzero(as_tuple=True)
    joints = joint_positions(raw_pred)[b, l, j]                                   # (M, 3)
    R = axis_angle_to_matrix(raw_gt[b, l, 23, 0:3]).detach()
    t = raw_gt[b, l, 23, 3:6].detach()
    d2 = []
    for s in range(0, len(b), CHUNK):
        sl = slice(s, s + CHUNK)
        tri = vertices[b[sl][:, None, None], faces[b[sl]]]                         # (m, F, 3, 3)
        tri = torch.einsum("mij,mfkj->mfki", R[sl], tri) + t[sl][:, None, None]
        d2.append(mesh_distance(joints[sl], tri) ** 2)
    d2 = torch.cat(d2)
    per_clip = torch.zeros(B, dtype=d2.dtype, device=d2.device).index_add(0, b, d2)
    count = gate.sum((1, 2)).to(d2.dtype)
    return (per_clip / count.clamp_min(1)).sum() / B


def object_loss(raw_pred: torch.Tensor, raw_gt: torch.Tensor, valid: torch.Tensor, vertices: torch.Tensor,
                vertex_valid: torch.Tensor) -> torch.Tensor:
    """``L_o``: mean over vertices and xyz of the squared posed-vertex error, times valid, mean over B x L."""
    diff = (posed_vertices(raw_pred, vertices) - posed_vertices(raw_gt, vertices)) ** 2       # (B, L, V, 3)
    m = vertex_valid.to(diff.dtype)[:, None, :, None]
    per_frame = (diff * m).sum((2, 3)) / (3.0 * m.sum((2, 3)).clamp_min(1))
    return (per_frame * valid.to(diff.dtype)).mean()


def losses(model, diffusion, batch: dict, cfg, mean: torch.Tensor, std: torch.Tensor,
           generator: torch.Generator) -> dict[str, torch.Tensor]:
    pred, x0 = denoise(model, diffusion, batch, cfg, generator)
    valid = batch["valid"]
    l_diff = masked_mse(pred, x0, valid)
    raw_pred, raw_gt = pred * std + mean, x0 * std + mean
    l_h = contact_loss(raw_pred, raw_gt, batch["joint_contacts"], valid, batch["mesh_vertices"], batch["mesh_faces"]) \
        if cfg.train.lambda_contact > 0 else pred.sum() * 0.0
    l_o = object_loss(raw_pred, raw_gt, valid, batch["mesh_vertices"], batch["mesh_vertex_valid"])
    total = l_diff + cfg.train.lambda_contact * l_h + cfg.train.lambda_object * l_o
    return {"loss": total, "diffusion": l_diff, "contact": l_h, "object": l_o}
