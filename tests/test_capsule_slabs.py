"""The multi-body IV counts a large overlap block by block (bounded memory) with the same
result as one grid."""
from __future__ import annotations

import numpy as np

from hoibench.bodies import capsules as C
from hoibench.bodies.multibody import Body, MultiBodyClip


def test_slab_by_slab_volume_equals_one_grid(monkeypatch):
    rng = np.random.default_rng(3)
    J = rng.normal(0, 0.03, (2, 21, 3))                       # two frames of a crumpled hand
    a = Body("left", "hand", J[:, 0].copy(), None, J, None, "left")
    b = Body("right", "hand", J[:, 0].copy() + 0.004, None, J + 0.004, None, "right")
    clip = MultiBodyClip("c", "t", "s", 20.0, [a, b])
    vol, dep = C.pair_penetration(clip, 0, 1, {})
    assert (vol > 0).all() and (dep > 0).all()
    lo, hi = np.zeros(3), np.array([0.1, 0.05, 0.05])
    monkeypatch.setattr(C, "GRID_BLOCK_VOXELS", 50)          # 20 x 10 x 10 voxels: one x-row per block
    blocks = list(C._slabs(lo, hi, 0.005))
    assert len(blocks) == 20 and np.allclose(np.concatenate([C._grid(l, h, 0.005) for l, h in blocks]),
                                             C._grid(lo, hi, 0.005), atol=1e-15)
    vol2, dep2 = C.pair_penetration(clip, 0, 1, {})
    assert np.array_equal(vol, vol2) and np.array_equal(dep, dep2)
