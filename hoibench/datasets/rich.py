"""RICH -> :class:`HOISequence` clips: **RICH-CAT (hoibench rebuild)**.

RICH-CAT (26 actions, template texts, 22-joint contacts) is described in the CATMO paper but
its data and code were never released; hoibench rebuilds it from RICH's release. Clips carry
``provenance["label"] = "RICH-CAT (hoibench rebuild)"``; texts come from the annotator.

Raw layout (RICH's release as its toolkit, paulchhuang/rich_toolkit, expects it; ``ROOT``
may be the toolkit folder holding ``data/``; hoibench also writes it with
:func:`hoibench.datasets.synthetic_layouts.write_rich_layout`)::

    ROOT/bodies/<split>/<seq>/<frame:05d>/<sub:03d>.pkl      SMPL-X parameters of one frame
    ROOT/human_scene_contact/<split>/<seq>/<frame:05d>/<sub:03d>.pkl   {'contact': (6890,)}
    ROOT/multicam2world/<Scene>[_<variant>]_multicam2world.json        {"R", "t", "c"}
    ROOT/resource/meta/{train,val,test}.txt   toolkit meta: seq, scene, scan, subject, _, gender
    ROOT/resource/gender.json                 {"<subject id>": "male" | "female"}

``<seq>`` is ``<Scene>_<sub>[_<sub2>]_<action><take>`` (e.g. ``Gym_010_pushup1``); a frame
folder holds one pickle per subject. Facts (rich_toolkit's ``smplx2images.py``,
``multicam2world.py``, ``hsc_params.py`` and ``README.md``):

* body pickles hold batch-first (1, D) arrays: ``betas`` (10), ``global_orient``,
  ``body_pose`` (63), ``left_hand_pose`` / ``right_hand_pose`` (12-D PCA), ``jaw_pose``,
  ``leye_pose``, ``reye_pose``, ``expression`` (10), ``transl``; the toolkit poses them with
  ``SMPLX(num_pca_comps=12, flat_hand_mean=False)``;
* they live in the calibrated multi-camera frame (camera 0 = identity), not gravity aligned;
  ``multicam2world`` maps that frame to the scan's z-up world as row vectors,
  ``X_world = c * X @ R + t`` (a similarity: ``c`` is a scale; some ``R`` are rounded to
  three decimals, so not exactly orthonormal). LectureHall has two scans (chair / yoga):
  the json is chosen from the meta file's scan name (``scan_<v>[_scene]_camcoord`` ->
  ``<Scene>_<v>_multicam2world.json``), else from the same mapping shipped as
  ``rich_scans.json``, else ``<Scene>_multicam2world.json`` (never guessed by action).
  Gym's table sequences name a ``scan_table_camcoord`` whose ``Gym_table_multicam2world.json``
  the release's README does not list: when it is absent they use ``Gym_multicam2world.json``,
  and the manifest's warnings name them (LectureHall ships both variants: never a fallback);
* ``human_scene_contact`` pickles hold ``contact`` (6890,) per-vertex 0/1 labels in **SMPL**
  topology (plus SMPL-X distance fields hoibench does not read);
* frame ids are 5-digit, start anywhere and may skip.

.. warning::
   Body and contact files are Python pickles: they are unpickled (``pickle.load``), which
   can run code. Only point hoibench at the RICH files you downloaded yourself.

Conversion (per subject of a sequence):

1. Frames: a frame id that does not follow its predecessor (id + 1) ends a run; gaps are
   never interpolated. Each run is resampled by time from ``SOURCE_FPS`` (30) to ``fps``
   (rotations by quaternion slerp, the rest linearly) and cut, from its start, into clips
   of 192, 128 or 64 frames (greedy: the longest that still fits; a remainder shorter than
   64 frames is dropped) -- RICH-CAT's clip lengths. One unit = one clip; its id is
   ``<seq>_<sub>_<first source frame id:05d>``.
2. Body: SMPL-X of the subject's gender (meta file, else ``gender.json``), hand PCA turned
   into axis-angle with the model's own components (``flat_hand_mean=False``: the hand mean
   is added by the model), expression included -- the toolkit's mesh, exactly. The stored
   parameters keep the expression and the hand convention as arrays (``expression``,
   ``flat_hand_mean``; :func:`hoibench.bodies.clip_body_forward` reads both), and the clip
   records ``body_params_max_dev_m``, the measured distance between the mesh they rebuild
   and the toolkit's.
3. Frame: camera 0 -> z-up world (``c X R + t``) -> y-up (``F = Rx(-90 deg)``, as OMOMO):
   joints and vertices are mapped with the full similarity, so they are exactly the
   toolkit's. The stored SMPL-X parameters get the rotation part (the nearest rotation to
   ``F R^T``) about the pelvis and the pelvis lands exactly; their mesh is the toolkit's
   scaled by ``1/c`` about the pelvis (exact when ``c = 1``; ``c`` is recorded).
4. Floor: per clip, y is shifted so the lowest body vertex sits at y = 0 (recorded).
5. Contacts: every SMPL vertex goes to the joint of its largest skinning weight (hand and
   finger joints to their wrist, SMPL-X face joints to the head); a joint is in contact in
   a frame when any of its vertices is (OR). The weights come from SMPL-topology model
   files under ``body_models`` (``smplh/`` or ``smpl/``; hoibench's proxy SMPL-H for
   synthetic data), else from SMPL-X's weights carried to SMPL topology by SMPL-X's
   deformation transfer setup (:func:`contact_joint_map`); with neither, clips are
   prepared without contacts and :func:`prepare_warnings` says what to add. Output frames
   take the nearest source frame's labels.
6. No object: RICH's scenes are static (``object_name`` None).
"""
from __future__ import annotations

import json
import pickle
import re
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..core import geometry as geo
from ..core import plausibility as pl
from ..core.ids import InvalidIdError, check_id
from ..core.skeleton import NUM_JOINTS
from ..core.io import read_json_file, read_text_file
from .behave import SequenceError, _lerp, _slerp_resample, load_split_file
from .omomo import ZUP_TO_YUP
from .rich_contacts import (SMPL_NUM_VERTICES, ContactMapUnavailable, contact_joint_map, joint_contacts,
                            read_deftrafo, vertex_joint_map)
from .sequence import BodyParams, HOISequence

__all__ = ["SOURCE_FPS", "CLIP_LENGTHS", "LABEL", "SequenceError", "ContactMapUnavailable", "split_runs",
           "cut_lengths", "vertex_joint_map", "joint_contacts", "contact_joint_map", "read_deftrafo", "read_frame",
           "load_clip", "prepare_warnings", "prepare_jobs", "transform_path", "shipped_scans",
           "scene_fallbacks"]

SOURCE_FPS = 30.0
CLIP_LENGTHS = (192, 128, 64)
LABEL = "RICH-CAT (hoibench rebuild)"
_BODY_KEYS = ("betas", "global_orient", "body_pose", "transl")
_KNOWN_KEYS = _BODY_KEYS + ("left_hand_pose", "right_hand_pose", "jaw_pose", "leye_pose", "reye_pose",
                            "expression")
_WIDTH = {"global_orient": (3,), "body_pose": (63,), "transl": (3,), "jaw_pose": (3,), "leye_pose": (3,),
          "reye_pose": (3,)}
_FRAME = re.compile(r"^\d{5}$")
#: ``bodies/<split>`` folders a complete download has; a missing one is reported (the
#: manifest's ``incomplete``) instead of giving a store without that split.
REQUIRED_SPLITS = ("train", "test")
_SCAN_VARIANT = re.compile(r"^scan_(\w+?)(?:_scene)?_camcoord$")


# --------------------------------------------------------------------------- frames and clips
def split_runs(frame_ids) -> list[list[int]]:
    """Sorted frame ids -> runs of consecutive ids (a gap, id != previous + 1, ends a run)."""
    ids = sorted(int(i) for i in frame_ids)
    runs: list[list[int]] = []
    for i in ids:
        if runs and i == runs[-1][-1] + 1:
            runs[-1].append(i)
        else:
            runs.append([i])
    return runs


def cut_lengths(n: int, lengths=CLIP_LENGTHS) -> list[tuple[int, int]]:
    """Cut ``n`` frames, from the start, into clips of the given lengths (greedy: the longest
    that still fits); a remainder shorter than the shortest length is dropped.
    Returns ``[(start, length), ...]``."""
    out, a = [], 0
    shortest = min(lengths)
    while n - a >= shortest:
        L = max(x for x in lengths if x <= n - a)
        out.append((a, L))
        a += L
    return out


def _n_resampled(n_src: int, fps: float) -> int:
    """Frames of a run of ``n_src`` consecutive source frames resampled to ``fps``
    (``behave.resample_times`` of ``arange(n_src) / SOURCE_FPS``)."""
    return int(np.floor((n_src - 1) / SOURCE_FPS * fps + 1e-9)) + 1


def prepare_warnings(root: str | Path, body_models: str | Path) -> list[str]:
    """Dataset-level warnings for ``hoibench prepare`` (recorded in the manifest): clips are
    prepared without contact labels when no model files map them to joints; sequences whose
    scan's ``multicam2world`` variant is absent use their scene's file (:func:`scene_fallbacks`)."""
    out = []
    try:
        contact_joint_map(str(Path(body_models)))
    except ContactMapUnavailable as exc:
        out.append(f"rich: clips are prepared WITHOUT contact labels: {exc}")
    try:
        fallbacks = scene_fallbacks(root)
    except FileNotFoundError:
        fallbacks = {}
    for variant, seqs in sorted(fallbacks.items()):
        scene = variant.split("_")[0]
        out.append(f"rich: multicam2world/{variant}_multicam2world.json is absent; {', '.join(seqs)} use "
                   f"multicam2world/{scene}_multicam2world.json (the release's README lists only that file)")
    return out


def scene_fallbacks(root: str | Path) -> dict[str, list[str]]:
    """``{"<Scene>_<v>": [sequence, ...]}``: sequences under ``bodies/`` whose scan names a
    ``multicam2world`` variant that is absent, so that :func:`transform_path` gives them the
    scene's file (one-scan-file scenes only; see :data:`MULTI_SCAN_SCENES`)."""
    root = Path(root)
    data_root = _data_root(root)
    meta = read_meta(_resource_dir(root, data_root))
    scans = {seq: info.get("scan") for (seq, _), info in meta.items()}
    out: dict[str, list[str]] = {}
    for split_path in sorted(p for p in (data_root / "bodies").iterdir() if p.is_dir()):
        for seq_path in sorted(p for p in split_path.iterdir() if p.is_dir()):
            seq = seq_path.name
            scan = scans.get(seq) or shipped_scans().get(seq)
            m = _SCAN_VARIANT.match(scan) if scan else None
            if m is None:
                continue
            variant = f"{seq.split('_')[0]}_{m.group(1)}"
            if transform_path(data_root, seq, scan).name != f"{variant}_multicam2world.json":
                out.setdefault(variant, []).append(seq)
    return out


# --------------------------------------------------------------------------- reading
def _rel(path: Path, data_root: Path) -> str:
    try:
        return str(path.relative_to(data_root))
    except ValueError:
        return str(path)


def _unpickle(path: Path, seq: str, data_root: Path):
    rel = _rel(path, data_root)
    if not path.is_file():
        raise SequenceError(f"{seq}: missing file {rel}")
    try:
        from ..core.io import check_regular_file
        check_regular_file(path, "RICH pickle")
        with open(path, "rb") as fh:  # read-ok: RICH's release is pickles (own download, docs/security.md)
            return pickle.load(fh, encoding="latin1")  # read-ok: RICH's release is pickles (own download)
    except Exception as exc:
        raise SequenceError(f"{seq}: {rel}: unreadable pickle ({type(exc).__name__}: {exc})") from None


def read_frame(path: str | Path, seq: str, data_root: str | Path | None = None) -> dict[str, np.ndarray]:
    """One RICH body pickle -> {key: (D,) float64}; SequenceError naming the sequence and
    file for a missing, unreadable or malformed file."""
    path = Path(path)
    data_root = Path(data_root) if data_root is not None else path.parent
    d = _unpickle(path, seq, data_root)
    rel = _rel(path, data_root)
    if not isinstance(d, dict):
        raise SequenceError(f"{seq}: {rel}: expected a dict of SMPL-X parameters, got {type(d).__name__}")
    out = {}
    for k in _KNOWN_KEYS:                 # other keys of the release are not read
        if k not in d:
            continue
        v = d[k]
        try:   # real dtype (complex refused, never cast to real), finite
            a = pl.real_array(v, k, f"{seq}: {rel}")
        except ValueError as exc:
            raise SequenceError(str(exc)) from None
        if a.ndim == 2 and a.shape[0] == 1:
            a = a[0]
        if a.ndim != 1:
            raise SequenceError(f"{seq}: {rel}: {k}: expected shape (1, D), got {np.shape(v)}")
        out[k] = a
    for k in _BODY_KEYS:
        if k not in out:
            raise SequenceError(f"{seq}: {rel}: missing key {k!r}")
    for k, w in _WIDTH.items():
        if k in out and out[k].shape != w:
            raise SequenceError(f"{seq}: {rel}: {k}: expected {w[0]} values, got {out[k].shape[0]}")
    if not 1 <= out["betas"].shape[0] <= pl.MAX_BETAS:
        raise SequenceError(f"{seq}: {rel}: betas: expected 1..{pl.MAX_BETAS} values, got {out['betas'].shape[0]}")
    for k in ("left_hand_pose", "right_hand_pose"):
        if k in out and not 1 <= out[k].shape[0] <= 45:
            raise SequenceError(f"{seq}: {rel}: {k}: expected 1..45 values (PCA or axis-angle), got "
                                f"{out[k].shape[0]}")
    return out


def _stack(frames: list[dict], key: str, width: int | None, seq: str) -> np.ndarray:
    present = [key in f for f in frames]
    if not any(present):
        return np.zeros((len(frames), width or 0))
    if not all(present):
        raise SequenceError(f"{seq}: {key}: present in some frames only")
    widths = {f[key].shape[0] for f in frames}
    if len(widths) != 1:
        raise SequenceError(f"{seq}: {key}: width changes between frames ({sorted(widths)})")
    return np.stack([f[key] for f in frames])


@lru_cache(maxsize=16)
def _body_model(model_dir: str, gender: str, num_betas: int, num_expr: int, num_pca: int):
    from ..bodies.smpl import load_body_model
    gender = check_id(gender, "gender")
    return load_body_model(model_dir, "smplx", gender, num_betas=num_betas,
                           num_expression_coeffs=max(num_expr, 1), use_pca=False,
                           flat_hand_mean=False, num_pca_comps=max(num_pca, 1))


def _hand_aa(pose: np.ndarray, components: np.ndarray, key: str, seq: str) -> np.ndarray:
    """(T, k) hand pose -> (T, 45) axis-angle: k = 45 is axis-angle already, else PCA
    coefficients times the model's first k components (what smplx does with use_pca)."""
    k = pose.shape[1]
    if k == 0:
        return np.zeros((len(pose), 45))
    if k == 45:
        return pose
    comp = np.asarray(components, dtype=np.float64)
    if comp.shape[0] < k:
        raise SequenceError(f"{seq}: {key}: {k} PCA coefficients, the model has {comp.shape[0]} components")
    return pose @ comp[:k]


def _smplx_forward(model, pose55, betas, expr, transl, chunk: int = 256):
    """SMPL-X forward with every parameter (expression included): joints (T, 22, 3) float64,
    vertices (T, V, 3) float32."""
    import torch
    buf = next(model.buffers())
    dt, dev = buf.dtype, buf.device
    tens = lambda x: torch.from_numpy(np.ascontiguousarray(x, dtype=np.float64)).to(device=dev, dtype=dt)  # noqa: E731
    J, V = [], []
    saved = getattr(model, "batch_size", None)
    try:
        model.batch_size = 1      # smplx repeats its landmark coefficients batch_size times
        with torch.no_grad():
            for s in range(0, len(pose55), chunk):
                p = pose55[s:s + chunk]
                n = len(p)
                out = model(betas=tens(betas[s:s + chunk]), expression=tens(expr[s:s + chunk]),
                            global_orient=tens(p[:, 0]), body_pose=tens(p[:, 1:22].reshape(n, 63)),
                            jaw_pose=tens(p[:, 22]), leye_pose=tens(p[:, 23]), reye_pose=tens(p[:, 24]),
                            left_hand_pose=tens(p[:, 25:40].reshape(n, 45)),
                            right_hand_pose=tens(p[:, 40:55].reshape(n, 45)),
                            transl=tens(transl[s:s + chunk]), return_verts=True)
                J.append(out.joints[:, :NUM_JOINTS].cpu().numpy().astype(np.float64))
                V.append(out.vertices.cpu().numpy())
    finally:
        if saved is not None:
            model.batch_size = saved
    return np.concatenate(J), np.concatenate(V)


def _read_transform(path: Path, seq: str) -> tuple[float, np.ndarray, np.ndarray]:
    from ..core.io import MAX_SMALL_JSON_BYTES, read_json_file
    if not Path(path).exists():
        raise SequenceError(f"{seq}: missing multicam2world file {Path(path).name}")
    try:
        d = read_json_file(path, MAX_SMALL_JSON_BYTES, "multicam2world file")
        c = float(d["c"])
        R = np.asarray(d["R"], dtype=np.float64).reshape(3, 3)
        t = np.asarray(d["t"], dtype=np.float64).reshape(3)
    except FileNotFoundError:
        raise SequenceError(f"{seq}: missing multicam2world file {Path(path).name}") from None
    except (json.JSONDecodeError, KeyError, TypeError, ValueError) as exc:
        raise SequenceError(f"{seq}: {Path(path).name}: expected JSON with 'R' (3x3), 't' (3), 'c' "
                            f"({type(exc).__name__}: {exc})") from None
    if not (np.isfinite(R).all() and np.isfinite(t).all() and np.isfinite(c) and c > 0):
        raise SequenceError(f"{seq}: {Path(path).name}: non-finite R/t or non-positive c")
    if abs(np.linalg.det(R) - 1.0) > 1e-2 or np.abs(R.T @ R - np.eye(3)).max() > 1e-2:
        raise SequenceError(f"{seq}: {Path(path).name}: R is not (close to) a rotation")
    return c, R, t


def _nearest_rotation(M: np.ndarray) -> np.ndarray:
    U, _, Vt = np.linalg.svd(M)
    R = U @ Vt
    if np.linalg.det(R) < 0:
        U[:, -1] *= -1
        R = U @ Vt
    return R


def _read_source(data_root: Path, split_dir: str, seq: str, sub: str, ids: np.ndarray, body_models: str | Path,
                 gender: str) -> tuple:
    """Read the clip's source frames ``ids`` and assemble, at the source rate, the SMPL-X
    model and parameters: ``(model, pose (N, 55, 3), transl, betas, expr, raw_files)``."""
    body_dir = data_root / "bodies" / split_dir / seq
    frames = [read_frame(body_dir / f"{i:05d}" / f"{sub}.pkl", seq, data_root) for i in ids]
    raw_files = f"bodies/{split_dir}/{seq}/{{{ids[0]:05d}..{ids[-1]:05d}}}/{sub}.pkl"
    N = len(frames)
    betas = _stack(frames, "betas", None, seq)
    expr = _stack(frames, "expression", 0, seq)
    lh = _stack(frames, "left_hand_pose", 0, seq)
    rh = _stack(frames, "right_hand_pose", 0, seq)
    model = _body_model(str(Path(body_models)), gender, betas.shape[1], expr.shape[1],
                        max(lh.shape[1] if lh.shape[1] != 45 else 0, rh.shape[1] if rh.shape[1] != 45 else 0, 12))
    if expr.shape[1] == 0:
        expr = np.zeros((N, model.num_expression_coeffs))
    pose = np.zeros((N, 55, 3))
    pose[:, 0] = _stack(frames, "global_orient", 3, seq)
    pose[:, 1:22] = _stack(frames, "body_pose", 63, seq).reshape(N, 21, 3)
    for j, k in ((22, "jaw_pose"), (23, "leye_pose"), (24, "reye_pose")):
        pose[:, j] = _stack(frames, k, 3, seq)
    pose[:, 25:40] = _hand_aa(lh, model.np_left_hand_components, "left_hand_pose", seq).reshape(N, 15, 3)
    pose[:, 40:55] = _hand_aa(rh, model.np_right_hand_components, "right_hand_pose", seq).reshape(N, 15, 3)
    transl = _stack(frames, "transl", 3, seq)
    pl.check_track(transl, f"transl (row 0 = frame {ids[0]:05d})", f"{seq}: {raw_files}", fps=SOURCE_FPS)
    return model, pose, transl, betas, expr, raw_files


def _to_world(transform_file: str | Path, seq: str, joints_c: np.ndarray,
              verts_c: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """Camera-0 joints to the y-up world, floor at the lowest vertex of the clip. Returns
    ``(c, R, A, b, joints, floor)``: ``p_world = A p_cam + b`` before the floor shift."""
    # camera 0 -> z-up world (X c R + t, row vectors) -> y-up; exact similarity for points
    c, R, t = _read_transform(Path(transform_file), seq)
    F = ZUP_TO_YUP
    A = c * F @ R.T
    b = F @ t
    joints = joints_c @ A.T + b
    floor = float((verts_c.reshape(-1, 3).astype(np.float64) @ A[1]).min() + b[1])
    joints[..., 1] -= floor
    return c, R, A, b, joints, floor


def _world_params(model, R: np.ndarray, A: np.ndarray, b: np.ndarray, floor: float, joints_c: np.ndarray,
                  verts_c: np.ndarray, pose_r: np.ndarray, transl_r: np.ndarray, betas_r: np.ndarray,
                  expr_r: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """The SMPL-X parameters in the world, as stored (float32), and how far the mesh they
    rebuild is from the toolkit's: ``(pose, betas, trans, expression, max deviation m)``."""
    F = ZUP_TO_YUP
    # parameters: rotation part about the pelvis, pelvis exactly on the mapped pelvis
    Rr = _nearest_rotation(F @ R.T)
    j0 = joints_c[:, 0] - transl_r                         # per-frame rest pelvis
    pose_w = pose_r.copy()
    pose_w[:, 0] = geo.matrix_to_axis_angle(Rr @ geo.axis_angle_to_matrix(pose_r[:, 0]))
    trans_w = (j0 + transl_r) @ A.T + b - j0
    trans_w[:, 1] -= floor
    betas_out = betas_r[0] if np.allclose(betas_r, betas_r[:1], atol=1e-6) else betas_r
    pose_store = np.concatenate([pose_w[:, 0], pose_w[:, 1:22].reshape(-1, 63), pose_w[:, 22:25].reshape(-1, 9),
                                 pose_w[:, 25:].reshape(-1, 90)], 1).astype(np.float32)
    betas_store = np.asarray(betas_out, dtype=np.float32)
    trans_store, expr_store = trans_w.astype(np.float32), expr_r.astype(np.float32)
    # what the stored parameters rebuild, measured against the toolkit's mesh in the store's frame
    n_out = len(pose_store)
    rebuilt = _smplx_forward(model, pose_store.astype(np.float64).reshape(n_out, 55, 3),
                             np.broadcast_to(betas_store, (n_out, betas_store.shape[-1])), expr_store, trans_store)[1]
    toolkit = verts_c.astype(np.float64) @ A.T + b
    toolkit[..., 1] -= floor
    params_dev = float(np.linalg.norm(rebuilt.astype(np.float64) - toolkit, axis=-1).max())
    return pose_store, betas_store, trans_store, expr_store, params_dev


def _clip_contacts(data_root: Path, split_dir: str, seq: str, sub: str, ids: np.ndarray,
                   body_models: str | Path, with_contacts: bool, src_t: np.ndarray,
                   dst: np.ndarray) -> tuple[np.ndarray | None, str | None]:
    """Per-joint contacts at the output times from ``human_scene_contact`` (nearest source
    frame), or None where not asked for or absent; and the contact map's source."""
    N = len(ids)
    contacts, cmap_src = None, None
    contact_dir = data_root / "human_scene_contact" / split_dir / seq
    if with_contacts and contact_dir.is_dir():
        vmap, cmap_src = contact_joint_map(str(Path(body_models)))   # fails the clip before reading labels
        labels = []
        for i in ids:
            cpath = contact_dir / f"{i:05d}" / f"{sub}.pkl"
            d = _unpickle(cpath, seq, data_root)
            lab = None
            if isinstance(d, dict) and "contact" in d:
                try:
                    lab = pl.real_array(d["contact"], "contact", str(cpath)).reshape(-1)
                except ValueError:
                    lab = None
            if lab is None or lab.shape != (SMPL_NUM_VERTICES,) or not np.isfinite(lab).all():
                raise SequenceError(f"{seq}: {_rel(cpath, data_root)}: expected 'contact' with "
                                    f"{SMPL_NUM_VERTICES} finite SMPL-vertex labels")
            labels.append(lab)
        jc = joint_contacts(np.stack(labels), vmap)
        nearest = np.clip(np.searchsorted(src_t, dst - 0.5 / SOURCE_FPS), 0, N - 1)
        contacts = jc[nearest]
    return contacts, cmap_src


def load_clip(data_root: str | Path, split_dir: str, seq: str, sub: str, frame_ids, run_first: int,
              out_start: int, length: int, fps: float, body_models: str | Path, gender: str,
              transform_file: str | Path, with_contacts: bool = True, clip_id: str | None = None
              ) -> HOISequence:
    """Load one RICH-CAT clip: output frames ``out_start .. out_start + length - 1`` of the
    run starting at source frame ``run_first`` (resampled to ``fps``), from the source
    frames ``frame_ids`` (consecutive, covering the clip). See the module docstring."""
    data_root = Path(data_root)
    for value, what in ((split_dir, "split folder"), (seq, "sequence folder"), (sub, "subject file name")):
        try:
            check_id(value, what, data_root / "bodies")
        except InvalidIdError as exc:
            raise SequenceError(f"{clip_id or seq}: {exc}") from None
    fps = pl.check_fps(fps, "fps", clip_id or seq)
    if gender not in pl.GENDERS:
        raise SequenceError(f"{clip_id or seq}: gender {gender!r} of subject {sub}: expected one of {pl.GENDERS}")
    ids = np.asarray(frame_ids, dtype=np.int64)
    if len(ids) < 1 or np.any(np.diff(ids) != 1):
        raise SequenceError(f"{seq}: frame ids of a clip must be consecutive, got {ids[:5].tolist()}...")
    model, pose, transl, betas, expr, raw_files = _read_source(data_root, split_dir, seq, sub, ids, body_models,
                                                              gender)
    N = len(ids)
    # resample by time (the run's clock: source frame i at (i - run_first) / 30 s)
    src_t = (ids - int(run_first)) / SOURCE_FPS
    dst = (int(out_start) + np.arange(int(length))) / float(fps)
    if dst[0] < src_t[0] - 1e-9 or dst[-1] > src_t[-1] + 1e-9:
        raise SequenceError(f"{seq}: clip times {dst[0]:.3f}..{dst[-1]:.3f} s outside the loaded frames "
                            f"{src_t[0]:.3f}..{src_t[-1]:.3f} s")
    if N == 1:
        pose_r, transl_r, betas_r, expr_r = pose, transl, betas, expr
    else:
        pose_r = _slerp_resample(src_t, dst, pose)
        transl_r, betas_r, expr_r = (_lerp(src_t, dst, x) for x in (transl, betas, expr))
    joints_c, verts_c = _smplx_forward(model, pose_r, betas_r, expr_r, transl_r)

    c, R, A, b, joints, floor = _to_world(transform_file, seq, joints_c, verts_c)
    pose_store, betas_store, trans_store, expr_store, params_dev = _world_params(
        model, R, A, b, floor, joints_c, verts_c, pose_r, transl_r, betas_r, expr_r)

    contacts, cmap_src = _clip_contacts(data_root, split_dir, seq, sub, ids, body_models, with_contacts,
                                        src_t, dst)

    scene = seq.split("_")[0]
    name = clip_id or f"{seq}_{sub}_{int(ids[0]):05d}"
    return HOISequence(
        name=name, dataset="rich-cat", subject=str(sub), fps=float(fps),
        joints=joints.astype(np.float32), contacts=contacts,
        body=BodyParams("smplx", gender, betas_store, pose_store, trans_store, flat_hand_mean=False,
                        expression=expr_store),
        provenance={"label": LABEL, "source": "rich", "sequence": seq, "scene": scene, "split_folder": split_dir,
                    "subject": str(sub), "gender": gender,
                    "source_frames": [int(ids[0]), int(ids[-1])], "run_first_frame": int(run_first),
                    "raw_source": f"{raw_files}, multicam2world/{Path(transform_file).name}",
                    "clip_output_frames": [int(out_start), int(out_start) + int(length)],
                    "source_fps": SOURCE_FPS, "resampled_to_fps": float(fps),
                    "source_frame": "RICH multi-camera frame (camera 0), not gravity aligned",
                    "transform": "p_yup = Rx(-90 deg) (c * p_cam @ R + t); y -= floor",
                    "multicam2world": Path(transform_file).name, "world_scale_c": c,
                    "world_R_orthonormality_error": float(np.abs(R.T @ R - np.eye(3)).max()),
                    "body_params_max_dev_m": params_dev,
                    "body_params_note": (f"measured: the stored SMPL-X parameters (flat_hand_mean=False, with "
                                         f"expression) rebuild the toolkit's mesh to {params_dev:.2e} m (largest "
                                         f"vertex distance over the clip); joints are the toolkit's mapped exactly"
                                         + ("" if abs(c - 1.0) < 1e-9 else
                                            f"; the parameters are rigid, so the mesh is the toolkit's scaled "
                                            f"by 1/c = {1 / c:.6g} about the pelvis")),
                    "floor_shift_m": floor,
                    "hands": "PCA -> axis-angle with the model's components; stored with flat_hand_mean=False "
                             "(the clip's flat_hand_mean array)",
                    "expression": f"{expr_store.shape[1]} SMPL-X expression coefficients stored (the clip's "
                                  f"expression array)",
                    "contacts": (None if contacts is None else
                                 f"human_scene_contact (6890 SMPL vertices) -> joint of largest skinning weight "
                                 f"({cmap_src}), OR over each joint's vertices; nearest source frame")},
    )


# --------------------------------------------------------------------------- jobs
def _data_root(root: Path) -> Path:
    for cand in (root, root / "data"):
        if (cand / "bodies").is_dir():
            return cand
    raise FileNotFoundError(f"--root: no 'bodies' folder in {root} or {root / 'data'} (expected RICH's release)")


def _resource_dir(root: Path, data_root: Path) -> Path | None:
    for cand in dict.fromkeys((root / "resource", data_root / "resource", data_root.parent / "resource")):
        if cand.is_dir():
            return cand
    return None


def read_meta(resource: Path | None) -> dict[tuple[str, str], dict]:
    """rich_toolkit's ``resource/meta/{train,val,test}.txt`` (tab-separated: seq, scene,
    scan, subject, _, gender, ...) -> {(seq, subject): {"scene", "scan", "gender", "split"}}."""
    out: dict[tuple[str, str], dict] = {}
    if resource is None:
        return out
    for split in ("train", "val", "test"):
        p = resource / "meta" / f"{split}.txt"
        if not p.is_file():
            continue
        for line in read_text_file(p, what="RICH meta file").splitlines():
            cols = line.strip().split("\t")
            if len(cols) >= 6 and cols[0]:
                out[(cols[0], cols[3].zfill(3))] = {"scene": cols[1], "scan": cols[2],
                                                     "gender": cols[5].lower(), "split": split}
    return out


def _gender_json(resource: Path | None) -> dict[str, str]:
    p = resource / "gender.json" if resource is not None else None
    if p is None or not p.is_file():
        return {}
    try:
        data = read_json_file(p, what="gender.json")
        return {str(int(k)): v.lower() for k, v in data.items() if isinstance(v, str)}
    except (AttributeError, ValueError, TypeError) as exc:
        raise ValueError(f"{p}: expected a JSON object {{subject number: gender}} "
                         f"({type(exc).__name__}: {exc})") from None


@lru_cache(maxsize=1)
def shipped_scans() -> dict[str, str]:
    """``{sequence: scan}`` for the RICH sequences whose scene has several scans, as
    rich_toolkit's meta files name them (``hoibench/datasets/rich_scans.json``); used when the
    download has no meta files."""
    data = read_json_file(Path(__file__).with_name("rich_scans.json"), what="shipped scan table")
    return dict(data["scans"])


#: Scenes whose release ships a ``multicam2world`` file per scan (chair / yoga): a missing
#: variant there is an error, never the scene's file. Gym's table scan has no file listed in
#: the release's README, so Gym's table sequences fall back to ``Gym_multicam2world.json``.
MULTI_SCAN_SCENES = ("LectureHall",)


def transform_path(data_root: Path, seq: str, scan: str | None = None) -> Path:
    """The ``multicam2world`` json of a sequence: the scan of the meta files (``scan``), else
    of :func:`shipped_scans`, selects ``<Scene>_<v>_multicam2world.json`` for a scan
    ``scan_<v>[_scene]_camcoord``; ``scan_camcoord`` (or no scan) selects
    ``<Scene>_multicam2world.json``. A variant file that is missing falls back to the
    scene's file, except in scenes with several scans (:data:`MULTI_SCAN_SCENES`), where
    the variant's name is returned (the clip then fails naming it)."""
    folder = data_root / "multicam2world"
    scene = seq.split("_")[0]
    scan = scan or shipped_scans().get(seq)
    m = _SCAN_VARIANT.match(scan) if scan else None
    default = folder / f"{scene}_multicam2world.json"
    if m is None:
        return default
    variant = folder / f"{scene}_{m.group(1)}_multicam2world.json"
    if variant.is_file() or scene in MULTI_SCAN_SCENES or not default.is_file():
        return variant
    return default


def prepare_jobs(root: str | Path, body_models: str | Path, out: str | Path, config,
                 split_file: str | Path | None = None) -> list[tuple]:
    """One :func:`hoibench.datasets.store.run_unit` job per RICH-CAT clip (see the module docstring).

    The split is RICH's (the ``bodies/<split>`` folder: train, val, test) unless
    ``split_file`` (``{"train": [...], "val": [...], "test": [...]}`` of sequence names or
    clip ids) names another; a clip it does not list is an error for that clip. A subject
    of a sequence with no run long enough for one clip is reported as a failed unit.
    """
    from .store import fail_unit, file_sha256, invalid_id_job, refuse_duplicates, source_failure_job
    root = Path(root)
    data_root = _data_root(root)
    resource = _resource_dir(root, data_root)
    meta = read_meta(resource)
    genders = _gender_json(resource)
    splits = load_split_file(split_file) if split_file else None
    fps = float(config.fps)
    try:
        contact_src = contact_joint_map(str(Path(body_models)))[1]
    except ContactMapUnavailable:
        contact_src = None          # clips without contacts (prepare_warnings says what to add)
    jobs, sources = [], []
    for split in REQUIRED_SPLITS:
        if not (data_root / "bodies" / split).is_dir():
            jobs.append(source_failure_job(f"bodies-{split}", f"bodies/{split}: missing in {data_root}: the store "
                                           f"has no {split} split", out, config.mode))
            sources.append(f"bodies/{split}")
    for split_path in sorted(p for p in (data_root / "bodies").iterdir() if p.is_dir()):
        for seq_path in sorted(p for p in split_path.iterdir() if p.is_dir()):
            seq = seq_path.name
            try:
                check_id(split_path.name, "split folder", data_root / "bodies")
                check_id(seq, "sequence folder", split_path)
            except InvalidIdError as exc:
                jobs.append(invalid_id_job(seq_path.name, str(exc), out, config.mode))
                sources.append(str(seq_path))
                continue
            by_sub: dict[str, list[int]] = {}
            for fdir in sorted(p for p in seq_path.iterdir() if p.is_dir() and _FRAME.match(p.name)):
                for f in fdir.iterdir():
                    if f.suffix == ".pkl":
                        by_sub.setdefault(f.stem, []).append(int(fdir.name))
            contact_seq = data_root / "human_scene_contact" / split_path.name / seq
            for sub, ids in sorted(by_sub.items()):
                try:
                    check_id(sub, "subject file name", seq_path / f"{ids[0]:05d}")
                except InvalidIdError as exc:
                    jobs.append(invalid_id_job(f"{seq}_{sub}", str(exc), out, config.mode))
                    sources.append(str(seq_path))
                    continue
                info = meta.get((seq, sub.zfill(3)), {})
                gender = info.get("gender") or (genders.get(str(int(sub))) if sub.isdigit() else None)
                tpath = transform_path(data_root, seq, info.get("scan"))
                runs = split_runs(ids)
                clips = [(run, a, L) for run in runs for a, L in cut_lengths(_n_resampled(len(run), fps))]
                if not clips:
                    cid = f"{seq}_{sub}"
                    msg = (f"{cid}: no run of consecutive frames long enough for a {min(CLIP_LENGTHS)}-frame clip "
                           f"at {fps:g} fps (runs of {', '.join(str(len(r)) for r in runs)} source frames)")
                    jobs.append((cid, split_path.name, "", str(out), fail_unit, (msg,), config.mode))
                    sources.append(f"bodies/{split_path.name}/{seq}/*/{sub}.pkl")
                    continue
                for run, a, L in clips:
                    t0, t1 = a / fps, (a + L - 1) / fps
                    i0 = int(np.floor(t0 * SOURCE_FPS + 1e-9))
                    i1 = min(len(run) - 1, int(np.ceil(t1 * SOURCE_FPS - 1e-9)))
                    fids = tuple(run[i0:i1 + 1])
                    cid = f"{seq}_{sub}_{fids[0]:05d}"
                    files = [seq_path / f"{i:05d}" / f"{sub}.pkl" for i in fids]
                    if contact_seq.is_dir():
                        files += [contact_seq / f"{i:05d}" / f"{sub}.pkl" for i in fids]
                    files.append(tpath)
                    sha = file_sha256(files, extra=f"{seq}|{sub}|{gender}|{run[0]}|{a}|{L}|{contact_src}|"
                                      + config.sha256())
                    loader, args = load_clip, (str(data_root), split_path.name, seq, sub, fids, run[0], a, L, fps,
                                               str(body_models), gender, str(tpath), contact_src is not None, cid)
                    split = split_path.name
                    if splits is not None:
                        split = splits.get(cid, splits.get(seq, "unknown"))
                        if split == "unknown":
                            loader, args = fail_unit, (f"{cid}: neither the clip nor {seq} is listed in split file "
                                                   f"{split_file}",)
                    if gender not in ("male", "female", "neutral"):
                        loader, args = fail_unit, (f"{cid}: gender unknown for subject {sub} of {seq}: put rich_toolkit's "
                                               f"resource/gender.json or resource/meta/*.txt under {root}",)
                    jobs.append((cid, split, sha, str(out), loader, args, config.mode))
                    sources.append(f"bodies/{split_path.name}/{seq}/{fids[0]:05d}/{sub}.pkl")
    return refuse_duplicates(jobs, sources)

