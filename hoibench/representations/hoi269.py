"""HOI-Diff's 269-dim human-object layout: hml263 followed by the object pose.

====== ===== ==================================================================
slice   dims  content
====== ===== ==================================================================
0:263   263   :mod:`hml263` features of the body
263:266 3     object rotation, axis-angle (rad)
266:269 3     object translation (m), canonical frame of the body (``v = R v0 + t``)
====== ===== ==================================================================

Modes:

``legacy``
    HOI-Diff's ``process_file``: the body is encoded with ``hml263`` mode
    ``legacy-hoidiff`` (no retargeting), the object translation gets the same floor
    shift, origin shift and frame-0 facing rotation as the body, but the object rotation is
    left in the world frame (HOI-Diff's quirk): decoding a legacy clip whose first frame
    did not face +Z gives the object the wrong orientation.
``clean``
    Body with ``hml263`` clean mode; the object rotation is rotated into the canonical
    frame like the translation, so body and object stay rigidly consistent.

Rows are frames 0..T-2, like hml263.
"""
from __future__ import annotations

import numpy as np

from ..core import geometry as geo
from . import hml263
from ._checks import as_float_array

DIM = 269
OBJ_ROTVEC = slice(263, 266)
OBJ_TRANS = slice(266, 269)
GROUPS: dict[str, slice] = {**hml263.GROUPS, "obj_rotvec": OBJ_ROTVEC, "obj_trans": OBJ_TRANS}
BODY_MODE = {"legacy": "legacy-hoidiff", "clean": "clean"}
VERSION = {"legacy": "hoi269-legacy-1.0", "clean": "hoi269-clean-1.0"}


def _mode(mode: str) -> str:
    if mode not in BODY_MODE:
        raise ValueError(f"mode: expected one of {sorted(BODY_MODE)}, got {mode!r}")
    return BODY_MODE[mode]


def encode(joints: np.ndarray, obj_rot: np.ndarray, obj_trans: np.ndarray,
           mode: str = "clean", fps: float = 20.0) -> np.ndarray:
    """Encode body joints and object poses into (T-1, 269) or (B, T-1, 269) float32.

    Args:
        joints: (T, 22, 3) or (B, T, 22, 3) positions (m, y-up).
        obj_rot: (T, 3, 3) rotation matrices or (T, 3) axis-angle (same batching).
            Legacy copies axis-angle input unchanged (HOI-Diff); clean re-expresses the
            rotation in the canonical frame with angle in [0, pi].
        obj_trans: (T, 3) translations (m), object vertices ``v = R v_template + t``.
        mode: ``"clean"`` or ``"legacy"`` (HOI-Diff).
        fps: frame rate (clean foot contacts).
    """
    body_mode = _mode(mode)
    pos, batched = as_float_array(joints, "joints", (22, 3), min_frames=2)
    rot, rotvec_in = _as_matrices(obj_rot, batched)
    trans, _ = as_float_array(obj_trans, "obj_trans", (3,), min_frames=2, batch_ok=batched)
    if rot.shape[:2] != pos.shape[:2] or trans.shape[:2] != pos.shape[:2]:
        raise ValueError(f"obj_rot/obj_trans: expected {pos.shape[:2]} leading dims like joints, "
                         f"got {rot.shape[:2]} and {trans.shape[:2]}")
    cfg = hml263.MODES[body_mode]
    body, _, (floor, origin, init_quat) = hml263._encode_batch(pos, cfg, float(fps))
    dt = np.float32 if cfg.float32 else np.float64
    t = trans.astype(np.float64).copy()
    t[..., 1] -= floor[:, None]
    t -= origin[:, None]
    q = np.broadcast_to(init_quat[:, None], t.shape[:-1] + (4,)).astype(dt)
    t = geo.quaternion_apply(q, t.astype(dt))
    if mode == "clean":
        rotvec = geo.matrix_to_axis_angle(geo.quaternion_to_matrix(q.astype(np.float64)) @ rot)
    elif rotvec_in is not None:
        rotvec = rotvec_in        # HOI-Diff copies the world-frame axis-angle unchanged
    else:
        rotvec = geo.matrix_to_axis_angle(rot)
    out = np.concatenate([body, rotvec[:, :-1].astype(np.float32), t[:, :-1].astype(np.float32)], -1)
    return out if batched else out[0]


def _as_matrices(obj_rot, batched: bool) -> tuple[np.ndarray, np.ndarray | None]:
    """(B, T, 3, 3) float64 matrices and, when given as axis-angle, the (B, T, 3) input."""
    arr = obj_rot.detach().cpu().numpy() if hasattr(obj_rot, "detach") else obj_rot
    if isinstance(arr, np.ndarray) and arr.shape[-2:] == (3, 3):
        m, _ = as_float_array(arr, "obj_rot", (3, 3), min_frames=2, batch_ok=batched)
        if not geo.is_rotation_matrix(m.astype(np.float64), atol=1e-4).all():
            raise ValueError("obj_rot: expected rotation matrices (orthonormal, det +1)")
        return m.astype(np.float64), None
    v, _ = as_float_array(arr, "obj_rot", (3,), min_frames=2, batch_ok=batched)
    return geo.axis_angle_to_matrix(v.astype(np.float64)), v.astype(np.float64)


def decode(features: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Joints (..., T, 22, 3), object rotation matrices (..., T, 3, 3) and translations
    (..., T, 3), float64, in the canonical frame (legacy: rotation left in world frame)."""
    f, batched = as_float_array(features, "features", (DIM,), min_frames=1)
    joints = hml263.decode(f[..., :hml263.DIM])
    rot = geo.axis_angle_to_matrix(f[..., OBJ_ROTVEC].astype(np.float64))
    trans = f[..., OBJ_TRANS].astype(np.float64)
    if not batched:
        return joints[0], rot[0], trans[0]
    return joints, rot, trans
