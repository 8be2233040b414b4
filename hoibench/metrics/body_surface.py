"""Body surfaces for the penetration metrics, from joint positions alone.

Submissions hold joints (T, 22, 3), not body-model parameters, so PS needs a surface fitted
to joints. The default is the license-free proxy body (:class:`hoibench.bodies.ProxyBody`,
SMPL-H structure, 6,890 vertices of rigid capsules) posed by :func:`proxy_vertices_from_joints`:

* scale ``s`` = :func:`hoibench.bodies.contact.body_scale` of the clip (summed bone lengths over
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

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..core import skeleton as sk
from ..bodies.contact import body_scale

PROXY_LABEL = "proxy (joint fit)"
PROXY_VERTICES = 6890            # the SMPL-H vertex count of the proxy body

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
    assert len(body.v_template) == PROXY_VERTICES
    return body.v_template.astype(np.float64), body.faces, rest, groups


#: proxy vertices are culled in clusters of at most this radius (m, at body scale 1)
CLUSTER_RADIUS_M = 0.07


@dataclass(frozen=True)
class _Clusters:
    """The proxy's vertices in compact clusters, each rigid to one joint, at body scale 1:
    cluster ``k`` holds vertices ``members[k]`` (offsets ``offsets[k]`` from ``joint[k]``),
    inside the sphere ``centre[k]`` (relative to the joint), ``radius[k]``;
    ``part_centre`` / ``part_radius`` (22,) enclose each joint's clusters (0 without any)."""

    joint: np.ndarray
    members: tuple
    offsets: tuple
    centre: np.ndarray
    radius: np.ndarray
    part_centre: np.ndarray
    part_radius: np.ndarray


@lru_cache(maxsize=1)
def _clusters() -> _Clusters:
    """:class:`_Clusters`: each part is split in halves along its longest extent until every
    piece fits in ``CLUSTER_RADIUS_M``."""
    v_template, _, rest, groups = _proxy()
    out = []

    def split(j, idx):
        x = v_template[idx] - rest[j]
        c = 0.5 * (x.min(0) + x.max(0))
        r = float(np.linalg.norm(x - c, axis=1).max())
        if r <= CLUSTER_RADIUS_M or len(idx) < 8:
            out.append((j, idx, x, c, r))
            return
        axis = int(np.argmax(x.max(0) - x.min(0)))
        order = np.argsort(x[:, axis], kind="stable")
        half = len(idx) // 2
        split(j, idx[np.sort(order[:half])])
        split(j, idx[np.sort(order[half:])])

    for j, idx in groups:
        if len(idx):
            split(j, idx)
    joint = np.array([c[0] for c in out])
    centre = np.array([c[3] for c in out])
    radius = np.array([c[4] for c in out])
    part_centre, part_radius = np.zeros((sk.NUM_JOINTS, 3)), np.zeros(sk.NUM_JOINTS)
    for j in np.unique(joint):
        sel = joint == j
        lo = (centre[sel] - radius[sel, None]).min(0)
        hi = (centre[sel] + radius[sel, None]).max(0)
        part_centre[j] = 0.5 * (lo + hi)
        part_radius[j] = (np.linalg.norm(centre[sel] - part_centre[j], axis=1) + radius[sel]).max()
    return _Clusters(joint, tuple(c[1] for c in out), tuple(c[2] for c in out), centre, radius,
                     part_centre, part_radius)


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


def _rigid(M: np.ndarray, b: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``M_t x_n + b_t`` (T, n, 3) for rotations M (T, 3, 3), offsets b (T, 3), points x (n, 3)
    (one matrix product; numpy's einsum is ~10x slower on this shape)."""
    y = (M.reshape(-1, 3) @ x.T).reshape(len(M), 3, len(x)).transpose(0, 2, 1)
    return y + b[:, None, :]


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


def proxy_vertices_from_joints(joints, frames: slice | None = None, vertices=None) -> np.ndarray:
    """Proxy body surface (T, 6890, 3) float64, metres, posed to ``joints`` (T, 22, 3).

    ``frames`` limits the output to some frames (the scale still comes from the whole clip);
    ``vertices`` (vertex ids) to those vertices, in that order (T, len(vertices), 3), each
    posed exactly as in the whole surface.
    """
    J = np.asarray(joints, dtype=np.float64)
    if J.ndim != 3 or J.shape[1:] != (sk.NUM_JOINTS, 3):
        raise ValueError(f"joints: expected shape (T, 22, 3), got {J.shape}")
    v_template, _, rest, groups = _proxy()
    s = body_scale(J)
    Jf = J if frames is None else J[frames]
    R = joint_global_rotations(Jf, rest * s)
    ids = None if vertices is None else np.asarray(vertices, dtype=np.int64)
    out = np.empty((len(Jf), len(v_template) if ids is None else len(ids), 3))
    for j, idx in groups:
        where = idx if ids is None else np.flatnonzero(np.isin(ids, idx))   # output rows of this joint's part
        if len(where):
            local = (v_template[idx if ids is None else ids[where]] - rest[j]) * s      # (n, 3)
            out[:, where] = _rigid(R[:, j], Jf[:, j], local)
    return out


def proxy_markers(joints) -> np.ndarray:
    """InterAct's 77 markers (T, 77, 3) float64, metres, on the proxy body posed to ``joints``
    (T, 22, 3): the SMPL-H marker vertices (:data:`hoibench.bodies.markers.MARKERS_SMPLH`) of
    :func:`proxy_vertices_from_joints`."""
    from ..bodies.markers import MARKERS_SMPLH
    return proxy_vertices_from_joints(joints, vertices=MARKERS_SMPLH)


def proxy_template_points(joints, frames: slice, field, obj_rot, obj_trans,
                          margin_m: float, scale: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The proxy body surface of ``frames`` in the object's template frame, posed only where
    it can come within ``margin_m`` of the object.

    The vertices rigid to one joint are split into clusters of radius ``r`` <=
    ``CLUSTER_RADIUS_M`` (times the body scale). Each cluster's centre goes to the template
    frame first; when the field's guaranteed lower bound there
    (:meth:`hoibench.bodies.contact.SignedDistance.bracket`) exceeds ``r + margin_m``, every vertex
    of the cluster is farther than ``margin_m`` from the object and it is skipped. Near
    clusters go straight to the template frame:
    ``Ro^T (R_j v + J_j - t) = (Ro^T R_j) v + Ro^T (J_j - t)``.

    ``scale``: the clip's :func:`body_scale` when the caller has it (computed otherwise).

    Returns:
        ``(index (N,), points (N, 3))``: flat indices ``frame * 6890 + vertex`` (frames
        counted within ``frames``; grouped by cluster) of the posed vertices and their
        template-frame positions; vertices left out are farther than ``margin_m`` from the
        object.
    """
    J = np.asarray(joints, dtype=np.float64)
    V, rest = PROXY_VERTICES, _proxy()[2]
    s = body_scale(J) if scale is None else float(scale)
    Jf = J[frames]
    Ro, to = np.asarray(obj_rot, dtype=np.float64)[frames], np.asarray(obj_trans, dtype=np.float64)[frames]
    # every joint's rigid map to the template frame, (T, 22, 3, 3) and (T, 22, 3)
    M = np.swapaxes(Ro, 1, 2)[:, None] @ joint_global_rotations(Jf, rest * s)
    b = (np.swapaxes(Ro, 1, 2)[:, None] @ (Jf - to[:, None, :])[..., None])[..., 0]
    cl = _clusters()
    # parts first (one sphere around each part's clusters), then the clusters of near parts;
    # every offset and radius scales with the body
    lo, _ = field.bracket(np.einsum("tjab,jb->tja", M, cl.part_centre * s) + b)
    near_part = lo.reshape(len(Jf), -1) <= cl.part_radius * s + margin_m     # (T, 22)
    tt, kk = np.nonzero(near_part[:, cl.joint])
    near_cluster = np.zeros((len(Jf), len(cl.joint)), bool)
    if len(tt):
        jj = cl.joint[kk]
        centres = np.einsum("nab,nb->na", M[tt, jj], cl.centre[kk] * s) + b[tt, jj]
        reach = cl.radius[kk] * s + margin_m
        lo, _ = field.bracket(centres)
        near = np.flatnonzero(lo <= reach)
        lo_cell, _ = field.bracket_cell(centres[near])         # the cell's tighter bound culls more
        near = near[lo_cell <= reach[near]]
        near_cluster[tt[near], kk[near]] = True
    counts = near_cluster.sum(0)
    sizes = counts * np.array([len(m) for m in cl.members])
    index, points = np.empty(int(sizes.sum()), np.int64), np.empty((int(sizes.sum()), 3))
    start = 0
    for c in np.flatnonzero(counts):
        j, idx = cl.joint[c], cl.members[c]
        near = np.flatnonzero(near_cluster[:, c])
        # vertex-major block (vertex, frame): x_v^T M_t^T for every near frame in one product
        n, block = len(near), slice(start, start + sizes[c])
        y = points[block].reshape(len(idx), 3 * n)
        np.matmul(cl.offsets[c] * s, M[near, j].transpose(2, 0, 1).reshape(3, 3 * n), out=y)
        y += b[near, j].reshape(-1)
        index[block] = (idx[:, None] + near[None, :] * V).reshape(-1)
        start += sizes[c]
    return index, points

