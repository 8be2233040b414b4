"""Basis point set features of object geometry (Prokudin et al. 2019; SyncDiff appendix C.3).

A fixed basis of ``n`` points drawn uniformly from the volume of a ball of radius
``radius`` (metres), seeded, is shared by every object; an object's feature is, for each
basis point, the distance to the nearest of its surface samples (template centred on its
vertex mean, so the ball is centred on the object). numpy only; deterministic for a seed.
"""
from __future__ import annotations

import numpy as np

__all__ = ["basis", "encode"]


def basis(n: int, radius: float, seed: int = 0) -> np.ndarray:
    """(n, 3) float64 points uniform in the ball ``|p| <= radius`` (direction Gaussian, radius
    ``radius * u^(1/3)``)."""
    rng = np.random.default_rng([int(seed), 0x8B95])
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return d * (radius * rng.random(n) ** (1.0 / 3.0))[:, None]


def encode(points: np.ndarray, basis_points: np.ndarray, chunk: int = 256) -> np.ndarray:
    """(n,) float32 distance from each basis point to the nearest of ``points`` (P, 3)."""
    p = np.asarray(points, np.float64)
    out = np.empty(len(basis_points))
    for i in range(0, len(basis_points), chunk):
        b = basis_points[i:i + chunk]
        out[i:i + chunk] = np.sqrt(((b[:, None] - p[None]) ** 2).sum(-1).min(1))
    return out.astype(np.float32)
