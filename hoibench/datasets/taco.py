"""TACO -> :class:`~hoibench.bodies.multibody.MultiBodyClip` (two hands, a tool, a target).

TACO (Liu et al., "TACO: Benchmarking Generalizable Bimanual Tool-ACtion-Object
Understanding", CVPR 2024; code and data CC BY 4.0 per its README) captures two hands using
a tool on a target object. Facts below come from leolyliu/TACO-Instructions c06f82c
(README "Data Organization", ``dataset_utils/hand_pose_loader.py``,
``dataset_utils/visualization.py``, ``dataset_utils/manopth/manopth/manolayer.py``,
``data_lists/``); *inferred* marks a deduction, not a statement of the authors.
:func:`hoibench.datasets.taco_layout.write_taco_layout` writes this layout license-free.

Layout read (``ROOT`` holds ``Hand_Poses``, ``Object_Poses``, ``Object_Models``)::

    ROOT/Hand_Poses/(<action>, <tool>, <target>)/<date>_<take>/{left,right}_hand.pkl
    ROOT/Hand_Poses/(...)/<seq>/{left,right}_hand_shape.pkl      (optional: zero betas)
    ROOT/Object_Poses/(...)/<seq>/tool_<id>.npy, target_<id>.npy   (T, 4, 4), metres
    ROOT/Object_Models/<id>_cm.obj  (or Object_Models/object_models_released/)  centimetres

* ``<side>_hand.pkl``: a pickle of ``{frame key: {"hand_pose": (48,), "hand_trans": (3,)}}``
  torch tensors, frames in **sorted key order** (``mano_params_to_hand_info``); read by
  :mod:`hoibench.datasets.torch_pickle` without torch or code execution. 48 = global
  axis-angle + 15 finger joints axis-angle, no PCA, ``flat_hand_mean=True`` (manopth's
  default), ``center_idx=0``, output mm / 1000 + ``hand_trans``: the translation is the
  wrist (see :mod:`hoibench.datasets.hand_object`).
* ``<side>_hand_shape.pkl``: ``{"hand_shape": tensor}`` of 10 betas (``read_hand_shape``:
  zeros when absent; recorded as ``betas_source``).
* object ``v_world = P[:3,:3] (0.01 v_cm) + P[:3,3]`` (``visualization.py``), meshes loaded
  by ``trimesh.load`` default processing; ids are the file stem after its last ``_``.
* world **z up**, metres (README axis images; the visualisation camera): mapped to y-up by
  ``(x, y, z) -> (x, z, -y)``. **30 fps** *(inferred: poses 1:1 with the egocentric video)*.
* split: ``data_lists/v1_overall_data_train_test_split.txt`` (embedded,
  :mod:`hoibench.datasets.taco_split`): ``train`` -> train, ``test_1..4`` -> test, the list
  in provenance (``taco_split``). A sequence in no list is refused unless ``split_file``
  names it.

Clip: id ``<date>_<take>``, subject the date, bodies ``left_hand``, ``right_hand``, ``tool``,
``target`` (templates ``taco_<id>``), action the verb, one template text from the triplet
(TACO has no captions), no contacts (none released), no floor shift (tabletop).
Refused, naming the sequence, file and key: pickle globals outside the allow-list; frame
keys not all ints / all digit strings or sorting differently from their numbers; shapes
other than (48,) / (3,) / 10 betas; unequal hand and object frame counts; non-rigid poses;
not exactly one ``tool_*`` and one ``target_*``; a missing mesh; a sequence whose folder
triplet differs from ``data_lists/v1_overall_data_sequences.txt`` (embedded,
:mod:`hoibench.datasets.taco_triplets`; a sequence absent from it is not checked).
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..core import plausibility as pl
from ..core.ids import InvalidIdError, check_id
from ..bodies.multibody import MultiBodyClip
from . import torch_pickle
from .behave import SequenceError, load_split_file, read_mesh, resample_times
from .hand_object import ZUP_TO_YUP, checked_clip, hand_body, object_body, rigid_poses
from .taco_split import TACO_SPLIT
from .taco_triplets import TACO_TRIPLETS

__all__ = ["SOURCE_FPS", "SequenceError", "official_lists", "official_split", "official_triplets", "parse_triplet", "read_hand",
           "read_betas", "load_sequence", "prepare_jobs", "LOADER_VERSION"]

SOURCE_FPS = 30.0
LOADER_VERSION = "taco-1"
SIDES = ("left", "right")
_TRIPLET = re.compile(r"^\(([^,()]+), ([^,()]+), ([^,()]+)\)$")
MAX_PICKLE_BYTES = 256 * 1024 ** 2


def official_lists() -> dict[str, str]:
    """``{<date>_<take>: list name}`` expanded from :data:`TACO_SPLIT`."""
    out = {}
    for name, dates in TACO_SPLIT.items():
        for date, takes in dates.items():
            for tok in takes.split():
                a, _, b = tok.partition("-")
                for k in range(int(a), int(b or a) + 1):
                    out[f"{date}_{k:03d}"] = name
    return out


def official_triplets() -> dict[str, str]:
    """``{<date>_<take>: "(action, tool, target)"}`` expanded from :data:`TACO_TRIPLETS`."""
    out, date = {}, None
    for triplet, text in TACO_TRIPLETS.items():
        for tok in text.split():
            if tok.endswith(":"):
                date = tok[:-1]
                continue
            a, _, b = tok.partition("-")
            for k in range(int(a), int(b or a) + 1):
                out[f"{date}_{k:03d}"] = triplet
    return out


def official_split(seq: str) -> tuple[str, str] | None:
    """(hoibench split, TACO list) of ``seq``, or None when it is in no list."""
    name = official_lists().get(seq)
    return None if name is None else ("train" if name == "train" else "test", name)


def parse_triplet(folder: str) -> tuple[str, str, str]:
    m = _TRIPLET.match(folder)
    if not m:
        raise SequenceError(f"Hand_Poses/{folder}: not a '(action, tool, target)' folder")
    return m.group(1), m.group(2), m.group(3)


def _frame_order(keys: list, where: str) -> list:
    if all(isinstance(k, int) and not isinstance(k, bool) for k in keys):
        return sorted(keys)
    if all(isinstance(k, str) and k.isdigit() for k in keys):
        order = sorted(keys)
        if order != sorted(keys, key=int):
            raise SequenceError(f"{where}: frame keys sort differently as text and as numbers (TACO sorts the text)")
        return order
    raise SequenceError(f"{where}: frame keys: expected all ints or all digit strings, got {keys[:3]!r}")


def read_hand(path: Path, where: str) -> tuple[np.ndarray, np.ndarray]:
    """(pose (T, 48), trans (T, 3)) of a ``<side>_hand.pkl`` in TACO's frame order."""
    if path.is_dir() or not path.is_file():
        raise SequenceError(f"{where}: missing (TACO's release has one pickle per hand, not a folder)")
    try:
        data = torch_pickle.load(path, MAX_PICKLE_BYTES)
    except (torch_pickle.TorchPickleError, OSError) as exc:
        raise SequenceError(f"{where}: {exc}") from None
    if not isinstance(data, dict) or not data:
        raise SequenceError(f"{where}: expected a non-empty dict of frames, got {type(data).__name__}")
    poses, trans = [], []
    for k in _frame_order(list(data), where):
        fr = data[k]
        if not isinstance(fr, dict) or "hand_pose" not in fr or "hand_trans" not in fr:
            raise SequenceError(f"{where}: frame {k!r}: expected keys 'hand_pose' and 'hand_trans'")
        p, t = np.asarray(fr["hand_pose"]), np.asarray(fr["hand_trans"])
        if p.shape != (48,) or t.shape != (3,):
            raise SequenceError(f"{where}: frame {k!r}: hand_pose {p.shape} / hand_trans {t.shape}, "
                                "expected (48,) / (3,)")
        poses.append(p)
        trans.append(t)
    try:
        return (pl.real_array(np.stack(poses), "hand_pose", where), pl.real_array(np.stack(trans), "hand_trans", where))
    except ValueError as exc:
        raise SequenceError(str(exc)) from None


def read_betas(path: Path, where: str) -> tuple[np.ndarray, str]:
    """(10 betas, source): ``hand_shape`` reshaped to 10, or zeros when the file is absent."""
    if not path.is_file():
        return np.zeros(10), "absent: zeros (TACO's read_hand_shape)"
    try:
        data = torch_pickle.load(path, MAX_PICKLE_BYTES)
    except (torch_pickle.TorchPickleError, OSError) as exc:
        raise SequenceError(f"{where}: {exc}") from None
    if not isinstance(data, dict) or "hand_shape" not in data:
        raise SequenceError(f"{where}: expected a dict with 'hand_shape'")
    b = np.asarray(data["hand_shape"], dtype=np.float64)
    if b.size != 10 or not np.isfinite(b).all():
        raise SequenceError(f"{where}: hand_shape: expected 10 finite values, got shape {b.shape}")
    return b.reshape(10), "file"


def _mesh(root: Path, oid: str, where: str) -> tuple[np.ndarray, np.ndarray, str]:
    found = [p for p in (root / "Object_Models" / f"{oid}_cm.obj",
                         root / "Object_Models" / "object_models_released" / f"{oid}_cm.obj") if p.is_file()]
    if len(found) != 1:
        raise SequenceError(f"{where}: object model {oid}_cm.obj: {'missing' if not found else 'found twice'} "
                            "under Object_Models/ (or Object_Models/object_models_released/)")
    v, f = read_mesh(found[0], f"{where}: {found[0].name}", process=True)
    try:
        v, f = pl.check_template(np.asarray(v, np.float64) * 0.01, f, f"{where}: {found[0].name}")
    except ValueError as exc:
        raise SequenceError(str(exc)) from None
    return v, f, found[0].relative_to(root).as_posix()


def _object_files(pose_dir: Path, where: str) -> dict[str, Path]:
    out = {}
    for role in ("tool", "target"):
        files = sorted(pose_dir.glob(f"{role}_*.npy")) if pose_dir.is_dir() else []
        if len(files) != 1:
            raise SequenceError(f"{where}: Object_Poses: expected exactly one {role}_<id>.npy, found {len(files)}")
        out[role] = files[0]
    return out


def load_sequence(hand_dir: str | Path, root: str | Path, body_models: str | Path, fps: float = SOURCE_FPS,
                  taco_list: str | None = None) -> MultiBodyClip:
    """One TACO sequence (``Hand_Poses/<triplet>/<seq>``) -> MultiBodyClip at ``fps``."""
    hand_dir, root = Path(hand_dir), Path(root)
    seq, folder = hand_dir.name, hand_dir.parent.name
    try:
        cid = check_id(seq, "sequence", hand_dir)
    except InvalidIdError as exc:
        raise SequenceError(str(exc)) from None
    fps = pl.check_fps(fps, "fps", cid)
    action, tool_cat, target_cat = parse_triplet(folder)
    listed = official_triplets().get(seq)
    if listed is not None and listed != folder:
        raise SequenceError(f"{cid}: Hand_Poses/{folder}/{seq}: TACO's sequence list puts {seq} under {listed}, "
                            f"not {folder}")
    rel = f"Hand_Poses/{folder}/{seq}"
    hands = {s: read_hand(hand_dir / f"{s}_hand.pkl", f"{cid}: {rel}/{s}_hand.pkl") for s in SIDES}
    betas = {s: read_betas(hand_dir / f"{s}_hand_shape.pkl", f"{cid}: {rel}/{s}_hand_shape.pkl") for s in SIDES}
    pose_dir = root / "Object_Poses" / folder / seq
    files = _object_files(pose_dir, f"{cid}: Object_Poses/{folder}/{seq}")
    T = len(hands["right"][0])
    objs = {}
    for role, path in files.items():
        where = f"{cid}: Object_Poses/{folder}/{seq}/{path.name}"
        try:
            from ..core.io import load_npy_file
            raw = load_npy_file(path, what="TACO object pose file")
        except Exception as exc:
            raise SequenceError(f"{where}: unreadable ({type(exc).__name__}: {str(exc)[:120]})") from None
        R, t, corr = rigid_poses(raw, where)
        oid = path.stem.split("_")[-1]
        objs[role] = (oid, R, t, corr, _mesh(root, oid, where))
    counts = {**{f"{s}_hand.pkl": len(hands[s][0]) for s in SIDES}, **{files[r].name: len(objs[r][1]) for r in objs}}
    if len(set(counts.values())) != 1:
        raise SequenceError(f"{cid}: frame counts differ: {counts}")
    if T < 2:
        raise SequenceError(f"{cid}: {T} frame(s); a clip needs at least 2")
    src_t = np.arange(T) / SOURCE_FPS
    dst = resample_times(src_t, fps)
    F = ZUP_TO_YUP
    bodies = [hand_body(f"{s}_hand", s, body_models, hands[s][0].reshape(T, 16, 3), np.repeat(betas[s][0][None], T, 0),
                        hands[s][1], src_t, dst, F) for s in SIDES]
    templates, obj_prov = {}, {}
    for role, (oid, R, t, corr, (v, f, mesh_rel)) in objs.items():
        name = f"taco_{oid}"
        try:
            check_id(name, "template name", mesh_rel)
        except InvalidIdError as exc:
            raise SequenceError(f"{cid}: {exc}") from None
        mean = v.mean(0)
        templates[name] = (v - mean, f)
        bodies.append(object_body(role, name, R, t, mean, src_t, dst, F))
        obj_prov[role] = {"id": oid, "mesh": mesh_rel, "rotation_correction_max": corr}
    split_list = taco_list or (official_split(seq) or (None, None))[1]
    prov = {"source": "taco", "triplet": [action, tool_cat, target_cat], "tool": tool_cat, "target": target_cat,
            "objects": obj_prov, "taco_split": split_list, "source_fps": SOURCE_FPS, "source_frames": T,
            "resampled_to_fps": float(fps), "betas": {s: betas[s][0].tolist() for s in SIDES},
            "betas_source": {s: betas[s][1] for s in SIDES},
            "source_frame": "TACO world, z-up, metres", "transform": "p_yup = (x, z, -y)", "floor_shift_m": 0.0,
            "hand_model": "mano (use_pca=False, flat_hand_mean=True); joints - joint0 + hand_trans; tips at smplx "
                          "MANO vertices 744, 320, 443, 554, 671", "loader": LOADER_VERSION}
    text = {"text": f"{action} the {target_cat} with the {tool_cat}.", "source": "taco-triplet-template",
            "start": 0, "end": len(dst)}
    clip = MultiBodyClip(name=cid, dataset="taco", subject=seq.split("_")[0], fps=float(fps), bodies=bodies,
                         templates=templates, action=action, texts=[text], provenance=prov)
    return checked_clip(clip, cid)


def prepare_jobs(root: str | Path, body_models: str | Path, out: str | Path, config,
                 split_file: str | Path | None = None) -> list[tuple]:
    """One job per ``Hand_Poses/<triplet>/<seq>`` folder; split from TACO's lists unless
    ``split_file`` names another; an unlisted sequence fails."""
    from .store import fail_unit, file_sha256, refuse_duplicates, refused_id_job
    root = Path(root)
    hp = root / "Hand_Poses"
    if not hp.is_dir():
        raise FileNotFoundError(f"--root: no 'Hand_Poses' folder in {root} (expected TACO's release layout)")
    splits = load_split_file(split_file) if split_file else None
    jobs, sources = [], []
    for tri in sorted(p for p in hp.iterdir() if p.is_dir()):
        for sd in sorted(p for p in tri.iterdir() if p.is_dir()):
            cid, origin = sd.name, f"Hand_Poses/{tri.name}/{sd.name}"
            refused = refused_id_job(cid, "sequence folder", origin, out, config.mode)
            if refused:
                jobs.append(refused)
                sources.append(origin)
                continue
            listed = official_split(cid)
            split = splits.get(cid) if splits is not None else (listed[0] if listed else None)
            poses = sorted((root / "Object_Poses" / tri.name / sd.name).glob("*.npy"))
            meshes = [m for p in poses for m in (root / "Object_Models" / f"{p.stem.split('_')[-1]}_cm.obj",
                      root / "Object_Models" / "object_models_released" / f"{p.stem.split('_')[-1]}_cm.obj")
                      if m.is_file()]
            files = sorted(sd.glob("*.pkl")) + poses + meshes
            sha = file_sha256(files, extra=f"{cid}|{LOADER_VERSION}|" + config.sha256())
            loader, args = load_sequence, (str(sd), str(root), str(body_models), float(config.fps),
                                           listed[1] if listed else None)
            if split is None:
                where = f"split file {split_file}" if splits is not None else "TACO's split lists (V1)"
                split, loader, args = "unknown", fail_unit, (f"{cid}: {origin}: not listed in {where}",)
            jobs.append((cid, split, sha, str(out), loader, args, config.mode))
            sources.append(origin)
    return refuse_duplicates(jobs, sources)
