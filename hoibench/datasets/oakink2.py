"""OAKINK2 -> :class:`~hoibench.bodies.multibody.MultiBodyClip` (two hands, one to three objects).

OAKINK2 (Zhan et al., "OAKINK2: A Dataset of Bimanual Hands-Object Manipulation in Complex
Task Completion", CVPR 2024; data CC BY-NC-SA 3.0 per its Hugging Face card) records two
hands manipulating objects through programs of primitives. Facts below come from
oakink/OakInk2-PreviewTool 63365c6 (``src/oakink2_preview/dataset/stream_preview.py``,
``launch/viz/seg_3d.py``, ``dataset/program.py``), oakink/OakInk2 README "Dataset Format"
and oakink/OakInk2-TaMF 4cb9c46 (``asset/split``); *inferred* marks a deduction.
:func:`hoibench.datasets.oakink2_layout.write_oakink2_layout` writes this layout license-free.

Layout read (``ROOT`` holds ``anno_preview``, ``program``, ``object_raw``)::

    ROOT/anno_preview/<token>.pkl      token = sequence key with '/' -> '++'
    ROOT/program/program_info/<token>.json, ROOT/program/desc_info/<token>.json
    ROOT/program/task_target.json      {seq_key: task text}
    ROOT/object_raw/align_ds/<obj_id>/ exactly one *.obj or *.ply (metres, inferred)

* annotation pickle (torch tensors read by :mod:`hoibench.datasets.torch_pickle`):
  ``mocap_frame_id_list``, ``obj_transf`` {obj: {frame id: 4x4}} (``v = T[:3,:3] v + T[:3,3]``),
  ``raw_mano`` {frame id: {``rh__pose_coeffs`` / ``lh__pose_coeffs`` (1, 16, 4) quaternions
  **w, x, y, z** (joint 0 global, then MANO's 15 finger joints), ``rh__tsl`` / ``lh__tsl``
  (1, 3) the wrist, ``rh__betas`` / ``lh__betas`` (1, 10)}}, ``raw_smplx`` {frame id: {...,
  ``world_rot`` (1, 4)}}. MANO is ``rot_mode="quat", center_idx=0, use_pca=False,
  flat_hand_mean=True`` plus ``tsl`` (``seg_3d.py``); lixiny/manotorch 2f6a701
  ``manolayer.py`` reads quat-mode coefficients as (16, 4) quaternions with the real part
  first (``utils/geometry.py``) and subtracts joint 0 (the wrist) for ``center_idx=0``.
* program: ``program_info`` keys are ``str((lh_interval, rh_interval))``, each ``[begin,
  end)`` in mocap frame ids or ``None``; values hold ``primitive`` and ``obj_list``;
  ``desc_info[key]["seg_desc"]`` describes the segment. ``hold``, ``rearrange``, ``swap`` and
  ``?(unk)`` are transient and skipped; the other primitives are numbered ``<nn>`` per name
  in file order.
* **120 fps** mocap (``stream_preview.py`` ``FPS_MOCAP``).
* world up axis: **not established** by any official code. hoibench takes it per sequence
  from the SMPL-X body: the mean over frames of ``R(world_rot) e_y`` (SMPL-X's rest body is
  y-up) must lie within 30 degrees of one signed world axis, which is rotated to +y (the
  angle is recorded); otherwise the sequence is refused. When the file has the
  ``allocentric_top`` camera (``cam_extr``, world to camera), its optical axis must point
  to the lower half-space of that choice (the angle to straight down is recorded).
* split: TaMF's ``asset/split/{train,val,test}.txt`` (``splits/oakink2.json``, 431/39/157
  sequences); a clip takes its sequence's split.

Clip: one per affordance primitive, id ``<scene>.<seq>.<primitive>.<nn>``; frames = the
union of the two hands' intervals; both hands over all of them (looked up by frame id;
a missing id is refused); objects = the primitive's ``obj_list`` present in ``obj_transf``
(templates ``oi2_<id>`` with ``@`` -> ``.``); texts = ``seg_desc`` and the task target; no
contacts, no floor shift.
"""
from __future__ import annotations

import ast
from pathlib import Path

import numpy as np

from ..core import geometry as geo
from ..core import plausibility as pl
from ..core.ids import InvalidIdError, check_id
from ..bodies.multibody import MultiBodyClip
from . import torch_pickle
from .behave import SequenceError, load_split_file, read_mesh, resample_times
from .hand_object import axis_to_yup, checked_clip, hand_body, object_body, rigid_poses

__all__ = ["SOURCE_FPS", "TRANSIENT", "SequenceError", "token", "seq_id", "primitives", "official_split",
           "up_rotation", "load_primitive", "prepare_jobs", "LOADER_VERSION"]

SOURCE_FPS = 120.0
LOADER_VERSION = "oakink2-1"
TRANSIENT = ("hold", "rearrange", "swap", "?(unk)")
UP_TOL_DEG = 30.0
QUAT_NORM_TOL = 1e-3
TOP_CAMERA = "allocentric_top"
MAX_KEY_CHARS = 200
MAX_PICKLE_BYTES = 4 * 1024 ** 3


def token(seq_key: str) -> str:
    return seq_key.replace("/", "++")


def seq_id(seq_key: str) -> str:
    return seq_key.replace("/", ".")


def official_split(seq_key: str) -> str | None:
    from .splits import get
    sp = get("oakink2", "official")
    sid = seq_id(seq_key)
    return next((s for s in ("train", "val", "test") if sid in set(sp.get(s, []))), None)


def _interval(x, where: str):
    if x is None:
        return None
    if (isinstance(x, (list, tuple)) and len(x) == 2 and all(isinstance(v, int) and not isinstance(v, bool) for v in x)
            and x[0] < x[1]):
        return int(x[0]), int(x[1])
    raise SequenceError(f"{where}: expected [begin, end) with begin < end, or None; got {x!r}")


def primitives(program_info: dict, where: str) -> list[tuple[str, str, tuple | None, tuple | None, dict]]:
    """(key, ``<primitive>.<nn>``, lh interval, rh interval, info) of each affordance primitive."""
    if not isinstance(program_info, dict):
        raise SequenceError(f"{where}: expected a JSON object")
    out, count = [], {}
    for key, info in program_info.items():
        if not isinstance(key, str) or len(key) > MAX_KEY_CHARS:
            raise SequenceError(f"{where}: key {str(key)[:60]!r}: not a short string")
        try:
            pair = ast.literal_eval(key)
        except (ValueError, SyntaxError):
            raise SequenceError(f"{where}: key {key!r}: not a pair of intervals") from None
        if not isinstance(pair, (list, tuple)) or len(pair) != 2:
            raise SequenceError(f"{where}: key {key!r}: not a pair of intervals")
        lh, rh = _interval(pair[0], f"{where}: key {key!r}"), _interval(pair[1], f"{where}: key {key!r}")
        if lh is None and rh is None:
            raise SequenceError(f"{where}: key {key!r}: both intervals are None")
        prim = info.get("primitive") if isinstance(info, dict) else None
        if not isinstance(prim, str):
            raise SequenceError(f"{where}: key {key!r}: 'primitive' missing")
        if prim in TRANSIENT:
            continue
        count[prim] = count.get(prim, -1) + 1
        out.append((key, f"{prim}.{count[prim]:02d}", lh, rh, info))
    return out


def up_rotation(raw_smplx: dict, frames: list[int], where: str) -> tuple[np.ndarray, str, float]:
    """(F, axis name, angle off the axis in degrees) from SMPL-X ``world_rot`` (see the module docstring)."""
    try:
        q = np.stack([np.asarray(raw_smplx[f]["world_rot"], np.float64).reshape(4) for f in frames])
    except (KeyError, TypeError, ValueError):
        raise SequenceError(f"{where}: raw_smplx: world_rot missing or not 4 values: the up axis cannot be "
                            "determined") from None
    up = (np.asarray(geo.quaternion_to_matrix(q / np.linalg.norm(q, axis=-1, keepdims=True)))[:, :, 1]).mean(0)
    norm = np.linalg.norm(up)
    k = int(np.argmax(np.abs(up)))
    ang = float(np.degrees(np.arccos(min(1.0, abs(up[k]) / norm)))) if norm > 0 else 180.0
    if ang > UP_TOL_DEG:
        raise SequenceError(f"{where}: raw_smplx: the body's up direction {np.round(up, 3).tolist()} is {ang:.0f} "
                            f"degrees from the nearest world axis (more than {UP_TOL_DEG:.0f}): up axis undetermined")
    axis = np.zeros(3)
    axis[k] = np.sign(up[k])
    return axis_to_yup(axis), ("+" if up[k] > 0 else "-") + "xyz"[k], ang


def top_camera_check(cam_extr, F: np.ndarray, where: str) -> float | None:
    """Angle (degrees) between the ``allocentric_top`` camera's optical axis in the world
    (``R^T e_z`` of its world-to-camera ``cam_extr``, first frame) and the chosen down
    direction; SequenceError when the camera would look upwards (over 90 degrees: the body
    and the camera disagree on the up axis). None when the file has no such camera."""
    frames = cam_extr.get(TOP_CAMERA) if isinstance(cam_extr, dict) else None
    if not isinstance(frames, dict) or not frames:
        return None
    E = np.asarray(next(iter(frames.values())), np.float64)
    if E.shape != (4, 4) or not np.isfinite(E).all():
        raise SequenceError(f"{where}: cam_extr[{TOP_CAMERA!r}]: expected finite 4x4 matrices, got {E.shape}")
    axis = F @ E[2, :3]
    down = np.array([0.0, -1.0, 0.0])
    deg = float(np.degrees(np.arccos(np.clip(axis @ down / max(np.linalg.norm(axis), 1e-12), -1.0, 1.0))))
    if deg > 90.0:
        raise SequenceError(f"{where}: cam_extr[{TOP_CAMERA!r}] looks {deg:.0f} degrees away from the down "
                            "direction the SMPL-X body gives: up axis undetermined")
    return deg


def _hand(raw_mano: dict, frames: list[int], pre: str, where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    aa, tsl, betas = [], [], []
    for f in frames:
        fr = raw_mano.get(f)
        try:
            q = np.asarray(fr[f"{pre}__pose_coeffs"], np.float64)
            t = np.asarray(fr[f"{pre}__tsl"], np.float64)
            b = np.asarray(fr[f"{pre}__betas"], np.float64)
        except (KeyError, TypeError):
            raise SequenceError(f"{where}: raw_mano: frame {f}: missing {pre}__pose_coeffs / __tsl / __betas") from None
        if q.shape != (1, 16, 4) or t.shape != (1, 3) or b.shape != (1, 10):
            raise SequenceError(f"{where}: raw_mano: frame {f}: {pre} shapes {q.shape}, {t.shape}, {b.shape}; "
                                "expected (1, 16, 4), (1, 3), (1, 10)")
        n = np.linalg.norm(q[0], axis=-1)
        if not np.isfinite(q).all() or np.abs(n - 1).max() > QUAT_NORM_TOL:
            raise SequenceError(f"{where}: raw_mano: frame {f}: {pre}__pose_coeffs: not unit quaternions")
        aa.append(np.asarray(geo.quaternion_to_axis_angle(q[0] / n[:, None])))
        tsl.append(t[0])
        betas.append(b[0])
    try:
        return np.stack(aa), pl.real_array(np.stack(tsl), f"{pre}__tsl", where), pl.real_array(np.stack(betas), "b", where)
    except ValueError as exc:
        raise SequenceError(str(exc)) from None


def _mesh(root: Path, oid: str, where: str) -> tuple[np.ndarray, np.ndarray, str]:
    d = root / "object_raw" / "align_ds" / oid
    files = sorted(p for p in d.iterdir() if p.suffix in (".obj", ".ply")) if d.is_dir() else []
    if len(files) != 1:
        raise SequenceError(f"{where}: object_raw/align_ds/{oid}: expected exactly one .obj/.ply, found {len(files)}")
    v, f = read_mesh(files[0], f"{where}: {oid}", process=False)
    try:
        v, f = pl.check_template(v, f, f"{where}: {files[0].name}")
    except ValueError as exc:
        raise SequenceError(str(exc)) from None
    return v, f, files[0].relative_to(root).as_posix()


def _seg_desc(desc, key: str) -> str | None:
    """``desc_info``'s ``seg_desc`` for program key ``key``; keys are compared as the pairs
    they spell (the toolkit ``eval``s both files' keys), not as text."""
    if not isinstance(desc, dict):
        return None
    def norm(x):
        return tuple(norm(y) for y in x) if isinstance(x, (list, tuple)) else x

    want = norm(ast.literal_eval(key))
    for k, v in desc.items():
        try:
            same = isinstance(k, str) and len(k) <= MAX_KEY_CHARS and norm(ast.literal_eval(k)) == want
        except (ValueError, SyntaxError):
            same = False
        if same and isinstance(v, dict) and isinstance(v.get("seg_desc"), str):
            return v["seg_desc"]
    return None


def _read_json(path: Path, where: str):
    try:
        from ..core.io import read_json_file
        return read_json_file(path, what="OAKINK2 JSON file")
    except (OSError, ValueError) as exc:
        raise SequenceError(f"{where}: {path.name}: unreadable ({type(exc).__name__})") from None


def load_primitive(root: str | Path, seq_key: str, key: str, name: str, body_models: str | Path,
                   fps: float = SOURCE_FPS) -> MultiBodyClip:
    """The affordance primitive ``key`` (a ``program_info`` key) of ``seq_key`` -> MultiBodyClip."""
    root = Path(root)
    cid = f"{seq_id(seq_key)}.{name}"
    where = f"{cid}: anno_preview/{token(seq_key)}.pkl"
    fps = pl.check_fps(fps, "fps", cid)
    prog = _read_json(root / "program" / "program_info" / f"{token(seq_key)}.json", cid)
    prim = {p[0]: p for p in primitives(prog, f"{cid}: program_info")}
    if key not in prim:
        raise SequenceError(f"{cid}: program_info: no affordance primitive {key!r}")
    _, _, lh, rh, info = prim[key]
    try:
        anno = torch_pickle.load(root / "anno_preview" / f"{token(seq_key)}.pkl", MAX_PICKLE_BYTES)
    except (torch_pickle.TorchPickleError, OSError) as exc:
        raise SequenceError(f"{where}: {exc}") from None
    if not isinstance(anno, dict) or any(k not in anno for k in ("mocap_frame_id_list", "obj_transf", "raw_mano")):
        raise SequenceError(f"{where}: expected a dict with mocap_frame_id_list, obj_transf, raw_mano")
    ivs = [iv for iv in (lh, rh) if iv is not None]
    frames = list(range(min(b for b, _ in ivs), max(e for _, e in ivs)))
    missing = sorted(set(frames) - set(int(f) for f in anno["mocap_frame_id_list"]))
    if missing:
        raise SequenceError(f"{where}: mocap_frame_id_list lacks frame {missing[0]} of the interval "
                            f"[{frames[0]}, {frames[-1] + 1})")
    F, axis, ang = up_rotation(anno.get("raw_smplx") or {}, frames, where)
    cam_deg = top_camera_check(anno.get("cam_extr"), F, where)
    T = len(frames)
    src_t = np.arange(T) / SOURCE_FPS
    dst = resample_times(src_t, fps)
    bodies = []
    for side, pre in (("left", "lh"), ("right", "rh")):
        aa, tsl, betas = _hand(anno["raw_mano"], frames, pre, where)
        bodies.append(hand_body(f"{side}_hand", side, body_models, aa, betas, tsl, src_t, dst, F))
    objs = info.get("obj_list") or []
    kept = [o for o in objs if isinstance(o, str) and o in anno["obj_transf"]]
    if not kept:
        raise SequenceError(f"{where}: primitive {key!r}: none of obj_list {objs!r} is in obj_transf")
    templates = {}
    for oid in kept:
        tname = "oi2_" + oid.replace("@", ".")
        try:
            check_id(tname, "template name", oid)
        except InvalidIdError as exc:
            raise SequenceError(f"{cid}: {exc}") from None
        try:
            P = np.stack([np.asarray(anno["obj_transf"][oid][f], np.float64) for f in frames])
        except KeyError as exc:
            raise SequenceError(f"{where}: obj_transf[{oid!r}]: no frame {exc}") from None
        R, t, _ = rigid_poses(P, f"{where}: obj_transf[{oid!r}]")
        v, f, _ = _mesh(root, oid, cid)
        mean = v.mean(0)
        templates[tname] = (v - mean, f)
        bodies.append(object_body(tname, tname, R, t, mean, src_t, dst, F))
    texts = []
    desc = _read_json(root / "program" / "desc_info" / f"{token(seq_key)}.json", cid) \
        if (root / "program" / "desc_info" / f"{token(seq_key)}.json").is_file() else {}
    seg = _seg_desc(desc, key)
    if isinstance(seg, str) and seg:
        texts.append({"text": seg, "source": "oakink2-seg_desc", "start": 0, "end": len(dst)})
    tt_path = root / "program" / "task_target.json"
    task = _read_json(tt_path, cid).get(seq_key) if tt_path.is_file() else None
    if isinstance(task, str) and task:
        texts.append({"text": task, "source": "oakink2-task_target", "start": 0, "end": len(dst)})
    prov = {"source": "oakink2", "seq_key": seq_key, "program_key": key, "primitive": info.get("primitive"),
            "interaction_mode": info.get("interaction_mode"), "lh_interval": lh, "rh_interval": rh,
            "objects": kept, "dropped_objects": [o for o in objs if o not in kept], "source_fps": SOURCE_FPS,
            "source_frames": T, "resampled_to_fps": float(fps), "up_axis": axis, "up_axis_off_deg": ang,
            "up_axis_evidence": "mean SMPL-X R(world_rot) e_y",
            "top_camera_axis_to_down_deg": cam_deg, "floor_shift_m": 0.0, "loader": LOADER_VERSION}
    clip = MultiBodyClip(name=cid, dataset="oakink2", subject=seq_key.split("/")[0], fps=float(fps), bodies=bodies,
                         templates=templates, action=str(info.get("primitive")), texts=texts, provenance=prov)
    return checked_clip(clip, cid)


def prepare_jobs(root: str | Path, body_models: str | Path, out: str | Path, config,
                 split_file: str | Path | None = None) -> list[tuple]:
    """One job per affordance primitive of each ``anno_preview/<token>.pkl``."""
    from .store import fail_unit, file_sha256, invalid_id_job, refuse_duplicates
    root = Path(root)
    anno_dir = root / "anno_preview"
    if not anno_dir.is_dir():
        raise FileNotFoundError(f"--root: no 'anno_preview' folder in {root} (expected OAKINK2's release layout)")
    splits = load_split_file(split_file) if split_file else None
    jobs, sources = [], []
    for p in sorted(anno_dir.glob("*.pkl")):
        seq_key = p.stem.replace("++", "/")
        prog_path = root / "program" / "program_info" / f"{p.stem}.json"
        origin = f"anno_preview/{p.name}"
        try:
            check_id(seq_id(seq_key), "sequence key", origin)
            prims = primitives(_read_json(prog_path, seq_key), f"{seq_key}: program_info")
        except (InvalidIdError, SequenceError) as exc:
            jobs.append(invalid_id_job(seq_id(seq_key), str(exc), out, config.mode))
            sources.append(origin)
            continue
        for key, name, _, _, _ in prims:
            cid = f"{seq_id(seq_key)}.{name}"
            split = (splits.get(cid) or splits.get(seq_id(seq_key))) if splits is not None else official_split(seq_key)
            sha = file_sha256([p, prog_path], extra=f"{cid}|{key}|{LOADER_VERSION}|" + config.sha256())
            loader, args = load_primitive, (str(root), seq_key, key, name, str(body_models), float(config.fps))
            if split is None:
                split, loader, args = "unknown", fail_unit, (f"{cid}: {origin}: sequence not in the split lists",)
            jobs.append((cid, split, sha, str(out), loader, args, config.mode))
            sources.append(f"{origin}#{key}")
    return refuse_duplicates(jobs, sources)
