"""License-free sequences in CORE4D-Real's release layout, with ground truth.

:func:`write_core4d_layout` writes a few deterministic two-person box-carrying sequences
exactly as CORE4D-Real lays out its release (the facts and their sources are in
:mod:`hoibench.datasets.core4d`), so :func:`hoibench.datasets.core4d.prepare_jobs` runs
end to end without licensed files, and the output can be checked against ground truth
computed here with the proxy body's own numpy forward pass (:class:`~hoibench.bodies.proxy.
ProxyBody`), never with ``smplx`` or the loader. Every file is byte-identical for the same
arguments (fixed zip timestamps; ``numpy.savez`` would stamp the current time)::

    OUT/CORE4D_Real/human_object_motions/<date>/<seq>/person{1,2}_poses.npz
        np.savez of one dict (member arr_0, a pickled 0-d object array) with CORE4D's keys:
        vertices (T, 10475, 3), joints (T, 127, 3), betas (T, 10), expression (T, 10),
        global_orient (T, 3), transl (T, 3), body_pose (T, 21, 3), left_hand_pose /
        right_hand_pose (T, 12) PCA coefficients -- float32; vertices and joints[:, :22] are
        the proxy body's (joints[:, 22:] are zeros: the proxy's numpy forward gives the 22
        body joints only)
    OUT/CORE4D_Real/human_object_motions/<date>/<seq>/smooth_objposes.npy   (T, 4, 4) float64
    OUT/CORE4D_Real/human_object_motions/<date>/<seq>/object_metadata.json  {"obj_name", "obj_model_path"}
    OUT/CORE4D_Real/human_object_motions/<date>/<seq>/aligned_frame_ids.txt
        one line per frame: RGB camera 1-4 frame ids and person 1, person 2, object mocap
        frame ids (90 fps mocap: 6 per 15 fps frame)
    OUT/CORE4D_Real/object_models/box/<name>_m.obj   a box with its origin at the centre of
        its base (not centred: its vertex mean is not the origin)
    OUT/CORE4D_Real/action_labels.json               {"<date>/<seq>": label}
    OUT/hoibench_gt/<date>.<seq>.npz + .json          ground truth in hoibench's world
    OUT/body_models/smplx/SMPLX_{MALE,FEMALE,NEUTRAL}.npz   the proxy body (SMPL-X structure)
    OUT/hoibench_synthetic.json                        the manifest

The world is CORE4D's: y-up metres, the floor at y = 0.011-0.026 (a small offset, so the
loader's floor shift is exercised). Two people face each other across a box (person 1 at
z = -0.6 facing +z, person 2 at z = +0.6 facing -z, SMPL-X's rest facing being +z) and
side-step along +x carrying it, arms forward, legs swinging, the box bobbing and yawing a
little: smooth at 15 fps. Ground truth (``hoibench_gt``): each person's 22 joints and the
object's posed vertices (the mesh file's vertex order) at the source frames, y shifted so
the lowest proxy vertex of either person is at y = 0 -- the convention the loader
documents. The proxy's hand components are the identity, so the 12 PCA coefficients are
the first 12 axis-angle hand components.

Sequence names are real CORE4D names, so the official split applies: ``20231002.004``
(train), ``20231002.001`` (test, seen object), ``20231002.009`` (test, unseen object),
``20231003_1.000`` (train), ``20231008.035`` (test, unseen), ``20231108.0-1`` (test, seen).
"""
from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

import numpy as np

from ..core import geometry as geo
from ..bodies.proxy import ProxyBody, write_proxy_model
from ..core.io import atomic_write_bytes, atomic_write_text, npz_bytes

__all__ = ["SOURCE_FPS", "SEQUENCES", "BOXES", "person_file_bytes", "box_mesh", "sequence_params",
           "ground_truth", "write_sequence", "write_core4d_layout"]

SOURCE_FPS = 15.0
#: (date, take, object, action label or None) of the sequences written, in order.
SEQUENCES = (
    ("20231002", "004", "box001", "move1"),
    ("20231002", "001", "box004", "raise_rot"),
    ("20231002", "009", "box001", None),
    ("20231003_1", "000", "box004", "pass1"),
    ("20231008", "035", "box001", "move2"),
    ("20231108", "0-1", "box004", "rot"),
)
#: box name -> (width x, height y, depth z), metres.
BOXES = {"box001": (0.60, 0.40, 0.42), "box004": (0.50, 0.32, 0.36)}
_NUM_JOINTS_FILE = 127
_ZIP_TIME = (1980, 1, 1, 0, 0, 0)


# --------------------------------------------------------------------------- files
def person_file_bytes(params: dict) -> bytes:
    """The bytes of a CORE4D person file: ``np.savez(path, params)`` (one uncompressed member
    ``arr_0.npy``, a pickled 0-d object array holding the dict), with fixed timestamps."""
    member = io.BytesIO()
    obj = np.empty((), dtype=object)
    obj[()] = params
    np.lib.format.write_array(member, obj, allow_pickle=True)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_STORED) as zf:
        info = zipfile.ZipInfo("arr_0.npy", date_time=_ZIP_TIME)
        info.compress_type = zipfile.ZIP_STORED
        info.external_attr = 0o644 << 16
        zf.writestr(info, member.getvalue())
    return buf.getvalue()


def _npy_bytes(array: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, np.asarray(array), allow_pickle=False)
    return buf.getvalue()


def _obj_text(vertices: np.ndarray, faces: np.ndarray, comment: str) -> str:
    lines = [f"# {comment}"]
    lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in np.asarray(vertices, np.float64).tolist()]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in np.asarray(faces, np.int64).tolist()]
    return "\n".join(lines) + "\n"


def box_mesh(size: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    """A closed box (width, height, depth) with its origin at the centre of its base, plus a
    vertex at the centre of its top and of its front (+z) face (fans of four triangles), so
    its vertex mean is neither the origin nor the box's centre. Outward triangles."""
    a, h, b = size[0] / 2, size[1], size[2] / 2
    v = [[x, y, z] for y in (0.0, h) for z in (-b, b) for x in (-a, a)]   # 0-3 bottom, 4-7 top
    v += [[0.0, h, 0.0], [0.0, h / 2, b]]                                 # 8 top centre, 9 front centre
    f = [[0, 1, 3], [0, 3, 2],                                            # bottom (y = 0, normal -y)
         [4, 6, 8], [6, 7, 8], [7, 5, 8], [5, 4, 8],                      # top fan (normal +y)
         [2, 3, 9], [3, 7, 9], [7, 6, 9], [6, 2, 9],                      # front fan (z = +b)
         [0, 4, 5], [0, 5, 1],                                            # back (z = -b)
         [0, 2, 6], [0, 6, 4],                                            # left (x = -a)
         [1, 5, 7], [1, 7, 3]]                                            # right (x = +a)
    return np.array(v, dtype=np.float64), np.array(f, dtype=np.int64)


def write_sequence(root: str | Path, date: str, seq: str, person1: dict, person2: dict, obj_poses: np.ndarray,
                   obj_name: str, vertices: np.ndarray, faces: np.ndarray,
                   aligned_frame_ids: np.ndarray | None = None) -> list[Path]:
    """Write one sequence in CORE4D-Real's layout under ``root`` (the ``CORE4D_Real``
    folder): both person files (each dict written as given, so a test can hand in a broken
    one), ``smooth_objposes.npy`` (``obj_poses`` as given), ``object_metadata.json``,
    ``aligned_frame_ids.txt`` (default: consecutive ids) and the object's mesh
    ``object_models/<category>/<obj_name>_m.obj``. Byte-identical for the same arguments.
    Returns the written paths."""
    root = Path(root)
    folder = root / "human_object_motions" / date / seq
    category = obj_name.lower()[:-3]
    paths = [atomic_write_bytes(folder / f"{p}_poses.npz", person_file_bytes(d))
             for p, d in (("person1", person1), ("person2", person2))]
    paths.append(atomic_write_bytes(folder / "smooth_objposes.npy", _npy_bytes(obj_poses)))
    meta = {"obj_name": obj_name, "obj_model_path": f"CORE4D_Real/object_models/{category}/{obj_name}_m.obj"}
    paths.append(atomic_write_text(folder / "object_metadata.json", json.dumps(meta)))
    T = len(obj_poses)
    if aligned_frame_ids is None:
        i = np.arange(T)
        aligned_frame_ids = np.stack([3 + i, 3 + i, 4 + i, 3 + i, 20 + 6 * i, 21 + 6 * i, 20 + 6 * i], 1)
    text = "".join(",".join(str(int(x)) for x in row) + "\n" for row in np.asarray(aligned_frame_ids))
    paths.append(atomic_write_text(folder / "aligned_frame_ids.txt", text))
    paths.append(atomic_write_text(root / "object_models" / category / f"{obj_name}_m.obj",
                                   _obj_text(vertices, faces, f"hoibench synthetic {obj_name} (CORE4D layout), "
                                                              "origin at the centre of the base, metres")))
    return paths


# --------------------------------------------------------------------------- motion
def _ry(angle: np.ndarray) -> np.ndarray:
    return geo.rotation_about_y(np.asarray(angle, np.float64))


def _rx(angle: np.ndarray) -> np.ndarray:
    return geo.rotation_about_x(np.asarray(angle, np.float64))


def _rz(angle: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    z, o = np.zeros_like(c), np.ones_like(c)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def _person(t: np.ndarray, side: int, x: np.ndarray, floor: float, rng: np.random.Generator,
            body: ProxyBody) -> dict:
    """One person's CORE4D parameters (float32) and the proxy's vertices/joints for them.
    ``side`` -1: person 1 at z = -0.6 facing +z; +1: person 2 at z = +0.6 facing -z."""
    T = len(t)
    w = 2 * np.pi * rng.uniform(1.0, 1.3)
    ph = rng.uniform(0, 2 * np.pi)
    betas = np.zeros(10)
    betas[0] = rng.uniform(-0.6, 0.6)
    betas[1:] = rng.normal(0.0, 0.5, 9)
    expression = rng.normal(0.0, 0.4, (T, 10))
    yaw = (0.0 if side < 0 else np.pi) + 0.08 * np.sin(0.6 * w * t + ph)
    go = geo.matrix_to_axis_angle(_ry(yaw) @ _rx(0.04 * np.sin(w * t + ph)))
    bp = np.zeros((T, 21, 3))
    swing = 0.2 * np.sin(w * t + ph)
    bp[:, 0, 0], bp[:, 1, 0] = swing, -swing                                    # hips (joints 1, 2)
    bp[:, 3, 0] = 0.15 + 0.08 * np.sin(w * t + ph + 0.5)                        # knees (4, 5)
    bp[:, 4, 0] = 0.15 - 0.08 * np.sin(w * t + ph + 0.5)
    bp[:, 2, 0] = 0.06 + 0.03 * np.sin(w * t)                                  # spine1 (3)
    bp[:, 14, 0] = 0.1 * np.sin(0.5 * w * t + ph)                              # head (15)
    lift = 0.1 * np.sin(w * t + ph + 1.0)
    bp[:, 15] = geo.matrix_to_axis_angle(_ry(-1.3 + 0.05 * lift) @ _rz(-0.75 + lift))   # left shoulder (16)
    bp[:, 16] = geo.matrix_to_axis_angle(_ry(1.3 - 0.05 * lift) @ _rz(0.75 - lift))     # right shoulder (17)
    bp[:, 17, 1] = -0.45 - 0.1 * lift                                          # elbows (18, 19)
    bp[:, 18, 1] = 0.45 + 0.1 * lift
    hands = 0.3 * np.sin(w * t[:, None] + rng.uniform(0, 2 * np.pi, (1, 24)))
    # pelvis: side-stepping along x with the box, feet near the floor
    rv, rest = body.forward(np.zeros((1, 55, 3)), None, betas)
    pelvis_h = float(rest[0, 0, 1] - rv[0, :, 1].min())
    pelvis = np.stack([x, floor + pelvis_h + 0.03 + 0.015 * np.cos(2 * w * t + ph), np.full(T, 0.6 * side)], 1)
    transl = pelvis - rest[0, 0]
    f32 = lambda a: np.asarray(a, dtype=np.float32)  # noqa: E731
    p = {"betas": f32(np.repeat(betas[None], T, 0)), "expression": f32(expression), "global_orient": f32(go),
         "transl": f32(transl), "body_pose": f32(bp), "left_hand_pose": f32(hands[:, :12]),
         "right_hand_pose": f32(hands[:, 12:])}
    verts, joints = body.forward(_pose55(p), p["transl"].astype(np.float64), p["betas"][0].astype(np.float64))
    full = np.zeros((T, _NUM_JOINTS_FILE, 3), np.float32)
    full[:, :22] = joints
    return {"vertices": f32(verts), "joints": full, **p}


def _pose55(p: dict) -> np.ndarray:
    """The proxy's (T, 55, 3) pose of CORE4D parameters: the proxy's hand components are
    the identity, so PCA coefficient k is axis-angle component k of the hand."""
    T = len(p["transl"])
    pose = np.zeros((T, 55, 3))
    pose[:, 0] = p["global_orient"]
    pose[:, 1:22] = np.asarray(p["body_pose"], np.float64).reshape(T, 21, 3)
    for sl, k in ((slice(25, 40), "left_hand_pose"), (slice(40, 55), "right_hand_pose")):
        h = np.zeros((T, 45))
        h[:, :12] = p[k]
        pose[:, sl] = h.reshape(T, 15, 3)
    return pose


def sequence_params(k: int, seed: int = 0, body: ProxyBody | None = None) -> dict:
    """Everything of sequence ``k`` of :data:`SEQUENCES`: ``date``, ``seq``, ``obj_name``,
    ``action``, ``person1`` / ``person2`` (CORE4D person dicts), ``obj_poses`` (T, 4, 4),
    ``vertices`` / ``faces`` (the mesh file's), ``floor`` (the world's floor height).
    Deterministic in ``(k, seed)``; T = 24 + 3 k frames at 15 fps."""
    date, seq, obj, action = SEQUENCES[k]
    body = body or ProxyBody("smplx")
    rng = np.random.default_rng([int(seed), 4041, int(k)])
    T = 24 + 3 * int(k)
    t = np.arange(T) / SOURCE_FPS
    floor = 0.011 + 0.003 * k
    x = rng.uniform(-1.0, 0.0) + rng.uniform(0.25, 0.45) * t
    p1 = _person(t, -1, x, floor, rng, body)
    p2 = _person(t, +1, x, floor, rng, body)
    verts, faces = box_mesh(BOXES[obj])
    w = 2 * np.pi * 1.1
    ph = rng.uniform(0, 2 * np.pi)
    R = _ry(0.12 * np.sin(0.7 * w * t + ph)) @ _rx(0.05 * np.sin(w * t))
    centre = np.stack([x + 0.02 * np.sin(w * t), floor + 0.95 + 0.02 * np.sin(w * t + ph),
                       0.02 * np.sin(0.5 * w * t)], 1)
    poses = np.zeros((T, 4, 4))
    poses[:, :3, :3] = R
    poses[:, :3, 3] = centre - R @ np.array([0.0, BOXES[obj][1] / 2, 0.0])
    poses[:, 3, 3] = 1.0
    return {"date": date, "seq": seq, "obj_name": obj, "action": action, "person1": p1, "person2": p2,
            "obj_poses": poses, "vertices": verts, "faces": faces, "floor": floor}


def ground_truth(params: dict, body: ProxyBody | None = None) -> dict[str, np.ndarray]:
    """Ground truth of :func:`sequence_params` output in hoibench's world, from the proxy's
    numpy forward pass of the parameters as stored (float32): ``person1_joints`` /
    ``person2_joints`` (T, 22, 3), ``object_vertices`` (T, V, 3) (``R v + t`` of the mesh
    file's vertices), ``times`` (T,) seconds, ``floor_shift_m``: y shifted so the lowest
    proxy vertex of either person over the frames is at 0 (CORE4D is y-up already)."""
    body = body or ProxyBody("smplx")
    out, low = {}, np.inf
    for p in ("person1", "person2"):
        d = params[p]
        v, j = body.forward(_pose55(d), np.asarray(d["transl"], np.float64), np.asarray(d["betas"][0], np.float64))
        out[f"{p}_joints"] = j
        low = min(low, float(v[..., 1].min()))
    P = np.asarray(params["obj_poses"], np.float64)
    ov = np.einsum("tij,vj->tvi", P[:, :3, :3], params["vertices"]) + P[:, None, :3, 3]
    for k in ("person1_joints", "person2_joints"):
        out[k][..., 1] -= low
    ov[..., 1] -= low
    out["object_vertices"] = ov
    out["times"] = np.arange(len(P)) / SOURCE_FPS
    out["floor_shift_m"] = np.float64(low)
    return out


# --------------------------------------------------------------------------- layout
def write_core4d_layout(root: str | Path, n_sequences: int = 3, seed: int = 0, body_model: bool = True) -> dict:
    """Write the first ``n_sequences`` of :data:`SEQUENCES` (at most six) in CORE4D-Real's
    layout under ``root/CORE4D_Real`` with ground truth in ``root/hoibench_gt`` and the
    proxy SMPL-X body in ``root/body_models`` (see the module docstring). Deterministic in
    ``(n_sequences, seed)``. Returns the manifest (also ``root/hoibench_synthetic.json``)."""
    n = int(n_sequences)
    if not 1 <= n <= len(SEQUENCES):
        raise ValueError(f"n_sequences: expected 1..{len(SEQUENCES)}, got {n_sequences!r}")
    root = Path(root)
    real = root / "CORE4D_Real"
    body = ProxyBody("smplx")
    labels, entries = {}, []
    for k in range(n):
        prm = sequence_params(k, seed, body)
        cid = f"{prm['date']}.{prm['seq']}"
        write_sequence(real, prm["date"], prm["seq"], prm["person1"], prm["person2"], prm["obj_poses"],
                       prm["obj_name"], prm["vertices"], prm["faces"])
        if prm["action"] is not None:
            labels[f"{prm['date']}/{prm['seq']}"] = prm["action"]
        gt = ground_truth(prm, body)
        atomic_write_bytes(root / "hoibench_gt" / f"{cid}.npz", npz_bytes(gt))
        meta = {"id": cid, "object": prm["obj_name"], "action": prm["action"], "frames": len(prm["obj_poses"]),
                "fps": SOURCE_FPS, "seed": [int(seed), int(k)], "floor_in_file_m": prm["floor"],
                "floor_shift_m": float(gt["floor_shift_m"]),
                "world": "ground truth in hoibench's y-up world: CORE4D's (y-up) with y -= floor_shift_m"}
        atomic_write_text(root / "hoibench_gt" / f"{cid}.json", json.dumps(meta, indent=2, sort_keys=True) + "\n")
        entries.append(meta)
    atomic_write_text(real / "action_labels.json", json.dumps(labels, indent=2, sort_keys=True) + "\n")
    if body_model:
        write_proxy_model(root / "body_models", "smplx")
    manifest = {"dataset": "synthetic", "layout": "core4d", "seed": int(seed), "n_sequences": n,
                "fps": SOURCE_FPS, "sequences": entries}
    atomic_write_text(root / "hoibench_synthetic.json", json.dumps(manifest, indent=2, sort_keys=True) + "\n")
    return manifest
