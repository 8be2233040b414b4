"""A multi-body submission's sample arrays (:mod:`hoibench.scoring.multibody`): one array per
body of the store's clip, named by the body -- ``<body>__joints`` (K, T, J, 3) for humans and
hands, ``<body>__rot`` (K, T, 3, 3) and ``<body>__trans`` (K, T, 3) for objects. Writing
(:func:`sample_arrays`) and reading one sample back as a clip (:func:`clip_from_sample`,
shared by the scorer and ``hoibench validate``)."""
from __future__ import annotations

from dataclasses import replace
from typing import Mapping

import numpy as np

from ..bodies.multibody import Body, MultiBodyClip

__all__ = ["sample_arrays", "clip_from_sample"]


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
            t = _field(arrays, sid, f"{b.name}__trans", (T, 3), k)
            det = np.linalg.det(R)
            ortho = np.abs(R @ R.swapaxes(-1, -2) - np.eye(3)).max((-2, -1))
            bad = np.flatnonzero((ortho > 1e-3) | (det < 0))
            if len(bad):
                raise ValueError(f"{sid}: {b.name}__rot: not a rotation matrix at sample {k}, frame {int(bad[0])}")
            bodies.append(Body(b.name, b.kind, t, R, None, b.template, b.side, b.owner))
        else:
            J = _field(arrays, sid, f"{b.name}__joints", (T, b.joints.shape[1], 3), k)
            bodies.append(Body(b.name, b.kind, J[:, 0].copy(), None, J, None, b.side, b.owner))
    return replace(gt, bodies=bodies, contacts={})


def _field(arrays, sid: str, key: str, tail: tuple, k: int) -> np.ndarray:
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
    return x
