"""Body surfaces for the penetration metrics, from joint positions alone.

Submissions hold joints (T, 22, 3), not body-model parameters, so PS needs a surface fitted
to joints. The default is the license-free proxy body (:class:`hoibench.bodies.ProxyBody`,
SMPL-H structure, 6,890 vertices of rigid capsules) posed by :func:`proxy_vertices_from_joints`:

* scale ``s`` = :func:`hoibench.contact.body_scale` of the clip (summed bone lengths over
  the SMPL mean skeleton's, median over frames);
* a global rotation ``R_j`` per joint: joints with several children (pelvis 0 -> 1, 2, 3;
  spine3 9 -> 12, 13, 14) take the least-squares rotation (Kabsch) of their rest child
  offsets onto the posed ones; joints with one child take the smallest rotation that turns
  ``R_parent`` times the rest bone onto the posed bone, composed with ``R_parent`` (the
  twist is inherited, as in HumanML3D's IK); leaf joints (feet 10/11, head 15, wrists
  20/21) take their parent's rotation; the hands (finger capsules) move rigidly with the
  wrists (a flat hand);
* every vertex is rigid to one joint ``j`` (the proxy's one-hot skinning):
  ``v = J_j + s R_j (v_template - rest_j)``.

Joints equal to the (scaled) rest skeleton give the proxy's template exactly. Metrics computed
with this surface are labelled ``"proxy (joint fit)"``. A user with SMPL-family files can
pass any callable ``joints (T, 22, 3) -> vertices (T, V, 3)`` instead (e.g. SMPLify
followed by :func:`hoibench.bodies.body_forward`) and label it.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from .. import skeleton as sk
from ..contact import body_scale

PROXY_LABEL = "proxy (joint fit)"

_CHILDREN = {j: [c for c in range(sk.NUM_JOINTS) if sk.PARENTS[c] == j] for j in range(sk.NUM_JOINTS)}


@lru_cache(maxsize=1)
def _proxy():
    from ..bodies.proxy import ProxyBody
    body = ProxyBody("smplh")
    joint_of = body.part_joint.copy()
    # finger joints (22..36 left, 37..51 right) move with their wrist under a flat hand
    joint_of[(joint_of >= 22) & (joint_of < 37)] = 20
    joint_of[joint_of >= 37] = 21
    groups = [(j, np.flatnonzero(joint_of == j)) for j in range(sk.NUM_JOINTS)]
    rest = body.rest_joints[:sk.NUM_JOINTS].astype(np.float64)
    return body.v_template.astype(np.float64), body.faces, rest, groups


def proxy_faces() -> np.ndarray:
    """Triangles (F, 3) of the proxy surface."""
    return _proxy()[1]


def _swing(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotations (n, 3, 3) turning directions a (n, 3) onto b (n, 3)."""
    a = a / np.maximum(np.linalg.norm(a, axis=-1, keepdims=True), 1e-12)
    b = b / np.maximum(np.linalg.norm(b, axis=-1, keepdims=True), 1e-12)
    v = np.cross(a, b)
    c = np.einsum("ni,ni->n", a, b)
    K = np.zeros(a.shape[:-1] + (3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = v[:, 2], -v[:, 1], v[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        f = np.where(c > -1 + 1e-9, 1.0 / (1.0 + c), 0.0)
    R = np.eye(3) + K + (K @ K) * f[:, None, None]
    opposite = c <= -1 + 1e-9
    if opposite.any():  # half turn about any axis perpendicular to a
        ax = np.cross(a[opposite], np.array([1.0, 0.0, 0.0]))
        small = np.linalg.norm(ax, axis=-1) < 1e-6
        ax[small] = np.cross(a[opposite][small], np.array([0.0, 1.0, 0.0]))
        ax /= np.linalg.norm(ax, axis=-1, keepdims=True)
        R[opposite] = 2.0 * ax[:, :, None] * ax[:, None, :] - np.eye(3)
    return R


def _kabsch(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Rotations (n, 3, 3) minimising sum |R src_k - dst_k|^2; src (k, 3), dst (n, k, 3)."""
    H = np.einsum("ki,nkj->nij", src, dst)
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(np.swapaxes(Vt, -1, -2) @ np.swapaxes(U, -1, -2)))
    D = np.zeros_like(H)
    D[:, 0, 0] = D[:, 1, 1] = 1.0
    D[:, 2, 2] = d
    return np.swapaxes(Vt, -1, -2) @ D @ np.swapaxes(U, -1, -2)


def joint_global_rotations(joints, rest_joints) -> np.ndarray:
    """Global rotations (T, 22, 3, 3) that pose ``rest_joints`` (22, 3) like ``joints``
    (T, 22, 3) (see the module docstring)."""
    J = np.asarray(joints, dtype=np.float64)
    R = np.empty(J.shape[:2] + (3, 3))
    for j in range(sk.NUM_JOINTS):            # parents come before children
        kids, p = _CHILDREN[j], sk.PARENTS[j]
        parent = np.broadcast_to(np.eye(3), (len(J), 3, 3)) if p < 0 else R[:, p]
        if len(kids) >= 2:
            R[:, j] = _kabsch(rest_joints[kids] - rest_joints[j], J[:, kids] - J[:, j, None])
        elif len(kids) == 1:
            c = kids[0]
            bone = np.einsum("nij,j->ni", parent, rest_joints[c] - rest_joints[j])
            R[:, j] = _swing(bone, J[:, c] - J[:, j]) @ parent
        else:
            R[:, j] = parent
    return R


def proxy_vertices_from_joints(joints, frames: slice | None = None) -> np.ndarray:
    """Proxy body surface (T, 6890, 3) float64, metres, posed to ``joints`` (T, 22, 3).

    ``frames`` limits the output to some frames (the scale still comes from the whole clip).
    """
    J = np.asarray(joints, dtype=np.float64)
    if J.ndim != 3 or J.shape[1:] != (sk.NUM_JOINTS, 3):
        raise ValueError(f"joints: expected shape (T, 22, 3), got {J.shape}")
    v_template, _, rest, groups = _proxy()
    s = body_scale(J)
    Jf = J if frames is None else J[frames]
    R = joint_global_rotations(Jf, rest * s)
    out = np.empty((len(Jf), len(v_template), 3))
    for j, idx in groups:
        local = (v_template[idx] - rest[j]) * s                      # (n, 3)
        out[:, idx] = np.einsum("tab,nb->tna", R[:, j], local) + Jf[:, j, None, :]
    return out


def proxy_object_distances(joints, frames: slice, field, template_vertices, obj_rot, obj_trans,
                           margin_m: float) -> np.ndarray:
    """Signed distances (T_frames, 6890) of the proxy body surface to the posed object,
    culled per body part before any vertex is posed.

    Each part (the vertices rigid to one joint) has a bounding sphere; the object has one
    around its template. A part whose posed sphere is farther than ``margin_m`` from the
    object's gets ``margin_m`` for all its vertices: a lower bound of their true, positive
    distance (the part is outside the object's sphere by more than the margin). Other parts
    are posed and queried with the field's own box culling (:meth:`SignedDistance.query`),
    so signs are exact everywhere and values are exact below ``margin_m`` -- the same
    contract as :func:`hoibench.metrics.contact_metrics.body_object_distances`, at a fraction
    of the cost (most of the body is far from the object on most frames).
    """
    J = np.asarray(joints, dtype=np.float64)
    v_template, _, rest, groups = _proxy()
    s = body_scale(J)
    Jf = J[frames]
    R = joint_global_rotations(Jf, rest * s)
    Ro, to = np.asarray(obj_rot, dtype=np.float64)[frames], np.asarray(obj_trans, dtype=np.float64)[frames]
    tv = np.asarray(template_vertices, dtype=np.float64)
    c_obj = 0.5 * (tv.min(0) + tv.max(0))
    r_obj = float(np.linalg.norm(tv - c_obj, axis=1).max())
    centre_obj = np.einsum("tab,b->ta", Ro, c_obj) + to
    out = np.full((len(Jf), len(v_template)), float(margin_m))
    for j, idx in groups:
        if len(idx) == 0:
            continue
        local = (v_template[idx] - rest[j]) * s
        c = local.mean(0)
        r = float(np.linalg.norm(local - c, axis=1).max())
        centre = np.einsum("tab,b->ta", R[:, j], c) + Jf[:, j]
        near = np.flatnonzero(np.linalg.norm(centre - centre_obj, axis=1) <= r + r_obj + margin_m)
        if len(near) == 0:
            continue
        # template frame in one step: Ro^T (R_j v + J_j - t) = (Ro^T R_j) v + Ro^T (J_j - t)
        M = np.einsum("tba,tbc->tac", Ro[near], R[near, j])
        b = np.einsum("tba,tb->ta", Ro[near], Jf[near, j] - to[near])
        loc = np.einsum("tab,nb->tna", M, local) + b[:, None, :]
        d, _ = field.query(loc.reshape(-1, 3), max_distance=margin_m)
        out[np.ix_(near, idx)] = d.reshape(len(near), len(idx))
    return out
