"""The signed-distance grids of :class:`hoibench.bodies.distance.SignedDistance` kept on disk
(:mod:`hoibench.core.disk_cache`, kind ``distance-grid``): building one costs up to 1.6 s of
exact queries per object template, and every pool worker of every evaluation builds the test
objects' grids. An entry holds the node values (float64) and closest surface points (float32)
exactly as computed; its key covers the prepared mesh, the inside test and its rays, the
method, the grid's step and constants, the open3d version and the toolkit's code."""
from __future__ import annotations

import hashlib

import numpy as np

from ..core.disk_cache import code_digest, read_cached, write_cached

GRID_KIND, GRID_FORMAT = "distance-grid", "hoibench-distance-grid-1"


def grid_key(field, step: float, with_closest: bool) -> str:
    """sha256 of what ``field``'s grid of spacing ``step`` is computed from (module docstring)."""
    version = ""
    if field.method == "open3d":             # already imported by the field's scene
        import open3d
        version = open3d.__version__
    h = hashlib.sha256(repr((GRID_FORMAT, code_digest(), field.method, field.inside_test, field.nsamples,
                             float(step), field.GRID_STEP_M, field.GRID_PAD_M, field.GRID_MAX_NODES, with_closest,
                             version, field.vertices.dtype.str, field.vertices.shape, field.faces.dtype.str,
                             field.faces.shape)).encode())
    h.update(np.ascontiguousarray(field.vertices).tobytes())
    h.update(np.ascontiguousarray(field.faces).tobytes())
    return h.hexdigest()


def read_grid(key: str, nodes: int, with_closest: bool) -> tuple[np.ndarray, np.ndarray | None] | None:
    """``(values, closest)`` of the cached grid ``key`` of ``nodes`` nodes, or None (none, or
    not whole)."""
    z = read_cached(GRID_KIND, key, GRID_FORMAT, 64 * nodes + (1 << 16))
    if z is None or "values" not in z or z["values"].shape != (nodes,) or z["values"].dtype != np.float64:
        return None
    closest = z.get("closest") if with_closest else None
    if with_closest and (closest is None or closest.shape != (nodes, 3)):
        return None
    return z["values"], closest


def write_grid(key: str, values: np.ndarray, closest: np.ndarray | None) -> None:
    """Keep a computed grid (nothing when the cache is off or cannot be written)."""
    write_cached(GRID_KIND, key, GRID_FORMAT, {"values": values, **({} if closest is None else {"closest": closest})})


__all__ = ["GRID_KIND", "GRID_FORMAT", "grid_key", "read_grid", "write_grid"]
