"""License-free GRAB fixtures: sequences in GRAB's exact file layout, with ground truth.

Writes what :mod:`hoibench.datasets.grab` reads (see its docstring for the facts and their
sources), posed with hoibench's proxy SMPL-X body and proxy MANO hands instead of the
licensed models, so the GRAB loader runs end to end in tests::

    OUT/grab/<subject>/<object>_<intent>[_<take>].npz   one sequence: 0-d entries gender,
        sbj_id, obj_name, motion_intent (str), framerate (float64), n_frames, n_comps
        (int64), and pickled dicts body / lhand / rhand {params, vtemp}, object {params,
        object_mesh}, table {params, table_mesh}, contact {body, object}; parameters
        float32 (GRAB's readers cast to float32; the release's dtype is not documented),
        contact labels int8 (``tools/utils.py`` ``contact_ids`` values, 0 = none)
    OUT/tools/subject_meshes/<gender>/<subject>{,_lhand,_rhand}.ply   the subject's SMPL-X
        and MANO templates: the proxies' templates scaled by ``1 + 0.05 beta`` (the
        proxies' beta_0), binary little-endian PLY, float32 vertices
    OUT/tools/object_meshes/contact_meshes/<object>.ply, table.ply   object meshes (not
        centred: an ellipsoid about an offset centre) and a box table
    OUT/body_models/smplx/SMPLX_<GENDER>.npz, OUT/body_models/mano/MANO_{RIGHT,LEFT}.pkl
        the proxy models (:func:`hoibench.bodies.write_proxy_model`,
        :func:`hoibench.bodies.proxy_hand.write_proxy_mano`)
    OUT/hoibench_gt/<subject>_<stem>.npz   ground truth in hoibench's y-up world (not GRAB)
    OUT/hoibench_synthetic.json            the manifest

Conventions the writer follows (GRAB's): the world is z-up, metres, 120 fps; the body is
SMPL-X posed with ``v_template`` = the subject mesh and ``n_comps`` hand PCA coefficients
(``flat_hand_mean=False``); the hands MANO with ``flat_hand_mean=True``; objects are posed
as row vectors, ``v @ R(global_orient) + transl``. The proxies' hand PCA bases are the
identity with zero mean, so ``fullpose`` is the PCA pose zero-padded to 45 per hand.

The ground truth is computed without the loader and without ``smplx``: joints with the
numpy forwards :class:`~hoibench.bodies.proxy.ProxyBody` (22 SMPL-X body joints, every
vertex for the floor) and :class:`~hoibench.bodies.proxy_hand.ProxyHand` (16 joints + 5
tips), object and table vertices from the generating rotation and translation (column
vectors), all mapped to y-up by ``(x, y, z) -> (x, z, -y)`` and shifted so the lowest body
vertex over all frames is at y = 0. Contacts are the authored per-frame flags.

Every file is byte-identical for the same arguments (fixed zip timestamps, deterministic
pickles and PLY bytes) with one numpy version (pickles name numpy's modules).
"""
from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

import numpy as np

from ..core import geometry as geo
from ..core.io import atomic_write_bytes, atomic_write_text, npz_bytes

__all__ = ["SOURCE_FPS", "N_COMPS", "GT_DIR", "BODY_MODELS", "SUBJECT_GENDER", "grab_npz_bytes", "ply_bytes",
           "subject_beta", "write_subject_meshes", "write_grab_sequence", "ground_truth", "write_grab_layout"]

SOURCE_FPS = 120.0
N_COMPS = 24
GT_DIR = "hoibench_gt"
BODY_MODELS = "body_models"
#: GRAB's subjects: 5 male, 5 female (README); which is which as in public readers.
SUBJECT_GENDER = {**{s: "male" for s in ("s1", "s2", "s8", "s9", "s10")},
                  **{s: "female" for s in ("s3", "s4", "s5", "s6", "s7")}}
#: subjects cycled by :func:`write_grab_layout`: train, val (s1), test (s10), ...
_SUBJECT_ORDER = ("s2", "s1", "s10", "s5", "s3", "s8", "s6", "s9", "s4", "s7")
_OBJECTS = {"cubesmall": (0.03, 0.03, 0.03), "mug": (0.045, 0.045, 0.06), "apple": (0.04, 0.04, 0.038),
            "duck": (0.05, 0.035, 0.04)}
_INTENTS = ("lift", "pass", "inspect")
_F = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])     # z-up -> y-up
_MESH_OFFSET = np.array([0.01, -0.02, 0.015])
_TABLE_TOP = 0.75
_R_HAND_SET = (22, 43, 53)
_L_HAND_SET = (21, 28)
_R_FOREARM = 20
_SMPLX_VERTICES = 10475


# --------------------------------------------------------------------------- file bytes
def grab_npz_bytes(entries: dict) -> bytes:
    """An ``.npz`` as GRAB stores a sequence: one member per key, each a 0-d array (a dict is
    a pickled 0-d object array, a string a 0-d unicode array, a number a 0-d float/int
    array), deflated, with fixed timestamps (byte-reproducible)."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for key, value in entries.items():
            if isinstance(value, dict):
                arr = np.empty((), dtype=object)
                arr[()] = value
            else:
                arr = np.asarray(value)
            member = io.BytesIO()
            np.save(member, arr, allow_pickle=arr.dtype.hasobject)
            info = zipfile.ZipInfo(f"{key}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            zf.writestr(info, member.getvalue())
    return buf.getvalue()


def ply_bytes(vertices: np.ndarray, faces: np.ndarray, comment: str = "hoibench synthetic GRAB layout") -> bytes:
    """Binary little-endian PLY: float32 vertices, triangles as ``uchar 3`` + 3 ``int``."""
    v = np.ascontiguousarray(vertices, dtype="<f4")
    f = np.asarray(faces, dtype=np.int64)
    head = (f"ply\nformat binary_little_endian 1.0\ncomment {comment}\nelement vertex {len(v)}\n"
            "property float x\nproperty float y\nproperty float z\n"
            f"element face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n").encode("ascii")
    rec = np.zeros(len(f), dtype=np.dtype([("n", "u1"), ("i", "<i4", (3,))]))
    rec["n"], rec["i"] = 3, f
    return head + v.tobytes() + rec.tobytes()


def _f32(x) -> np.ndarray:
    return np.ascontiguousarray(x, dtype=np.float32)


# --------------------------------------------------------------------------- subjects
def subject_beta(subject: str) -> float:
    """The proxies' ``beta_0`` of a synthetic subject (``s<k>``), in -0.8..0.8."""
    k = int(str(subject).lstrip("s"))
    return round(((k * 7) % 9 - 4) / 5.0, 2)


def _subject_templates(beta: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    from ..bodies.proxy import PROXY_SCALE_PER_BETA, ProxyBody
    from ..bodies.proxy_hand import ProxyHand
    s = 1.0 + PROXY_SCALE_PER_BETA * float(beta)
    body = ProxyBody("smplx")
    out = {"": (body.v_template * s, body.faces)}
    for side, suffix in (("left", "_lhand"), ("right", "_rhand")):
        h = ProxyHand(side)
        out[suffix] = (h.v_template * s, h.faces)
    return out


def write_subject_meshes(root: str | Path, subject: str, gender: str, beta: float) -> list[Path]:
    """``tools/subject_meshes/<gender>/<subject>{,_lhand,_rhand}.ply``: the proxy SMPL-X and
    MANO templates scaled as ``beta_0 = beta`` scales them."""
    folder = Path(root) / "tools" / "subject_meshes" / gender
    return [atomic_write_bytes(folder / f"{subject}{suffix}.ply",
                               ply_bytes(v, f, f"hoibench proxy template, beta_0 {beta:g}"))
            for suffix, (v, f) in _subject_templates(beta).items()]


def _write_models(root: Path, gender: str) -> None:
    from ..bodies.proxy import write_proxy_model
    from ..bodies.proxy_hand import write_proxy_mano
    models = root / BODY_MODELS
    if not (models / "smplx" / f"SMPLX_{gender.upper()}.npz").exists():
        write_proxy_model(models, "smplx", genders=(gender,))
    if not (models / "mano" / "MANO_RIGHT.pkl").exists() or not (models / "mano" / "MANO_LEFT.pkl").exists():
        write_proxy_mano(models)


# --------------------------------------------------------------------------- one sequence
def _body_params(p: dict, T: int, n_comps: int) -> dict:
    """GRAB's body params (float32), missing ones zero, ``fullpose`` = root, body, jaw,
    eyes, then each hand's PCA pose as axis-angle with the proxy's identity basis."""
    def get(k, w):
        return np.asarray(p[k], np.float64).reshape(T, w) if k in p else np.zeros((T, w))
    out = {"transl": get("transl", 3), "global_orient": get("global_orient", 3), "body_pose": get("body_pose", 63),
           "jaw_pose": get("jaw_pose", 3), "leye_pose": get("leye_pose", 3), "reye_pose": get("reye_pose", 3),
           "left_hand_pose": get("left_hand_pose", n_comps), "right_hand_pose": get("right_hand_pose", n_comps)}
    pad = np.zeros((T, 45 - n_comps))
    out["fullpose"] = (np.asarray(p["fullpose"], np.float64) if "fullpose" in p else np.concatenate(
        [out[k] for k in ("global_orient", "body_pose", "jaw_pose", "leye_pose", "reye_pose")]
        + [out["left_hand_pose"], pad, out["right_hand_pose"], pad], 1))
    out["expression"] = get("expression", np.asarray(p["expression"]).shape[-1]) if "expression" in p \
        else np.zeros((T, 10))
    return {k: _f32(v) for k, v in out.items()}


def _hand_params(p: dict, T: int, n_comps: int) -> dict:
    hp = np.asarray(p["hand_pose"], np.float64).reshape(T, n_comps)
    return {"global_orient": _f32(np.asarray(p["global_orient"]).reshape(T, 3)), "hand_pose": _f32(hp),
            "transl": _f32(np.asarray(p["transl"]).reshape(T, 3)),
            "fullpose": _f32(p["fullpose"] if "fullpose" in p else np.pad(hp, ((0, 0), (0, 45 - n_comps))))}


def write_grab_sequence(root: str | Path, subject: str, object_name: str, intent: str, take: int | None, fps: float,
                        body_params: dict, rhand_params: dict, lhand_params: dict, object_pose: dict,
                        object_mesh: tuple[np.ndarray, np.ndarray], table_pose: dict | None = None,
                        contacts: dict | None = None, gender: str = "male", *, beta: float | None = None,
                        table_mesh: tuple[np.ndarray, np.ndarray] | None = None, n_comps: int = N_COMPS,
                        body_models: bool = True) -> Path:
    """Write one sequence ``grab/<subject>/<object>_<intent>[_<take>].npz`` exactly as GRAB
    stores it, the meshes it references (subject templates from the proxies scaled by
    ``beta``, default :func:`subject_beta`; the object's ``object_mesh`` (V, F); the table's
    ``table_mesh`` when ``table_pose`` is given, default a box) and, with ``body_models``,
    the proxy models under ``body_models/`` when missing.

    ``body_params``: GRAB's ``body/params`` keys ((T, 3) ``transl``, ``global_orient``,
    (T, 63) ``body_pose``; optional jaw/eye poses, (T, n_comps) hand PCA poses,
    ``expression``; missing ones are zero, ``fullpose`` is built). ``rhand_params`` /
    ``lhand_params``: ``global_orient``, ``hand_pose`` (T, n_comps), ``transl``.
    ``object_pose`` / ``table_pose``: GRAB's ``global_orient`` and ``transl`` (row-vector
    convention). ``contacts``: ``{"object": (T, V), "body": (T, 10475)}`` labels (zero when
    absent). Returns the path of the ``.npz``.
    """
    root = Path(root)
    T = int(np.asarray(body_params["transl"]).shape[0])
    beta = subject_beta(subject) if beta is None else float(beta)
    stem = f"{object_name}_{intent}" + (f"_{take}" if take is not None else "")
    sm = f"tools/subject_meshes/{gender}/{subject}"
    write_subject_meshes(root, subject, gender, beta)
    ov, of = object_mesh
    atomic_write_bytes(root / "tools" / "object_meshes" / "contact_meshes" / f"{object_name}.ply",
                       ply_bytes(ov, of, f"hoibench synthetic object {object_name}"))
    labels_obj = np.zeros((T, len(ov)), np.int8) if not contacts or "object" not in contacts else \
        np.asarray(contacts["object"]).astype(np.int8)
    labels_body = np.zeros((T, _SMPLX_VERTICES), np.int8) \
        if not contacts or "body" not in contacts else np.asarray(contacts["body"]).astype(np.int8)
    entries = {
        "gender": gender, "sbj_id": subject, "obj_name": object_name, "motion_intent": intent,
        "framerate": np.float64(fps), "n_frames": np.int64(T), "n_comps": np.int64(n_comps),
        "body": {"params": _body_params(body_params, T, n_comps), "vtemp": f"{sm}.ply"},
        "lhand": {"params": _hand_params(lhand_params, T, n_comps), "vtemp": f"{sm}_lhand.ply"},
        "rhand": {"params": _hand_params(rhand_params, T, n_comps), "vtemp": f"{sm}_rhand.ply"},
        "object": {"params": {"transl": _f32(object_pose["transl"]),
                              "global_orient": _f32(object_pose["global_orient"])},
                   "object_mesh": f"tools/object_meshes/contact_meshes/{object_name}.ply"},
    }
    if table_pose is not None:
        tv, tf = table_mesh if table_mesh is not None else _box((1.2, 0.7, _TABLE_TOP))
        atomic_write_bytes(root / "tools" / "object_meshes" / "contact_meshes" / "table.ply",
                           ply_bytes(tv, tf, "hoibench synthetic table"))
        entries["table"] = {"params": {"transl": _f32(table_pose["transl"]),
                                       "global_orient": _f32(table_pose["global_orient"])},
                            "table_mesh": "tools/object_meshes/contact_meshes/table.ply"}
    entries["contact"] = {"body": labels_body, "object": labels_obj}
    path = atomic_write_bytes(root / "grab" / subject / f"{stem}.npz", grab_npz_bytes(entries))
    if body_models:
        _write_models(root, gender)
    return path


# --------------------------------------------------------------------------- ground truth
def ground_truth(body_params: dict, lhand_params: dict, rhand_params: dict, beta: float,
                 rigid: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]], n_comps: int = N_COMPS) -> dict:
    """Joints and vertices in hoibench's y-up world, computed with the numpy proxies (no
    ``smplx``, no loader code): ``human_joints`` (T, 22, 3), ``left_hand_joints`` /
    ``right_hand_joints`` (T, 21, 3), ``<name>_vertices`` (T, V, 3) for each ``rigid[name]
    = (vertices (V, 3), rotation (T, 3, 3) acting on column vectors, translation (T, 3))``
    and ``floor_shift_m`` (the lowest body vertex over all frames, z-up, before the shift).
    The parameters are GRAB's as written (float32), read back as float64."""
    from ..bodies.proxy import ProxyBody
    from ..bodies.proxy_hand import ProxyHand
    bp = _body_params(body_params, len(np.asarray(body_params["transl"])), n_comps)
    T = len(bp["transl"])
    pad = np.zeros((T, 45 - n_comps))
    pose = np.concatenate([bp[k].astype(np.float64) for k in ("global_orient", "body_pose", "jaw_pose", "leye_pose",
                                                              "reye_pose")]
                          + [bp["left_hand_pose"].astype(np.float64), pad, bp["right_hand_pose"].astype(np.float64),
                             pad], 1).reshape(T, 55, 3)
    verts, joints = ProxyBody("smplx").forward(pose, bp["transl"].astype(np.float64), betas=[beta])
    floor = float(verts[..., 2].min())

    def to_world(x):
        y = np.asarray(x, np.float64) @ _F.T
        y[..., 1] -= floor
        return y

    out = {"floor_shift_m": np.float64(floor), "human_joints": to_world(joints)}
    for side, p in (("left", lhand_params), ("right", rhand_params)):
        hp = _hand_params(p, T, n_comps)
        _, hj = ProxyHand(side).forward(hp["global_orient"].astype(np.float64), hp["fullpose"].astype(np.float64),
                                        betas=[beta], transl=hp["transl"].astype(np.float64), tips=True)
        out[f"{side}_hand_joints"] = to_world(hj)
    for name, (v, R, t) in rigid.items():
        out[f"{name}_vertices"] = to_world(np.einsum("tij,vj->tvi", R, np.asarray(v, np.float64)) + t[:, None])
    return out


# --------------------------------------------------------------------------- motions
def _ease(x) -> np.ndarray:
    x = np.clip(np.asarray(x, np.float64), 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * x)


def _smooth(rng, T: int, dims: int, amp: float) -> np.ndarray:
    """(T, dims) sums of three slow sinusoids (0.3-1.5 Hz at 120 fps), deterministic in ``rng``."""
    t = np.arange(T)[:, None] / SOURCE_FPS
    out = np.zeros((T, dims))
    for _ in range(3):
        f = rng.uniform(0.3, 1.5, dims)
        ph = rng.uniform(0.0, 2 * np.pi, dims)
        a = rng.uniform(0.3, 1.0, dims)
        out += a * np.sin(2 * np.pi * f * t + ph)
    return amp * out / 3.0


def _rz(a) -> np.ndarray:
    a = np.asarray(a, np.float64)
    c, s = np.cos(a), np.sin(a)
    R = np.zeros(a.shape + (3, 3))
    R[..., 0, 0], R[..., 0, 1], R[..., 1, 0], R[..., 1, 1], R[..., 2, 2] = c, -s, s, c, 1.0
    return R


def _rx(a) -> np.ndarray:
    a = np.asarray(a, np.float64)
    c, s = np.cos(a), np.sin(a)
    R = np.zeros(a.shape + (3, 3))
    R[..., 0, 0], R[..., 1, 1], R[..., 1, 2], R[..., 2, 1], R[..., 2, 2] = 1.0, c, -s, s, c
    return R


def _ellipsoid(radii, n_lat: int = 6, n_lon: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """A UV ellipsoid about :data:`_MESH_OFFSET` (not centred, as GRAB's meshes need not be)."""
    rx, ry, rz = radii
    verts = [(0.0, 0.0, rz)]
    for i in range(1, n_lat):
        th = np.pi * i / n_lat
        for j in range(n_lon):
            ph = 2 * np.pi * j / n_lon
            verts.append((rx * np.sin(th) * np.cos(ph), ry * np.sin(th) * np.sin(ph), rz * np.cos(th)))
    verts.append((0.0, 0.0, -rz))
    V = np.array(verts) + _MESH_OFFSET
    faces = [(0, 1 + j, 1 + (j + 1) % n_lon) for j in range(n_lon)]
    for i in range(n_lat - 2):
        a, b = 1 + i * n_lon, 1 + (i + 1) * n_lon
        for j in range(n_lon):
            k = (j + 1) % n_lon
            faces += [(a + j, b + j, b + k), (a + j, b + k, a + k)]
    last, base = len(V) - 1, 1 + (n_lat - 2) * n_lon
    faces += [(base + j, last, base + (j + 1) % n_lon) for j in range(n_lon)]
    return V, np.array(faces, dtype=np.int64)


def _box(size) -> tuple[np.ndarray, np.ndarray]:
    """A table: a box ``sx`` x ``sy`` centred on x, y, from z = 0 to z = ``sz``."""
    sx, sy, sz = size
    V = np.array([[x, y, z] for z in (0.0, sz) for y in (-sy / 2, sy / 2) for x in (-sx / 2, sx / 2)])
    F = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                  [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]])
    return V, F


def _sequence(i: int, seed: int) -> dict:
    """The i-th synthetic sequence: a right hand reaching for an object on a table and
    lifting it (``pass``: the left hand takes it over at the end), the body standing."""
    from ..bodies.proxy import PROXY_SCALE_PER_BETA, ProxyBody
    from ..bodies.proxy_hand import PROXY_MANO_WRIST
    rng = np.random.default_rng([int(seed), int(i)])
    subject = _SUBJECT_ORDER[i % len(_SUBJECT_ORDER)]
    gender = SUBJECT_GENDER[subject]
    beta = subject_beta(subject)
    obj = list(_OBJECTS)[i % len(_OBJECTS)]
    intent = _INTENTS[i % len(_INTENTS)]
    T = 97 + 8 * (i % 4)
    t = np.arange(T)
    g = int(0.45 * T)                       # grasp frame
    scale = 1.0 + PROXY_SCALE_PER_BETA * beta

    # body: standing (model y-up turned z-up by Rx(+90 deg)), facing -y, arms down
    yaw = rng.uniform(-0.3, 0.3) + _smooth(rng, T, 1, 0.05)[:, 0]
    body_go = geo.matrix_to_axis_angle(_rz(yaw) @ _rx(np.pi / 2))
    body_pose = _smooth(rng, T, 63, 0.08)
    body_pose[:, 47] -= 1.2                 # left shoulder (joint 16) down
    body_pose[:, 50] += 1.2                 # right shoulder (joint 17) down
    transl = np.zeros((T, 3))
    transl[:, :2] = rng.uniform(-0.05, 0.05, 2) + _smooth(rng, T, 2, 0.02)
    body = {"global_orient": body_go, "body_pose": body_pose, "transl": transl,
            "jaw_pose": _smooth(rng, T, 3, 0.05), "leye_pose": _smooth(rng, T, 3, 0.05),
            "reye_pose": _smooth(rng, T, 3, 0.05), "left_hand_pose": _smooth(rng, T, N_COMPS, 0.2),
            "right_hand_pose": _smooth(rng, T, N_COMPS, 0.2), "expression": _smooth(rng, T, 10, 0.3)}
    pose = np.concatenate([body_go, body_pose], 1).reshape(T, 22, 3)
    v0, _ = ProxyBody("smplx").forward(pose, transl, betas=[beta])
    transl[:, 2] = -float(v0[..., 2].min()) + 0.004          # feet just above z = 0

    # object on the table, lifted (and turned) by the right hand after the grasp
    V, Fc = _ellipsoid(_OBJECTS[obj])
    V = V.astype(np.float32).astype(np.float64)               # as written to the PLY
    rest = np.array([rng.uniform(-0.25, -0.05), -0.5 + rng.uniform(-0.05, 0.05), _TABLE_TOP + _OBJECTS[obj][2]])
    u = _ease((t - g) / max(1, T - 1 - g))
    Q = _rz(rng.uniform(-np.pi, np.pi) + 0.4 * u) @ _rx(rng.uniform(-0.1, 0.1))
    lift = np.stack([np.zeros(T), 0.05 * u, 0.18 * u], 1)
    o_t = rest - Q[0] @ _MESH_OFFSET + lift
    obj_pose = {"global_orient": geo.matrix_to_axis_angle(Q.swapaxes(-1, -2)), "transl": o_t}   # GRAB: v @ R + t

    # right hand: palm down, fingers forward (-y), reaching then carrying
    R_r = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    w_start = np.array([-0.25, -0.1, 0.85]) + rng.uniform(-0.03, 0.03, 3)
    w_grasp = rest + np.array([0.0, 0.09, 0.03])
    w = w_start + (w_grasp - w_start) * _ease(t / g)[:, None]
    w[t >= g] = w_grasp + lift[t >= g]
    wob = _smooth(rng, T, 3, 0.05)
    r_go = geo.matrix_to_axis_angle(geo.axis_angle_to_matrix(wob) @ R_r)
    r_hp = _smooth(rng, T, N_COMPS, 0.15)
    r_hp[:, [2, 5, 8, 11]] += 0.5 * _ease((t - g + 12) / 12.0)[:, None]      # fingers close at the grasp
    wrist0 = scale * np.array(PROXY_MANO_WRIST)
    rhand = {"global_orient": r_go, "hand_pose": r_hp, "transl": w - wrist0}

    # left hand: fingers down by the left side; "pass": takes the object over at the end
    R_l = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])
    wl = np.array([0.25, -0.1, 0.85]) + _smooth(rng, T, 3, 0.02)
    h = int(0.7 * T)
    obj_pos = rest + lift
    R_lt = np.repeat(R_l[None], T, 0)
    if intent == "pass":                    # turn palm down, fingers forward, and reach the object
        k = _ease((t - h) / max(1, T - 1 - h))
        wl = wl + (obj_pos + np.array([0.0, 0.09, 0.03]) - wl) * k[:, None]
        turn = geo.matrix_to_axis_angle(R_l.T @ np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]))
        R_lt = R_l @ geo.axis_angle_to_matrix(k[:, None] * turn)
    l_go = geo.matrix_to_axis_angle(geo.axis_angle_to_matrix(_smooth(rng, T, 3, 0.05)) @ R_lt)
    lhand = {"global_orient": l_go, "hand_pose": _smooth(rng, T, N_COMPS, 0.15),
             "transl": wl - wrist0 * np.array([-1.0, 1.0, 1.0])}

    # table: a box, static
    tv, tf = _box((1.2, 0.7, _TABLE_TOP))
    Qt = np.repeat(_rz(rng.uniform(-0.05, 0.05))[None], T, 0)
    t_t = np.repeat(np.array([rest[0], -0.55, 0.0])[None], T, 0)
    table_pose = {"global_orient": geo.matrix_to_axis_angle(Qt.swapaxes(-1, -2)), "transl": t_t}

    # contacts (authored): object vertices facing the hand carry hand-part labels
    local = V - _MESH_OFFSET
    side_r = np.flatnonzero((local[:, 1] > 0) & (local[:, 0] <= 0))
    side_l = np.flatnonzero((local[:, 1] > 0) & (local[:, 0] > 0))
    right = t >= g
    left = np.zeros(T, bool)
    if intent == "pass":
        right &= t < int(0.85 * T)
        left = t >= int(0.8 * T)
    forearm = (t >= g - 6) & (t < g)                          # the forearm brushes it first
    lab_o = np.zeros((T, len(V)), np.int8)
    lab_o[np.ix_(forearm, side_r[:2])] = _R_FOREARM
    for k, vid in enumerate(side_r):
        lab_o[right, vid] = _R_HAND_SET[k % len(_R_HAND_SET)]
    for k, vid in enumerate(side_l):
        lab_o[left, vid] = _L_HAND_SET[k % len(_L_HAND_SET)]
    part = ProxyBody("smplx").part_joint
    lab_b = np.zeros((T, len(part)), np.int8)
    lab_b[np.ix_(right | forearm, np.flatnonzero(np.isin(part, [19, 21] + list(range(40, 55)))))] = 1
    lab_b[np.ix_(left, np.flatnonzero(np.isin(part, [20] + list(range(25, 40)))))] = 1
    human = right | left | forearm
    return {"subject": subject, "gender": gender, "beta": beta, "object": obj, "intent": intent,
            "take": None if intent == "lift" else 1, "T": T, "body": body, "rhand": rhand, "lhand": lhand,
            "object_pose": obj_pose, "object_mesh": (V, Fc), "object_rigid": (V, Q, o_t),
            "table_pose": table_pose, "table_mesh": (tv, tf), "table_rigid": (tv.astype(np.float32), Qt, t_t),
            "contacts": {"object": lab_o, "body": lab_b},
            "truth": {"contact_right": right, "contact_left": left, "contact_human": human}}


def write_grab_layout(root: str | Path, n_sequences: int = 3, seed: int = 0) -> dict:
    """Write ``n_sequences`` deterministic synthetic sequences in GRAB's layout under
    ``root`` (see the module docstring): subjects cycle s2, s1, s10, ... (IMoS's train, val,
    test), objects cubesmall / mug / apple / duck, intents lift / pass / inspect, 97-121
    frames at 120 fps, every sequence with a table. Ground truth goes to
    ``root/hoibench_gt/<clip id>.npz``: ``human_joints``, ``left_hand_joints``,
    ``right_hand_joints``, ``object_vertices``, ``table_vertices``, ``contact_right``,
    ``contact_left``, ``contact_human``, ``floor_shift_m``, ``fps``. Byte-identical for the
    same arguments. Returns the manifest (also ``root/hoibench_synthetic.json``)."""
    root = Path(root)
    entries, used = [], set()
    for i in range(int(n_sequences)):
        s = _sequence(i, seed)
        take = s["take"]
        stem = f"{s['object']}_{s['intent']}" + (f"_{take}" if take is not None else "")
        while (s["subject"], stem) in used:                   # never overwrite an earlier sequence
            take = (take or 0) + 1
            stem = f"{s['object']}_{s['intent']}_{take}"
        used.add((s["subject"], stem))
        path = write_grab_sequence(root, s["subject"], s["object"], s["intent"], take, SOURCE_FPS, s["body"],
                                   s["rhand"], s["lhand"], s["object_pose"], s["object_mesh"], s["table_pose"],
                                   s["contacts"], s["gender"], beta=s["beta"], table_mesh=s["table_mesh"])
        cid = f"{s['subject']}_{path.stem}"
        gt = ground_truth(s["body"], s["lhand"], s["rhand"], s["beta"],
                          {"object": s["object_rigid"], "table": s["table_rigid"]})
        gt.update({k: np.asarray(v, bool) for k, v in s["truth"].items()})
        gt.update(fps=np.float64(SOURCE_FPS), clip_id=np.array(cid), object_name=np.array(s["object"]))
        atomic_write_bytes(root / GT_DIR / f"{cid}.npz", npz_bytes(gt))
        entries.append({"clip_id": cid, "file": path.relative_to(root).as_posix(), "subject": s["subject"],
                        "gender": s["gender"], "beta": s["beta"], "object": s["object"], "intent": s["intent"],
                        "frames": s["T"], "fps": SOURCE_FPS, "split_imos": {"s1": "val", "s10": "test"}.get(
                            s["subject"], "train"), "floor_shift_m": float(gt["floor_shift_m"])})
    manifest = {"dataset": "synthetic", "layout": "grab", "seed": int(seed), "n_sequences": int(n_sequences),
                "fps": SOURCE_FPS, "body_models": BODY_MODELS,
                "world": "files: GRAB's z-up world; ground truth: hoibench's y-up world, p_yup = (x, z, -y), "
                         "y -= floor_shift_m (lowest proxy SMPL-X vertex over all frames)",
                "sequences": entries}
    atomic_write_text(root / "hoibench_synthetic.json", json.dumps(manifest, indent=2, sort_keys=True) + "\n")
    return manifest
