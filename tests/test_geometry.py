"""Tests for hoibench.core.geometry against scipy.spatial.transform.Rotation and closed forms."""

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from hoibench.core import geometry as g

RNG = np.random.default_rng(0)
N = 64
ROTS = Rotation.random(N, random_state=1)


def _wxyz(xyzw):
    return np.concatenate([xyzw[..., 3:], xyzw[..., :3]], -1)


def _as(x, backend, dtype):
    x = np.asarray(x, dtype=dtype)
    return torch.from_numpy(x) if backend == "torch" else x


def _np(x):
    return x.detach().cpu().numpy() if isinstance(x, torch.Tensor) else np.asarray(x)


def _check_type(out, backend, dtype):
    assert isinstance(out, torch.Tensor if backend == "torch" else np.ndarray)
    want = {"float32": (np.float32, torch.float32), "float64": (np.float64, torch.float64)}[dtype]
    assert out.dtype == (want[1] if backend == "torch" else want[0])


def _same_quat(a, b, atol):
    """Quaternions equal up to sign."""
    d = np.minimum(np.abs(a - b).max(-1), np.abs(a + b).max(-1))
    return np.all(d < atol)


BACKENDS = [(b, d) for b in ("numpy", "torch") for d in ("float32", "float64")]
TOL = {"float32": 2e-5, "float64": 1e-10}


# --------------------------------------------------------------------------- vs scipy
@pytest.mark.parametrize("backend,dtype", BACKENDS)
def test_conversions_match_scipy(backend, dtype):
    tol = TOL[dtype]
    mat, rv, q = ROTS.as_matrix(), ROTS.as_rotvec(), _wxyz(ROTS.as_quat())
    M, A, Q = (_as(x, backend, dtype) for x in (mat, rv, q))

    for fn, arg, ref in [
        (g.axis_angle_to_matrix, A, mat),
        (g.quaternion_to_matrix, Q, mat),
        (g.matrix_to_axis_angle, M, rv),
        (g.quaternion_to_axis_angle, Q, rv),
    ]:
        out = fn(arg)
        _check_type(out, backend, dtype)
        np.testing.assert_allclose(_np(out), ref, atol=tol * 10, err_msg=fn.__name__)

    for fn, arg in [(g.axis_angle_to_quaternion, A), (g.matrix_to_quaternion, M)]:
        out = fn(arg)
        _check_type(out, backend, dtype)
        assert _same_quat(_np(out), q, tol * 10), fn.__name__
    assert np.all(_np(g.matrix_to_quaternion(M))[:, 0] >= 0)


@pytest.mark.parametrize("backend,dtype", BACKENDS)
def test_round_trips(backend, dtype):
    tol = TOL[dtype] * 10
    A = _as(ROTS.as_rotvec().reshape(4, 16, 3), backend, dtype)  # extra batch dim
    M = g.axis_angle_to_matrix(A)
    assert tuple(M.shape) == (4, 16, 3, 3)
    for back in [
        g.matrix_to_axis_angle(M),
        g.quaternion_to_axis_angle(g.axis_angle_to_quaternion(A)),
        g.quaternion_to_axis_angle(g.matrix_to_quaternion(g.quaternion_to_matrix(g.axis_angle_to_quaternion(A)))),
        g.rot6d_to_axis_angle(g.axis_angle_to_rot6d(A)),
    ]:
        _check_type(back, backend, dtype)
        np.testing.assert_allclose(_np(back), _np(A), atol=tol)
    assert bool(np.all(_np(g.is_rotation_matrix(M, atol=1e-5))))


def test_single_unbatched_and_python_input():
    R = g.axis_angle_to_matrix(np.array([0.0, 0.3, 0.0]))
    assert R.shape == (3, 3)
    np.testing.assert_allclose(R, Rotation.from_rotvec([0, 0.3, 0]).as_matrix(), atol=1e-12)
    assert isinstance(g.is_rotation_matrix(R), np.ndarray) and bool(g.is_rotation_matrix(R))
    Ry = g.rotation_about_y(0.3)  # python float -> float64 numpy
    assert isinstance(Ry, np.ndarray) and Ry.dtype == np.float64
    np.testing.assert_allclose(Ry, R, atol=1e-12)


# --------------------------------------------------------------------------- edge angles
@pytest.mark.parametrize("backend,dtype", BACKENDS)
def test_small_angles(backend, dtype):
    rv = RNG.normal(size=(5, 3))
    rv /= np.linalg.norm(rv, axis=-1, keepdims=True)
    rv = np.concatenate([np.zeros((1, 3)), rv * np.array([1e-12, 1e-8, 1e-6, 1e-4, 1e-3])[:, None]])
    A = _as(rv, backend, dtype)
    mat = Rotation.from_rotvec(rv).as_matrix()
    np.testing.assert_allclose(_np(g.axis_angle_to_matrix(A)), mat, atol=TOL[dtype])
    q = _np(g.axis_angle_to_quaternion(A))
    np.testing.assert_allclose(q, _wxyz(Rotation.from_rotvec(rv).as_quat()), atol=TOL[dtype])
    # quaternion -> axis-angle is exact-ish for tiny angles (no matrix roundoff)
    back = _np(g.quaternion_to_axis_angle(_as(q, backend, dtype)))
    np.testing.assert_allclose(back, rv, rtol=1e-5 if dtype == "float32" else 1e-12, atol=1e-30)
    assert np.all(np.isfinite(back))
    np.testing.assert_allclose(_np(g.matrix_to_axis_angle(_as(mat, backend, dtype))), rv,
                               atol=TOL[dtype])


def test_small_angle_gradients_finite():
    A = torch.tensor([[0.0, 0.0, 0.0], [1e-9, 0, 0], [0.5, -0.2, 0.1]], dtype=torch.float64,
                     requires_grad=True)
    out = g.matrix_to_axis_angle(g.axis_angle_to_matrix(A)).sum() + g.axis_angle_to_quaternion(A).sum()
    out.backward()
    assert torch.isfinite(A.grad).all()


@pytest.mark.parametrize("backend,dtype", BACKENDS)
def test_angles_at_and_near_pi(backend, dtype):
    axes = RNG.normal(size=(6, 3))
    axes[:3] = np.eye(3)
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    for ang in (np.pi, np.pi - 1e-4, np.pi - 1e-7):
        rv = axes * ang
        mat = Rotation.from_rotvec(rv).as_matrix()
        out = _np(g.matrix_to_axis_angle(_as(mat, backend, dtype)))
        tol = 1e-3 if dtype == "float32" else 1e-7
        np.testing.assert_allclose(np.linalg.norm(out, axis=-1), ang, atol=tol)
        # equal up to the arbitrary axis sign at exactly pi
        err = np.minimum(np.abs(out - rv).max(-1), np.abs(out + rv).max(-1))
        assert np.all(err < tol), (ang, err)
        np.testing.assert_allclose(_np(g.axis_angle_to_matrix(_as(out, backend, dtype))), mat,
                                   atol=10 * TOL[dtype])
        q = _np(g.matrix_to_quaternion(_as(mat, backend, dtype)))
        assert np.all(q[:, 0] >= 0)
        assert _same_quat(q, _wxyz(Rotation.from_matrix(mat).as_quat()), 10 * TOL[dtype])


# --------------------------------------------------------------------------- quaternion algebra
@pytest.mark.parametrize("backend", ["numpy", "torch"])
def test_quaternion_multiply_and_apply(backend):
    q = _wxyz(ROTS.as_quat())
    r = _wxyz(Rotation.random(N, random_state=2).as_quat())
    Q, Rq = _as(q, backend, "float64"), _as(r, backend, "float64")
    prod = g.quaternion_to_matrix(g.quaternion_multiply(Q, Rq))
    np.testing.assert_allclose(
        _np(prod), _np(g.quaternion_to_matrix(Q) @ g.quaternion_to_matrix(Rq)), atol=1e-12)
    # scipy composition (a * b applies b first) agrees
    ref = (ROTS * Rotation.from_quat(np.concatenate([r[:, 1:], r[:, :1]], -1))).as_matrix()
    np.testing.assert_allclose(_np(prod), ref, atol=1e-12)

    ident = g.quaternion_multiply(Q, g.quaternion_inverse(Q))
    np.testing.assert_allclose(_np(ident), np.tile([1.0, 0, 0, 0], (N, 1)), atol=1e-12)
    np.testing.assert_allclose(_np(g.quaternion_conjugate(Q)), q * [1, -1, -1, -1])
    np.testing.assert_allclose(_np(g.quaternion_inverse(2 * Q)), q * [1, -1, -1, -1] / 2, atol=1e-12)

    v = RNG.normal(size=(N, 3))
    V = _as(v, backend, "float64")
    rotated = g.quaternion_apply(Q, V)
    np.testing.assert_allclose(_np(rotated), np.einsum("nij,nj->ni", ROTS.as_matrix(), v), atol=1e-12)
    # non-unit quaternion denotes the same rotation; broadcasting one q over many v
    np.testing.assert_allclose(_np(g.quaternion_apply(3 * Q[:1], V)),
                               v @ ROTS[0].as_matrix().T, atol=1e-12)


@pytest.mark.parametrize("backend,dtype", BACKENDS)
def test_quaternion_between(backend, dtype):
    tol = 1e-4 if dtype == "float32" else 1e-10
    u = RNG.normal(size=(N, 3)) * RNG.uniform(0.5, 3, size=(N, 1))
    v = RNG.normal(size=(N, 3))
    v[:8] = -u[:8] * 2.0  # exactly antiparallel
    v[8:12] = u[8:12]  # parallel
    v[12:14] = -u[12:14] + 1e-9 * RNG.normal(size=(2, 3))  # nearly antiparallel
    v[14] = [0, 0, -1.0]
    u[14] = [0, 0, 1.0]
    v[15] = [-1.0, 0, 0]
    u[15] = [1.0, 0, 0]
    q = g.quaternion_between(_as(u, backend, dtype), _as(v, backend, dtype))
    _check_type(q, backend, dtype)
    qn = _np(q)
    np.testing.assert_allclose(np.linalg.norm(qn, axis=-1), 1, atol=tol)
    assert np.all(qn[:, 0] >= -tol)
    un, vn = (x / np.linalg.norm(x, axis=-1, keepdims=True) for x in (u, v))
    moved = _np(g.quaternion_apply(q, _as(un, backend, dtype)))
    np.testing.assert_allclose(moved, vn, atol=tol * 10)
    # shortest arc: rotation angle equals the angle between u and v
    ang = np.linalg.norm(_np(g.quaternion_to_axis_angle(q)), axis=-1)
    ref = np.arccos(np.clip((un * vn).sum(-1), -1, 1))
    np.testing.assert_allclose(ang, ref, atol=1e-3 if dtype == "float32" else 1e-6)


# --------------------------------------------------------------------------- 6D
@pytest.mark.parametrize("backend,dtype", BACKENDS)
def test_rot6d(backend, dtype):
    mat = ROTS.as_matrix()
    M = _as(mat, backend, dtype)
    d6 = g.matrix_to_rot6d(M)
    _check_type(d6, backend, dtype)
    # column layout (HumanML3D cont6d)
    np.testing.assert_allclose(_np(d6), np.concatenate([mat[:, :, 0], mat[:, :, 1]], -1), atol=1e-6)
    np.testing.assert_allclose(_np(g.rot6d_to_matrix(d6)), mat, atol=10 * TOL[dtype])
    # perturbed / unnormalised 6D -> valid rotation whose first column follows a
    noisy = _np(d6) * 2.5 + 0.1 * RNG.normal(size=(N, 6))
    R = g.rot6d_to_matrix(_as(noisy, backend, dtype))
    assert bool(np.all(_np(g.is_rotation_matrix(R, atol=1e-5))))
    a = noisy[:, :3] / np.linalg.norm(noisy[:, :3], axis=-1, keepdims=True)
    np.testing.assert_allclose(_np(R)[:, :, 0], a, atol=1e-5)
    # second column lies in span(a, b) on b's side
    assert np.all(np.einsum("ni,ni->n", _np(R)[:, :, 1], noisy[:, 3:]) > 0)
    np.testing.assert_allclose(_np(g.axis_angle_to_rot6d(_as(ROTS.as_rotvec(), backend, dtype))),
                               _np(d6), atol=10 * TOL[dtype])


# --------------------------------------------------------------------------- elementary rotations
@pytest.mark.parametrize("backend", ["numpy", "torch"])
def test_rotation_about_axes(backend):
    Ry = g.rotation_about_y(_as(np.pi / 2, backend, "float64"))
    np.testing.assert_allclose(_np(Ry) @ [0, 0, 1.0], [1.0, 0, 0], atol=1e-12)
    Rx = g.rotation_about_x(_as(np.pi / 2, backend, "float64"))
    np.testing.assert_allclose(_np(Rx) @ [0, 1.0, 0], [0, 0, 1.0], atol=1e-12)
    ang = RNG.uniform(-np.pi, np.pi, size=(2, 5))
    for fn, ax in [(g.rotation_about_y, [0, 1, 0]), (g.rotation_about_x, [1, 0, 0])]:
        out = fn(_as(ang, backend, "float32"))
        _check_type(out, backend, "float32")
        assert tuple(out.shape) == (2, 5, 3, 3)
        ref = Rotation.from_rotvec(ang.reshape(-1, 1) * ax).as_matrix().reshape(2, 5, 3, 3)
        np.testing.assert_allclose(_np(out), ref, atol=1e-6)


def test_is_rotation_matrix():
    R = ROTS.as_matrix()[:3]
    bad = np.stack([R[0] @ np.diag([1.0, 1, -1]), 1.01 * R[1], R[2]])
    np.testing.assert_array_equal(g.is_rotation_matrix(bad), [False, False, True])
    out = g.is_rotation_matrix(torch.from_numpy(bad).float())
    assert out.dtype == torch.bool and out.tolist() == [False, False, True]
    assert not bool(g.is_rotation_matrix(-np.eye(3)))  # det -1


# --------------------------------------------------------------------------- rigid transforms
@pytest.mark.parametrize("backend,dtype", BACKENDS)
def test_rigid(backend, dtype):
    tol = 10 * TOL[dtype]
    R = _as(ROTS.as_matrix()[:8], backend, dtype)
    t = _as(RNG.normal(size=(8, 3)), backend, dtype)
    R2 = _as(Rotation.random(8, random_state=5).as_matrix(), backend, dtype)
    t2 = _as(RNG.normal(size=(8, 3)), backend, dtype)
    p = _as(RNG.normal(size=(8, 20, 3)), backend, dtype)
    out = g.apply_rigid(R, t, p)
    _check_type(out, backend, dtype)
    ref = np.einsum("bij,bnj->bni", _np(R), _np(p)) + _np(t)[:, None]
    np.testing.assert_allclose(_np(out), ref, atol=tol)
    Ri, ti = g.invert_rigid(R, t)
    np.testing.assert_allclose(_np(g.apply_rigid(Ri, ti, out)), _np(p), atol=tol)
    Rc, tc = g.compose_rigid(R2, t2, R, t)
    np.testing.assert_allclose(_np(g.apply_rigid(Rc, tc, p)),
                               _np(g.apply_rigid(R2, t2, g.apply_rigid(R, t, p))), atol=tol)
    Rid, tid = g.compose_rigid(Ri, ti, R, t)
    np.testing.assert_allclose(_np(Rid), np.broadcast_to(np.eye(3), (8, 3, 3)), atol=tol)
    np.testing.assert_allclose(_np(tid), 0, atol=tol)


# --------------------------------------------------------------------------- validation
@pytest.mark.parametrize("fn,args,msg", [
    (g.matrix_to_axis_angle, (np.zeros((4, 3)),), r"matrix: expected shape \(\.\.\., 3, 3\), got \(4, 3\)"),
    (g.matrix_to_quaternion, (torch.zeros(2, 3, 4),), r"matrix: expected shape \(\.\.\., 3, 3\), got \(2, 3, 4\)"),
    (g.axis_angle_to_matrix, (np.zeros(4),), r"axis_angle: expected shape \(\.\.\., 3\), got \(4,\)"),
    (g.quaternion_to_matrix, (np.zeros((5, 3)),), r"quaternion: expected shape \(\.\.\., 4\)"),
    (g.quaternion_multiply, (np.zeros(4), np.zeros(3)), r"^r: expected shape \(\.\.\., 4\)"),
    (g.quaternion_apply, (np.zeros(4), np.zeros(4)), r"^v: expected shape \(\.\.\., 3\)"),
    (g.rot6d_to_matrix, (np.zeros((2, 3, 2)),), r"rot6d: expected shape \(\.\.\., 6\)"),
    (g.apply_rigid, (np.eye(3), np.zeros(3), np.zeros(3)), r"points: expected shape \(\.\.\., N, 3\), got \(3,\)"),
    (g.axis_angle_to_matrix, (np.zeros((2, 3), dtype=np.int64),), r"axis_angle: .*floating"),
    (g.quaternion_to_axis_angle, (torch.zeros(2, 4, dtype=torch.int32),), r"quaternion: .*floating"),
    (g.rotation_about_y, (np.arange(3),), r"angle: .*floating"),
    (g.is_rotation_matrix, (np.zeros((2, 2)),), r"R: expected shape"),
])
def test_validation_errors(fn, args, msg):
    with pytest.raises(ValueError, match=msg):
        fn(*args)


def test_mixing_backends_rejected():
    with pytest.raises(TypeError):
        g.quaternion_multiply(np.ones(4), torch.ones(4))
