"""Loss terms of the joint-level diffusion baselines, on raw (de-normalised) joint-level rows,
and :func:`denoise`, the noising and x0 prediction every baseline's losses start from.

- :func:`contact_loss` (ChainHOI eq. 6, ``L_h``): squared distance (m^2) from each of the eight
  interaction joints (0, 10, 11, 12, 16, 17, 20, 21) of the prediction to the nearest sample of
  the GT object surface posed by the GT pose, gated by the GT contact label, averaged over
  gated joint-rows (the paper sums; the mean keeps the weight independent of length and batch).
  :func:`contact_loss_exact` is the same term with the exact point-to-triangle distance to the
  GT-posed template mesh (the joint mapped into the template frame by the inverse GT pose).
- :func:`object_loss` (ChainHOI eq. 7 ``L_o``, EJIM's object loss): squared error of the
  object 6-DoF (axis-angle rad, translation m), averaged over valid rows.
- :func:`smooth_loss` (EJIM ``L_smooth``): squared error between the frame-to-frame changes of
  the prediction and of the GT (normalised units), over pairs of valid rows: it penalises
  jitter without pulling the motion towards standing still.
"""
from __future__ import annotations

import torch

from ..core.geometry import axis_angle_to_matrix
from . import joint_data as D
from .diffusion import GaussianDiffusion, drop_condition, masked_mse
from .mesh_distance import squared_distance


def denoise(model, diffusion: GaussianDiffusion, batch: dict, cfg, generator: torch.Generator):
    """(x0 prediction, clean x0) for a batch: random timesteps, noise and condition drops."""
    x0 = batch["x0"]
    B = x0.shape[0]
    dev = x0.device
    t = diffusion.sample_timesteps(B, generator).to(dev)
    noise = torch.randn(x0.shape, generator=generator).to(dev)
    keep = drop_condition(B, cfg.diffusion.cond_drop, generator).to(dev)
    xt = diffusion.q_sample(x0, t, noise)
    text = model.encode_text(batch["text"], batch["text_pad"])
    obj = model.encode_object(batch["points"])
    return model(xt, t, keep, text, batch["text_pad"], obj, batch["valid"]), x0


def interaction_positions(rows: torch.Tensor) -> torch.Tensor:
    """(B, L, 8, 3) absolute positions (canonical frame, m) of the interaction joints from raw
    joint-level rows (B, L, 24, 12): ``p = R_y(yaw)^T ric + (root_x, 0, root_z)``; the pelvis
    is the root itself."""
    yaw = rows[..., 0, 7]
    root = rows[..., 0, 8:11]
    c, s = torch.cos(yaw)[..., None], torch.sin(yaw)[..., None]
    idx = list(D.INTERACTION_JOINTS[1:])
    ric = rows[..., idx, 0:3]
    x = c * ric[..., 0] - s * ric[..., 2] + root[..., None, 0]
    z = s * ric[..., 0] + c * ric[..., 2] + root[..., None, 2]
    others = torch.stack([x, ric[..., 1], z], -1)
    return torch.cat([root[..., None, :], others], -2)


def posed_points(rows: torch.Tensor, points: torch.Tensor) -> torch.Tensor:
    """(B, L, P, 3): object surface points (B, P, 3) posed by the object node of raw rows."""
    R = axis_angle_to_matrix(rows[..., 23, 0:3])                 # (B, L, 3, 3)
    t = rows[..., 23, 3:6]
    return torch.einsum("blij,bpj->blpi", R, points) + t[..., None, :]


def contact_loss(raw_pred: torch.Tensor, raw_gt: torch.Tensor, contacts: torch.Tensor, valid: torch.Tensor,
                 surface: torch.Tensor) -> torch.Tensor:
    """``L_h``: raw rows (B, L, 24, 12), contacts (B, L, 8) bool, valid (B, L), surface (B, P, 3)."""
    gate = contacts & valid[..., None]
    if not bool(gate.any()):
        return raw_pred.sum() * 0.0
    joints = interaction_positions(raw_pred)                          # (B, L, 8, 3)
    surf = posed_points(raw_gt, surface)                              # (B, L, P, 3)
    B, L = joints.shape[:2]
    d2 = torch.cdist(joints.reshape(B * L, -1, 3), surf.reshape(B * L, -1, 3)).min(-1).values.reshape(B, L, -1) ** 2
    return (d2 * gate).sum() / gate.sum()


def contact_loss_exact(raw_pred: torch.Tensor, raw_gt: torch.Tensor, contacts: torch.Tensor, valid: torch.Tensor,
                       meshes: torch.Tensor) -> torch.Tensor:
    """``L_h`` with exact distances: raw rows (B, L, 24, 12), contacts (B, L, 8) bool, valid
    (B, L), meshes (B, F, 3, 3) template triangles. ``d^2 = dist(R^T (p - t), mesh)^2`` with
    (R, t) the GT object pose of the row, averaged over gated joint-rows."""
    gate = contacts & valid[..., None]
    if not bool(gate.any()):
        return raw_pred.sum() * 0.0
    joints = interaction_positions(raw_pred)                          # (B, L, 8, 3)
    R = axis_angle_to_matrix(raw_gt[..., 23, 0:3])                    # (B, L, 3, 3)
    t = raw_gt[..., 23, 3:6]
    local = torch.einsum("blji,blkj->blki", R, joints - t[..., None, :])   # R^T (p - t)
    b = torch.arange(gate.shape[0], device=gate.device)[:, None, None].expand_as(gate)
    return squared_distance(local[gate], b[gate], meshes).sum() / gate.sum()


def contact_term(raw_pred: torch.Tensor, raw_gt: torch.Tensor, batch: dict, valid: torch.Tensor) -> torch.Tensor:
    """``L_h`` with the batch's distance: exact, to the template meshes, when the batch carries
    them (``train.contact_distance = "exact"``), else to the nearest surface sample."""
    if "contact_mesh" in batch:
        return contact_loss_exact(raw_pred, raw_gt, batch["contacts"], valid, batch["contact_mesh"])
    return contact_loss(raw_pred, raw_gt, batch["contacts"], valid, batch["contact_points"])


def object_loss(raw_pred: torch.Tensor, raw_gt: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
    """``L_o``: mean squared error of the object node's 6-DoF over valid rows."""
    return masked_mse(raw_pred[..., 23, 0:6], raw_gt[..., 23, 0:6], valid)


def smooth_loss(pred: torch.Tensor, target: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
    """``L_smooth``: mean squared error of first differences over time, pairs of valid rows."""
    pair = valid[:, 1:] & valid[:, :-1]
    return masked_mse(pred[:, 1:] - pred[:, :-1], target[:, 1:] - target[:, :-1], pair)
