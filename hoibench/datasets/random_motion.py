"""Smooth random body motion for tests, benchmarks and the representation demo.

Not an HOI dataset (see :mod:`hoibench.datasets.synthetic` for that): a body built by
forward kinematics from the SMPL rest skeleton, with sinusoidal joint rotations, a heading
that turns at a random rate and a root that travels along the heading. Deterministic for
a seed.
"""
from __future__ import annotations

import numpy as np

from ..core import geometry as geo
from ..core import skeleton as sk


def random_motion(num_frames: int, seed: int = 0, fps: float = 20.0, *,
                  speed_mps: float = 1.0, turn_dps: float = 30.0, amplitude_rad: float = 0.35,
                  batch: int | None = None) -> np.ndarray:
    """Joint positions (T, 22, 3) — or (batch, T, 22, 3) — float64, metres, y-up.

    The feet are lifted so the lowest joint of frame 0 sits at y = 0.
    """
    if batch is not None:
        return np.stack([random_motion(num_frames, seed * 100_003 + i, fps, speed_mps=speed_mps,
                                       turn_dps=turn_dps, amplitude_rad=amplitude_rad)
                         for i in range(batch)])
    rng = np.random.default_rng(seed)
    t = np.arange(num_frames) / fps
    freq = rng.uniform(0.3, 1.5, size=(22, 3))
    phase = rng.uniform(0, 2 * np.pi, size=(22, 3))
    amp = amplitude_rad * rng.uniform(0.2, 1.0, size=(22, 3))
    aa = amp * np.sin(2 * np.pi * freq * t[:, None, None] + phase)          # (T, 22, 3)
    heading = np.deg2rad(rng.uniform(0, 360) + rng.uniform(-1, 1) * turn_dps * t)
    aa[:, 0] = 0.2 * aa[:, 0]
    rots = geo.axis_angle_to_matrix(aa)
    rots[:, 0] = geo.rotation_about_y(heading) @ rots[:, 0]
    direction = np.stack([np.sin(heading), np.zeros_like(heading), np.cos(heading)], -1)
    trans = np.cumsum(direction * speed_mps / fps, axis=0) + rng.uniform(-3, 3, size=3) * [1, 0, 1]
    scale = rng.uniform(0.9, 1.1)
    joints, _ = sk.forward_kinematics(rots, sk.SMPL_REST_JOINTS * scale, trans)
    joints[..., 1] -= joints[0, :, 1].min()
    return joints
