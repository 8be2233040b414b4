"""The files of InterAct's conditioned tasks (tracks ``interact-o2h`` and ``interact-h2o``):
what a generator is given, what it submits, and the reference rows.

**Conditions.** ``hoibench submission prompts DATA --protocol interact-o2h-clean --out
prompts.jsonl`` writes, beside the prompts file, ``conditions/<id>.npz`` per test clip, and
each prompts line gains ``task``, ``condition`` (that file's absolute path) and ``submit``
(the arrays to give). Every conditions file holds ``object_points`` (N, 3) metres: the
object's points in its centred template frame (InterAct's ``sample_points.npy``; the
template's vertices when the store has none), the points both tasks measure against. Besides:

* ``o2h`` (the human from the object): the object's pose per frame, ``obj_rot`` (T, 3, 3)
  rotation matrices, ``obj_rotvec`` (T, 3) the same as axis-angle, ``obj_trans`` (T, 3)
  metres, posing the template (and the points) as ``v = R v + t``;
* ``h2o`` (the object from the human): ``markers`` (T, 77, 3) metres, the human's
  body-surface markers (:mod:`hoibench.bodies.markers`). InterAct's human2object model is
  given these and the object's rest geometry only: no object pose of any frame.

**Submissions** (``samples/<id>.npz``, ``submission.json`` as for every track): ``o2h``:
``markers`` (K, T, 77, 3); ``h2o``: ``obj_trans`` (K, T, 3) and ``obj_rot`` (K, T, 3, 3) or
``obj_rotvec`` (K, T, 3); float32 or float64, T the ground truth's frames (the prompt's
``frames``), K from 1 to the protocol's ``samples_per_prompt``.

**Reference rows** (``hoibench submission reference DATA --protocol ... --kind KIND``, K = 1):
``gt``, the test clip itself; ``static-first-pose``, the ground truth's first frame held for
every frame (o2h: the human's first-frame markers; h2o: the object's first-frame pose). Like
every reference row they read the store's ground truth: the static row is a floor of the
scale, not a method (the h2o condition has no object pose).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import __version__
from ..core.io import atomic_write_bytes, npz_bytes
from ..core.plausibility import ROTATION_TOL
from ..datasets.store import Store
from .submission_read import Problem, Submission, SubmissionError
from .validate_arrays import expect_shape

#: the arrays a sample file of each task may hold (the first listed are required; h2o takes
#: ``obj_rot`` or ``obj_rotvec``) and their shapes after (K, T)
TASK_ARRAYS: dict[str, dict[str, tuple[int, ...]]] = {
    "o2h": {"markers": (77, 3)},
    "h2o": {"obj_trans": (3,), "obj_rot": (3, 3), "obj_rotvec": (3,)},
}
#: what a generator gives back, per task (the prompts' ``submit`` field)
SUBMIT = {"o2h": {"markers": "(K, T, 77, 3) metres"},
          "h2o": {"obj_rot": "(K, T, 3, 3) rotation matrices, or obj_rotvec (K, T, 3) axis-angle",
                  "obj_trans": "(K, T, 3) metres"}}
REFERENCE_KINDS = ("gt", "static-first-pose")
MAX_ABS_M = 1000.0


# ====================================================================== ground truth
def posed(points: np.ndarray, rot: np.ndarray, trans: np.ndarray) -> np.ndarray:
    """(T, N, 3) points ``R_t p + t_t`` of (N, 3) ``points`` under (T, 3, 3) ``rot`` and
    (T, 3) ``trans`` (metres)."""
    return np.einsum("tij,nj->tni", np.asarray(rot, np.float64), np.asarray(points, np.float64)) \
        + np.asarray(trans, np.float64)[:, None, :]


def ground_truth(store: Store, cid: str) -> dict[str, np.ndarray]:
    """A test clip as the tasks read it (float64): ``markers`` (T, 77, 3), ``points`` (N, 3)
    (``object_sample_points``, else the template's vertices), ``obj_rot`` (T, 3, 3),
    ``obj_trans`` (T, 3) and ``origin`` (3,): InterAct's object-file origin in the centred
    template (zeros when the store does not record it). ValueError naming the clip file and
    field when a field is missing."""
    clip = store.load(cid, keys=("markers", "object_sample_points", "obj_rot", "obj_trans", "object_name",
                                 "object_origin"))
    for key in ("markers", "obj_rot", "obj_trans", "object_name"):
        if key not in clip:
            raise ValueError(f"{store.root}/clips/{cid}.npz: {key}: missing: InterAct's tasks need a store made by "
                             f"`hoibench prepare interact` (markers and object poses)")
    points = clip.get("object_sample_points")
    if points is None:
        points = store.object_template(str(clip["object_name"]))[0]
    return {"markers": np.asarray(clip["markers"], np.float64), "points": np.asarray(points, np.float64),
            "obj_rot": np.asarray(clip["obj_rot"], np.float64), "obj_trans": np.asarray(clip["obj_trans"], np.float64),
            "origin": np.asarray(clip.get("object_origin", np.zeros(3)), np.float64)}


# ====================================================================== conditions
def condition_arrays(task: str, gt: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """What the generator of ``task`` is given for one clip (module docstring), float32."""
    from scipy.spatial.transform import Rotation
    out = {"object_points": gt["points"]}
    if task == "o2h":
        out.update(obj_rot=gt["obj_rot"], obj_rotvec=Rotation.from_matrix(gt["obj_rot"]).as_rotvec(),
                   obj_trans=gt["obj_trans"])
    else:
        out["markers"] = gt["markers"]
    return {k: np.asarray(v, np.float32) for k, v in out.items()}


def check_conditions_dir(folder: Path, ids: list[str]) -> None:
    """FileExistsError when ``folder`` exists and holds anything but conditions files of
    ``ids`` (an earlier run's are replaced; nothing else is overwritten)."""
    if not folder.exists():
        return
    if not folder.is_dir():
        raise FileExistsError(f"{folder}: exists and is not a folder: the conditions files go there; choose "
                              f"another --out folder")
    names = {f"{i}.npz" for i in ids}
    other = sorted(p.name for p in folder.iterdir() if p.name not in names)
    if other:
        raise FileExistsError(f"{folder}: holds {other[0]!r}, not a conditions file of this store: not "
                              f"overwritten; write the prompts into another folder")


def write_conditions(store: Store, ids: list[str], task: str, folder: Path) -> dict[str, Path]:
    """``folder/<id>.npz`` of :func:`condition_arrays` per test id; their absolute paths."""
    check_conditions_dir(folder, ids)
    out = {}
    for cid in ids:
        path = folder / f"{cid}.npz"
        atomic_write_bytes(path, npz_bytes(condition_arrays(task, ground_truth(store, cid))))
        out[cid] = path.resolve()
    return out


def prompt_fields(task: str, condition: Path) -> dict:
    """The fields a task adds to a prompts line."""
    return {"task": task, "condition": str(condition), "submit": SUBMIT[task]}


# ====================================================================== sample files
def _missing(task: str, headers: dict, sid: str) -> list[Problem]:
    where = f"samples/{sid}.npz"
    if task == "o2h":
        return [] if "markers" in headers else [Problem(sid, "markers", f"{where}: missing: the object-to-human task "
                                                                        f"reads markers (K, T, 77, 3)")]
    out = [] if "obj_trans" in headers else [Problem(sid, "obj_trans", f"{where}: missing: the object's translation "
                                                                       f"(K, T, 3) is required")]
    rots = [k for k in ("obj_rot", "obj_rotvec") if k in headers]
    if len(rots) != 1:
        out.append(Problem(sid, "obj_rot", f"{where}: give exactly one of obj_rot (K, T, 3, 3) and obj_rotvec "
                                           f"(K, T, 3), got {len(rots)}"))
    return out


def _value_problems(sid: str, arrays: dict[str, np.ndarray]) -> list[Problem]:
    out = []
    for k, a in arrays.items():
        if not np.isfinite(a).all() or np.abs(a).max() > MAX_ABS_M:
            out.append(Problem(sid, k, f"samples/{sid}.npz: values must be finite metres within {MAX_ABS_M:g} m"))
    if "obj_rot" in arrays and not out:
        r = np.asarray(arrays["obj_rot"], np.float64)
        err = np.abs(r @ np.swapaxes(r, -1, -2) - np.eye(3)).max()
        if err > ROTATION_TOL or (np.linalg.det(r) <= 0).any():
            out.append(Problem(sid, "obj_rot", f"samples/{sid}.npz: not rotation matrices (R R^T - I up to "
                                               f"{err:.2g}, or det <= 0)"))
    return out


def file_problems(sub: Submission, sid: str, task: str, frames: int, cap: int) -> tuple[list[Problem], int | None]:
    """Problems of one sample file of ``task`` and its K (None when unknown): arrays present,
    shapes and dtypes, one K from 1 to ``cap`` and T = ``frames`` (the ground truth's) in every
    array, finite values within 1 km, rotation matrices. Each message names the file."""
    try:
        headers = sub.headers(sid)
    except SubmissionError as e:
        return [Problem(sid, "file", f"samples/{sid}.npz: {e}")], None
    known = TASK_ARRAYS[task]
    probs = [Problem(sid, k, f"samples/{sid}.npz: not read by the {task} task (it reads {', '.join(known)})",
                     "warning") for k in headers if k not in known]
    probs += _missing(task, headers, sid)
    used = [k for k in known if k in headers]
    for k in used:
        probs += expect_shape(headers[k], known[k], k, sid, where=f"samples/{sid}.npz: ")
    if any(p.severity == "error" for p in probs):
        return probs, None
    kts = {k: headers[k].shape[:2] for k in used}
    K, T = kts[used[0]]
    for k, (kk, tt) in kts.items():
        if (kk, tt) != (K, T):
            probs.append(Problem(sid, k, f"samples/{sid}.npz: (K, T) = {(kk, tt)} but {used[0]} has {(K, T)}"))
        elif tt != frames:
            probs.append(Problem(sid, k, f"samples/{sid}.npz: {tt} frames; this task compares frame by frame with "
                                         f"the ground truth's {frames} (the prompt's frames)"))
        elif kk > cap:
            probs.append(Problem(sid, k, f"samples/{sid}.npz: K = {kk} samples, over the protocol's {cap} (the "
                                         f"selection picks from at most {cap}): not loaded"))
    if any(p.severity == "error" for p in probs):
        return probs, K
    try:
        arrays = sub.load(sid, used)
    except SubmissionError as e:
        return probs + [Problem(sid, "file", f"samples/{sid}.npz: {e}")], K
    return probs + _value_problems(sid, arrays), K


def sample_poses(arrays: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """(K, T, 3, 3) rotations and (K, T, 3) translations of an h2o sample file."""
    from ..core.geometry import axis_angle_to_matrix
    rot = arrays["obj_rot"] if "obj_rot" in arrays else axis_angle_to_matrix(np.asarray(arrays["obj_rotvec"], np.float64))
    return np.asarray(rot, np.float64), np.asarray(arrays["obj_trans"], np.float64)


# ====================================================================== reference rows
def reference_samples(store: Store, ids: list[str], task: str, kind: str):
    """``(id, arrays)`` of the ``kind`` reference row (module docstring), K = 1."""
    for cid in ids:
        gt = ground_truth(store, cid)
        T = len(gt["markers"])
        hold = (lambda a: a) if kind == "gt" else (lambda a: np.repeat(a[:1], T, 0))
        if task == "o2h":
            yield cid, {"markers": hold(gt["markers"])[None].astype(np.float32)}
        else:
            yield cid, {"obj_rot": hold(gt["obj_rot"])[None].astype(np.float32),
                        "obj_trans": hold(gt["obj_trans"])[None].astype(np.float32)}


def write_task_reference(kind: str, data: str | Path, out: str | Path, task: str, *, as_zip: bool = False) -> Path:
    """Write the ``kind`` reference submission of ``task`` for ``data``'s test split."""
    from .submission_write import write_submission
    if kind not in REFERENCE_KINDS:
        raise ValueError(f"reference kind {kind!r}: the {task} track has {', '.join(REFERENCE_KINDS)}")
    st = Store(data)
    ids = st.clip_ids("test")
    if not ids:
        raise ValueError(f"{data}: the test split has no clips")
    label = {"gt": "ground truth", "static-first-pose": {"o2h": "static first pose (the human's first frame held)",
                                                         "h2o": "static first pose (the object's first frame held)"}
             [task]}[kind]
    m = st.manifest
    meta = {"method": label, "version": __version__, "url": "",
            "representation": m.get("representations", {}).get("hml263", ""), "fps": float(m["config"]["fps"]),
            "flags": {"uses_gt_length": True, "samples_per_prompt": 1, "checkpoint_selection": "n/a"},
            "source": {"reference": kind, "task": task, "store": m.get("dataset", ""), "split": "test",
                       "toolkit_version": __version__}}
    return write_submission(out, meta, reference_samples(st, ids, task, kind), as_zip=as_zip)


__all__ = ["TASK_ARRAYS", "SUBMIT", "REFERENCE_KINDS", "ground_truth", "posed",
           "condition_arrays", "write_conditions", "prompt_fields", "file_problems", "sample_poses",
           "reference_samples", "write_task_reference"]
