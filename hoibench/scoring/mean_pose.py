"""The "mean pose + static object" baseline: a lower bound that ignores the text.

It uses only statistics of the store's TRAIN split (never a test clip's motion) and, like the
ground-truth row, the test clip's length (``uses_gt_length``) and whether it has an object.

Every train clip is decoded into the canonical frame (first frame's root at the xz origin,
facing +Z, floor at y = 0): ``hoi269.decode`` when the clip has ``hoi269`` rows, else
``hml263.decode`` (body only). Over all N train frames ``t`` (frame-weighted, every clip):

- mean pose, one (22, 3) pose with the pelvis at x = z = 0::

      P[j, x] = mean_t (J_t[j, x] - J_t[0, x])      (same for z)
      P[j, y] = mean_t  J_t[j, y]                   (height above the floor)

- static object, over the frames of train clips with an object::

      t_obj[x] = mean_t (obj_trans_t[x] - J_t[0, x])   (same for z)
      t_obj[y] = mean_t  obj_trans_t[y]
      R_obj    = I (3 x 3)

For each test clip: K = 1 sample of T = the ground truth's frame count, ``joints[0, t] = P``
for every ``t``; ``obj_rot[0, t] = I`` and ``obj_trans[0, t] = t_obj`` when the clip has an
object (relative to P's pelvis at the xz origin).
"""
from __future__ import annotations

from pathlib import Path
from typing import Iterator

import numpy as np

from .. import __version__
from ..representations import hml263, hoi269
from ..datasets.store import Store
from .submission import write_submission

METHOD = "mean pose + static object"
TRAIN_SPLIT = "train"
_XZ = [0, 2]


def _train_statistics(st: Store) -> tuple[np.ndarray, np.ndarray | None, int]:
    """(mean pose (22, 3), static object translation (3,) or None when no train clip has an
    object, number of train clips) in the canonical frame, float64."""
    ids = st.clip_ids(TRAIN_SPLIT)
    if not ids:
        raise ValueError(f"{st.root}: no {TRAIN_SPLIT!r} clips: the mean pose needs train-split statistics")
    pose_sum, pose_n = np.zeros((22, 3)), 0
    obj_sum, obj_n = np.zeros(3), 0
    for cid in ids:
        clip = st.load(cid)
        if "hoi269" in clip:
            joints, _, trans = hoi269.decode(clip["hoi269"])
        else:
            joints, trans = hml263.decode(clip["hml263"]), None
        pelvis_xz = joints[:, :1, _XZ]                               # (T-1, 1, 2)
        rel = joints.copy()
        rel[..., _XZ] -= pelvis_xz
        pose_sum += rel.sum(axis=0)
        pose_n += len(rel)
        if trans is not None:
            rel_obj = trans.copy()
            rel_obj[:, _XZ] -= pelvis_xz[:, 0]
            obj_sum += rel_obj.sum(axis=0)
            obj_n += len(rel_obj)
    return pose_sum / pose_n, (obj_sum / obj_n if obj_n else None), len(ids)


def mean_pose_samples(data: str | Path | Store, split: str = "test"
                      ) -> Iterator[tuple[str, dict[str, np.ndarray]]]:
    """``(clip id, arrays)`` for every clip of ``split`` (store order): K = 1 sample of the
    ground truth's length T, ``joints`` (1, T, 22, 3) the train mean pose in every frame and,
    when the clip has an object, ``obj_rot`` (1, T, 3, 3) identity and ``obj_trans`` (1, T, 3)
    the train mean object offset; all float32. ``ValueError`` when the store has no train
    clip, or a clip of ``split`` has an object but no train clip has one."""
    st = data if isinstance(data, Store) else Store(data)
    pose, obj_trans, _ = _train_statistics(st)
    for sid in st.clip_ids(split):
        clip = st.load(sid)
        T = int(clip["joints"].shape[0])
        arrays = {"joints": np.ascontiguousarray(np.broadcast_to(pose, (1, T, 22, 3)), dtype=np.float32)}
        if "obj_rot" in clip:
            if obj_trans is None:
                raise ValueError(f"{sid}: has an object but no {TRAIN_SPLIT!r} clip has one: no static object "
                                 "statistics")
            arrays["obj_rot"] = np.ascontiguousarray(np.broadcast_to(np.eye(3), (1, T, 3, 3)), dtype=np.float32)
            arrays["obj_trans"] = np.ascontiguousarray(np.broadcast_to(obj_trans, (1, T, 3)), dtype=np.float32)
        yield sid, arrays


def write_mean_pose_submission(data: str | Path | Store, out: str | Path, split: str = "test",
                               as_zip: bool = False) -> Path:
    """Write the mean-pose submission for ``split`` of ``data`` to ``out`` (a folder, or a
    ``.zip`` when ``as_zip``); returns the path written."""
    st = data if isinstance(data, Store) else Store(data)
    manifest = st.manifest
    reps = manifest.get("representations", {})
    meta = {"method": METHOD, "version": __version__, "url": "",
            "representation": reps.get("hoi269") or reps.get("hml263", ""),
            "fps": float(manifest["config"]["fps"]),
            "flags": {"uses_gt_length": True, "samples_per_prompt": 1, "checkpoint_selection": "n/a"},
            "source": {"store": manifest.get("dataset", ""), "split": split, "statistics_split": TRAIN_SPLIT,
                       "toolkit_version": __version__}}
    return write_submission(out, meta, mean_pose_samples(st, split), as_zip=as_zip)


__all__ = ["mean_pose_samples", "write_mean_pose_submission", "METHOD"]
