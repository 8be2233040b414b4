"""License-free proxy MANO hand in MANO's file structure.

The proxy is the hand of the proxy body (:mod:`hoibench.bodies.proxy`) on its own: a palm
capsule and three rigid capsules per finger around the bones of MANO's 16-joint skeleton,
written as ``MANO_RIGHT.pkl`` / ``MANO_LEFT.pkl`` so that ``smplx`` loads it exactly like
the real (licensed) MANO files::

    smplx.create(root, model_type='mano', is_rhand=True, use_pca=False, flat_hand_mean=True)

reads ``root/mano/MANO_RIGHT.pkl`` (``is_rhand=False``: ``MANO_LEFT.pkl``; ``ext='npz'``:
``.npz`` files, which :func:`write_proxy_mano` can also write).

Frame (the right hand; metres, MANO's template frame): the wrist joint is at MANO's
mean-shape wrist :data:`PROXY_MANO_WRIST` ``(0.0957, 0.0064, 0.0062)``, the flat hand
points along -x, palm down (-y), thumb towards +z, as the real right MANO template. So
``global_orient`` (a rotation about the wrist joint) and ``transl`` fitted with the real
MANO (GRAB, TACO, ARCTIC...) put the proxy's wrist where the real hand's wrist is. The
finger joints relative to the wrist, and the finger capsules' sizes, are those of the proxy
body's hands (:mod:`hoibench.bodies.proxy`), so the proxy MANO hand and the proxy SMPL-H /
SMPL-X hands share one finger skeleton, as the real models do. Those joints are 4-31 mm
from MANO's mean-shape joints (the proxy's fingers are straighter and less spread; worst at
pinky3). The left hand is the mirror image ``x -> -x`` (as the real ``MANO_LEFT``): left
wrist ``(-0.0957, 0.0064, 0.0062)``, fingers along +x.

Structure (the keys and shapes of the released MANO ``.pkl`` that ``smplx`` reads, stored
as plain numpy arrays, no ``chumpy`` / ``scipy`` objects):

* ``v_template`` (778, 3) float64 -- MANO's vertex count; the finger-tip pole of each
  finger is at the vertex index ``smplx`` picks for that tip (``vertex_ids['mano']``,
  :data:`MANO_TIP_VERTEX_IDS`: thumb 744, index 320, middle 443, ring 554, pinky 671).
* ``f`` (1492, 3) int64 -- outward-oriented triangles; each of the 16 capsules is a closed
  surface (a union of overlapping closed parts, not one manifold). The real MANO has 1538
  faces, but its mesh is open at the wrist: 778 vertices on closed oriented triangle
  surfaces need ``V - F/2`` even (twice the number of parts minus genus), which 1538 makes
  odd (9), so no closed mesh has MANO's counts; 16 closed parts give ``2 * 778 - 4 * 16``.
* ``kintree_table`` (2, 16) int64 -- row 0 parents (the root's stored as 4294967295, as
  in the released files), row 1 joint ids; joints in MANO order: wrist, index1-3,
  middle1-3, pinky1-3, ring1-3, thumb1-3 (:data:`MANO_JOINT_NAMES`).
* ``J`` (16, 3) rest joints; ``J_regressor`` (16, 778) dense: row ``j`` averages one
  symmetric ring of 8 (wrist: 16) vertices centred on joint ``j``, so
  ``J_regressor @ v_template == J`` up to float rounding.
* ``weights`` (778, 16) one-hot: each capsule is rigid to the joint that moves its bone
  (palm: wrist; finger segment ``k``: finger joint ``k``), so capsules stay closed.
* ``shapedirs`` (778, 3, 10): ``shapedirs[..., 0] = 0.05 * v_template``, the rest zero,
  so ``beta_0`` scales the whole hand (and its joints) by ``1 + 0.05 beta_0`` about the
  model origin (not the wrist), as in the proxy body.
* ``posedirs`` (778, 3, 135) zeros (no pose correctives).
* ``hands_components`` (45, 45) identity and ``hands_mean`` (45,) zeros, so PCA
  coefficient ``k`` is axis-angle component ``k`` and ``flat_hand_mean`` has no effect.
* ``bs_style`` ``'lbs'`` and ``bs_type`` ``'lrotmin'`` (strings, as in the real files).

The real files also hold ``hands_coeffs`` (the PCA coefficients of MANO's training poses);
the proxy does not. The pickles reference only ``numpy.ndarray`` and
``builtins.bytearray`` (each array is rebuilt as ``ndarray(shape, dtype, buffer)`` from
little-endian bytes), so they load with any numpy, need no ``chumpy``, and are
byte-identical on every write. Metrics computed with this hand must be labelled
"proxy hand".
"""
from __future__ import annotations

import io
import pickle
import sys
from functools import lru_cache
from pathlib import Path
from typing import Sequence

import numpy as np

from ..core.geometry import axis_angle_to_matrix
from ..core.io import atomic_write_bytes, npz_bytes
from .proxy import (_FINGER_RADIUS, _FINGERS, _LEFT_FINGERS, PROXY_SCALE_PER_BETA, _assemble, _Part,
                    _reorder_and_skin, _skinned_arrays, _split_faces)
from .smpl import first_file

__all__ = [
    "MANO_NUM_VERTICES",
    "MANO_NUM_JOINTS",
    "MANO_NUM_BETAS",
    "MANO_POSE_DIM",
    "MANO_JOINT_NAMES",
    "MANO_PARENTS",
    "MANO_TIP_VERTEX_IDS",
    "PROXY_MANO_WRIST",
    "build_proxy_mano_arrays",
    "write_proxy_mano",
    "mano_model_path",
    "load_mano_model",
    "ProxyHand",
]

MANO_NUM_VERTICES = 778
MANO_NUM_JOINTS = 16
#: Shape coefficients in the MANO files (``shapedirs`` (778, 3, 10)).
MANO_NUM_BETAS = 10
#: Axis-angle hand pose width (15 finger joints x 3); the PCA basis is 45 x 45.
MANO_POSE_DIM = 45

#: MANO joint names (``smplx``'s MANO order).
MANO_JOINT_NAMES: tuple[str, ...] = ("wrist",) + tuple(f"{f}{k}" for f in _FINGERS for k in (1, 2, 3))
#: Parents: each finger is a chain wrist -> 1 -> 2 -> 3.
MANO_PARENTS: tuple[int, ...] = (-1,) + tuple(p for f in range(5) for p in (0, 1 + 3 * f, 2 + 3 * f))
#: ``smplx``'s ``vertex_ids['mano']`` (its order: thumb, index, middle, ring, pinky): the
#: vertices ``smplx`` appends as finger-tip joints. The proxy's tip poles are there.
MANO_TIP_VERTEX_IDS: dict[str, int] = {"thumb": 744, "index": 320, "middle": 443, "ring": 554, "pinky": 671}
#: Right-hand wrist joint of the proxy: MANO's mean-shape wrist, metres (left: x negated).
PROXY_MANO_WRIST = (0.0957, 0.0064, 0.0062)

_SIDES = ("right", "left")
_FILE_NAME = {"right": "MANO_RIGHT", "left": "MANO_LEFT"}
_MIRROR = np.array([-1.0, 1.0, 1.0])
_Y, _Z = np.eye(3)[1], np.eye(3)[2]
#: Capsule resolutions (points around, cylinder segments, rings per cap): finger segments
#: 1-2, finger tips, palm. 5 * (34 + 34 + 50) + 178 = 768 vertices; 10 palm faces are split
#: to reach 778.
_RES_SEGMENT, _RES_TIP, _RES_PALM = (8, 1, 1), (8, 1, 2), (16, 4, 3)
_PICKLE_PROTOCOL = 4


def _check_side(side) -> str:
    s = str(side).lower()
    if s not in _SIDES:
        raise ValueError(f"side: expected 'right' or 'left', got {str(side)[:40]!r}")
    return s


# --------------------------------------------------------------------------- geometry
def _right_joints_and_tips() -> tuple[np.ndarray, np.ndarray]:
    """(16, 3) right-hand rest joints and (5, 3) finger-tip points (end of each 3rd
    segment, MANO finger order): the proxy body's fingers mirrored to the right hand,
    hung from :data:`PROXY_MANO_WRIST`."""
    J = np.zeros((MANO_NUM_JOINTS, 3))
    J[0] = PROXY_MANO_WRIST
    tips = np.zeros((5, 3))
    for f, name in enumerate(_FINGERS):
        p = J[0]
        for k in range(3):
            p = p + np.array(_LEFT_FINGERS[name][k]) * _MIRROR
            J[1 + 3 * f + k] = p
        tips[f] = p + np.array(_LEFT_FINGERS[name][3]) * _MIRROR
    return J, tips


def _parts() -> list[_Part]:
    """The 16 capsules of the right hand; part ``j`` is rigid to joint ``j``."""
    J, tips = _right_joints_and_tips()
    knuckles = J[[1, 4, 7, 10]].mean(0)  # index1, middle1, pinky1, ring1
    P = [_Part("palm", J[0], knuckles, _Z, 0.04, 0.016, 0.045, 0.013, 0.016, 0.013, 0, j0=0, res=_RES_PALM)]
    for f, name in enumerate(_FINGERS):
        r = _FINGER_RADIUS[name]
        rr = (r, 0.93 * r, 0.86 * r, 0.78 * r)
        j1, j2, j3 = 1 + 3 * f, 2 + 3 * f, 3 + 3 * f
        P.append(_Part(f"{name}1", J[j1], J[j2], _Y, rr[0], rr[0], rr[1], rr[1], rr[0], rr[1], j1,
                       j0=j1, j1=j2, res=_RES_SEGMENT))
        P.append(_Part(f"{name}2", J[j2], J[j3], _Y, rr[1], rr[1], rr[2], rr[2], rr[1], rr[2], j2,
                       j1=j3, res=_RES_SEGMENT))
        P.append(_Part(f"{name}3", J[j3], tips[f], _Y, rr[2], rr[2], rr[3], rr[3], rr[2], rr[3], j3,
                       res=_RES_TIP))
    return P


@lru_cache(maxsize=None)
def _build(side: str) -> dict:
    """The arrays of one hand (read-only); the left hand mirrors the right."""
    side = _check_side(side)
    if side == "left":
        r = _build("right")
        out = dict(r)
        out["v_template"] = r["v_template"] * _MIRROR
        out["f"] = r["f"][:, [0, 2, 1]].copy()  # mirroring flips orientation: flip it back
        out["J"] = r["J"] * _MIRROR
        shapedirs = np.zeros_like(r["shapedirs"])
        shapedirs[:, :, 0] = PROXY_SCALE_PER_BETA * out["v_template"]
        out["shapedirs"] = shapedirs
        for a in out.values():
            if isinstance(a, np.ndarray):
                a.setflags(write=False)
        return out

    J, _ = _right_joints_and_tips()
    parts = _parts()
    V, F, part_of, ring, starts = _assemble(parts, MANO_NUM_JOINTS)
    # the pole at each finger tip: the last vertex of the finger's third segment
    tip_src = {p.name[:-1]: starts[k + 1] - 1 for k, p in enumerate(parts) if p.name.endswith("3")}

    # Pad to 778 vertices by splitting palm faces at their centroid (1 -> 3 triangles,
    # orientation kept; the new vertices lie on the palm surface, after all others).
    pad = MANO_NUM_VERTICES - len(V)
    assert 0 <= pad, f"proxy hand resolution too high: {len(V)} > {MANO_NUM_VERTICES} vertices"
    if pad:
        cand = np.flatnonzero(part_of[F[:, 0]] == 0)
        V, F, part_of = _split_faces(V, F, part_of, cand[(np.arange(pad) * len(cand)) // pad])

    # Move the tip poles to smplx's MANO tip indices; everything else keeps its order.
    order = np.full(len(V), -1)
    for name, idx in MANO_TIP_VERTEX_IDS.items():
        order[idx] = tip_src[name]
    order[order < 0] = np.setdiff1d(np.arange(len(V)), list(tip_src.values()))
    V, F, part_of, weights, J_reg = _reorder_and_skin(V, F, part_of, order, ring, parts, MANO_NUM_JOINTS)
    n_v = len(V)
    shapedirs = np.zeros((n_v, 3, MANO_NUM_BETAS))
    shapedirs[:, :, 0] = PROXY_SCALE_PER_BETA * V
    out = {
        **_skinned_arrays(V, F, J, J_reg, weights, MANO_PARENTS, shapedirs,
                          np.zeros((n_v, 3, 9 * (MANO_NUM_JOINTS - 1)))),
        "hands_components": np.eye(MANO_POSE_DIM),
        "hands_mean": np.zeros(MANO_POSE_DIM),
        "bs_style": "lbs",
        "bs_type": "lrotmin",
    }
    for a in out.values():
        if isinstance(a, np.ndarray):
            a.setflags(write=False)
    return out


def build_proxy_mano_arrays(side: str = "right") -> dict:
    """The proxy hand's file contents, keyed as in ``MANO_RIGHT.pkl`` / ``MANO_LEFT.pkl``
    (fresh, writable copies of the arrays; ``bs_style`` / ``bs_type`` are strings).
    Deterministic. See the module docstring for shapes."""
    return {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in _build(_check_side(side)).items()}


# --------------------------------------------------------------------------- files
class _PlainPickler(pickle.Pickler):
    """Pickles every ndarray as ``numpy.ndarray(shape, '<dtype', bytearray(data))``: no
    numpy-version-specific globals (numpy 2's own pickles name ``numpy._core``), writable
    arrays on load, the same bytes whatever the numpy version."""

    def reducer_override(self, obj):
        if isinstance(obj, np.ndarray):
            if obj.dtype.hasobject:
                raise TypeError("proxy MANO files hold numeric arrays only")
            a = np.ascontiguousarray(obj, dtype=obj.dtype.newbyteorder("<"))
            # interned dtype string: pickle's memo then treats it the same on every call
            return np.ndarray, (tuple(int(n) for n in a.shape), sys.intern(a.dtype.str), bytearray(a.tobytes()))
        return NotImplemented


def _pickle_bytes(data: dict) -> bytes:
    buf = io.BytesIO()
    _PlainPickler(buf, protocol=_PICKLE_PROTOCOL).dump(dict(data))
    return buf.getvalue()


@lru_cache(maxsize=None)
def _file_bytes(side: str, ext: str) -> bytes:
    data = _build(side)
    if ext == "npz":
        return npz_bytes({k: np.asarray(v) for k, v in data.items()})
    return _pickle_bytes(data)


def _check_ext(ext) -> str:
    e = str(ext).lower().lstrip(".")
    if e not in ("pkl", "npz"):
        raise ValueError(f"ext: expected 'pkl' or 'npz', got {str(ext)[:40]!r}")
    return e


def write_proxy_mano(root, sides: Sequence[str] = _SIDES, ext: str = "pkl") -> list[Path]:
    """Write the proxy hand as ``root/mano/MANO_RIGHT.pkl`` and ``root/mano/MANO_LEFT.pkl``
    (the layout ``smplx.create(root, model_type='mano', is_rhand=...)`` reads).

    ``ext='npz'`` writes ``MANO_RIGHT.npz`` / ``MANO_LEFT.npz`` instead (for
    ``smplx.create(..., ext='npz')``). Each file is written atomically (temporary file in
    the same folder, then ``os.replace``) and is byte-identical on every call. The pickles
    hold plain numpy arrays and two strings (see the module docstring). Returns the paths.
    """
    e = _check_ext(ext)
    folder = Path(root) / "mano"
    paths = []
    for side in sides:
        s = _check_side(side)
        paths.append(atomic_write_bytes(folder / f"{_FILE_NAME[s]}.{e}", _file_bytes(s, e)))
    return paths


def mano_model_path(model_dir, side: str = "right", ext: str | None = None) -> Path:
    """``model_dir/mano/MANO_RIGHT.<ext>`` (``side='left'``: ``MANO_LEFT``). With
    ``ext=None`` the first existing of ``pkl``, ``npz`` is taken. Raises
    FileNotFoundError naming every path tried."""
    s = _check_side(side)
    folder = Path(model_dir).expanduser() / "mano"
    exts = ("pkl", "npz") if ext is None else (_check_ext(ext),)
    tried = [folder / f"{_FILE_NAME[s]}.{e}" for e in exts]
    return first_file(tried, f"MANO {s} hand",
                      "Download MANO yourself from https://mano.is.tue.mpg.de (it is licensed) and pass the folder "
                      "that contains 'mano/', or write the license-free proxy with "
                      "hoibench.bodies.proxy_hand.write_proxy_mano(model_dir).")


def load_mano_model(model_dir, side: str = "right", ext: str | None = None, **kwargs):
    """``smplx``'s MANO for ``model_dir/mano/MANO_<SIDE>.<ext>`` (real or proxy files).

    Defaults ``use_pca=False, flat_hand_mean=True`` (45-D axis-angle finger pose, zero =
    flat hand), as :func:`hoibench.bodies.load_body_model` uses for SMPL-H hands; ``kwargs``
    override them and are passed on (``num_pca_comps``, ``dtype``, ``batch_size``...).
    Real MANO ``.pkl`` files contain ``chumpy`` objects: unpickling them needs ``chumpy``.
    ``.pkl`` files are unpickled by ``smplx``: load only files you made or downloaded yourself.
    """
    from .smpl import import_smplx

    s = _check_side(side)
    path = mano_model_path(model_dir, s, ext)
    smplx = import_smplx()
    opts = dict(kwargs)
    opts.setdefault("use_pca", False)
    opts.setdefault("flat_hand_mean", True)
    import contextlib

    with contextlib.redirect_stdout(io.StringIO()):  # smplx prints a notice about 10 betas
        return smplx.create(str(Path(model_dir).expanduser()), model_type="mano",
                            is_rhand=(s == "right"), ext=path.suffix[1:], **opts)


# --------------------------------------------------------------------------- forward pass
class ProxyHand:
    """Pure-numpy forward pass of the proxy hand (no ``smplx`` / ``torch`` needed).

    Reproduces ``smplx``'s MANO forward on the proxy files in float64:
    ``v_shaped = v_template + shapedirs . betas``, rest joints ``(1 + 0.05 b_0) J``, the
    finger chains posed from the wrist, ``v = G_j v_shaped + J_j - G_j rest_j`` for the joint
    ``j`` each vertex is rigid to, then ``+ transl``.

    Attributes: ``side``, ``v_template`` (778, 3), ``faces`` (F, 3), ``weights``
    (778, 16), ``shapedirs`` (778, 3, 10), ``parents`` (16,), ``rest_joints`` (16, 3),
    ``part_joint`` (778,) the joint each vertex is rigid to, ``tip_ids`` (5,) the finger-tip
    vertices in ``smplx``'s order (thumb, index, middle, ring, pinky).
    """

    def __init__(self, side: str = "right"):
        self.side = _check_side(side)
        arr = _build(self.side)
        self.v_template = arr["v_template"]
        self.faces = arr["f"]
        self.weights = arr["weights"]
        self.shapedirs = arr["shapedirs"]
        self.rest_joints = arr["J"]
        self.parents = np.array(MANO_PARENTS)
        self.part_joint = self.weights.argmax(1)
        self.tip_ids = np.array(list(MANO_TIP_VERTEX_IDS.values()))
        self._groups = [(j, np.flatnonzero(self.part_joint == j)) for j in range(MANO_NUM_JOINTS)]

    @property
    def num_vertices(self) -> int:
        return len(self.v_template)

    def forward(self, global_orient, hand_pose, betas=None, transl=None,
                tips: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Pose the hand.

        Args:
            global_orient: (T, 3) or (3,) axis-angle (radians) of the wrist.
            hand_pose: (T, k) or (k,), k <= 45: axis-angle of the 15 finger joints in MANO
                order, flat (zero-padded to 45; zero = flat hand). As the proxy's PCA basis
                is the identity with zero mean, ``smplx``'s ``use_pca=True`` coefficients
                (any ``num_pca_comps``) mean the same and may be passed as they are.
            betas: (k,) or (T, k), k <= 10; None = mean shape (only ``beta_0`` moves the
                proxy).
            transl: (T, 3) or (3,) metres; None = 0.
            tips: also return the 5 finger-tip vertices as joints 16-20 (thumb, index,
                middle, ring, pinky: what ``smplx``'s vertex joint selector appends).

        Returns:
            ``(vertices (T, 778, 3), joints (T, 16, 3))`` (``tips``: (T, 21, 3)), float64.
        """
        go = np.asarray(global_orient, dtype=np.float64)
        hp = np.asarray(hand_pose, dtype=np.float64)
        if go.ndim == 1:
            go = go[None]
        if hp.ndim == 1:
            hp = hp[None]
        if go.ndim != 2 or go.shape[1] != 3:
            raise ValueError(f"global_orient: expected shape (T, 3) or (3,), got {np.shape(global_orient)}")
        if hp.ndim != 2 or hp.shape[1] > MANO_POSE_DIM:
            raise ValueError(f"hand_pose: expected shape (T, k) or (k,) with k <= 45, got {np.shape(hand_pose)}")
        T = max(len(go), len(hp))
        if len(go) not in (1, T) or len(hp) not in (1, T):
            raise ValueError(f"global_orient and hand_pose disagree on T: {len(go)} vs {len(hp)}")
        pose = np.zeros((T, MANO_NUM_JOINTS * 3))
        pose[:, :3] = go
        pose[:, 3:3 + hp.shape[1]] = hp
        rots = axis_angle_to_matrix(pose.reshape(T, MANO_NUM_JOINTS, 3))  # (T, 16, 3, 3)
        transl = np.zeros((T, 3)) if transl is None else np.broadcast_to(np.asarray(transl, np.float64), (T, 3))

        if betas is None:
            b = np.zeros((T, MANO_NUM_BETAS))
        else:
            b = np.asarray(betas, dtype=np.float64)
            if b.ndim not in (1, 2) or b.shape[-1] > MANO_NUM_BETAS or (b.ndim == 2 and len(b) not in (1, T)):
                raise ValueError(f"betas: expected shape (k,) or (T, k) with k <= {MANO_NUM_BETAS}, got {b.shape}")
            b = np.broadcast_to(b, (T, b.shape[-1]))
        v_shaped = self.v_template + np.einsum("vck,tk->tvc", self.shapedirs[..., :b.shape[-1]], b)
        rest = self.rest_joints * (1.0 + PROXY_SCALE_PER_BETA * np.pad(b, ((0, 0), (0, 1)))[:, :1, None])

        G = np.empty_like(rots)
        Jp = np.empty((T, MANO_NUM_JOINTS, 3))
        G[:, 0] = rots[:, 0]
        Jp[:, 0] = rest[:, 0]
        for j in range(1, MANO_NUM_JOINTS):  # parents precede children
            p = self.parents[j]
            G[:, j] = G[:, p] @ rots[:, j]
            Jp[:, j] = (G[:, p] @ (rest[:, j] - rest[:, p])[..., None])[..., 0] + Jp[:, p]
        t = Jp - (G @ rest[..., None])[..., 0] + transl[:, None, :]
        v = np.empty((T, self.num_vertices, 3))
        for j, idx in self._groups:  # one-hot weights: rigid per joint
            v[:, idx] = v_shaped[:, idx] @ G[:, j].swapaxes(-1, -2) + t[:, j, None, :]
        joints = Jp + transl[:, None, :]
        if tips:
            joints = np.concatenate([joints, v[:, self.tip_ids]], 1)
        return v, joints

    __call__ = forward
