"""Grid bounds of the signed distance field (nearest node and cell) and the joint contacts that
read exact distances only where the bounds leave the answer open."""
from __future__ import annotations

import numpy as np
import pytest

open3d = pytest.importorskip("open3d")

from hoibench.bodies.distance import SignedDistance, signed_distance_field  # noqa: E402
from hoibench.datasets.synthetic import build_object  # noqa: E402
from hoibench.metrics import contact_metrics as cm  # noqa: E402


@pytest.fixture(scope="module", params=["yogaball", "chairwood"])
def field(request) -> SignedDistance:
    obj = build_object(request.param)
    return signed_distance_field(obj.vertices, obj.faces)


def _points(field: SignedDistance, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(field.box_min - 0.08, field.box_max + 0.08, (n, 3))


def test_cell_bounds_hold_and_are_tighter_than_the_nearest_node(field):
    p = _points(field, 4000, 0)
    d = field(p)
    lo, hi = field.bracket(p)
    clo, chi = field.bracket_cell(p)
    assert np.all(lo <= d) and np.all(d <= hi)
    assert np.all(clo <= d) and np.all(d <= chi)
    inner = np.isfinite(clo)
    assert inner.mean() > 0.5                      # most points lie in a whole cell of the grid
    width, cell = (hi - lo)[inner], (chi - clo)[inner]
    assert cell.mean() < 0.5 * width.mean()        # about a quarter on these meshes


def test_cell_bounds_at_grid_nodes_pin_the_node_values(field):
    g = field._grid()
    rng = np.random.default_rng(1)
    ijk = np.stack([rng.integers(0, s - 1, 50) for s in g.shape], 1)
    nodes = g.origin + g.step * ijk
    lo, hi = field.bracket_cell(nodes)
    flat = (ijk[:, 0] * g.shape[1] + ijk[:, 1]) * g.shape[2] + ijk[:, 2]
    v = g.values[flat]                 # other corners may tighten by float32 noise, never past v
    assert np.all(lo <= v) and np.all(v <= hi)
    assert np.all(hi - lo <= 2 * field.BOUND_SLACK_M + 1e-12)


def test_points_outside_the_grid_get_open_cell_bounds(field):
    far = np.array([[10.0, 0.0, 0.0], [np.nan, 0.0, 0.0], [-10.0, -10.0, -10.0]])
    lo, hi = field.bracket_cell(far)
    assert np.all(lo == -np.inf) and np.all(hi == np.inf)
    blo, bhi = field.bracket(far[[0, 2]])
    assert np.all(blo > 0) and np.all(bhi == np.inf)


def test_joint_contacts_match_every_exact_distance(field):
    rng = np.random.default_rng(2)
    T = 40
    centre = 0.5 * (field.box_min + field.box_max)
    J = centre + rng.normal(scale=0.25, size=(T, 22, 3))
    ang = rng.uniform(0, 2 * np.pi, T)
    R = np.zeros((T, 3, 3))
    R[:, 0, 0] = R[:, 2, 2] = np.cos(ang)
    R[:, 0, 2], R[:, 2, 0] = np.sin(ang), -np.sin(ang)
    R[:, 1, 1] = 1.0
    t = rng.normal(scale=0.02, size=(T, 3))
    full = cm.joint_object_distances(J, None, None, R, t, field=field)
    tau = np.full(22, 0.1)
    tau[[20, 21]] = 0.03
    needed = rng.random((T + 5, 22)) < 0.2          # longer than the clip: its first T frames count
    d, pred = cm.joint_contacts(J, R, t, field, tau, needed)
    np.testing.assert_array_equal(pred, cm.predicted_contacts(full, tau))
    assert pred.any() and (~pred).any()
    np.testing.assert_array_equal(d[needed[:T]], full[needed[:T]])
    assert np.isnan(d).any()                        # not every distance was queried
    none, pred2 = cm.joint_contacts(J, R, t, field, tau)
    np.testing.assert_array_equal(pred2, pred)
    assert np.isnan(none).sum() > np.isnan(d).sum()


@pytest.mark.parametrize("name", ["yogaball", "backpack"])          # one closest-point grid, one per-component
def test_the_grid_read_back_from_the_disk_cache_is_the_computed_one(name, tmp_path, monkeypatch):
    from hoibench.core import disk_cache
    monkeypatch.setenv(disk_cache.CACHE_ENV, str(tmp_path / "cache"))
    obj = build_object(name)
    computed = SignedDistance(obj.vertices, obj.faces)._grid()
    (entry,) = (tmp_path / "cache" / "distance-grid").glob("*.npz")

    def no_queries(*_a, **_k):
        raise AssertionError("the grid was computed again although cached")
    fresh = SignedDistance(obj.vertices, obj.faces)
    monkeypatch.setattr(fresh, "_exact", no_queries)
    read = fresh._grid()
    assert read.values.dtype == np.float64 and np.array_equal(read.values, computed.values)
    assert (read.closest is None) == (computed.closest is None)
    if computed.closest is not None:
        assert np.array_equal(read.closest, computed.closest) and read.closest.dtype == computed.closest.dtype
    # another mesh (moved by 1 mm) has another entry; a damaged entry is computed again
    SignedDistance(obj.vertices + 0.001, obj.faces)._grid()
    assert len(list(entry.parent.glob("*.npz"))) == 2
    entry.write_bytes(entry.read_bytes()[:100])
    again = SignedDistance(obj.vertices, obj.faces)._grid()
    assert np.array_equal(again.values, computed.values)
    monkeypatch.setenv(disk_cache.CACHE_ENV, "off")               # off: computed, nothing read or written
    entry.unlink()
    assert np.array_equal(SignedDistance(obj.vertices, obj.faces)._grid().values, computed.values)
    assert not entry.exists()
