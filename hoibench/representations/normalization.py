"""Normalisation statistics with HumanML3D's grouped standard deviation.

``mean`` is the per-feature mean over every frame of every clip (clips concatenated along
time, as ``cal_mean_variance.ipynb``); ``std`` is the per-feature population std, then
replaced within each feature group (root rotation velocity, root linear velocity, root
height, ric, rot6d, local velocity, foot contacts; hoi269 adds object rotation and object
translation as HOI-Diff does) by the group's mean std. A model sees ``(x - mean) / std``.

``clean`` statistics differ in one respect: a group whose std is 0 (e.g. foot contacts that
never change in a small split) gets std 1 instead of producing inf/NaN. Statistics are
computed on the train split only; :meth:`NormStats.sha256` names them in evaluator cards.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import Iterable

import numpy as np

from . import hml263, hoi269


def groups_for(dim: int) -> dict[str, slice]:
    """Feature groups of a 263- or 269-dim layout."""
    if dim == hml263.DIM:
        return hml263.GROUPS
    if dim == hoi269.DIM:
        return hoi269.GROUPS
    raise ValueError(f"features: expected 263 or 269 dims, got {dim}")


@dataclass(frozen=True)
class NormStats:
    mean: np.ndarray   # (D,) float32
    std: np.ndarray    # (D,) float32
    count: int         # frames the statistics were computed on

    def normalize(self, x: np.ndarray) -> np.ndarray:
        return (x - self.mean) / self.std

    def denormalize(self, x: np.ndarray) -> np.ndarray:
        return x * self.std + self.mean

    def sha256(self) -> str:
        h = hashlib.sha256()
        h.update(np.ascontiguousarray(self.mean, dtype="<f4").tobytes())
        h.update(np.ascontiguousarray(self.std, dtype="<f4").tobytes())
        return h.hexdigest()

    def to_npz_bytes(self) -> bytes:
        """Byte-reproducible .npz (``mean``, ``std``, ``count``) that :meth:`from_npz` reads."""
        from ..core.io import npz_bytes
        return npz_bytes({"mean": self.mean, "std": self.std, "count": np.int64(self.count)})

    @classmethod
    def from_npz(cls, path) -> "NormStats":
        from ..core.io import MAX_CLIP_BYTES, load_raw_npz
        z = load_raw_npz(path, MAX_CLIP_BYTES, "normalisation statistics")
        return cls(z["mean"].astype(np.float32), z["std"].astype(np.float32), int(z["count"]))


def compute_stats(clips: Iterable[np.ndarray], mode: str = "clean") -> NormStats:
    """Grouped mean/std over (T_i, D) feature clips (D = 263 or 269).

    Sums are accumulated in float64 (sum and sum of squares), so the result does not
    depend on how the clips are chunked; ``legacy`` keeps zero-std groups as in HumanML3D.
    """
    if mode not in ("legacy", "clean"):
        raise ValueError(f"mode: expected 'legacy' or 'clean', got {mode!r}")
    total = total_sq = None
    n = 0
    for i, clip in enumerate(clips):
        c = np.asarray(clip, dtype=np.float64)
        if c.ndim != 2:
            raise ValueError(f"clips[{i}]: expected (T, D) features, got shape {c.shape}")
        if not np.isfinite(c).all():
            raise ValueError(f"clips[{i}]: non-finite feature values")
        if total is None:
            total, total_sq = np.zeros(c.shape[1]), np.zeros(c.shape[1])
        elif c.shape[1] != len(total):
            raise ValueError(f"clips[{i}]: expected {len(total)} dims, got {c.shape[1]}")
        total += c.sum(0)
        total_sq += (c * c).sum(0)
        n += len(c)
    if n == 0:
        raise ValueError("clips: no frames to compute statistics from")
    mean = total / n
    std = np.sqrt(np.maximum(total_sq / n - mean * mean, 0.0))
    for sl in groups_for(len(mean)).values():
        g = std[sl].mean()
        std[sl] = 1.0 if (mode == "clean" and g == 0.0) else g
    return NormStats(mean.astype(np.float32), std.astype(np.float32), n)
