"""Points around hoibench's synthetic objects with their analytic signed distances
(tests/test_contact.py, tests/test_synthetic.py)."""
from __future__ import annotations

from typing import Iterator

import numpy as np

from hoibench.datasets import synthetic as syn


def points_around_objects(seed: int, margin: float, n: int) -> Iterator[tuple[str, object, np.ndarray, np.ndarray]]:
    """(name, object, points, analytic signed distances) of every synthetic object: ``n``
    points uniform in its bounding box grown by ``margin`` metres, one generator for all."""
    rng = np.random.default_rng(seed)
    for name in syn.OBJECTS:
        obj = syn.build_object(name)
        lo, hi = obj.vertices.min(0) - margin, obj.vertices.max(0) + margin
        p = rng.uniform(lo, hi, (n, 3))
        yield name, obj, p, obj.sdf_local(p)
