"""CHOIS's two penetration measures, read from a signed-distance grid of the rest-pose object.

Source: GitHub ``lijiaman/chois_release`` (commit 9cd4cf6).

* ``hand_penetration`` / ``penetration`` (:func:`hand_penetration`): ``trainer_chois.py``
  ``compute_hand_penetration_metric`` (L909-938) with ``compute_signed_distances``
  (L63-87): the hand vertices (``data/part_vert_ids``, left then right; or the whole body
  with ``eval_fullbody``) are moved into the object's rest frame as ``R (v - com)`` -- R
  where R^T is meant (the object is posed as ``R v_rest + com``); ``legacy=False`` uses
  ``R^T (v - com)``. The signed distance is read there and rescaled to metres; the value is
  ``mean |min(d, 0)|`` over all vertices and frames (metres, no threshold).
* ``penetration_depth`` / ``penetration_percent`` (:func:`collision_penetration`):
  ``evaluation_metrics.py`` ``compute_collision`` (L235-352), in the released file but
  never called: body vertices to the object's template frame as ``R^T (v - t) / s``; per
  frame the negative distances whose magnitude exceeds 0.04 are averaged; the value is the
  mean of those frame averages over the frames that have any (0 when none), and the
  fraction of such frames. Its distances are the grid's values times ``obj_scale``: the
  grid's normalised units (half the template's largest extent = 1), not metres, and so is
  the 0.04 threshold.

Sampling (:meth:`SdfGrid.sample`) is ``F.grid_sample(..., align_corners=True,
padding_mode='border')`` on a (N, N, N) grid after the query's axes are reversed: the grid
is indexed ``sdf[ix, iy, iz]`` at ``(p + 1) / 2 * (N - 1)`` per axis, trilinearly, the
coordinates clamped to [-1, 1].
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: compute_collision's depth threshold (L291), in the grid's normalised units
COLLISION_THRESHOLD = 0.04


@dataclass(frozen=True)
class SdfGrid:
    """A (N, N, N) signed-distance grid and its normalisation: ``centroid`` and ``extents``
    (``<object>.ply.json``: query ``(p - centroid) * 2 / max(extents)``), or, for grids made
    by SIREN's code, ``coord_center``/``coord_min``/``coord_max`` (compute_collision L268-277)."""

    values: np.ndarray
    centroid: np.ndarray | None = None
    extents: np.ndarray | None = None
    coord_center: np.ndarray | None = None
    coord_min: float | None = None
    coord_max: float | None = None

    def normalise(self, points: np.ndarray) -> np.ndarray:
        """Points (..., 3) in the rest frame -> the grid's [-1, 1] coordinates."""
        p = np.asarray(points, np.float64)
        if self.coord_center is not None:
            q = (p - np.asarray(self.coord_center) - self.coord_min) / (self.coord_max - self.coord_min)
            return (q - 0.5) * 2.0
        if self.centroid is None or self.extents is None:
            raise ValueError("sdf grid: needs centroid and extents (or coord_center, coord_min, coord_max)")
        return (p - np.asarray(self.centroid)) * 2.0 / float(np.max(self.extents))

    def sample(self, coords: np.ndarray) -> np.ndarray:
        """Trilinear values at [-1, 1] coordinates (..., 3), clamped to the border."""
        v = np.asarray(self.values, np.float64)
        if v.ndim != 3:
            raise ValueError(f"sdf grid: expected a (N, N, N) array, got shape {v.shape}")
        c = np.clip(np.asarray(coords, np.float64), -1.0, 1.0)
        u = (c + 1.0) / 2.0 * (np.array(v.shape) - 1)
        i0 = np.clip(np.floor(u).astype(np.int64), 0, np.array(v.shape) - 2)
        f = u - i0
        out = np.zeros(c.shape[:-1])
        for dx in (0, 1):
            wx = f[..., 0] if dx else 1 - f[..., 0]
            for dy in (0, 1):
                wy = f[..., 1] if dy else 1 - f[..., 1]
                for dz in (0, 1):
                    wz = f[..., 2] if dz else 1 - f[..., 2]
                    out += wx * wy * wz * v[i0[..., 0] + dx, i0[..., 1] + dy, i0[..., 2] + dz]
        return out


def hand_penetration(verts, obj_com, obj_rot, sdf: SdfGrid, vertex_ids=None, legacy: bool = True) -> float:
    """Metres: ``mean |min(d, 0)|`` over the chosen vertices and all frames, ``d`` the
    rest-pose object's signed distance times ``max(extents) / 2``. ``verts`` (T, V, 3);
    ``vertex_ids``: the hand vertices (None: all, CHOIS's full-body ``penetration``);
    ``legacy``: CHOIS's ``R (v - com)`` (True) or the rest-frame ``R^T (v - com)``."""
    v = np.asarray(verts, np.float64)
    if vertex_ids is not None:
        v = v[:, np.asarray(vertex_ids, np.int64)]
    rel = v - np.asarray(obj_com, np.float64)[:, None, :]
    r = np.asarray(obj_rot, np.float64)
    rest = np.einsum("tij,tvj->tvi", r, rel) if legacy else np.einsum("tji,tvj->tvi", r, rel)
    if sdf.extents is None:
        raise ValueError("hand_penetration: the sdf grid needs extents (<object>.ply.json)")
    d = sdf.sample(sdf.normalise(rest)) * float(np.max(sdf.extents)) / 2.0
    return float(np.abs(np.minimum(d, 0.0)).mean())


def collision_penetration(verts, obj_rot, obj_trans, obj_scale, sdf: SdfGrid,
                          threshold: float = COLLISION_THRESHOLD) -> tuple[float, float]:
    """(penetration_percent, penetration_depth) of ``compute_collision``: per frame the
    vertices go to the template frame ``R^T (v - t) / s``, the grid value times ``s`` is
    read; the frame penetrates when some negative value has magnitude > ``threshold``, and
    adds the mean of those magnitudes. Depth: the sum over penetrating frames divided by
    their number (0 when none); percent: their fraction of all frames. Units: the grid's
    normalised ones times ``s`` (not metres)."""
    v = np.asarray(verts, np.float64)
    s = np.broadcast_to(np.asarray(obj_scale, np.float64), (len(v),))
    rel = (v - np.asarray(obj_trans, np.float64)[:, None, :]) / s[:, None, None]
    rest = np.einsum("tji,tvj->tvi", np.asarray(obj_rot, np.float64), rel)
    d = sdf.sample(sdf.normalise(rest)) * s[:, None]
    total, frames = 0.0, 0
    for row in d:
        deep = -row[(row < 0) & (-row > threshold)]
        if len(deep):
            total += float(deep.mean())
            frames += 1
    return frames / len(v), (total / frames if frames else 0.0)


__all__ = ["SdfGrid", "hand_penetration", "collision_penetration", "COLLISION_THRESHOLD"]
