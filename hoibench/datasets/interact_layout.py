"""Synthetic sequences written in InterAct's processed layout (``hoibench synth --layout interact``).

Writes, license-free, what :mod:`hoibench.datasets.interact` reads::

    OUT/<source>/sequences_canonical/<name>/human.npz, object.npz, text.txt [, markers.npy]
    OUT/<source>/objects/<object>/<object>.obj, sample_points.npy
    OUT/test.txt, OUT/test_seq.txt            the object split and the sequence split
    OUT/body_models/smplh, smplx              hoibench's proxy models (SMPL-H and SMPL-X files)

Sources cycle behave, grab, omomo: BEHAVE-style sequences carry SMPL-H poses (T, 156) and 10
betas, OMOMO-style SMPL-X poses (T, 156) and 16 betas, GRAB-style SMPL-X poses with 24 PCA
hand components (T, 114) and a subject template ``vtemp`` (10475, 3) instead of betas; every
other sequence has a ``markers.npy`` (computed with ``smplx`` on the proxy, as InterAct's
canonicalisation does), so both the kept and the computed marker paths are exercised. Objects
are boxes whose mesh is off-centre (the loader must centre it). 36 frames at 30 fps, y-up,
feet on y = 0 in the first frame. Deterministic for a seed.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core.io import atomic_write_bytes, atomic_write_text, npz_bytes

SOURCE_CYCLE = ("behave", "grab", "omomo")
OBJECTS = {"behave": ("boxsmall", "boxlarge"), "grab": ("cubesmall", "mug"), "omomo": ("largebox", "smallbox")}
#: objects in the object split's test list (every other object is train)
TEST_OBJECTS = ("boxlarge", "cubesmall", "smallbox")
FRAMES = 36
FPS = 30.0


def _box_obj(size: np.ndarray, offset: np.ndarray) -> str:
    """A closed box as OBJ text: 8 vertices (``offset`` +- size/2), 12 outward triangles."""
    s = np.asarray(size) / 2
    v = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) * s + offset
    f = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1), (2, 3, 7), (2, 7, 6), (0, 2, 6),
         (0, 6, 4), (1, 5, 7), (1, 7, 3)]
    lines = [f"v {a:.6f} {b:.6f} {c:.6f}" for a, b, c in v] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f]
    return "\n".join(lines) + "\n"


def _smooth(rng, T: int, n: int, scale: float) -> np.ndarray:
    """(T, n) smooth random curves: a few random sinusoids per column, amplitude ``scale``."""
    t = np.arange(T)[:, None] / FPS
    a, w, p = rng.normal(0, scale, (3, n)), rng.uniform(0.5, 2.0, (3, n)), rng.uniform(0, 2 * np.pi, (3, n))
    return sum(a[i] * np.sin(2 * np.pi * w[i] * t + p[i]) for i in range(3)) / 3


def _pose_body(models: Path, source: str, poses, betas, trans, vtemp):
    """(vertices, joints) with ``smplx`` as InterAct's canonicalisation calls it."""
    import contextlib
    import io
    with contextlib.redirect_stdout(io.StringIO()):     # smplx's notice about 10 betas
        return _pose_body_quiet(models, source, poses, betas, trans, vtemp)


def _pose_body_quiet(models: Path, source: str, poses, betas, trans, vtemp):
    import smplx
    import torch
    T = len(poses)
    f = lambda a: torch.from_numpy(np.asarray(a, np.float32))       # noqa: E731
    if source == "grab":
        m = smplx.create(str(models), model_type="smplx", gender="male", num_pca_comps=24, v_template=f(vtemp),
                         batch_size=T, ext="npz")
        out = m(body_pose=f(poses[:, 3:66]), global_orient=f(poses[:, :3]), left_hand_pose=f(poses[:, 66:90]),
                right_hand_pose=f(poses[:, 90:114]), transl=f(trans))
    else:
        mt = "smplh" if source == "behave" else "smplx"
        nb = 10 if source == "behave" else 16
        m = smplx.create(str(models), model_type=mt, gender="male", use_pca=False, num_betas=nb, ext="npz",
                         flat_hand_mean=source == "omomo")
        kw = {} if mt == "smplh" else {"jaw_pose": f(np.zeros((T, 3))), "leye_pose": f(np.zeros((T, 3))),
                                      "reye_pose": f(np.zeros((T, 3))), "expression": f(np.zeros((T, 10)))}
        out = m(body_pose=f(poses[:, 3:66]), global_orient=f(poses[:, :3]), left_hand_pose=f(poses[:, 66:111]),
                right_hand_pose=f(poses[:, 111:156]), betas=f(np.repeat(betas[None], T, 0)), transl=f(trans), **kw)
    return out.vertices.detach().numpy(), out.joints.detach().numpy()


def _sequence(root: Path, i: int, rng, models: Path) -> tuple[str, str, str]:
    source = SOURCE_CYCLE[i % len(SOURCE_CYCLE)]
    obj = OBJECTS[source][(i // len(SOURCE_CYCLE)) % 2]
    name = f"sub{i % 4 + 1:02d}_{obj}_{i}"
    T = FRAMES
    width = 114 if source == "grab" else 156
    poses = _smooth(rng, T, width, 0.15)
    poses[:, :3] = np.array([0.0, rng.uniform(-np.pi, np.pi), 0.0]) + _smooth(rng, T, 3, 0.05)
    betas = rng.normal(0, 0.5, 10 if source == "behave" else 16)
    vtemp = None
    if source == "grab":
        from ..bodies.proxy import build_proxy_arrays
        vtemp = build_proxy_arrays("smplx")["v_template"] * (1.0 + rng.uniform(-0.05, 0.05))
    trans = np.zeros((T, 3))
    trans[:, 0] = np.linspace(0, 0.6, T)
    trans[:, 2] = _smooth(rng, T, 1, 0.1)[:, 0]
    verts, _ = _pose_body(models, source, poses, betas, trans, vtemp)
    lift = verts[0, :, 1].min()                            # feet on y = 0 in the first frame
    trans[:, 1] -= lift
    verts[..., 1] -= lift
    human = {"poses": poses, "trans": trans, "gender": np.array("male")}
    human.update({"vtemp": vtemp} if source == "grab" else {"betas": betas})
    seq = root / source / "sequences_canonical" / name
    atomic_write_bytes(seq / "human.npz", npz_bytes(human))
    yaw = np.linspace(0, 1.0, T) + rng.uniform(0, 1)
    angles = np.stack([np.zeros(T), yaw, np.zeros(T)], 1) + _smooth(rng, T, 3, 0.05)
    o_trans = trans + np.array([0.35, 0.0, 0.25]) + _smooth(rng, T, 3, 0.03)
    atomic_write_bytes(seq / "object.npz", npz_bytes({"angles": angles, "trans": o_trans, "name": np.array(obj)}))
    atomic_write_text(seq / "text.txt", f"A person lifts the {obj} with both hands.#a/DET person/NOUN lift/VERB "
                                        f"the/DET {obj}/NOUN#0.0#0.0\n  the person carries the {obj}  #x#0.0#0.0\n")
    if i % 2 == 0:
        from ..bodies.markers import markers_from_vertices
        atomic_write_bytes(seq / "markers.npy", _npy(markers_from_vertices(verts).astype(np.float32)))
    folder = root / source / "objects" / obj
    size = np.array([0.3, 0.2, 0.25]) * (1.5 if obj in TEST_OBJECTS else 1.0)
    offset = np.array([0.05, -0.02, 0.1])
    if not (folder / f"{obj}.obj").exists():
        atomic_write_text(folder / f"{obj}.obj", _box_obj(size, offset))
        pts = (rng.uniform(-0.5, 0.5, (64, 3)) * size + offset).astype(np.float32)
        atomic_write_bytes(folder / "sample_points.npy", _npy(pts))
    return source, name, obj


def _npy(a: np.ndarray) -> bytes:
    import io
    buf = io.BytesIO()
    np.save(buf, a, allow_pickle=False)
    return buf.getvalue()


def write_interact_layout(root: str | Path, n_sequences: int = 6, seed: int = 0) -> dict:
    """Write ``n_sequences`` synthetic sequences in InterAct's layout under ``root``;
    return ``{"sequences": [(source, name, object), ...], "test_objects", "test_sequences"}``.
    The sequence split lists sequences 2, 5, 8, ... (the OMOMO-style ones)."""
    from ..bodies.proxy import write_proxy_model
    root = Path(root)
    models = root / "body_models"
    write_proxy_model(models, "smplh")
    write_proxy_model(models, "smplx")
    rng = np.random.default_rng(seed)
    seqs = [_sequence(root, i, rng, models) for i in range(int(n_sequences))]
    test_seq = [name for k, (_, name, _) in enumerate(seqs) if k % 3 == 2]
    atomic_write_text(root / "test.txt", "\n".join(TEST_OBJECTS) + "\n")
    atomic_write_text(root / "test_seq.txt", "\n".join(test_seq) + "\n")
    return {"sequences": seqs, "test_objects": list(TEST_OBJECTS), "test_sequences": test_seq}


__all__ = ["write_interact_layout", "SOURCE_CYCLE", "TEST_OBJECTS", "FRAMES", "FPS"]
