"""License-free proxy body model in the SMPL-H and SMPL-X file structures.

The proxy is a closed surface of rigid, elliptic-section capsules around the bones of the
22-joint skeleton (:data:`hoibench.core.skeleton.SMPL_REST_JOINTS`, metres, y-up, T-pose, the
SMPL family's mean-shape joint positions in the model frame) plus 30 finger joints, so the
pose parameters and ``trans`` mean exactly what they mean for the real SMPL-H files.

Structure (what ``smplx.create(root, model_type='smplh', gender=g, ext='npz',
use_pca=False, flat_hand_mean=True)`` reads; the same keys and shapes as the released
SMPL-H ``.npz`` files):

* ``v_template`` (6890, 3) float64 -- the same vertex count as SMPL / SMPL-H, so
  per-vertex arrays in SMPL topology (e.g. RICH contact labels) have the right shape, and
  ``smplx``'s extra joints (picked by fixed vertex indices, ``vertex_ids['smplh']``, max
  6787) land on sensible places: nose, eyes and ears on the head, finger tips on the
  finger tips, big/small toe and heel on the feet.
* ``f`` (F, 3) int64 -- outward-oriented triangles; every capsule is closed, so the whole
  mesh is watertight (a union of overlapping closed parts, not one manifold).
* ``kintree_table`` (2, 52) int64 -- SMPL-H kinematic tree (row 0 parents, the root's
  parent stored as 4294967295 as in the released files; row 1 joint ids). Joints 0-21 are
  the body, 22-36 the left hand, 37-51 the right hand, each hand in MANO order
  index1-3, middle1-3, pinky1-3, ring1-3, thumb1-3.
* ``J`` (52, 3) rest joints; ``J_regressor`` (52, V): row ``j`` averages one symmetric
  ring of ``n`` vertices centred on joint ``j`` (weights ``1/n``), so
  ``J_regressor @ v_template == J`` up to float rounding.
* ``weights`` (V, 52): one-hot, every capsule is rigid to the joint that moves its bone
  (the bone's parent joint), so capsules stay closed and undistorted in any pose.
* ``shapedirs`` (V, 3, 16): ``shapedirs[..., 0] = 0.05 * v_template``, the others zero, so
  ``v_shaped = (1 + 0.05 * beta_0) * v_template`` (uniform scaling about the model origin)
  and the rest joints are ``(1 + 0.05 * beta_0) * J``.
* ``posedirs`` (V, 3, 459) zeros (no pose corrective blend shapes).
* ``hands_componentsl/r`` (45, 45) identity, ``hands_meanl/r`` (45,) zeros (so PCA and
  flat-hand-mean settings do not matter).

SMPL-X structure (``model_type='smplx'``; what ``smplx.create(root, model_type='smplx',
gender=g, ext='npz')`` reads, the keys and shapes of the released SMPL-X v1.1 ``.npz``):
the same body capsules plus a chin (skinned to the jaw) and two eyeballs, and

* ``v_template`` (10475, 3) -- SMPL-X's vertex count; ``smplx``'s extra joints
  (``vertex_ids['smplx']``, max 9929) sit on the head, finger tips, toes and heels;
* ``kintree_table`` (2, 55) -- SMPL-X's tree: joints 0-21 the body, 22 jaw, 23 left eye,
  24 right eye (parent: head), 25-39 the left hand, 40-54 the right hand (MANO order);
  ``J`` (55, 3), ``J_regressor`` (55, V) (rings, as above), ``weights`` (V, 55) one-hot;
* ``shapedirs`` (V, 3, 400) float32 -- 300 shape + 100 expression directions as in v1.1
  (fewer than 300 would make ``smplx`` cap ``num_betas`` at 10; OMOMO uses 16); column 0
  is ``0.05 * v_template`` (the same uniform scaling as SMPL-H), the rest zero, so
  expressions do not move the proxy;
* ``posedirs`` (V, 3, 486) float32 zeros; ``hands_componentsl/r`` (45, 45) identity,
  ``hands_meanl/r`` (45,) zeros (so hand PCA with any number of components, and
  ``flat_hand_mean`` either way, are well defined: PCA coefficient ``k`` is axis-angle
  component ``k``);
* ``lmk_faces_idx`` (51,) / ``lmk_bary_coords`` (51, 3) and ``dynamic_lmk_faces_idx``
  (79, 17) / ``dynamic_lmk_bary_coords`` (79, 17, 3): face landmarks on faces of the head
  (barycentre of each face), so ``use_face_contour`` works too.

The 22 body joints, their rest positions and the body surface are the same in both
structures, so SMPL-H and SMPL-X proxies pose the body identically.

All genders get the same arrays (the proxy has no gendered shapes): files named
``SMPLH_MALE.npz`` etc. exist only so gendered code paths run. ``model_type='smpl'``
raises ``NotImplementedError``. Metrics computed with this body must be labelled
"proxy body".
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Sequence

import numpy as np

from ..core.geometry import axis_angle_to_matrix
from ..core.io import atomic_write_bytes, npz_bytes
from ..core.skeleton import NUM_JOINTS, SMPL_REST_JOINTS, forward_kinematics

__all__ = [
    "PROXY_SCALE_PER_BETA",
    "PROXY_NUM_BETAS",
    "SMPLH_NUM_JOINTS",
    "SMPLH_PARENTS",
    "SMPLH_JOINT_NAMES",
    "SMPLX_NUM_JOINTS",
    "SMPLX_PARENTS",
    "SMPLX_JOINT_NAMES",
    "proxy_rest_joints",
    "build_proxy_arrays",
    "write_proxy_model",
    "ProxyBody",
]

#: ``beta_0 = 1`` makes the proxy 5 % larger (uniform scale about the model origin).
PROXY_SCALE_PER_BETA = 0.05
#: Shape coefficients stored in the proxy file (the released SMPL-H ``.npz`` have 16).
PROXY_NUM_BETAS = 16
SMPLH_NUM_JOINTS = 52
SMPLX_NUM_JOINTS = 55
_NUM_VERTICES = {"smplh": 6890, "smplx": 10475}
_SUPPORTED = ("smplh", "smplx")
_FILE_PREFIX = {"smplh": "SMPLH", "smplx": "SMPLX"}
#: SMPL-X v1.1 shapedirs width: 300 shape + 100 expression components.
_SMPLX_SHAPE_DIMS, _SMPLX_EXPR_DIMS = 300, 100
_GENDERS = ("male", "female", "neutral")

_FINGERS = ("index", "middle", "pinky", "ring", "thumb")  # MANO / SMPL-H order

#: SMPL-H joint names: the 22 body joints, then left and right hand (MANO order).
SMPLH_JOINT_NAMES: tuple[str, ...] = (
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2",
    "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot", "neck",
    "left_collar", "right_collar", "head", "left_shoulder", "right_shoulder",
    "left_elbow", "right_elbow", "left_wrist", "right_wrist",
) + tuple(f"{side}_{f}{k}" for side in ("left", "right") for f in _FINGERS for k in (1, 2, 3))

#: SMPL-H parents (52): body as :data:`hoibench.core.skeleton.PARENTS`; each finger is a chain
#: wrist -> 1 -> 2 -> 3 (left wrist 20, right wrist 21).
SMPLH_PARENTS: tuple[int, ...] = (
    -1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19,
) + tuple(p for wrist, base in ((20, 22), (21, 37)) for f in range(5)
          for p in (wrist, base + 3 * f, base + 3 * f + 1))

#: SMPL-X joint names (smplx's order): the 22 body joints, jaw, eyes, then left and right
#: hand (MANO order).
SMPLX_JOINT_NAMES: tuple[str, ...] = (
    SMPLH_JOINT_NAMES[:22] + ("jaw", "left_eye_smplhf", "right_eye_smplhf") + SMPLH_JOINT_NAMES[22:])

#: SMPL-X parents (55): body, jaw and eyes on the head (15), fingers as SMPL-H's from the
#: wrists (left hand 25-39, right hand 40-54).
SMPLX_PARENTS: tuple[int, ...] = SMPLH_PARENTS[:22] + (15, 15, 15) + tuple(
    p for wrist, base in ((20, 25), (21, 40)) for f in range(5)
    for p in (wrist, base + 3 * f, base + 3 * f + 1))

#: model type -> (number of joints, parents, first left-hand joint, first right-hand joint)
_LAYOUT = {"smplh": (SMPLH_NUM_JOINTS, SMPLH_PARENTS, 22, 37),
           "smplx": (SMPLX_NUM_JOINTS, SMPLX_PARENTS, 25, 40)}

# Left-hand finger joints (1, 2, 3) and tip, as offsets from the previous point (the
# wrist for joint 1), metres; the hand points along +x, palm down, thumb towards +z.
_LEFT_FINGERS = {
    "index": [(0.090, -0.005, 0.028), (0.034, -0.002, 0.0), (0.022, -0.002, 0.0), (0.020, -0.002, 0.0)],
    "middle": [(0.094, -0.004, 0.005), (0.037, -0.002, 0.0), (0.025, -0.002, 0.0), (0.021, -0.002, 0.0)],
    "pinky": [(0.078, -0.008, -0.037), (0.024, -0.002, -0.002), (0.017, -0.002, -0.001), (0.017, -0.002, 0.0)],
    "ring": [(0.088, -0.006, -0.016), (0.034, -0.002, -0.001), (0.023, -0.002, 0.0), (0.020, -0.002, 0.0)],
    "thumb": [(0.022, -0.012, 0.030), (0.025, -0.004, 0.020), (0.022, -0.002, 0.012), (0.020, -0.002, 0.008)],
}
_FINGER_RADIUS = {"index": 0.0090, "middle": 0.0092, "pinky": 0.0078, "ring": 0.0086, "thumb": 0.0105}
_SOLE_Y = -1.170  # proxy sole height in the model frame (below the foot joints)

_X, _Y, _Z = np.eye(3)


def _check_model_type(model_type: str) -> str:
    mt = str(model_type).lower()
    if mt not in _SUPPORTED:
        raise NotImplementedError(
            f"proxy body: model_type={model_type!r} is not implemented yet; only 'smplh' "
            "(SMPL-H structure: 52 joints, 6890 vertices, 16 betas) and 'smplx' (SMPL-X "
            "structure: 55 joints, 10475 vertices) are available. Load real SMPL files with "
            "hoibench.bodies.load_body_model instead.")
    return mt


# --------------------------------------------------------------------------- rest joints
#: SMPL-X face joints relative to the head joint (15), metres: jaw, left eye, right eye.
_FACE_JOINTS = ((0.0, 0.005, 0.045), (0.032, 0.075, 0.085), (-0.032, 0.075, 0.085))


def _rest_joints(model_type: str = "smplh") -> np.ndarray:
    """(J, 3) rest joints: SMPL_REST_JOINTS, the face joints (SMPL-X) and the fingers
    (right hand mirrored in x)."""
    n, _, lbase, rbase = _LAYOUT[model_type]
    out = np.zeros((n, 3))
    out[:NUM_JOINTS] = SMPL_REST_JOINTS
    if model_type == "smplx":
        out[22:25] = SMPL_REST_JOINTS[15] + np.array(_FACE_JOINTS)
    for wrist, base, sx in ((20, lbase, 1.0), (21, rbase, -1.0)):
        for f, name in enumerate(_FINGERS):
            p = SMPL_REST_JOINTS[wrist]
            for k in range(3):
                p = p + np.array(_LEFT_FINGERS[name][k]) * (sx, 1.0, 1.0)
                out[base + 3 * f + k] = p
    return out


def _finger_tip(joint3: int, model_type: str = "smplh") -> np.ndarray:
    _, _, lbase, rbase = _LAYOUT[model_type]
    side = 0 if joint3 < rbase else 1
    f = ((joint3 - lbase) % 15) // 3
    sx = 1.0 if side == 0 else -1.0
    return _rest_joints(model_type)[joint3] + np.array(_LEFT_FINGERS[_FINGERS[f]][3]) * (sx, 1.0, 1.0)


def _scale(betas, lead: tuple) -> np.ndarray:
    """``1 + 0.05 * beta_0`` with shape ``lead`` (betas None, (k,) or (T, k))."""
    if betas is None:
        return np.ones(lead)
    b = np.asarray(betas, dtype=np.float64)
    if b.ndim not in (1, 2) or b.shape[-1] < 1:
        raise ValueError(f"betas: expected shape (k,) or (T, k), got {b.shape}")
    return 1.0 + PROXY_SCALE_PER_BETA * b[..., 0]


def proxy_rest_joints(betas=None) -> np.ndarray:
    """Rest joints of the proxy for shape ``betas``: ``SMPL_REST_JOINTS * (1 + 0.05 b_0)``.

    ``betas`` None -> (22, 3); (k,) -> (22, 3); (T, k) -> (T, 22, 3). Metres, model frame.
    """
    s = _scale(betas, ())
    return SMPL_REST_JOINTS * np.asarray(s)[..., None, None]


# --------------------------------------------------------------------------- surface
@dataclass(frozen=True)
class _Part:
    """A capsule from ``p0`` to ``p1``: elliptic sections with semi-axes ``(a, b)`` along
    ``(u, v)`` (``u`` = ``ref`` made perpendicular to the axis, ``v = axis x u``), linearly
    tapered from ``(a0, b0)`` to ``(a1, b1)``, closed by half-ellipsoid caps of length
    ``c0`` / ``c1``. ``joint`` is the joint it is rigidly skinned to; ``j0`` / ``j1`` name
    the joint whose J_regressor ring is the section at ``p0`` / ``p1`` (-1: none)."""
    name: str
    p0: np.ndarray
    p1: np.ndarray
    ref: np.ndarray
    a0: float
    b0: float
    a1: float
    b1: float
    c0: float
    c1: float
    joint: int
    j0: int = -1
    j1: int = -1
    res: tuple = (20, 6, 4)  # (points around, cylinder segments, rings per cap)


def _capsule(part: _Part) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Vertices (N, 3), outward faces (F, 3), and the vertex ids of the sections at p0, p1.

    Vertex layout: pole at ``p0 - c0 d``, start-cap rings, cylinder rings ``t = 0..1``
    (centres ``(1-t) p0 + t p1``, so the ``t = 0`` / ``t = 1`` rings are centred exactly on
    ``p0`` / ``p1``), end-cap rings, pole at ``p1 + c1 d``. Cap ring at angle ``phi``:
    centre offset ``c sin(phi)`` along the axis, semi-axes scaled by ``cos(phi)``.
    """
    n, n_len, n_cap = part.res
    p0, p1 = np.asarray(part.p0, float), np.asarray(part.p1, float)
    d = p1 - p0
    d = d / np.linalg.norm(d)
    u = part.ref - (part.ref @ d) * d
    u = u / np.linalg.norm(u)
    v = np.cross(d, u)
    phi = 0.5 * np.pi * np.arange(1, n_cap + 1) / (n_cap + 1)
    t = np.arange(n_len + 1) / n_len
    centres = np.concatenate([
        p0 - part.c0 * np.sin(phi[::-1])[:, None] * d,
        (1.0 - t)[:, None] * p0 + t[:, None] * p1,
        p1 + part.c1 * np.sin(phi)[:, None] * d,
    ])
    sa = np.concatenate([part.a0 * np.cos(phi[::-1]), (1 - t) * part.a0 + t * part.a1, part.a1 * np.cos(phi)])
    sb = np.concatenate([part.b0 * np.cos(phi[::-1]), (1 - t) * part.b0 + t * part.b1, part.b1 * np.cos(phi)])
    theta = 2.0 * np.pi * np.arange(n) / n
    rings = (centres[:, None, :] + (sa[:, None] * np.cos(theta))[..., None] * u
             + (sb[:, None] * np.sin(theta))[..., None] * v)  # (R, n, 3)
    R = rings.shape[0]
    verts = np.concatenate([(p0 - part.c0 * d)[None], rings.reshape(-1, 3), (p1 + part.c1 * d)[None]])
    ids = 1 + np.arange(R * n).reshape(R, n)
    nxt = np.roll(ids, -1, axis=1)
    a, b, c, e = ids[:-1], nxt[:-1], ids[1:], nxt[1:]
    quads = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([b, e, c], -1).reshape(-1, 3)])
    end = R * n + 1
    fan0 = np.stack([np.zeros(n, np.int64), nxt[0], ids[0]], -1)
    fan1 = np.stack([np.full(n, end), ids[-1], nxt[-1]], -1)
    faces = np.concatenate([fan0, quads, fan1]).astype(np.int64)
    return verts, faces, ids[n_cap], ids[n_cap + n_len]


def _parts(model_type: str = "smplh") -> list[_Part]:
    J = _rest_joints(model_type)
    _, _, lbase, rbase = _LAYOUT[model_type]
    big, mid, small, finger = (20, 5, 4), (16, 4, 3), (12, 3, 3), (8, 1, 2)
    P = []

    def add(name, i0, i1, ref, r0, r1, c0, c1, joint, j0=-1, j1=-1, res=mid):
        p0 = J[i0] if isinstance(i0, (int, np.integer)) else np.asarray(i0, float)
        p1 = J[i1] if isinstance(i1, (int, np.integer)) else np.asarray(i1, float)
        P.append(_Part(name, p0, p1, ref, r0[0], r0[1], r1[0], r1[1], c0, c1, joint, j0, j1, res))

    # torso and head (a: lateral x half-width, b: depth z)
    add("spine1", 0, 3, _X, (0.125, 0.095), (0.12, 0.09), 0.06, 0.05, 0, j0=0, j1=3, res=big)
    add("spine2", 3, 6, _X, (0.12, 0.09), (0.13, 0.10), 0.05, 0.05, 3, j1=6, res=big)
    add("spine3", 6, 9, _X, (0.13, 0.10), (0.14, 0.105), 0.05, 0.05, 6, j1=9, res=big)
    add("chest", 9, 12, _X, (0.14, 0.105), (0.10, 0.07), 0.05, 0.03, 9, j1=12, res=big)
    add("neck", 12, 15, _X, (0.05, 0.05), (0.048, 0.048), 0.05, 0.048, 12, j1=15, res=mid)
    head0, head1 = J[15] + (0.0, 0.04, 0.015), J[15] + (0.0, 0.12, 0.015)
    add("head", head0, head1, _X, (0.078, 0.095), (0.078, 0.095), 0.075, 0.075, 15, res=big)
    for s, sx in (("left", 1.0), ("right", -1.0)):
        hip, knee, ankle, foot = (1, 4, 7, 10) if s == "left" else (2, 5, 8, 11)
        collar, shoulder, elbow, wrist = (13, 16, 18, 20) if s == "left" else (14, 17, 19, 21)
        base = lbase if s == "left" else rbase
        # legs (a: x half-width, b: z depth)
        add(f"{s}_hip", 0, hip, _Y, (0.085, 0.085), (0.085, 0.085), 0.085, 0.085, 0, j1=hip)
        add(f"{s}_thigh", hip, knee, _X, (0.08, 0.08), (0.055, 0.055), 0.08, 0.055, hip, j1=knee, res=big)
        add(f"{s}_shin", knee, ankle, _X, (0.055, 0.055), (0.04, 0.04), 0.055, 0.04, knee, j1=ankle, res=big)
        heel = np.array([J[ankle][0], _SOLE_Y + 0.035, J[ankle][2] - 0.03])
        toe = J[foot] + np.array([0.005 * sx, _SOLE_Y + 0.018 - J[foot][1], 0.06])
        add(f"{s}_foot", heel, foot, _X, (0.045, 0.035), (0.045, 0.025), 0.03, 0.02, ankle, j1=foot)
        add(f"{s}_toes", foot, toe, _X, (0.045, 0.025), (0.04, 0.018), 0.02, 0.02, foot, res=small)
        # arms (a: z depth, b: y height)
        add(f"{s}_collar", 9, collar, _Z, (0.06, 0.06), (0.055, 0.055), 0.06, 0.055, 9, j1=collar)
        add(f"{s}_shoulder", collar, shoulder, _Z, (0.055, 0.055), (0.05, 0.05), 0.055, 0.05, collar, j1=shoulder)
        add(f"{s}_upper_arm", shoulder, elbow, _Z, (0.048, 0.045), (0.04, 0.038), 0.045, 0.038, shoulder, j1=elbow)
        add(f"{s}_forearm", elbow, wrist, _Z, (0.04, 0.036), (0.032, 0.024), 0.036, 0.024, elbow, j1=wrist)
        knuckles = J[[base, base + 3, base + 6, base + 9]].mean(0)
        add(f"{s}_palm", wrist, knuckles, _Z, (0.04, 0.016), (0.045, 0.013), 0.016, 0.013, wrist, res=small)
        for f, name in enumerate(_FINGERS):
            j1, j2, j3 = base + 3 * f, base + 3 * f + 1, base + 3 * f + 2
            r = _FINGER_RADIUS[name]
            rr = [(r, r), (0.93 * r, 0.93 * r), (0.86 * r, 0.86 * r), (0.78 * r, 0.78 * r)]
            add(f"{s}_{name}1", j1, j2, _Y, rr[0], rr[1], rr[0][0], rr[1][0], j1, j0=j1, j1=j2, res=finger)
            add(f"{s}_{name}2", j2, j3, _Y, rr[1], rr[2], rr[1][0], rr[2][0], j2, j1=j3, res=finger)
            add(f"{s}_{name}3", j3, _finger_tip(j3, model_type), _Y, rr[2], rr[3], rr[2][0], rr[3][0], j3,
                res=finger)
    if model_type == "smplx":  # chin on the jaw, eyeballs on the eyes (after the SMPL-H parts)
        add("jaw", 22, J[22] + (0.0, -0.035, 0.055), _X, (0.035, 0.025), (0.03, 0.02), 0.025, 0.02,
            22, j0=22, res=small)
        for name, j in (("left_eye", 23), ("right_eye", 24)):
            add(name, j, J[j] + (0.0, 0.0, 0.025), _X, (0.012, 0.012), (0.012, 0.012), 0.012, 0.012,
                j, j0=j, res=finger)
    return P


#: ``smplx``'s ``vertex_ids`` (smplx/vertex_ids.py): head, finger tips, toes and heels.
_VERTEX_IDS = {
    "smplh": {"head": (332, 6260, 2800, 4071, 583),
              "l": dict(thumb=2746, index=2319, middle=2445, ring=2556, pinky=2673),
              "r": dict(thumb=6191, index=5782, middle=5905, ring=6016, pinky=6133),
              "L": (3216, 3226, 3387), "R": (6617, 6624, 6787)},
    "smplx": {"head": (9120, 9929, 9448, 616, 6),
              "l": dict(thumb=5361, index=4933, middle=5058, ring=5169, pinky=5286),
              "r": dict(thumb=8079, index=7669, middle=7794, ring=7905, pinky=8022),
              "L": (5770, 5780, 8846), "R": (8463, 8474, 8635)},
}


def _landmark_targets(J: np.ndarray, model_type: str = "smplh") -> list[tuple[str, int, str, np.ndarray]]:
    """``smplx``'s ``vertex_ids[model_type]`` -> (name, required vertex index, part, target
    point): the part vertex nearest the target is moved to that index."""
    ids_ = _VERTEX_IDS[model_type]
    _, _, lbase, rbase = _LAYOUT[model_type]
    h = J[15]
    nose, reye, leye, rear, lear = ids_["head"]
    out = [("nose", nose, "head", h + (0.0, 0.10, 0.20)),
           ("reye", reye, "head", h + (-0.03, 0.12, 0.20)),
           ("leye", leye, "head", h + (0.03, 0.12, 0.20)),
           ("rear", rear, "head", h + (-0.20, 0.09, 0.015)),
           ("lear", lear, "head", h + (0.20, 0.09, 0.015))]
    tips = {"l": ids_["l"], "r": ids_["r"]}
    for s, side in (("l", "left"), ("r", "right")):
        for f in _FINGERS:
            j3 = (lbase if s == "l" else rbase) + 3 * _FINGERS.index(f) + 2
            tip = _finger_tip(j3, model_type)
            out.append((f"{s}{f}", tips[s][f], f"{side}_{f}3", tip + (tip - J[j3])))  # the tip pole
    for s, side, sx, ids in (("L", "left", 1.0, ids_["L"]), ("R", "right", -1.0, ids_["R"])):
        ankle, foot = (7, 10) if s == "L" else (8, 11)
        toe = J[foot] + np.array([0.005 * sx, _SOLE_Y + 0.018 - J[foot][1], 0.06])
        out.append((f"{s}BigToe", ids[0], f"{side}_toes", toe + (-0.03 * sx, 0.0, 0.05)))
        out.append((f"{s}SmallToe", ids[1], f"{side}_toes", toe + (0.04 * sx, 0.0, 0.02)))
        out.append((f"{s}Heel", ids[2], f"{side}_foot", np.array([J[ankle][0], _SOLE_Y - 0.02, J[ankle][2] - 0.1])))
    return out


def _assemble(parts: list[_Part], n_joints: int):
    """The capsules of ``parts`` as one mesh: vertices, faces, each vertex's part, each
    joint's regressor ring (vertex ids) and each part's first vertex id."""
    verts, faces, part_of, ring, starts = [], [], [], {}, []
    off = 0
    for k, p in enumerate(parts):
        v, f, r0, r1 = _capsule(p)
        starts.append(off)
        verts.append(v)
        faces.append(f + off)
        part_of.append(np.full(len(v), k))
        for j, r in ((p.j0, r0), (p.j1, r1)):
            if j >= 0:
                assert j not in ring, f"joint {j} has two regressor rings"
                ring[j] = r + off
        off += len(v)
    assert sorted(ring) == list(range(n_joints)), "every joint needs one ring"
    return np.concatenate(verts), np.concatenate(faces), np.concatenate(part_of), ring, starts + [off]


def _split_faces(V: np.ndarray, F: np.ndarray, part_of: np.ndarray, pick: np.ndarray):
    """Split the faces ``pick`` at their centroid (1 -> 3 triangles, orientation kept); the
    new vertices lie on the surface, after all others, in the part of the face."""
    new = len(V) + np.arange(len(pick))
    a, b, c = F[pick, 0], F[pick, 1], F[pick, 2]
    V = np.concatenate([V, (V[a] + V[b] + V[c]) / 3.0])
    part_of = np.concatenate([part_of, part_of[a]])
    F[pick] = np.stack([a, b, new], -1)
    F = np.concatenate([F, np.stack([b, c, new], -1), np.stack([c, a, new], -1)])
    return V, F, part_of


def _skinned_arrays(V: np.ndarray, F: np.ndarray, J: np.ndarray, J_reg: np.ndarray, weights: np.ndarray,
                    joint_parents: Sequence[int], shapedirs: np.ndarray, posedirs: np.ndarray) -> dict[str, np.ndarray]:
    """The arrays every SMPL-family file holds, keyed and ordered as in the released files:
    template, faces, joints, joint regressor, skinning weights, kinematic tree, shape and pose
    directions."""
    parents = np.array(joint_parents, dtype=np.int64)
    parents[0] = 4294967295  # as in the released files (uint32 -1)
    return {"v_template": V, "f": F.astype(np.int64), "J": J, "J_regressor": J_reg, "weights": weights,
            "kintree_table": np.stack([parents, np.arange(len(parents), dtype=np.int64)]),
            "shapedirs": shapedirs, "posedirs": posedirs}


def _reorder_and_skin(V: np.ndarray, F: np.ndarray, part_of: np.ndarray, order: np.ndarray, ring: dict,
                      parts: list[_Part], n_joints: int):
    """Put vertex ``order[i]`` at index ``i`` (faces renumbered), then one-hot skinning
    weights (each vertex rigid to its part's joint) and a joint regressor averaging each
    joint's ring: ``(V, F, part_of, weights (V, J), J_regressor (J, V))``."""
    inv = np.empty_like(order)
    inv[order] = np.arange(len(order))
    V, part_of, F = V[order], part_of[order], inv[F]
    weights = np.zeros((len(V), n_joints))
    weights[np.arange(len(V)), np.array([p.joint for p in parts])[part_of]] = 1.0
    J_reg = np.zeros((n_joints, len(V)))
    for j, r in ring.items():
        J_reg[j, inv[r]] = 1.0 / len(r)
    return V, F, part_of, weights, J_reg


@lru_cache(maxsize=None)
def _build(model_type: str) -> dict[str, np.ndarray]:
    mt = _check_model_type(model_type)
    n_joints, joint_parents, _, _ = _LAYOUT[mt]
    J = _rest_joints(mt)
    parts = _parts(mt)
    n_target = _NUM_VERTICES[mt]

    V, F, part_of, ring, _ = _assemble(parts, n_joints)

    # Pad to the SMPL vertex count by splitting faces of the big parts at their centroid
    # (1 -> 3 triangles, orientation kept): the new vertices lie on the surface.
    pad = n_target - len(V)
    if pad < 0:
        raise AssertionError(f"proxy resolution too high: {len(V)} > {n_target} vertices")
    big = {i for i, p in enumerate(parts) if p.res[0] >= 20}
    while pad:  # one round for SMPL-H; SMPL-X's larger count splits the split faces again
        cand = np.flatnonzero(np.isin(part_of[F[:, 0]], sorted(big)))
        step = min(pad, len(cand))
        V, F, part_of = _split_faces(V, F, part_of, cand[(np.arange(step) * len(cand)) // step])
        pad -= step

    # Move smplx's landmark vertices (extra joints) to the indices smplx reads.
    names = [p.name for p in parts]
    order = np.full(len(V), -1)
    taken = np.zeros(len(V), bool)
    for _, idx, part, target in _landmark_targets(J, mt):
        cand = np.flatnonzero((part_of == names.index(part)) & ~taken)
        src = cand[np.argmin(((V[cand] - target) ** 2).sum(-1))]
        order[idx] = src
        taken[src] = True
    order[order < 0] = np.flatnonzero(~taken)
    V, F, part_of, weights, J_reg = _reorder_and_skin(V, F, part_of, order, ring, parts, n_joints)
    n_v = len(V)
    if mt == "smplx":  # float32: 400 directions of 10475 vertices (the files store no more)
        shapedirs = np.zeros((n_v, 3, _SMPLX_SHAPE_DIMS + _SMPLX_EXPR_DIMS), dtype=np.float32)
        posedirs = np.zeros((n_v, 3, 9 * (n_joints - 1)), dtype=np.float32)
    else:
        shapedirs = np.zeros((n_v, 3, PROXY_NUM_BETAS))
        posedirs = np.zeros((n_v, 3, 9 * (n_joints - 1)))
    shapedirs[:, :, 0] = PROXY_SCALE_PER_BETA * V
    out = {
        **_skinned_arrays(V, F, J, J_reg, weights, joint_parents, shapedirs, posedirs),
        "hands_componentsl": np.eye(45),
        "hands_componentsr": np.eye(45),
        "hands_meanl": np.zeros(45),
        "hands_meanr": np.zeros(45),
    }
    if mt == "smplx":
        out.update(_face_landmarks(V, F, part_of == names.index("head")))
    for a in out.values():
        a.setflags(write=False)
    return out


def _face_landmarks(V: np.ndarray, F: np.ndarray, head: np.ndarray) -> dict[str, np.ndarray]:
    """SMPL-X landmark arrays on the front of the head: 51 static landmarks and 79 x 17
    dynamic contour candidates, each the barycentre of a head face (deterministic)."""
    faces = np.flatnonzero(head[F].all(1))
    centre = V[F[faces]].mean(1)
    front = faces[np.argsort(-centre[:, 2], kind="stable")][: max(51, len(faces) // 3)]
    front = np.sort(front)
    static = front[(np.arange(51) * len(front)) // 51]
    dyn = faces[(np.arange(79 * 17) * len(faces)) // (79 * 17)].reshape(79, 17)
    third = np.full(3, 1.0 / 3.0)
    return {"lmk_faces_idx": static.astype(np.int64),
            "lmk_bary_coords": np.tile(third, (51, 1)),
            "dynamic_lmk_faces_idx": dyn.astype(np.int64),
            "dynamic_lmk_bary_coords": np.tile(third, (79, 17, 1))}


def build_proxy_arrays(model_type: str = "smplh") -> dict[str, np.ndarray]:
    """The proxy model's arrays, keyed as in the SMPL-H / SMPL-X ``.npz`` (fresh, writable
    copies; deterministic: byte-identical on every call). See the module docstring for
    shapes."""
    return {k: v.copy() for k, v in _build(_check_model_type(model_type)).items()}


# --------------------------------------------------------------------------- files
@lru_cache(maxsize=None)
def _file_bytes(model_type: str) -> bytes:
    return npz_bytes(_build(model_type))


def write_proxy_model(root, model_type: str = "smplh",
                      genders: Sequence[str] = _GENDERS) -> list[Path]:
    """Write the proxy as ``root/<model_type>/<PREFIX>_<GENDER>.npz`` (e.g.
    ``root/smplh/SMPLH_MALE.npz``, ``root/smplx/SMPLX_NEUTRAL.npz``), the layout ``smplx.create(root, model_type=...,
    gender=..., ext='npz')`` expects. Every gender gets the same arrays. Each file is
    written atomically (temporary file in the same folder, then ``os.replace``) and is
    byte-identical across calls. Returns the written paths."""
    mt = _check_model_type(model_type)
    folder = Path(root) / mt
    folder.mkdir(parents=True, exist_ok=True)
    data = _file_bytes(mt)
    paths = []
    for g in genders:
        if str(g).lower() not in _GENDERS:
            raise ValueError(f"gender: expected one of {_GENDERS}, got {g!r}")
        path = folder / f"{_FILE_PREFIX[mt]}_{str(g).upper()}.npz"
        paths.append(atomic_write_bytes(path, data))
    return paths


# --------------------------------------------------------------------------- forward pass
class ProxyBody:
    """Pure-numpy linear blend skinning of the proxy (no ``smplx`` needed).

    ``forward`` reproduces ``smplx``'s SMPL-H (or, with ``model_type='smplx'``, SMPL-X with
    zero expression) forward pass on the proxy files (``use_pca=False``) in float64:
    ``v_shaped = v_template + shapedirs . betas``, rest joints ``(1 + 0.05 b_0) J``,
    joints by :func:`hoibench.core.skeleton.forward_kinematics` (hands continue from the
    wrists), and ``v = sum_j w_vj (G_j v_shaped + J_j - G_j rest_j)`` (``trans`` included
    in ``J_j``).

    Attributes: ``v_template`` (V, 3), ``faces`` (F, 3), ``weights`` (V, J),
    ``shapedirs`` (V, 3, 16) (SMPL-X: (V, 3, 400)), ``parents`` (J,), ``rest_joints``
    (J, 3), ``part_joint`` (V,) the joint each vertex is rigid to; J = 52 (SMPL-H) or 55
    (SMPL-X).
    """

    def __init__(self, model_type: str = "smplh", chunk: int = 256):
        mt = _check_model_type(model_type)
        arr = _build(mt)
        self.model_type = mt
        self.num_joints = _LAYOUT[mt][0]
        self.max_betas = PROXY_NUM_BETAS if mt == "smplh" else _SMPLX_SHAPE_DIMS
        self.v_template = arr["v_template"]
        self.faces = arr["f"]
        self.weights = arr["weights"]
        self.shapedirs = arr["shapedirs"]
        self.rest_joints = arr["J"]
        self.parents = np.array(_LAYOUT[mt][1])
        self.part_joint = self.weights.argmax(1)
        self._rigid = bool(np.all(self.weights[np.arange(len(self.weights)), self.part_joint] == 1.0))
        self._groups = [(j, np.flatnonzero(self.part_joint == j)) for j in np.unique(self.part_joint)]
        self.chunk = int(chunk)

    @property
    def num_vertices(self) -> int:
        return len(self.v_template)

    def forward(self, body_pose_aa, trans=None, betas=None) -> tuple[np.ndarray, np.ndarray]:
        """Pose the proxy.

        Args:
            body_pose_aa: (T, 22, 3) axis-angle (radians), joint 0 = global orientation
                about the pelvis; or (T, 52, 3) with the 30 hand joints too (SMPL-H
                ``poses`` (T, 156) reshaped); flat (T, 66) / (T, 156) also accepted.
                SMPL-X proxy: (T, 55, 3) / flat (T, 165) in SMPL-X order (root, body,
                jaw, eyes, hands) instead of 52 / 156. Missing hand joints are the flat hand.
            trans: (T, 3) or (3,) root translation (SMPL ``transl``), metres; None = 0.
            betas: (k,) or (T, k), k <= 16 (SMPL-X proxy: k <= 300); None = mean shape.

        Returns:
            ``(vertices (T, V, 3), joints (T, 22, 3))``, float64, metres.
        """
        pose = np.asarray(body_pose_aa, dtype=np.float64)
        nj = self.num_joints
        if pose.ndim == 2 and pose.shape[1] in (3 * NUM_JOINTS, 3 * nj):
            pose = pose.reshape(len(pose), -1, 3)
        if pose.ndim != 3 or pose.shape[1:] not in ((NUM_JOINTS, 3), (nj, 3)):
            raise ValueError(f"body_pose_aa: expected shape (T, 22, 3) or (T, {nj}, 3), got {pose.shape}")
        T = len(pose)
        trans = np.zeros((T, 3)) if trans is None else np.broadcast_to(np.asarray(trans, np.float64), (T, 3))
        if betas is not None:
            betas = np.asarray(betas, dtype=np.float64)
            if betas.ndim not in (1, 2) or betas.shape[-1] > self.max_betas or (
                    betas.ndim == 2 and len(betas) not in (1, T)):
                raise ValueError(f"betas: expected shape (k,) or (T, k) with k <= {self.max_betas}, "
                                 f"got {betas.shape}")
            if betas.ndim == 2 and len(betas) == 1:
                betas = betas[0]
        verts = np.empty((T, self.num_vertices, 3))
        joints = np.empty((T, NUM_JOINTS, 3))
        for s in range(0, T, self.chunk):
            sl = slice(s, min(T, s + self.chunk))
            b = betas if betas is None or betas.ndim == 1 else betas[sl]
            verts[sl], joints[sl] = self._forward(pose[sl], trans[sl], b)
        return verts, joints

    __call__ = forward

    def _forward(self, pose, trans, betas):
        n = len(pose)
        nj = self.num_joints
        rots = np.broadcast_to(np.eye(3), (n, nj, 3, 3)).copy()
        rots[:, :pose.shape[1]] = axis_angle_to_matrix(pose)
        scale = _scale(betas, ())
        scale_n = np.broadcast_to(scale, (n,))
        rest = self.rest_joints * scale_n[:, None, None]  # (n, J, 3)
        body, G = forward_kinematics(rots[:, :NUM_JOINTS], rest[:, :NUM_JOINTS], trans)
        Jp = np.concatenate([body, np.empty((n, nj - NUM_JOINTS, 3))], 1)
        G = np.concatenate([G, np.empty((n, nj - NUM_JOINTS, 3, 3))], 1)
        for j in range(NUM_JOINTS, nj):  # face and fingers: same recursion as the body
            p = self.parents[j]
            G[:, j] = G[:, p] @ rots[:, j]
            Jp[:, j] = (G[:, p] @ (rest[:, j] - rest[:, p])[..., None])[..., 0] + Jp[:, p]
        t = Jp - (G @ rest[..., None])[..., 0]  # (n, J, 3)
        if betas is None:
            v_shaped = self.v_template
        else:
            k = betas.shape[-1]
            v_shaped = self.v_template + np.einsum("vck,...k->...vc", self.shapedirs[..., :k], betas)
        if self._rigid:  # one-hot weights: v = G_j v_shaped + t_j per joint's vertex group
            v = np.empty((n, len(self.v_template), 3))
            for j, idx in self._groups:
                v[:, idx] = v_shaped[..., idx, :] @ G[:, j].swapaxes(-1, -2) + t[:, j, None, :]
        else:  # general LBS: blend the 3x4 transforms
            A = np.concatenate([G.reshape(n, -1, 9), t], -1)  # (n, 52, 12)
            M = self.weights @ A  # (n, V, 12)
            v = (M[..., :9].reshape(n, -1, 3, 3) @ v_shaped[..., None])[..., 0] + M[..., 9:]
        return v, body
