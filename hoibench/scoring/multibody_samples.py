"""Multi-body submission samples: the arrays of ``samples/<id>.npz`` (one per body of the
clip: ``<body>__joints``, or ``<body>__rot`` and ``<body>__trans`` for objects), a sample read
back as a clip with the single-body plausibility bounds, and the byte budgets of a
multi-body submission (the single-body rule over the clip's own arrays)."""
from __future__ import annotations

from dataclasses import replace
from typing import Mapping

import numpy as np

from ..bodies.multibody import Body, MultiBodyClip

__all__ = ["sample_arrays", "clip_from_sample", "sample_values_per_frame", "multibody_limits"]


def sample_arrays(clips: list[MultiBodyClip]) -> dict[str, np.ndarray]:
    """The ``samples/<id>.npz`` arrays of K generated versions of one clip."""
    out: dict[str, np.ndarray] = {}
    for i, b in enumerate(clips[0].bodies):
        group = [c.bodies[i] for c in clips]
        if b.is_rigid:
            out[f"{b.name}__rot"] = np.stack([g.rot for g in group]).astype(np.float32)
            out[f"{b.name}__trans"] = np.stack([g.trans for g in group]).astype(np.float32)
        else:
            out[f"{b.name}__joints"] = np.stack([g.joints for g in group]).astype(np.float32)
    return out


def clip_from_sample(gt: MultiBodyClip, arrays: Mapping[str, np.ndarray], k: int, sid: str) -> MultiBodyClip:
    """Sample ``k`` of a submission file as a clip shaped like ``gt``; ValueError naming the
    id and field for a missing, misshapen or non-finite array."""
    T = gt.num_frames
    bodies = []
    for b in gt.bodies:
        if b.is_rigid:
            R = _field(arrays, sid, f"{b.name}__rot", (T, 3, 3), k)
            t = _field(arrays, sid, f"{b.name}__trans", (T, 3), k, gt.fps)
            det = np.linalg.det(R)
            ortho = np.abs(R @ R.swapaxes(-1, -2) - np.eye(3)).max((-2, -1))
            bad = np.flatnonzero((ortho > 1e-3) | (det < 0))
            if len(bad):
                raise ValueError(f"{sid}: {b.name}__rot: not a rotation matrix at sample {k}, frame {int(bad[0])}")
            bodies.append(Body(b.name, b.kind, t, R, None, b.template, b.side, b.owner))
        else:
            J = _field(arrays, sid, f"{b.name}__joints", (T, b.joints.shape[1], 3), k, gt.fps)
            bodies.append(Body(b.name, b.kind, J[:, 0].copy(), None, J, None, b.side, b.owner))
    return replace(gt, bodies=bodies, contacts={})


def _field(arrays, sid: str, key: str, tail: tuple, k: int, fps: float | None = None) -> np.ndarray:
    if key not in arrays:
        raise ValueError(f"{sid}: missing array {key!r} (one per body of the clip: <body>__joints, or "
                         f"<body>__rot and <body>__trans for objects)")
    a = np.asarray(arrays[key])
    if a.ndim != len(tail) + 1 or a.shape[1:] != tail:
        raise ValueError(f"{sid}: {key}: expected shape (K, {', '.join(map(str, tail))}), got {a.shape}")
    if k >= len(a):
        raise ValueError(f"{sid}: {key}: {len(a)} sample(s), sample {k} asked for")
    x = a[k].astype(np.float64)
    if not np.isfinite(x).all():
        raise ValueError(f"{sid}: {key}: non-finite values in sample {k}")
    from .validate_arrays import MAX_ABS_COORD_M, MAX_SPEED_MPS
    if key.endswith(("__trans", "__joints")):
        top = float(np.abs(x).max()) if x.size else 0.0
        if top > MAX_ABS_COORD_M:
            raise ValueError(f"{sid}: {key}: |value| {top:.3g} m in sample {k} exceeds {MAX_ABS_COORD_M:g} m: "
                             "implausible")
    if key.endswith("__trans") and len(x) > 1 and fps:
        speed = np.linalg.norm(np.diff(x, axis=0), axis=-1) * fps
        if speed.max() > MAX_SPEED_MPS:
            t = int(speed.argmax())
            raise ValueError(f"{sid}: {key}: speed {speed[t]:.3g} m/s between frames {t} and {t + 1} of sample {k} "
                             f"(limit {MAX_SPEED_MPS:g} m/s): implausible")
    return x


def sample_values_per_frame(arrays: Mapping[str, np.ndarray]) -> int:
    """Values per frame of one sample of a stored multi-body clip: 12 per rigid body
    (rotation and translation), 3 per joint of an articulated one."""
    n = 0
    for i in range(len(arrays["body_names"])):
        if f"body{i}_joints" in arrays:
            n += int(np.prod(np.shape(arrays[f"body{i}_joints"])[1:]))
        else:
            n += 12
    return max(n, 1)


def multibody_limits(store, ids: list[str], samples_per_prompt: int):
    """Byte budgets of a multi-body submission, the single-body rule over the clip's own
    arrays: ``K x max_frames(T) x values per frame x 8 bytes + 1 MiB`` per test id."""
    from .submission_read import limits_for
    rows = {c["id"]: c for c in store.manifest["clips"] if c["id"] in set(ids)}
    vpf = {cid: sample_values_per_frame(store.load(cid)) for cid in rows}
    return limits_for(rows, float(store.manifest["config"]["fps"]), max(int(samples_per_prompt), 1), vpf)
