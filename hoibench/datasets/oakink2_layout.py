"""License-free sequences in OAKINK2's release layout, with ground truth.

:func:`write_oakink2_layout` writes up to three deterministic sequences as OAKINK2 lays out
its release (facts and sources in :mod:`hoibench.datasets.oakink2`)::

    OUT/anno_preview/<token>.pkl   mocap_frame_id_list (ids from 1000), obj_list, obj_transf
        {obj: {frame id: 4x4 float32 ndarray}}, raw_mano {frame id: {rh__/lh__pose_coeffs
        (1, 16, 4) w-first quaternions, __tsl (1, 3), __betas (1, 10)}} and raw_smplx
        {frame id: {"world_rot": (1, 4)}} float32 torch tensors (pickled without torch),
        cam_extr {"allocentric_top": {frame id: 4x4}} (a camera 20 degrees off looking down)
    OUT/program/program_info/<token>.json   three segments: a two-hand affordance primitive,
        a right-hand one (``(None, [b, e])``) and a transient ``hold``
    OUT/program/desc_info/<token>.json, OUT/program/task_target.json
    OUT/object_raw/obj_desc.json, OUT/object_raw/align_ds/<obj id>/model.obj   metres
    OUT/body_models/mano/MANO_{RIGHT,LEFT}.pkl   the proxy hand
    OUT/hoibench_gt/<seq id>.<primitive>.<nn>.npz   per primitive clip, at its source frames:
        ``left_hand`` / ``right_hand`` (T, 21, 3), ``oi2_<id>`` (T, V, 3) posed vertices
    OUT/hoibench_synthetic.json

The first sequence's world is z-up (the SMPL-X ``world_rot`` turns the body's y to +z), the
others y-up. Ground truth comes from the axis-angle the quaternions were made from, the proxy
hand's numpy forward (:class:`~hoibench.bodies.proxy_hand.ProxyHand`), ``joints - joint0 +
tsl``, object vertices ``T v``, then the world's up axis rotated to +y: never the loader.
Sequence keys are real OAKINK2 keys, one per TaMF list (train, val, test).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..core import geometry as geo
from ..core.io import atomic_write_bytes, atomic_write_text, npz_bytes
from ..bodies.proxy_hand import ProxyHand, write_proxy_mano
from . import torch_pickle as tp
from .taco_layout import ellipsoid_cm

__all__ = ["SEQUENCES", "SOURCE_FPS", "FIRST_FRAME", "write_oakink2_layout"]

SOURCE_FPS = 120.0
FIRST_FRAME = 1000
FRAMES = 24
#: (sequence key, TaMF list, object ids) of the sequences written.
SEQUENCES = (
    ("scene_01__A001/seq__9e46184387ba83f60895__2023-04-27-18-43-58", "train", ("O02@0011@00003", "C10001")),
    ("scene_01__A003/seq__e76b290b0440c2db3e27__2023-04-15-11-27-51", "val", ("O01@0005@00001", "C10002")),
    ("scene_01__A001/seq__5ad66440a8b11dd306f3__2023-04-27-19-41-45", "test", ("O02@0011@00003", "C10003")),
)
_UP = {0: np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])}   # z-up -> y-up; else identity


def _quat(aa: np.ndarray) -> np.ndarray:
    """w-first unit quaternions of axis-angle (..., 3), written out here (not via the loader's geometry)."""
    th = np.linalg.norm(aa, axis=-1, keepdims=True)
    axis = np.where(th > 0, aa / np.maximum(th, 1e-300), 0.0)
    return np.concatenate([np.cos(th / 2), np.sin(th / 2) * axis], -1)


def _program(lh_a: tuple, rh_a: tuple, rh_b: tuple, hold: tuple, objs: tuple) -> tuple[dict, dict]:
    prog = {str((list(lh_a), list(rh_a))): {"primitive": "pour", "obj_list": list(objs) + ["O09@9999@00000"],
                                            "interaction_mode": "bh_main"},
            str((None, list(rh_b))): {"primitive": "uncap", "obj_list": [objs[0]], "interaction_mode": "rh_main"},
            str((list(hold), None)): {"primitive": "hold", "obj_list": [objs[1]], "interaction_mode": "lh_main"}}
    desc = {str((list(lh_a), list(rh_a))).replace(" ", ""): {"seg_desc": "pour from the bottle into the cup"},
            str((None, tuple(rh_b))): {"seg_desc": "take the cap off the bottle"}}   # spelled unlike the program
    return prog, desc


def write_oakink2_layout(root: str | Path, n_sequences: int = 3, seed: int = 0, body_model: bool = True) -> dict:
    """Write ``n_sequences`` (1..3) of :data:`SEQUENCES` and their ground truth under ``root``."""
    n = int(n_sequences)
    if not 1 <= n <= len(SEQUENCES):
        raise ValueError(f"n_sequences: expected 1..{len(SEQUENCES)}, got {n_sequences!r}")
    root = Path(root)
    ids = FIRST_FRAME + np.arange(FRAMES)
    t = np.arange(FRAMES) / SOURCE_FPS
    tasks, entries, meshes = {}, [], {}
    for k, (key, lst, objs) in enumerate(SEQUENCES[:n]):
        rng = np.random.default_rng([int(seed), k])
        F = _UP.get(k, np.eye(3))
        world_q = _quat(np.array([np.pi / 2, 0.0, 0.0])) if k == 0 else _quat(np.array([0.0, 0.3, 0.0]))
        raw_mano = {int(f): {} for f in ids}
        joints = {}
        for side, pre in (("left", "lh"), ("right", "rh")):
            aa = rng.normal(0, 0.4, (1, 16, 3)) + np.einsum("t,jc->tjc", np.sin(8 * t), rng.normal(0, 0.3, (16, 3)))
            q = _quat(aa).astype(np.float32)
            tsl = (np.array([0.25 if side == "right" else -0.25, 0.1, 0.3]) + rng.normal(0, 0.03, 3)
                   + np.outer(t, rng.normal(0, 0.4, 3))).astype(np.float32)
            betas = np.concatenate([[rng.uniform(0.5, 1.5)], rng.normal(0, 0.5, 9)]).astype(np.float32)
            for i, f in enumerate(ids):
                raw_mano[int(f)].update({f"{pre}__pose_coeffs": tp.Tensor(q[i][None]),
                                         f"{pre}__tsl": tp.Tensor(tsl[i][None]),
                                         f"{pre}__betas": tp.Tensor(betas[None])})
            _, j = ProxyHand(side).forward(aa[:, 0], aa[:, 1:].reshape(FRAMES, 45), betas.astype(np.float64)[None],
                                           tips=True)
            joints[f"{side}_hand"] = (j - j[:, :1] + tsl.astype(np.float64)[:, None]) @ F.T
        obj_transf, verts = {}, {}
        for oid in objs:
            v, f = meshes.setdefault(oid, ellipsoid_cm(str(sum(map(ord, oid)))))
            P = np.tile(np.eye(4), (FRAMES, 1, 1))
            P[:, :3, :3] = geo.axis_angle_to_matrix(rng.normal(0, 0.8, 3) + np.outer(t, rng.normal(0, 2.0, 3)))
            P[:, :3, 3] = rng.normal(0, 0.1, 3) + np.outer(t, rng.normal(0, 0.5, 3)) + [0, 0, 0.3]
            P = P.astype(np.float32)
            obj_transf[oid] = {int(fr): P[i] for i, fr in enumerate(ids)}
            Pd = P.astype(np.float64)
            verts[oid] = (np.einsum("tij,vj->tvi", Pd[:, :3, :3], 0.01 * v) + Pd[:, None, :3, 3]) @ F.T
        # a top camera 20 degrees off straight down, world -> camera (its optical axis is E[2, :3])
        down = np.linalg.inv(F) @ np.array([0.0, -1.0, 0.0])
        look = np.asarray(geo.axis_angle_to_matrix(np.array([0.35, 0.0, 0.0]))) @ down
        E = np.eye(4)
        E[2, :3] = look
        E[0, :3] = np.cross(look, [1.0, 0.0, 0.0] if abs(look[0]) < 0.9 else [0.0, 1.0, 0.0])
        E[0, :3] /= np.linalg.norm(E[0, :3])
        E[1, :3] = np.cross(E[2, :3], E[0, :3])
        anno = {"cam_def": {}, "cam_selection": [], "cam_extr": {"allocentric_top": {int(ids[0]): E}}, "frame_id_list": [int(f) for f in ids[::4]],
                "mocap_frame_id_list": [int(f) for f in ids], "obj_list": list(objs), "obj_transf": obj_transf,
                "raw_mano": raw_mano, "raw_smplx": {int(f): {"world_rot": tp.Tensor(world_q[None].astype(np.float32))}
                                                    for f in ids}}
        tok = key.replace("/", "++")
        atomic_write_bytes(root / "anno_preview" / f"{tok}.pkl", tp.dumps(anno))
        f0 = FIRST_FRAME
        segs = {"pour.00": ((f0, f0 + 16), (f0 + 2, f0 + 18)), "uncap.00": (None, (f0 + 6, f0 + 24))}
        prog, desc = _program(segs["pour.00"][0], segs["pour.00"][1], segs["uncap.00"][1], (f0 + 20, f0 + 24), objs)
        atomic_write_text(root / "program" / "program_info" / f"{tok}.json", json.dumps(prog, indent=1) + "\n")
        atomic_write_text(root / "program" / "desc_info" / f"{tok}.json", json.dumps(desc, indent=1) + "\n")
        tasks[key] = "make a drink"
        sid = key.replace("/", ".")
        for name, (lh, rh) in segs.items():
            ivs = [iv for iv in (lh, rh) if iv is not None]
            a, b = min(i[0] for i in ivs) - f0, max(i[1] for i in ivs) - f0
            gt = {h: joints[h][a:b] for h in joints}
            used = objs if name.startswith("pour") else objs[:1]
            gt.update({"oi2_" + o.replace("@", "."): verts[o][a:b] for o in used})
            atomic_write_bytes(root / "hoibench_gt" / f"{sid}.{name}.npz", npz_bytes(gt))
        entries.append({"seq_key": key, "split": lst, "up": "+z" if k == 0 else "+y", "frames": FRAMES})
    atomic_write_text(root / "program" / "task_target.json", json.dumps(tasks, indent=1) + "\n")
    desc = {}
    for oid, (v, f) in sorted(meshes.items()):
        lines = [f"v {a!r} {b!r} {c!r}" for a, b, c in (0.01 * v).tolist()]
        lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f.tolist()]
        atomic_write_text(root / "object_raw" / "align_ds" / oid / "model.obj", "\n".join(lines) + "\n")
        desc[oid] = {"obj_id": oid, "obj_name": f"object {oid}"}
    atomic_write_text(root / "object_raw" / "obj_desc.json", json.dumps(desc, indent=1) + "\n")
    if body_model:
        write_proxy_mano(root / "body_models")
    manifest = {"dataset": "synthetic", "layout": "oakink2", "seed": int(seed), "n_sequences": n,
                "fps": SOURCE_FPS, "sequences": entries}
    atomic_write_text(root / "hoibench_synthetic.json", json.dumps(manifest, indent=2, sort_keys=True) + "\n")
    return manifest
