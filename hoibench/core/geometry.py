"""Rotations and rigid transforms for numpy arrays and torch tensors.

Conventions
-----------
* Right-handed frames.  Rotation matrices act on column vectors, ``v' = R v``
  (for row-stacked points ``P' = P @ R.T``).
* Quaternions are ``(w, x, y, z)``, scalar first, as in HumanML3D (scipy uses
  ``(x, y, z, w)``).  A nonzero quaternion ``q`` denotes the rotation of
  ``q / |q|``; quaternion outputs are unit, and ``matrix_to_quaternion`` /
  ``quaternion_between`` return them canonicalised with ``w >= 0``.
* Hamilton product: ``quaternion_multiply(q, r) = q * r`` applies ``r`` first,
  i.e. ``R(q * r) = R(q) @ R(r)``.
* Axis-angle is a rotation vector ``axis * angle`` with angle = its norm in
  radians; outputs have angle in ``[0, pi]`` (at exactly ``pi`` the sign of the
  axis is arbitrary).
* 6D ("rot6d") is the first two *columns* of ``R`` concatenated,
  ``(R00, R10, R20, R01, R11, R21)`` -- HumanML3D's cont6d layout.  NB:
  pytorch3d's ``matrix_to_rotation_6d`` takes the first two *rows* instead
  (its 6D of ``R`` is our 6D of ``R.T``).  6D -> matrix by Gram-Schmidt:
  ``x = a/|a|, z = normalize(x cross b), y = z cross x, R = [x y z]`` (columns).
* A rigid transform ``(R, t)`` maps ``v' = R v + t``.

Every function accepts ``np.ndarray`` or ``torch.Tensor`` (Python scalars and
lists are taken as numpy) with any broadcastable leading batch dims, and
returns the same type and floating dtype.  A wrong trailing shape or a
non-floating dtype raises ``ValueError`` naming the argument.  Each formula is
written once against a tiny numpy/torch backend shim; no Python loops over
elements.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any, TypeVar

import sys
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:                 # torch is imported only when a tensor is passed (numpy callers never pay for it)
    import torch

__all__ = [
    "axis_angle_to_matrix",
    "matrix_to_axis_angle",
    "axis_angle_to_quaternion",
    "quaternion_to_axis_angle",
    "quaternion_to_matrix",
    "matrix_to_quaternion",
    "quaternion_multiply",
    "quaternion_conjugate",
    "quaternion_inverse",
    "quaternion_apply",
    "matrix_to_rot6d",
    "rot6d_to_matrix",
    "axis_angle_to_rot6d",
    "rot6d_to_axis_angle",
    "rotation_about_x",
    "rotation_about_y",
    "quaternion_between",
    "is_rotation_matrix",
    "apply_rigid",
    "compose_rigid",
    "invert_rigid",
    "resample_frames",
]

Array = TypeVar("Array", np.ndarray, "torch.Tensor")

# --------------------------------------------------------------------------- backend shim
_NP = SimpleNamespace(
    sqrt=np.sqrt, sin=np.sin, cos=np.cos, atan2=np.arctan2, where=np.where,
    zeros_like=np.zeros_like, det=np.linalg.det, out=np.asarray,
    stack=lambda xs, axis=-1: np.stack(xs, axis=axis),
    cat=lambda xs: np.concatenate(xs, axis=-1),
    cross=lambda a, b: np.cross(a, b),
    clamp_min=np.maximum,
    take_along=lambda x, i, axis: np.take_along_axis(x, i, axis=axis),
    eye=lambda x: np.eye(3, dtype=x.dtype),
    eps=lambda x: float(np.finfo(x.dtype).eps),
)
_TORCH: SimpleNamespace | None = None


def _torch_backend() -> SimpleNamespace:
    global _TORCH
    if _TORCH is None:
        import torch
        _TORCH = SimpleNamespace(
            sqrt=torch.sqrt, sin=torch.sin, cos=torch.cos, atan2=torch.atan2, where=torch.where,
            zeros_like=torch.zeros_like, det=torch.linalg.det, out=lambda x: x,
            stack=lambda xs, axis=-1: torch.stack(xs, dim=axis),
            cat=lambda xs: torch.cat(xs, dim=-1),
            cross=lambda a, b: torch.linalg.cross(*torch.broadcast_tensors(a, b)),
            clamp_min=lambda x, m: torch.clamp(x, min=m),
            take_along=lambda x, i, axis: torch.take_along_dim(x, i, dim=axis),
            eye=lambda x: torch.eye(3, dtype=x.dtype, device=x.device),
            eps=lambda x: float(torch.finfo(x.dtype).eps),
        )
    return _TORCH


def _is_tensor(x: Any) -> bool:
    """A torch tensor (torch must already be imported for ``x`` to be one)."""
    torch = sys.modules.get("torch")
    return torch is not None and isinstance(x, torch.Tensor)


def _prep(x: Any, name: str, tail: tuple = ()) -> tuple[Any, SimpleNamespace]:
    """Validate dtype (floating) and trailing shape (``None`` = any size); pick the backend."""
    if _is_tensor(x):
        B, floating = _torch_backend(), x.is_floating_point()
    else:
        x = x if isinstance(x, np.ndarray) else np.asarray(x)
        B, floating = _NP, np.issubdtype(x.dtype, np.floating)
    if not floating:
        raise ValueError(f"{name}: expected a floating-point array (float32/float64), got dtype {x.dtype}")
    shape = tuple(x.shape)
    if tail and (len(shape) < len(tail)
                 or any(t is not None and s != t for s, t in zip(shape[-len(tail):], tail))):
        want = ", ".join("N" if t is None else str(t) for t in tail)
        raise ValueError(f"{name}: expected shape (..., {want}), got {shape}")
    return x, B


def _prep_all(*specs: tuple) -> tuple[list, SimpleNamespace]:
    """``_prep`` several ``(x, name, tail)`` arguments that must share one backend."""
    out = [_prep(*s) for s in specs]
    if len({id(B) for _, B in out}) > 1:
        names = ", ".join(s[1] for s in specs)
        raise TypeError(f"{names}: cannot mix numpy arrays and torch tensors")
    return [x for x, _ in out], out[0][1]


def _norm(B, x):  # (..., k) -> (..., 1)
    return B.sqrt((x * x).sum(-1))[..., None]


def _normalize(B, x, eps: float = 1e-12):
    return x / B.clamp_min(_norm(B, x), eps)


def _matvec(R, v):
    return (R @ v[..., None])[..., 0]


def _mat(B, rows):
    """3x3 nested list of (...) arrays -> (..., 3, 3), rows given row-major."""
    return B.stack([B.stack(r, -1) for r in rows], -2)


def _angle_terms(B, aa):
    """theta^2, small-angle mask and a safe (nonzero) theta for rotation vectors."""
    th2 = (aa * aa).sum(-1)
    small = th2 < B.eps(aa) ** 0.5
    return th2, small, B.sqrt(B.where(small, 1.0, th2))


def _canonical(B, q):
    """Flip quaternions to w >= 0."""
    return B.where(q[..., :1] < 0, -q, q)


# --------------------------------------------------------------------------- axis-angle
def axis_angle_to_matrix(axis_angle: Array) -> Array:
    """Rodrigues: ``R = I + sin(t)/t K + (1-cos t)/t^2 K^2``, ``K = [aa]_x``, ``t = |aa|``.

    Shape (..., 3) -> (..., 3, 3); Taylor series near ``t = 0``.
    """
    aa, B = _prep(axis_angle, "axis_angle", (3,))
    th2, small, th = _angle_terms(B, aa)
    a = B.where(small, 1 - th2 / 6, B.sin(th) / th)
    b = B.where(small, 0.5 - th2 / 24, 2 * B.sin(th / 2) ** 2 / (th * th))
    x, y, z = aa[..., 0], aa[..., 1], aa[..., 2]
    o = B.zeros_like(x)
    K = _mat(B, [[o, -z, y], [z, o, -x], [-y, x, o]])
    return B.eye(aa) + a[..., None, None] * K + b[..., None, None] * (K @ K)


def axis_angle_to_quaternion(axis_angle: Array) -> Array:
    """``q = (cos(t/2), sin(t/2) aa/t)``, ``t = |aa|``.  Shape (..., 3) -> (..., 4)."""
    aa, B = _prep(axis_angle, "axis_angle", (3,))
    th2, small, th = _angle_terms(B, aa)
    w = B.where(small, 1 - th2 / 8, B.cos(th / 2))
    s = B.where(small, 0.5 - th2 / 48, B.sin(th / 2) / th)
    return B.cat([w[..., None], aa * s[..., None]])


def quaternion_to_axis_angle(quaternion: Array) -> Array:
    """``aa = v * 2 atan2(|v|, w) / |v|`` after flipping to ``w >= 0`` (angle in [0, pi]).

    Scale-invariant in ``q``; series ``2/w (1 - |v|^2/(3w^2))`` near ``v = 0``.
    Shape (..., 4) -> (..., 3).
    """
    q, B = _prep(quaternion, "quaternion", (4,))
    q = _canonical(B, q)
    w, v = q[..., 0], q[..., 1:]
    n2 = (v * v).sum(-1)
    small = n2 <= B.eps(q) ** 0.5 * w * w
    n = B.sqrt(B.where(small, 1.0, n2))
    ws = B.where(small & (w != 0), w, 1.0)
    f = B.where(small, 2 / ws * (1 - n2 / (3 * ws * ws)), 2 * B.atan2(n, w) / n)
    return v * f[..., None]


def matrix_to_axis_angle(matrix: Array) -> Array:
    """Via ``matrix_to_quaternion`` + ``atan2``: accurate near 0 and near pi.

    Shape (..., 3, 3) -> (..., 3).
    """
    _prep(matrix, "matrix", (3, 3))
    return quaternion_to_axis_angle(matrix_to_quaternion(matrix))


# --------------------------------------------------------------------------- quaternions
def quaternion_to_matrix(quaternion: Array) -> Array:
    """Rotation matrix of ``q / |q|`` (uses ``s = 2/|q|^2``).  Shape (..., 4) -> (..., 3, 3)."""
    q, B = _prep(quaternion, "quaternion", (4,))
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    s = 2 / (q * q).sum(-1)
    return _mat(B, [
        [1 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w)],
        [s * (x * y + z * w), 1 - s * (x * x + z * z), s * (y * z - x * w)],
        [s * (x * z - y * w), s * (y * z + x * w), 1 - s * (x * x + y * y)],
    ])


def matrix_to_quaternion(matrix: Array) -> Array:
    """Unit quaternion with ``w >= 0``; shape (..., 3, 3) -> (..., 4).

    ``4w^2 = 1 + tr R``, ``4x^2 = 1 + R00 - R11 - R22`` (etc.); the largest of
    these picks the branch, whose component ``c`` divides the off-diagonal sums /
    differences (``R21 - R12 = 4wx``, ``R10 + R01 = 4xy``, ...).
    """
    m, B = _prep(matrix, "matrix", (3, 3))
    m00, m01, m02 = m[..., 0, 0], m[..., 0, 1], m[..., 0, 2]
    m10, m11, m12 = m[..., 1, 0], m[..., 1, 1], m[..., 1, 2]
    m20, m21, m22 = m[..., 2, 0], m[..., 2, 1], m[..., 2, 2]
    d = B.stack([1 + m00 + m11 + m22, 1 + m00 - m11 - m22,
                 1 - m00 + m11 - m22, 1 - m00 - m11 + m22], -1)  # 4 q_i^2
    qa = B.where(d > 0, B.sqrt(B.where(d > 0, d, 1.0)), 0.0)  # 2 |q_i|
    cand = B.stack([
        B.stack([d[..., 0], m21 - m12, m02 - m20, m10 - m01], -1),
        B.stack([m21 - m12, d[..., 1], m10 + m01, m02 + m20], -1),
        B.stack([m02 - m20, m10 + m01, d[..., 2], m12 + m21], -1),
        B.stack([m10 - m01, m02 + m20, m12 + m21, d[..., 3]], -1),
    ], -2) / (2 * B.clamp_min(qa, 0.1))[..., None]  # row i = 4 q_i q / (4 |q_i|)
    q = B.take_along(cand, qa.argmax(-1)[..., None, None], -2)[..., 0, :]
    return _canonical(B, _normalize(B, q))


def quaternion_multiply(q: Array, r: Array) -> Array:
    """Hamilton product ``q * r`` (apply ``r`` first): ``R(q*r) = R(q) R(r)``.  (..., 4)."""
    (q, r), B = _prep_all((q, "q", (4,)), (r, "r", (4,)))
    w1, x1, y1, z1 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    w2, x2, y2, z2 = r[..., 0], r[..., 1], r[..., 2], r[..., 3]
    return B.stack([
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    ], -1)


def quaternion_conjugate(quaternion: Array) -> Array:
    """``(w, -x, -y, -z)``."""
    q, B = _prep(quaternion, "quaternion", (4,))
    return B.cat([q[..., :1], -q[..., 1:]])


def quaternion_inverse(quaternion: Array) -> Array:
    """``conj(q) / |q|^2`` (equals the conjugate for unit quaternions)."""
    q, B = _prep(quaternion, "quaternion", (4,))
    return quaternion_conjugate(q) / (q * q).sum(-1)[..., None]


def quaternion_apply(q: Array, v: Array) -> Array:
    """Rotate vectors: ``v' = v + w t + u x t``, ``t = 2 u x v``, ``(w, u) = q/|q|``.

    q (..., 4), v (..., 3), leading dims broadcast.
    """
    (q, v), B = _prep_all((q, "q", (4,)), (v, "v", (3,)))
    q = _normalize(B, q)
    w, u = q[..., :1], q[..., 1:]
    t = 2 * B.cross(u, v)
    return v + w * t + B.cross(u, t)


def quaternion_between(u: Array, v: Array) -> Array:
    """Shortest-arc unit quaternion rotating direction ``u`` onto ``v`` (w >= 0).

    ``q = normalize(1 + u.v, u x v)`` for unit ``u, v``; for (nearly) antiparallel
    inputs a rotation by pi about an axis perpendicular to ``u``.  (..., 3) -> (..., 4).
    """
    (u, v), B = _prep_all((u, "u", (3,)), (v, "v", (3,)))
    u, v = _normalize(B, u), _normalize(B, v)
    q = B.cat([1 + (u * v).sum(-1)[..., None], B.cross(u, v)])
    qn = _norm(B, q)
    ux, uy, uz = u[..., 0], u[..., 1], u[..., 2]
    o = B.zeros_like(ux)
    # u x e_x if u is not close to e_x, else u x e_y; both have norm >= 0.43
    axis = B.where(abs(ux)[..., None] < 0.9, B.stack([o, uz, -uy], -1), B.stack([-uz, o, ux], -1))
    flip = B.cat([o[..., None], _normalize(B, axis)])
    return B.where(qn < B.eps(q) ** 0.5, flip, q / B.clamp_min(qn, 1e-30))


# --------------------------------------------------------------------------- 6D
def matrix_to_rot6d(matrix: Array) -> Array:
    """First two columns: ``(R00, R10, R20, R01, R11, R21)``.  (..., 3, 3) -> (..., 6)."""
    m, B = _prep(matrix, "matrix", (3, 3))
    return B.cat([m[..., :, 0], m[..., :, 1]])


def rot6d_to_matrix(rot6d: Array) -> Array:
    """Gram-Schmidt: ``x = a/|a|, z = normalize(x cross b), y = z cross x``, columns ``[x y z]``.

    (..., 6) -> (..., 3, 3); ``a = rot6d[..., :3]``, ``b = rot6d[..., 3:]``.
    """
    d, B = _prep(rot6d, "rot6d", (6,))
    x = _normalize(B, d[..., :3])
    z = _normalize(B, B.cross(x, d[..., 3:]))
    y = B.cross(z, x)
    return B.stack([x, y, z], -1)


def axis_angle_to_rot6d(axis_angle: Array) -> Array:
    """``matrix_to_rot6d(axis_angle_to_matrix(axis_angle))``."""
    return matrix_to_rot6d(axis_angle_to_matrix(axis_angle))


def rot6d_to_axis_angle(rot6d: Array) -> Array:
    """``matrix_to_axis_angle(rot6d_to_matrix(rot6d))``."""
    return matrix_to_axis_angle(rot6d_to_matrix(rot6d))


# --------------------------------------------------------------------------- elementary
def rotation_about_x(angle: Array) -> Array:
    """``R_x(a) = [[1,0,0],[0,cos a,-sin a],[0,sin a,cos a]]``.  (...) -> (..., 3, 3)."""
    a, B = _prep(angle, "angle")
    c, s = B.cos(a), B.sin(a)
    o = B.zeros_like(c)
    return _mat(B, [[o + 1, o, o], [o, c, -s], [o, s, c]])


def rotation_about_y(angle: Array) -> Array:
    """``R_y(a) = [[cos a,0,sin a],[0,1,0],[-sin a,0,cos a]]``.  (...) -> (..., 3, 3)."""
    a, B = _prep(angle, "angle")
    c, s = B.cos(a), B.sin(a)
    o = B.zeros_like(c)
    return _mat(B, [[c, o, s], [o, o + 1, o], [-s, o, c]])


def is_rotation_matrix(R: Array, atol: float = 1e-6) -> Array:
    """Boolean (...): ``|R^T R - I| <= atol`` elementwise and ``|det R - 1| <= atol``."""
    R, B = _prep(R, "R", (3, 3))
    orth = (abs(R.swapaxes(-1, -2) @ R - B.eye(R)) <= atol).all(-1).all(-1)
    return B.out(orth & (abs(B.det(R) - 1) <= atol))


# --------------------------------------------------------------------------- rigid transforms
def apply_rigid(R: Array, t: Array, points: Array) -> Array:
    """``p' = R p + t`` for R (..., 3, 3), t (..., 3), points (..., N, 3)."""
    (R, t, p), _ = _prep_all((R, "R", (3, 3)), (t, "t", (3,)), (points, "points", (None, 3)))
    return p @ R.swapaxes(-1, -2) + t[..., None, :]


def compose_rigid(R1: Array, t1: Array, R2: Array, t2: Array) -> tuple[Array, Array]:
    """``(R1, t1) o (R2, t2)`` (apply 2 first): ``(R1 R2, R1 t2 + t1)``."""
    (R1, t1, R2, t2), _ = _prep_all((R1, "R1", (3, 3)), (t1, "t1", (3,)),
                                    (R2, "R2", (3, 3)), (t2, "t2", (3,)))
    return R1 @ R2, _matvec(R1, t2) + t1


def invert_rigid(R: Array, t: Array) -> tuple[Array, Array]:
    """Inverse transform ``(R^T, -R^T t)``."""
    (R, t), _ = _prep_all((R, "R", (3, 3)), (t, "t", (3,)))
    Rt = R.swapaxes(-1, -2)
    return Rt, -_matvec(Rt, t)


# --------------------------------------------------------------------------- time
def resample_frames(x: np.ndarray, src_fps: float, dst_fps: float) -> np.ndarray:
    """(T, ...) sampled at ``src_fps`` -> the frames at ``dst_fps`` over the same duration
    (frame k at k / dst_fps s, ``T' = floor((T - 1) dst_fps / src_fps) + 1``), linear in time
    (the last frame held; no extrapolation); ``x`` itself when the rates agree."""
    if abs(src_fps - dst_fps) < 1e-9:
        return x
    T = x.shape[0]
    n = int(np.floor((T - 1) * dst_fps / src_fps + 1e-9)) + 1
    t = np.arange(n) * src_fps / dst_fps
    i0 = np.clip(np.floor(t).astype(int), 0, T - 1)
    i1 = np.clip(i0 + 1, 0, T - 1)
    w = (t - i0).reshape((-1,) + (1,) * (x.ndim - 1))
    return (1 - w) * x[i0] + w * x[i1]
