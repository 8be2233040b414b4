"""ChainHOI's joint-level layout: (T, 24, 12) per frame, one row per node of the HOI graph.

==== ======================================================================================
node content (12 values)
==== ======================================================================================
0    root: hml263[0:4] (heading step, xz velocity, height), root local velocity
     (hml263[193:196]), yaw (rad, ``local = R_y(yaw) world``), global root x, y, z, 0
1-21 joint j: relative position (hml263 ric, 3), rot6d (6), local velocity (3)
22   foot contacts (hml263[259:263]) then 8 zeros
23   object axis-angle (3) and translation (3) (hoi269[263:269]) then 6 zeros
==== ======================================================================================

This is ChainHOI's ``behave_joint_5`` layout (its 273-dim vectors: hoi269 + the four global
root values). The yaw and global root are not free: they are recovered from the heading
step and root velocity (:func:`hml263.recover_root`), so hoi269 -> joint_level -> hoi269 is
exact and joint_level -> (hoi269, global root) -> joint_level is exact.
"""
from __future__ import annotations

import numpy as np

from . import hml263, hoi269
from ._checks import as_float_array

NODES = 24
WIDTH = 12


def from_hoi269(features: np.ndarray, global_root: np.ndarray | None = None) -> np.ndarray:
    """(T, 269) or (B, T, 269) -> (T, 24, 12) or (B, T, 24, 12) float32.

    Also accepts hml263 rows (T, 263): the object node is then zero. ``global_root``
    (..., T, 4) = (yaw, x, y, z) overrides the values recovered from the features.
    """
    dim = features.shape[-1] if hasattr(features, "shape") else None
    if dim not in (hml263.DIM, hoi269.DIM):
        raise ValueError(f"features: expected last dimension 263 or 269, got shape "
                         f"{getattr(features, 'shape', None)}")
    f, batched = as_float_array(features, "features", (dim,), min_frames=1)
    if global_root is None:
        yaw, root = hml263.recover_root(f[..., :hml263.DIM])
        glob = np.concatenate([yaw[..., None], root], -1)
    else:
        glob, _ = as_float_array(global_root, "global_root", (4,), min_frames=1, batch_ok=batched)
        if glob.shape[:2] != f.shape[:2]:
            raise ValueError(f"global_root: expected leading dims {f.shape[:2]}, got {glob.shape[:2]}")
    B, T = f.shape[:2]
    out = np.zeros((B, T, NODES, WIDTH), dtype=np.float32)
    out[:, :, 0, 0:4] = f[..., 0:4]
    out[:, :, 0, 4:7] = f[..., 193:196]
    out[:, :, 0, 7:11] = glob
    out[:, :, 1:22, 0:3] = f[..., hml263.RIC].reshape(B, T, 21, 3)
    out[:, :, 1:22, 3:9] = f[..., hml263.ROT6D].reshape(B, T, 21, 6)
    out[:, :, 1:22, 9:12] = f[..., 196:259].reshape(B, T, 21, 3)
    out[:, :, 22, 0:4] = f[..., hml263.FOOT_CONTACT]
    if dim == hoi269.DIM:
        out[:, :, 23, 0:6] = f[..., 263:269]
    return out if batched else out[0]


def to_hoi269(joint_level: np.ndarray, with_object: bool = True,
              return_global_root: bool = False):
    """(T, 24, 12) or (B, T, 24, 12) -> hoi269 rows (or hml263 rows when ``with_object``
    is False) [and the (..., T, 4) global root values (yaw, x, y, z)]."""
    x, batched = as_float_array(joint_level, "joint_level", (NODES, WIDTH), min_frames=1)
    B, T = x.shape[:2]
    dim = hoi269.DIM if with_object else hml263.DIM
    out = np.zeros((B, T, dim), dtype=x.dtype)
    out[..., 0:4] = x[:, :, 0, 0:4]
    out[..., 193:196] = x[:, :, 0, 4:7]
    out[..., hml263.RIC] = x[:, :, 1:22, 0:3].reshape(B, T, 63)
    out[..., hml263.ROT6D] = x[:, :, 1:22, 3:9].reshape(B, T, 126)
    out[..., 196:259] = x[:, :, 1:22, 9:12].reshape(B, T, 63)
    out[..., hml263.FOOT_CONTACT] = x[:, :, 22, 0:4]
    if with_object:
        out[..., 263:269] = x[:, :, 23, 0:6]
    glob = x[:, :, 0, 7:11]
    if not batched:
        out, glob = out[0], glob[0]
    return (out, glob) if return_global_root else out
