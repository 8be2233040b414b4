"""BEHAVE raw layout -> :class:`HOISequence` (canonical y-up world, floor at 0).

Raw layout (the official release, which ``hoibench synth`` also writes)::

    ROOT/sequences/<Date0X_SubYY_<object>_<action>>/smpl_fit_all.npz    poses (T,156) f32, betas (T,10),
                                                                        trans (T,3), frame_times
    ROOT/sequences/<...>/object_fit_all.npz                             angles (T,3) f64, trans (T,3), frame_times
    ROOT/sequences/<...>/info.json                                      {"gender", "cat", ...}
    ROOT/objects/<obj>/<obj>_f1000.ply (or _f2000, _f2500; monitor: monitor_closed_f1000.ply)

Conversion (per sequence):

1. Body: SMPL-H of the ``info.json`` gender, ``flat_hand_mean=True`` (BEHAVE's meshes),
   run through ``smplx`` on the user's model files (or hoibench's proxy).
2. Frame: BEHAVE's world is the Kinect camera with OpenCV axes (y down). hoibench rotates
   it by 180 degrees about x: ``p_yup = F p_cam``, ``F = diag(1, -1, -1)``. SMPL parameters are
   rotated about the pelvis: ``R0' = F R0`` and ``trans' = F (J0 + trans) - J0`` with ``J0``
   the rest pelvis of the subject's shape (rotating ``trans`` alone would shift the body by
   ``(I - F) J0``). The object pose becomes ``R' = F R``, ``t' = F t``.
3. Floor: y is shifted so the lowest body-surface vertex of the sequence sits at y = 0.
   BEHAVE's floor is tilted by a few degrees in the camera frame; hoibench does not level
   it (neither does HOI-Diff), and records the shift in the provenance.
4. Objects: the template is centred on its vertex mean (BEHAVE's fits assume that):
   ``v = R (v_template - mean) + t``.
5. Time: ``frame_times`` ('t0003.033' = 3.033 s, millisecond stamps of a 30 fps clock,
   snapped to the 1/30 s grid) are parsed and the sequence is resampled by time to ``fps`` (poses by quaternion slerp, translations linearly), never by an
   integer decimation factor.
"""
from __future__ import annotations

import json
import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..core.io import MAX_RAW_MESH_BYTES, MAX_SMALL_JSON_BYTES, check_regular_file, load_raw_npz, read_json_file

from ..core import geometry as geo
from ..core import plausibility as pl
from ..bodies.transform import rigid_transform_smpl
from ..core.ids import InvalidIdError, check_id
from .sequence import BodyParams, HOISequence

SOURCE_FPS = 30.0
FLIP = np.diag([1.0, -1.0, -1.0])       # OpenCV camera (y down) -> y up
OFFICIAL_TEST_DATE = "Date03"
_NAME = re.compile(r"^(Date\d+)_(Sub\d+)_([A-Za-z0-9]+)(?:_(.*))?$")
_BODY_KEYS = {"poses": (156,), "betas": (10,), "trans": (3,)}
_OBJECT_KEYS = {"angles": (3,), "trans": (3,)}


class SequenceError(ValueError):
    """A sequence that cannot be prepared: names the sequence, the file and the problem."""


@dataclass(frozen=True)
class ParsedName:
    date: str
    subject: str
    object: str
    action: str


def parse_name(name: str) -> ParsedName:
    m = _NAME.match(name)
    if not m:
        raise SequenceError(f"{name}: name does not match Date0X_SubYY_<object>_<action>")
    return ParsedName(m.group(1), m.group(2), m.group(3), m.group(4) or "")


def official_split(name: str) -> str:
    """BEHAVE's official split: every Date03 sequence is test."""
    return "test" if parse_name(name).date == OFFICIAL_TEST_DATE else "train"


def parse_frame_times(times, name: str, where: str = "smpl_fit_all.npz") -> np.ndarray:
    """'t0003.033' -> 3.033 seconds: finite, strictly increasing and spanning at most
    :data:`hoibench.core.plausibility.MAX_DURATION_S`, or a SequenceError naming ``where``."""
    raw = np.asarray(times).ravel()
    try:
        secs = np.array([float(str(t).lstrip("t")) for t in raw], dtype=np.float64)
    except ValueError as exc:
        raise SequenceError(f"{name}: {where}: frame_times: cannot parse ({exc})") from None
    bad = np.flatnonzero(~np.isfinite(secs))
    if len(bad):
        raise SequenceError(f"{name}: {where}: frame_times: non-finite time {str(raw[bad[0]])!r} at frame {bad[0]}")
    if len(secs) > 1 and not np.all(np.diff(secs) > 0):
        t = int(np.flatnonzero(np.diff(secs) <= 0)[0])
        raise SequenceError(f"{name}: {where}: frame_times: not strictly increasing at frame {t + 1}")
    if len(secs) > 1 and secs[-1] - secs[0] > pl.MAX_DURATION_S:
        raise SequenceError(f"{name}: {where}: frame_times: span {secs[-1] - secs[0]:.4g} s exceeds "
                            f"{pl.MAX_DURATION_S:g} s (a corrupt time stamp?)")
    return secs


def snap_to_frame_grid(secs: np.ndarray, fps: float = SOURCE_FPS, tol_s: float = 1e-3) -> np.ndarray:
    """BEHAVE stamps frames in milliseconds ('t0003.033'). Times within ``tol_s`` of the
    ``1/fps`` grid started at the first frame are snapped onto it (skipped frames keep their
    gap), so resampling at the source rate returns the source frames exactly."""
    k = np.round((secs - secs[0]) * fps)
    grid = secs[0] + k / fps
    return np.where(np.abs(grid - secs) <= tol_s, grid, secs)


def object_template_path(objects_root: Path, obj: str) -> Path:
    folder = Path(objects_root) / check_id(obj, "object name", "info.json 'cat' or the sequence name")
    names = ["monitor_closed_f1000.ply"] if obj == "monitor" else []
    names += [f"{obj}_f1000.ply", f"{obj}_f2000.ply", f"{obj}_f2500.ply"]
    for n in names:
        if (folder / n).exists():
            return folder / n
    raise SequenceError(f"unknown object template {obj!r}: none of {names} in {folder}")


def read_mesh(path: str | Path, what: str, process: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and faces of a mesh file as read by ``trimesh`` (``process=False``: as in the
    file; ``process=True``: trimesh's default processing, which merges vertices at equal
    positions, as ``trimesh.load_mesh(path)`` does); a SequenceError naming ``what`` (the
    sequence and object) for an unreadable file."""
    import trimesh
    try:
        size = check_regular_file(path, "mesh file").stat().st_size
        if size > MAX_RAW_MESH_BYTES:
            raise ValueError(f"{size} bytes, over the {MAX_RAW_MESH_BYTES}-byte limit for a mesh file")
        mesh = trimesh.load(str(path), process=bool(process), force="mesh")
        return np.asarray(mesh.vertices), np.asarray(mesh.faces)
    except Exception as exc:
        raise SequenceError(f"{what}: unreadable mesh ({type(exc).__name__}: {exc})") from None


@lru_cache(maxsize=64)
def _template(path: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    v, f = pl.check_template(*read_mesh(path, Path(path).name), Path(path).name)
    mean = v.mean(0)
    return v - mean, f, mean


def load_object_template(path: str, obj: str = "", name: str = "") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(centred vertices (V,3) float64, faces (F,3) int64, the subtracted mean (3,)) of a
    template that passes :func:`hoibench.core.plausibility.check_template` (finite, >= 4
    vertices, >= 1 face, indices in range, non-zero area, 1 cm..10 m); errors name the
    sequence ``name``, the object ``obj`` and the mesh file."""
    try:
        return _template(str(path))
    except ValueError as exc:
        raise SequenceError(f"{name or Path(path).name}: object {obj!r} template: {exc}") from None


def _read_npz(path: Path, name: str, keys: dict[str, tuple[int, ...]]) -> dict[str, np.ndarray]:
    if not path.exists():
        raise SequenceError(f"{name}: missing file {path.name}")
    try:
        data = load_raw_npz(path, what=path.name)
    except Exception as exc:  # zip/format errors of a truncated or corrupt file, special files, bombs
        raise SequenceError(f"{name}: {path.name}: unreadable ({type(exc).__name__}: {exc})") from None
    for k, tail in keys.items():
        if k not in data:
            raise SequenceError(f"{name}: {path.name}: missing key {k!r}")
        a = data[k]
        if a.ndim != 2 or a.shape[1:] != tail:
            raise SequenceError(f"{name}: {path.name}: {k}: expected shape (T, {tail[0]}), got {a.shape}")
        if a.dtype.kind == "f":
            bad = ~np.isfinite(a)
            if bad.any():
                t = int(np.argwhere(bad)[0, 0])
                raise SequenceError(f"{name}: {path.name}: {k}: non-finite value at frame {t}")
        else:   # complex (never cast to real), integers, strings
            raise SequenceError(f"{name}: {path.name}: {k}: expected real floats, got {a.dtype}")
    if "frame_times" not in data:
        raise SequenceError(f"{name}: {path.name}: missing key 'frame_times'")
    return data


@lru_cache(maxsize=8)
def _body_model(model_dir: str, gender: str):
    gender = check_id(gender, "gender")
    from ..bodies.smpl import load_body_model
    return load_body_model(model_dir, "smplh", gender)


def _slerp_resample(src_t: np.ndarray, dst_t: np.ndarray, aa: np.ndarray) -> np.ndarray:
    """Resample (T, K, 3) axis-angle rotations at times ``dst_t`` by quaternion slerp."""
    if len(src_t) == 1:
        return np.repeat(aa, len(dst_t), 0)
    q = geo.axis_angle_to_quaternion(aa)
    # one hemisphere along time: flip q_t when it points away from q_{t-1} (cumulated)
    sign = np.where(np.sum(q[1:] * q[:-1], -1) < 0, -1.0, 1.0)
    q[1:] *= np.cumprod(sign, axis=0)[..., None]
    idx = np.clip(np.searchsorted(src_t, dst_t, side="right") - 1, 0, len(src_t) - 2)
    w = ((dst_t - src_t[idx]) / (src_t[idx + 1] - src_t[idx]))[:, None, None]
    a, b = q[idx], q[idx + 1]
    theta = np.arccos(np.clip(np.sum(a * b, -1, keepdims=True), -1.0, 1.0))
    small = theta < 1e-6
    st = np.where(small, 1.0, np.sin(theta))
    wa = np.where(small, 1 - w, np.sin((1 - w) * theta) / st)
    wb = np.where(small, w, np.sin(w * theta) / st)
    return geo.quaternion_to_axis_angle(wa * a + wb * b)


def resample_times(src_t: np.ndarray, fps: float) -> np.ndarray:
    """Times t0, t0 + 1/fps, ... up to the last source time (inclusive, 1e-9 s slack)."""
    n = int(np.floor((src_t[-1] - src_t[0]) * fps + 1e-9)) + 1
    return src_t[0] + np.arange(n) / fps


def _lerp(src_t, dst_t, x):
    return np.stack([np.interp(dst_t, src_t, x[:, k]) for k in range(x.shape[1])], -1)


def resample_rigid(src_t: np.ndarray, dst_t: np.ndarray, R: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A rigid pose track (T, 3, 3), (T, 3) at times ``dst_t``: rotations by quaternion
    slerp (:func:`_slerp_resample`), translations linearly."""
    aa = _slerp_resample(src_t, dst_t, geo.matrix_to_axis_angle(R)[:, None])[:, 0]
    return np.asarray(geo.axis_angle_to_matrix(aa)), _lerp(src_t, dst_t, t)


def load_sequence(seq_dir: str | Path, objects_root: str | Path, body_models: str | Path,
                  fps: float = SOURCE_FPS) -> HOISequence:
    """Read one BEHAVE sequence folder into a canonical :class:`HOISequence` at ``fps``.

    Raises :class:`SequenceError` naming the sequence, file and field for bad input.
    """
    seq_dir = Path(seq_dir)
    name = check_id(seq_dir.name, "sequence folder", seq_dir.parent)
    parsed = parse_name(name)
    fps = pl.check_fps(fps, "fps", name)
    body = _read_npz(seq_dir / "smpl_fit_all.npz", name, _BODY_KEYS)
    obj = _read_npz(seq_dir / "object_fit_all.npz", name, _OBJECT_KEYS)
    gender, obj_name = read_info(seq_dir / "info.json", name, parsed.object)
    T = _frame_count(body, obj, name)
    times = snap_to_frame_grid(parse_frame_times(body["frame_times"], name))
    pl.check_track(body["trans"], "trans", f"{name}: smpl_fit_all.npz", times=times)
    pl.check_track(obj["trans"], "trans", f"{name}: object_fit_all.npz", times=times)
    template_path = object_template_path(Path(objects_root), obj_name)
    verts, faces, mean = load_object_template(str(template_path), obj_name, name)

    # resample by time
    dst = resample_times(times, fps)
    poses = _slerp_resample(times, dst, body["poses"].astype(np.float64).reshape(T, 52, 3)).reshape(len(dst), 156)
    trans = _lerp(times, dst, body["trans"].astype(np.float64))
    betas = body["betas"].astype(np.float64).mean(0)   # BEHAVE fits one shape per subject
    o_aa = _slerp_resample(times, dst, obj["angles"].astype(np.float64)[:, None])[:, 0]
    o_t = _lerp(times, dst, obj["trans"].astype(np.float64))

    # camera (y down) -> y up, about the pelvis
    from ..bodies.smpl import body_forward
    model = _body_model(str(Path(body_models)), gender)
    rest, _ = body_forward(model, np.zeros((1, 156)), betas, np.zeros((1, 3)), return_vertices=False)
    j0 = rest[0, 0].astype(np.float64)
    poses[:, :3], trans = rigid_transform_smpl(poses[:, :3], trans, j0, FLIP, np.zeros(3))
    o_rot = FLIP @ geo.axis_angle_to_matrix(o_aa)
    o_t = o_t @ FLIP.T
    joints, vertices = body_forward(model, poses, betas, trans)
    floor = float(vertices[..., 1].min())
    trans[:, 1] -= floor
    o_t[:, 1] -= floor
    joints = joints[:, :22].astype(np.float64)
    joints[..., 1] -= floor
    contacts = _ground_truth_contacts(seq_dir, times, dst)
    return HOISequence(
        name=name, dataset="behave", subject=parsed.subject, fps=float(fps),
        joints=joints.astype(np.float32), object_name=obj_name,
        object_vertices=verts, object_faces=faces, obj_rot=o_rot, obj_trans=o_t,
        contacts=contacts,
        body=BodyParams("smplh", gender, betas.astype(np.float32), poses.astype(np.float32),
                        trans.astype(np.float32), flat_hand_mean=True),
        provenance={"source": "behave-raw", "source_frame": "kinect camera, OpenCV (y down)",
                    "transform": "p_yup = diag(1,-1,-1) p_cam; y -= floor", "floor_shift_m": floor,
                    "source_fps": SOURCE_FPS, "resampled_to_fps": float(fps),
                    "source_start_s": float(times[0]),
                    "source_frames": T, "template": template_path.name,
                    "raw_source": f"sequences/{name}/ (smpl_fit_all.npz, object_fit_all.npz, info.json), "
                                  f"objects/{obj_name}/{template_path.name}",
                    "template_mean_subtracted": mean.tolist(), "date": parsed.date,
                    "action": parsed.action},
    )


def read_info(path: Path, name: str, default_object: str) -> tuple[str, str]:
    """(gender, object name) of ``info.json``: a JSON object whose ``gender`` is one of
    male/female/neutral and whose ``cat`` (optional; else the name's object) is a valid id.
    SequenceError naming the sequence, the file and the field otherwise."""
    if not path.exists():
        raise SequenceError(f"{name}: missing file info.json")
    try:
        info = read_json_file(path, 1024 ** 2, "info.json")
    except ValueError as exc:
        raise SequenceError(f"{name}: info.json: {exc}") from None
    if not isinstance(info, dict):
        raise SequenceError(f"{name}: info.json: expected a JSON object, got {type(info).__name__}")
    gender = info.get("gender")
    if not isinstance(gender, str) or gender.lower() not in pl.GENDERS:
        raise SequenceError(f"{name}: info.json: gender: expected one of {', '.join(pl.GENDERS)} (a string), "
                            f"got {gender!r}")
    cat = info.get("cat")
    if cat is not None and not isinstance(cat, str):
        raise SequenceError(f"{name}: info.json: cat: expected an object name (a string), got {cat!r}")
    try:
        obj = check_id(cat or default_object, "object name", "info.json 'cat'")
    except InvalidIdError as exc:
        raise SequenceError(f"{name}: info.json: cat: {exc}") from None
    return gender.lower(), obj


def _frame_count(body: dict, obj: dict, name: str) -> int:
    """Frames shared by every per-frame field of the two files (the odd field is named)."""
    counts = {f"smpl_fit_all.npz: {k}": len(body[k]) for k in ("poses", "betas", "trans")}
    counts["smpl_fit_all.npz: frame_times"] = int(np.asarray(body["frame_times"]).size)
    counts.update({f"object_fit_all.npz: {k}": len(obj[k]) for k in ("angles", "trans")})
    return pl.common_frame_count(counts, name, pl.MIN_FRAMES)


def _ground_truth_contacts(seq_dir: Path, src_t: np.ndarray, dst_t: np.ndarray) -> np.ndarray | None:
    """Per-joint contact labels from a ``hoibench_gt.npz`` sidecar (written by ``hoibench
    synth``; real BEHAVE has none), resampled to ``dst_t`` by nearest source frame."""
    path = seq_dir / "hoibench_gt.npz"
    if not path.exists():
        return None
    z = load_raw_npz(path, what="hoibench_gt.npz")
    if "contacts" not in z:
        return None
    c = z["contacts"].astype(bool)
    if c.shape != (len(src_t), 22):
        raise SequenceError(f"{seq_dir.name}: hoibench_gt.npz: contacts: expected ({len(src_t)}, 22), got {c.shape}")
    nearest = np.clip(np.searchsorted(src_t, dst_t - 0.5 / SOURCE_FPS), 0, len(src_t) - 1)
    return c[nearest]


def list_sequences(root: str | Path) -> list[Path]:
    """Sequence folders under ``root/sequences`` in sorted order."""
    seqs = Path(root) / "sequences"
    if not seqs.is_dir():
        raise FileNotFoundError(f"--root: no 'sequences' folder in {root} (expected the BEHAVE raw layout)")
    return sorted(p for p in seqs.iterdir() if p.is_dir())


def load_split_file(path: str | Path) -> dict[str, str]:
    """``{"train": [...], "test": [...]}`` -> {sequence: split}; a file with an invalid id
    or an id in two splits is refused (:func:`hoibench.datasets.splits.read_split_file`)."""
    from .splits import read_split_file
    return read_split_file(path)


def prepare_jobs(root: str | Path, body_models: str | Path, out: str | Path, config,
                 split_file: str | Path | None = None) -> list[tuple]:
    """One :func:`hoibench.datasets.store.run_unit` job per sequence folder.

    The split is the official one (test = Date03) unless ``split_file`` names another; a
    sequence the split file does not list is an error for that sequence.
    """
    from .store import fail_unit, file_sha256, refuse_duplicates, refused_id_job, unlisted_split_jobs
    root = Path(root)
    splits = load_split_file(split_file) if split_file else None
    jobs, sources = [], []
    for seq in list_sequences(root):
        name = seq.name
        refused = refused_id_job(name, "sequence folder", root / "sequences", out, config.mode)
        if refused:
            jobs.append(refused)
            sources.append(str(seq))
            continue
        loader, args = load_sequence, (str(seq), str(root / "objects"), str(body_models), config.fps)
        try:
            split = splits[name] if splits is not None else official_split(name)
        except KeyError:
            split, loader, args = "unknown", fail_unit, (f"{name}: not listed in split file {split_file}",)
        except SequenceError as exc:
            split, loader, args = "unknown", fail_unit, (str(exc),)
        try:
            obj = read_json_file(seq / "info.json", MAX_SMALL_JSON_BYTES, "info.json").get("cat") or parse_name(name).object
            template = object_template_path(root / "objects", obj)
        except Exception:   # the unit reports the reason when it loads
            template = seq / "<no template>"
        files = [seq / "smpl_fit_all.npz", seq / "object_fit_all.npz", seq / "info.json", template]
        sha = file_sha256(files, extra=config.sha256())
        jobs.append((name, split, sha, str(out), loader, args, config.mode))
        sources.append(f"{seq}")
    jobs = refuse_duplicates(jobs, sources)
    if splits is not None:
        jobs += unlisted_split_jobs(jobs, splits, split_file, out, config.mode, "no sequence folder")
    return jobs

