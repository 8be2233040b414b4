"""Motion-branch inputs: normalised hml263 rows and, for the ``hoi`` variant, the object
trajectory relative to the body.

Object-relative features (15 per row, computed from hoi269 ``clean`` rows only, so a
submission that provides joints and object poses can be embedded after encoding them):

====== ===== ==================================================================
slice   dims  content
====== ===== ==================================================================
0:3     3     object translation minus root, in the heading frame of the row (m)
3:9     6     object rotation in the heading frame, rot6d (first two matrix columns)
9:12    3     object translation minus left wrist (joint 20), heading frame (m)
12:15   3     object translation minus right wrist (joint 21), heading frame (m)
====== ===== ==================================================================

The heading frame and the root come from the hml263 root channels (:func:`hml263.recover_root`:
``local = R_y(yaw) (p - root)``), the wrists from the decoded joints, so the features are
invariant to where the clip starts and which way it faces. They are normalised like hml263:
per-feature mean, grouped std (the three groups above), computed on the train split.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

from ..core import geometry as geo
from ..representations import hml263, hoi269

OBJ_DIM = 15
OBJ_GROUPS = {"obj_rel_trans": slice(0, 3), "obj_rel_rot6d": slice(3, 9), "obj_rel_wrists": slice(9, 15)}


def object_relative(features: np.ndarray) -> np.ndarray:
    """(..., T, 15) float32 object-relative features from (..., T, 269) hoi269 clean rows."""
    f = np.asarray(features, dtype=np.float64)
    if f.shape[-1] != hoi269.DIM:
        raise ValueError(f"features: the hoi variant needs hoi269 rows (269 dims), got {f.shape[-1]}")
    body = f[..., :hml263.DIM]
    yaw, root = hml263.recover_root(body)
    joints = hml263.decode(body)
    heading = geo.rotation_about_y(yaw)                       # (..., T, 3, 3): local = R world
    t = f[..., hoi269.OBJ_TRANS]
    rot = geo.axis_angle_to_matrix(f[..., hoi269.OBJ_ROTVEC])

    def local(v):
        return np.einsum("...ij,...j->...i", heading, v)

    out = np.concatenate([local(t - root), geo.matrix_to_rot6d(heading @ rot),
                          local(t - joints[..., 20, :]), local(t - joints[..., 21, :])], axis=-1)
    return out.astype(np.float32)


@dataclass(frozen=True)
class FeatureStats:
    """Mean / grouped std of the motion-branch inputs (hml263 and, for ``hoi``, the 15
    object-relative features)."""

    mean: np.ndarray
    std: np.ndarray
    obj_mean: np.ndarray | None = None
    obj_std: np.ndarray | None = None

    def sha256(self) -> str:
        """hml263 part: identical to :meth:`NormStats.sha256` of the store's statistics."""
        h = hashlib.sha256()
        h.update(np.ascontiguousarray(self.mean, dtype="<f4").tobytes())
        h.update(np.ascontiguousarray(self.std, dtype="<f4").tobytes())
        return h.hexdigest()

    def obj_sha256(self) -> str | None:
        if self.obj_mean is None:
            return None
        h = hashlib.sha256()
        h.update(np.ascontiguousarray(self.obj_mean, dtype="<f4").tobytes())
        h.update(np.ascontiguousarray(self.obj_std, dtype="<f4").tobytes())
        return h.hexdigest()

    def to_card(self, source: str) -> dict:
        d = {"features": "hml263", "source": source, "mean": [float(x) for x in self.mean],
             "std": [float(x) for x in self.std], "sha256": self.sha256()}
        if self.obj_mean is not None:
            d["object"] = {"features": "object_relative_15",
                           "groups": {k: [s.start, s.stop] for k, s in OBJ_GROUPS.items()},
                           "mean": [float(x) for x in self.obj_mean], "std": [float(x) for x in self.obj_std],
                           "sha256": self.obj_sha256()}
        return d

    @classmethod
    def from_card(cls, d: dict) -> "FeatureStats":
        o = d.get("object")
        st = cls(np.asarray(d["mean"], np.float32), np.asarray(d["std"], np.float32),
                 None if o is None else np.asarray(o["mean"], np.float32),
                 None if o is None else np.asarray(o["std"], np.float32))
        if st.sha256() != d["sha256"] or (o is not None and st.obj_sha256() != o["sha256"]):
            raise ValueError("normalisation statistics in card.json do not match their recorded sha256")
        return st


def object_stats(clips: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Per-feature mean and grouped population std (float64 sums) of object-relative rows."""
    x = np.concatenate([np.asarray(c, np.float64) for c in clips], axis=0)
    mean = x.mean(0)
    std = x.std(0)
    for sl in OBJ_GROUPS.values():
        g = std[sl].mean()
        std[sl] = g if g > 0 else 1.0
    return mean.astype(np.float32), std.astype(np.float32)


def motion_inputs(features: np.ndarray, variant: str, stats: FeatureStats) -> tuple[np.ndarray, np.ndarray | None]:
    """Normalised (T, 263) body rows and (T, 15) object rows (``None`` for ``human``) of one
    clip's raw features: hml263 (263) or hoi269 (269) rows."""
    f = np.asarray(features, dtype=np.float32)
    if f.ndim != 2 or f.shape[-1] not in (hml263.DIM, hoi269.DIM):
        raise ValueError(f"features: expected (T, 263) or (T, 269) rows, got shape {f.shape}")
    body = (f[:, :hml263.DIM] - stats.mean) / stats.std
    if variant == "human":
        return body.astype(np.float32), None
    obj = (object_relative(f) - stats.obj_mean) / stats.obj_std
    return body.astype(np.float32), obj.astype(np.float32)
