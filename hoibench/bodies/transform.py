"""Moving SMPL-family parameters between frames (about the pelvis)."""
from __future__ import annotations

import numpy as np

from ..core import geometry as geo


def rigid_transform_smpl(root_orient: np.ndarray, trans: np.ndarray, rest_pelvis: np.ndarray,
                         R: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Apply ``p -> R p + c`` to SMPL parameters (axis-angle root (T,3), trans (T,3)).

    The posed body is ``R0 (v - J0) + J0 + t`` about the rest pelvis ``J0`` (which depends
    on the shape); moving it gives ``R R0 (v - J0) + R (J0 + t) + c``, i.e. ``R0' = R R0``
    and ``t' = R (J0 + t) + c - J0``. Rotating ``t`` alone would shift the body by
    ``(I - R) J0``. Returns ``(R0' as axis-angle, t')``.
    """
    R = np.asarray(R, dtype=np.float64)
    R0 = R @ geo.axis_angle_to_matrix(np.asarray(root_orient, dtype=np.float64))
    J0 = np.asarray(rest_pelvis, dtype=np.float64)
    t = (J0 + np.asarray(trans, dtype=np.float64)) @ R.T + np.asarray(c, dtype=np.float64) - J0
    return geo.matrix_to_axis_angle(R0), t
