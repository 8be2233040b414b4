"""Exact point-to-triangle distance in PyTorch (the ``exact`` ChainHOI ``L_h``): analytic cases,
a dense-sampling bound, the pruned nearest face against every face, padding, the loss."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from hoibench.baselines.joint_data import stack_meshes
from hoibench.baselines.joint_losses import contact_loss_exact
from hoibench.baselines.mesh_distance import closest_point_on_triangle, nearest_face, squared_distance

A, B, C = torch.tensor([0.0, 0, 0]), torch.tensor([1.0, 0, 0]), torch.tensor([0.0, 1, 0])


@pytest.mark.parametrize("p, expect", [
    ((0.2, 0.3, 0.5), (0.2, 0.3, 0.0)),          # above the face: its projection
    ((-1.0, -2.0, 0.3), (0.0, 0.0, 0.0)),        # beyond vertex a
    ((3.0, -0.5, 0.0), (1.0, 0.0, 0.0)),         # beyond vertex b
    ((-0.5, 4.0, 1.0), (0.0, 1.0, 0.0)),         # beyond vertex c
    ((0.5, -1.0, 2.0), (0.5, 0.0, 0.0)),         # beyond edge ab
    ((-2.0, 0.25, 0.0), (0.0, 0.25, 0.0)),       # beyond edge ac
    ((1.0, 1.0, -0.5), (0.5, 0.5, 0.0)),         # beyond edge bc
])
def test_closest_point_in_every_voronoi_region(p, expect):
    c = closest_point_on_triangle(torch.tensor(p), A, B, C)
    torch.testing.assert_close(c, torch.tensor(expect), atol=1e-6, rtol=0)


def test_closest_point_is_the_minimum_over_a_dense_sampling():
    g = torch.Generator().manual_seed(0)
    tri = torch.randn(50, 3, 3, generator=g, dtype=torch.float64)
    p = torch.randn(50, 3, generator=g, dtype=torch.float64) * 2
    c = closest_point_on_triangle(p, tri[:, 0], tri[:, 1], tri[:, 2])
    d = (p - c).norm(dim=-1)
    u, v = torch.meshgrid(torch.linspace(0, 1, 201, dtype=torch.float64), torch.linspace(0, 1, 201, dtype=torch.float64),
                          indexing="ij")
    keep = (u + v) <= 1
    u, v = u[keep], v[keep]
    grid = tri[:, None, 0] + u[None, :, None] * (tri[:, None, 1] - tri[:, None, 0]) \
        + v[None, :, None] * (tri[:, None, 2] - tri[:, None, 0])
    dense = (grid - p[:, None]).norm(dim=-1).min(1).values
    edge = (tri - tri.roll(1, 1)).norm(dim=-1).max(1).values
    assert (d <= dense + 1e-12).all()                                   # never farther than a sample
    assert (dense - d <= edge / 200 + 1e-9).all()                       # and within the grid spacing


@pytest.mark.parametrize("backend", ["torch", "open3d"])
def test_pruned_nearest_face_equals_the_minimum_over_every_face(backend):
    from hoibench.datasets.synthetic_objects import build_object
    meshes = [torch.from_numpy(build_object(n).vertices[build_object(n).faces].astype(np.float32))
              for n in ("stool", "backpack")]
    stacked = torch.from_numpy(stack_meshes([m.numpy() for m in meshes]))
    g = torch.Generator().manual_seed(1)
    p = torch.cat([torch.randn(300, 3, generator=g) * 0.3, torch.zeros(20, 3)])   # incl. the centre
    owner = torch.randint(0, 2, (len(p),), generator=g)
    if backend == "open3d":
        pytest.importorskip("open3d")
    idx = nearest_face(p, owner, stacked, chunk_points=64, backend=backend)
    t = stacked[owner]
    every = ((p[:, None] - closest_point_on_triangle(p[:, None], t[:, :, 0], t[:, :, 1], t[:, :, 2])) ** 2).sum(-1)
    d2 = squared_distance(p, owner, stacked)
    torch.testing.assert_close(d2, every.min(1).values, atol=1e-7, rtol=1e-6)
    torch.testing.assert_close(every.gather(1, idx[:, None])[:, 0], every.min(1).values, atol=1e-7, rtol=1e-6)
    alone = squared_distance(p[owner == 0], owner[owner == 0] * 0, meshes[0][None])   # padding changes nothing
    torch.testing.assert_close(alone, d2[owner == 0])


def test_gradient_is_twice_the_offset_to_the_closest_point():
    p = torch.tensor([[0.2, 0.3, 0.5], [0.5, -1.0, 2.0]], requires_grad=True)
    tri = torch.stack([A, B, C])[None, None]
    d2 = squared_distance(p, torch.zeros(2, dtype=torch.long), tri)
    d2.sum().backward()
    torch.testing.assert_close(d2.detach(), torch.tensor([0.25, 5.0]))
    torch.testing.assert_close(p.grad, torch.tensor([[0.0, 0.0, 1.0], [0.0, -2.0, 4.0]]))


def _cube() -> torch.Tensor:
    v = torch.tensor([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return torch.stack([v[list(t)] for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])


def test_exact_contact_loss_on_a_posed_cube():
    """Cube of side 1 turned 90 degrees about y and moved to (2, 0.5, 0): a joint 0.1 m beyond
    the +x face and a joint 0.3 m above the top face; the third joint is not in contact."""
    rows = torch.zeros(1, 1, 24, 12)
    rows[0, 0, 23, 0:3] = torch.tensor([0.0, np.pi / 2, 0.0])
    rows[0, 0, 23, 3:6] = torch.tensor([2.0, 0.5, 0.0])
    rows[0, 0, 0, 8:11] = torch.tensor([2.6, 0.2, 0.0])          # pelvis (interaction joint 0)
    rows[0, 0, 10, 0:3] = torch.tensor([2.0, 1.3, 0.1])         # joint 10 (index 1), root-relative x/z
    rows[0, 0, 10, [0, 2]] -= torch.tensor([2.6, 0.0])           # yaw 0: p = ric + root (x, z)
    rows[0, 0, 11, 0:3] = torch.tensor([5.0, 5.0, 5.0])
    contacts = torch.zeros(1, 1, 8, dtype=torch.bool)
    contacts[0, 0, :2] = True
    loss = contact_loss_exact(rows, rows, contacts, torch.ones(1, 1, dtype=torch.bool), _cube()[None])
    assert float(loss) == pytest.approx((0.1 ** 2 + 0.3 ** 2) / 2, rel=1e-5)
