"""License-free sequences in TACO's release layout, with ground truth.

:func:`write_taco_layout` writes up to five deterministic sequences exactly as TACO lays out
its release (facts and sources in :mod:`hoibench.datasets.taco`), so
:func:`hoibench.datasets.taco.prepare_jobs` runs end to end without licensed files::

    OUT/Hand_Poses/(<action>, <tool>, <target>)/<seq>/{left,right}_hand.pkl
        {frame key: {"hand_pose": (48,), "hand_trans": (3,)}} float32 torch tensors, pickled
        without torch (:func:`hoibench.datasets.torch_pickle.dumps`); keys "00001"... in
        most sequences, ints in the second
    OUT/Hand_Poses/(...)/<seq>/{left,right}_hand_shape.pkl   {"hand_shape": (10,)} (the third
        stores (1, 10); the fourth has no left shape file: zero betas)
    OUT/Object_Poses/(...)/<seq>/tool_<id>.npy, target_<id>.npy   (T, 4, 4) (float32 in the
        first sequence, float64 elsewhere), metres, z-up
    OUT/Object_Models/<id>_cm.obj     an off-centre ellipsoid per id, centimetres
    OUT/body_models/mano/MANO_{RIGHT,LEFT}.pkl   the proxy hand
    OUT/hoibench_gt/<seq>.npz          ground truth in hoibench's y-up world at the source
        frames: ``left_hand`` / ``right_hand`` (T, 21, 3) joints and ``tool`` / ``target``
        (T, V, 3) posed vertices (mesh file order)
    OUT/hoibench_synthetic.json

Ground truth is computed here from the written (float32-rounded) values with the proxy
hand's own numpy forward (:class:`~hoibench.bodies.proxy_hand.ProxyHand`, tips included),
``joints - joint0 + hand_trans``, object vertices ``R (0.01 v) + t``, then ``(x, y, z) ->
(x, z, -y)``: never with ``smplx`` or the loader. Sequence names are real TACO names, one
per official list, so the embedded split applies.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..core import geometry as geo
from ..core.io import atomic_write_bytes, atomic_write_text, npz_bytes
from ..bodies.proxy_hand import ProxyHand, write_proxy_mano
from . import torch_pickle as tp

__all__ = ["SEQUENCES", "SOURCE_FPS", "ellipsoid_cm", "write_taco_layout"]

SOURCE_FPS = 30.0
FRAMES = 16
#: (seq, triplet folder, tool id, target id, official list) of the sequences written.
SEQUENCES = (
    ("20230927_032", "(dust, roller, pan)", "012", "104", "train"),
    ("20231019_072", "(dust, roller, pan)", "012", "104", "test_1"),
    ("20230926_034", "(scrape off, knife, plate)", "031", "117", "test_2"),
    ("20230917_032", "(pour in some, teapot, bowl)", "055", "101", "test_3"),
    ("20231105_019", "(stir, spoon, bowl)", "007", "101", "test_4"),
)
_ZUP_TO_YUP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def ellipsoid_cm(oid: str) -> tuple[np.ndarray, np.ndarray]:
    """A closed UV ellipsoid (vertices in centimetres, off the origin; faces outward),
    its semi-axes and offset drawn from the id."""
    rng = np.random.default_rng(int(oid))
    axes = rng.uniform(2.0, 9.0, 3)
    off = rng.uniform(-3.0, 3.0, 3)
    n_lat, n_lon = 6, 8
    v = [[0.0, 0.0, 1.0]]
    for i in range(1, n_lat):
        th = np.pi * i / n_lat
        v += [[np.sin(th) * np.cos(2 * np.pi * j / n_lon), np.sin(th) * np.sin(2 * np.pi * j / n_lon), np.cos(th)]
              for j in range(n_lon)]
    v.append([0.0, 0.0, -1.0])
    v = np.array(v) * axes + off
    f = []
    for j in range(n_lon):
        f.append([0, 1 + j, 1 + (j + 1) % n_lon])
    for i in range(n_lat - 2):
        a, b = 1 + i * n_lon, 1 + (i + 1) * n_lon
        for j in range(n_lon):
            j2 = (j + 1) % n_lon
            f += [[a + j, b + j, b + j2], [a + j, b + j2, a + j2]]
    last, base = len(v) - 1, 1 + (n_lat - 2) * n_lon
    for j in range(n_lon):
        f.append([base + j, last, base + (j + 1) % n_lon])
    return v, np.array(f)


def _obj_text(v: np.ndarray, f: np.ndarray) -> str:
    lines = [f"v {a!r} {b!r} {c!r}" for a, b, c in v.tolist()] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f.tolist()]
    return "\n".join(lines) + "\n"


def _hand_params(rng, side: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(FRAMES) / SOURCE_FPS
    sgn = -1.0 if side == "left" else 1.0
    pose = np.zeros((FRAMES, 48))
    pose[:, :3] = rng.normal(0, 0.6, 3) + np.outer(np.sin(2 * t), rng.normal(0, 0.3, 3))
    pose[:, 3:] = rng.uniform(-0.3, 0.5, 45) * (0.6 + 0.4 * np.cos(3 * t))[:, None]
    trans = np.array([sgn * 0.2, 0.0, 0.15]) + rng.normal(0, 0.05, 3) + np.outer(t, rng.normal(0, 0.2, 3))
    betas = np.concatenate([[rng.uniform(0.5, 1.5) * (1 if side == "right" else -1)], rng.normal(0, 0.5, 9)])
    return pose.astype(np.float32), trans.astype(np.float32), betas.astype(np.float32)


def _object_poses(rng, dtype) -> np.ndarray:
    t = np.arange(FRAMES) / SOURCE_FPS
    aa = rng.normal(0, 0.8, 3) + np.outer(t, rng.normal(0, 1.0, 3))
    P = np.tile(np.eye(4), (FRAMES, 1, 1))
    P[:, :3, :3] = geo.axis_angle_to_matrix(aa)
    P[:, :3, 3] = rng.normal(0, 0.15, 3) + np.outer(t, rng.normal(0, 0.3, 3))
    return P.astype(dtype)


def write_taco_layout(root: str | Path, n_sequences: int = 5, seed: int = 0, body_model: bool = True) -> dict:
    """Write ``n_sequences`` (1..5) of :data:`SEQUENCES` and their ground truth under ``root``."""
    n = int(n_sequences)
    if not 1 <= n <= len(SEQUENCES):
        raise ValueError(f"n_sequences: expected 1..{len(SEQUENCES)}, got {n_sequences!r}")
    root = Path(root)
    entries, meshes = [], {}
    for k, (seq, folder, tool, target, lst) in enumerate(SEQUENCES[:n]):
        rng = np.random.default_rng([int(seed), k])
        hdir = root / "Hand_Poses" / folder / seq
        gt = {}
        for side in ("left", "right"):
            pose, trans, betas = _hand_params(rng, side)
            keys = [i + 1 for i in range(FRAMES)] if k == 1 else [f"{i + 1:05d}" for i in range(FRAMES)]
            frames = {key: {"hand_pose": tp.Tensor(pose[i]), "hand_trans": tp.Tensor(trans[i])}
                      for i, key in enumerate(keys)}
            atomic_write_bytes(hdir / f"{side}_hand.pkl", tp.dumps(frames))
            if k == 3 and side == "left":
                betas = np.zeros(10, np.float32)
            else:
                shape = betas.reshape(1, 10) if k == 2 else betas
                atomic_write_bytes(hdir / f"{side}_hand_shape.pkl", tp.dumps({"hand_shape": tp.Tensor(shape)}))
            _, j = ProxyHand(side).forward(pose[:, :3].astype(np.float64), pose[:, 3:].astype(np.float64),
                                           betas.astype(np.float64)[None], tips=True)
            gt[f"{side}_hand"] = (j - j[:, :1] + trans.astype(np.float64)[:, None]) @ _ZUP_TO_YUP.T
        odir = root / "Object_Poses" / folder / seq
        for role, oid in (("tool", tool), ("target", target)):
            P = _object_poses(rng, np.float32 if k == 0 else np.float64)
            atomic_write_bytes(odir / f"{role}_{oid}.npy", _npy(P))
            v, f = meshes.setdefault(oid, ellipsoid_cm(oid))
            Pd = P.astype(np.float64)
            gt[role] = (np.einsum("tij,vj->tvi", Pd[:, :3, :3], 0.01 * v) + Pd[:, None, :3, 3]) @ _ZUP_TO_YUP.T
        atomic_write_bytes(root / "hoibench_gt" / f"{seq}.npz", npz_bytes(gt))
        entries.append({"id": seq, "triplet": folder, "tool": tool, "target": target, "taco_split": lst,
                        "frames": FRAMES})
    for oid, (v, f) in sorted(meshes.items()):
        atomic_write_text(root / "Object_Models" / f"{oid}_cm.obj", _obj_text(v, f))
    if body_model:
        write_proxy_mano(root / "body_models")
    manifest = {"dataset": "synthetic", "layout": "taco", "seed": int(seed), "n_sequences": n, "fps": SOURCE_FPS,
                "sequences": entries}
    atomic_write_text(root / "hoibench_synthetic.json", json.dumps(manifest, indent=2, sort_keys=True) + "\n")
    return manifest


def _npy(a: np.ndarray) -> bytes:
    import io
    buf = io.BytesIO()
    np.save(buf, a, allow_pickle=False)
    return buf.getvalue()
