"""OMOMO processed release -> :class:`HOISequence` (canonical y-up world, floor at 0).

Raw layout (the processed release that OMOMO and CHOIS train on; ``hoibench`` also writes it
with :func:`hoibench.datasets.synthetic_layouts.write_omomo_layout`)::

    ROOT/train_diffusion_manip_seq_joints24.p   joblib pickle: {int: sequence dict}
    ROOT/test_diffusion_manip_seq_joints24.p    (ROOT may also be the folder holding data/)
    ROOT/captured_objects/<object>_cleaned_simplified.obj
    ROOT/omomo_text_anno_json_data/<seq_name>.json   {seq_name: sentence} (optional; also
        found under ROOT/omomo_text_anno/omomo_text_anno_json_data/)

A sequence dict holds (facts read from ``manip/data/hand_foot_dataset.py`` of
lijiaman/omomo_release and ``cal_normalize_data_input`` of lijiaman/chois_release):
``seq_name`` ('sub16_clothesstand_000': subject, object, take), ``gender``, ``betas``
(1, 16), ``trans`` and ``root_orient`` (T, 3), ``pose_body`` (T, 63) axis-angle,
``rest_offsets`` (24, 3), ``trans2joint`` (3,), ``obj_trans`` (T, 3, 1), ``obj_rot``
(T, 3, 3), ``obj_scale`` (T,), ``obj_com_pos`` (T, 3). Two-part objects (vacuum, mop) add
``obj_bottom_trans/rot/scale``.

.. warning::
   The pickles are read with ``joblib.load``, which unpickles them: it can run code. Only
   point hoibench at the OMOMO files you downloaded yourself (hoibench never unpickles
   anything else: its own outputs are ``.npz`` read with ``allow_pickle=False`` and JSON).
   ``joblib`` is needed (``pip install joblib``).

Conversion (per sequence):

1. Body: SMPL-X of the sequence's gender with its 16 betas (``num_betas=16``), hands flat
   (OMOMO stores no hand pose), run through ``smplx`` on the user's model files (or the
   hoibench proxy in the SMPL-X structure). ``trans`` is SMPL-X's ``transl``.
   ``rest_offsets``/``trans2joint`` are not needed: the joints come from the body model.
   As a check, the joints OMOMO's own code computes (forward kinematics over
   ``rest_offsets`` with the root at ``trans - trans2joint``) are compared with the body
   model's and the largest difference is recorded as ``rest_offsets_fk_max_dev_m``.
2. Frame: OMOMO's world is z-up (mocap). hoibench rotates it by -90 degrees about x,
   ``p_yup = F p_zup`` with ``F = [[1,0,0],[0,0,1],[0,-1,0]]`` ((x, y, z) -> (x, z, -y), a
   proper rotation: no mirroring). SMPL-X parameters are moved about the pelvis
   (``R0' = F R0``, ``trans' = F (J0 + trans) - J0``); the object pose ``R' = F R``,
   ``t' = F t``.
3. Floor: y is shifted so the lowest body-surface vertex of the sequence sits at y = 0
   (as for BEHAVE; OMOMO's own floor is z = 0, so the shift is small); recorded in the
   provenance.
4. Objects: OMOMO's templates are *not* centred and carry a per-frame scale:
   ``v = s_t R v_obj + t``. Templates are loaded as OMOMO and CHOIS load them
   (``trimesh.load_mesh``: vertices at equal positions merged). hoibench stores the template
   scaled by the mean scale ``s`` and centred on the merged vertices' mean ``m``,
   ``v' = s (v_obj - m)``, and the translation ``t' = t + s_t R m``, so ``R v' + t'``
   reproduces OMOMO's vertices exactly for a constant scale. A varying scale is kept when
   the shape error ``max_t |s_t - s| * max_v |v_obj - m|`` is at most
   :data:`OBJECT_SCALE_TOL_M` (recorded as ``object_scale_max_dev_m``), else the sequence
   fails with the error. If one object name appears with different scales in the release,
   each scale gets its own template name ``<object>_s<scale>`` (the store keeps one template
   per name); the category stays in the provenance. Two-part objects (vacuum, mop:
   ``obj_bottom_*`` keys, ``_top`` / ``_bottom`` templates) keep both parts
   (:class:`~hoibench.datasets.sequence.ObjectPart`): the top is the clip's object (the
   representations and metrics use it), the bottom ``<object>_bottom`` a second part. Each
   part is named by its own scale (``obj_scale`` for the top, ``obj_bottom_scale`` for the
   bottom: ``<object>_bottom_s<scale>`` when the release has several bottom scales), so two
   sequences with one top scale and two bottom scales keep two bottom templates.
5. Time: 30 fps, resampled by time to ``fps`` (poses by quaternion slerp, translations
   linearly).
6. Text: the sentence of ``<seq_name>.json`` as one sequence-level text, source "omomo"
   (about 84 % of the sequences have one; the others get none).
7. Split: the official subject split (sub1-15 train, sub16-17 test) unless a split file
   names another (e.g. CHOIS's unseen-object split).
"""
from __future__ import annotations

import hashlib
import json
import re
from functools import lru_cache
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..core import geometry as geo
from ..core import plausibility as pl
from ..bodies.transform import rigid_transform_smpl
from ..core.ids import InvalidIdError, check_id
from ..core.skeleton import NUM_JOINTS, PARENTS, forward_kinematics
from .behave import SequenceError, _lerp, _slerp_resample, load_split_file, read_mesh, resample_rigid, resample_times
from .sequence import BodyParams, HOISequence, ObjectPart

__all__ = ["SOURCE_FPS", "ZUP_TO_YUP", "PICKLES", "SequenceError", "parse_name", "official_split",
           "object_template_path", "read_pickle", "load_sequence", "prepare_jobs"]

SOURCE_FPS = 30.0
#: z-up -> y-up: rotation by -90 degrees about x, (x, y, z) -> (x, z, -y).
ZUP_TO_YUP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
PICKLES = {"train": "train_diffusion_manip_seq_joints24.p", "test": "test_diffusion_manip_seq_joints24.p"}
TEST_SUBJECTS = (16, 17)
NUM_BETAS = 16
TEXT_DIRS = ("omomo_text_anno_json_data", "omomo_text_anno/omomo_text_anno_json_data", "omomo_text_anno")
GT_DIR = "hoibench_gt"           # ground-truth sidecars written by hoibench's synthetic layout
_NAME = re.compile(r"^sub(\d+)_([A-Za-z0-9]+)_(.+)$")
_SEQ_KEYS = {"trans": (3,), "root_orient": (3,), "pose_body": (63,), "obj_rot": (3, 3)}
#: Largest accepted shape error, metres, of storing one scale for an ``obj_scale`` that
#: varies over a sequence: ``max_t |s_t - s| * max_v |v - m|`` (the translation keeps each
#: frame's own scale, so the template's centre is exact); more is refused, naming the
#: sequence, the part and the error.
OBJECT_SCALE_TOL_M = 1e-3
#: in every clip's checksum: a store prepared by an older loader (unmerged templates, no
#: object parts) is rebuilt on the next ``prepare`` instead of being kept.
LOADER_VERSION = "omomo-loader-0.7"
#: OMOMO's two-part objects: a top (the handle the hands hold) and an articulated bottom,
#: ``<object>_cleaned_simplified_{top,bottom}.obj`` posed by ``obj_*`` and ``obj_bottom_*``.
TWO_PART_SUFFIXES = ("top", "bottom")
#: Largest accepted ``rest_offsets`` bone and ``trans2joint`` length, metres (SMPL-X's
#: longest bone is about 0.45 m; centimetres or millimetres read 45 or 450).
MAX_REST_OFFSET_M = 1.0


def parse_name(name: str) -> tuple[int, str, str]:
    """'sub16_clothesstand_000' -> (16, 'clothesstand', '000')."""
    m = _NAME.match(str(name))
    if not m:
        raise SequenceError(f"{name}: seq_name does not match sub<N>_<object>_<take>")
    return int(m.group(1)), m.group(2), m.group(3)


def official_split(name: str) -> str:
    """OMOMO's subject split: sub16 and sub17 are test, sub1-15 train."""
    return "test" if parse_name(name)[0] in TEST_SUBJECTS else "train"


def object_template_path(objects_root: str | Path, obj: str, part: str = "") -> Path:
    """``<obj>_cleaned_simplified.obj``, or ``<obj>_cleaned_simplified_<part>.obj`` for a part
    (``top`` / ``bottom``) of a two-part object."""
    return Path(objects_root) / (f"{obj}_cleaned_simplified_{part}.obj" if part else f"{obj}_cleaned_simplified.obj")


def read_pickle(path: str | Path) -> Any:
    """``joblib.load`` of one of the user's OMOMO pickles (this unpickles: own downloads only)."""
    try:
        import joblib
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("reading OMOMO's pickles needs the 'joblib' package: pip install joblib") from exc
    from ..core.io import check_regular_file
    check_regular_file(path, "OMOMO pickle")
    return joblib.load(str(path))  # read-ok: OMOMO's release is a pickle (own download, docs/security.md)


@lru_cache(maxsize=64)
def _template(path: str) -> tuple[np.ndarray, np.ndarray, int]:
    raw_count = len(read_mesh(path, Path(path).name)[0])
    v, f = pl.check_mesh(*read_mesh(path, Path(path).name, process=True), Path(path).name)
    return v, f, raw_count


def load_object_template(path: str, obj: str = "", name: str = "") -> tuple[np.ndarray, np.ndarray, int]:
    """Template vertices (V, 3) float64 (not centred, unscaled) and faces (F, 3) int64 as
    OMOMO and CHOIS load them (``trimesh.load_mesh``: vertices at equal positions merged),
    of a mesh that passes :func:`hoibench.core.plausibility.check_mesh` (its extent is checked
    once scaled), and the file's own vertex count; errors name the sequence ``name``, the
    object ``obj`` and the file."""
    try:
        return _template(str(path))
    except ValueError as exc:
        raise SequenceError(f"{name or Path(path).name}: object {obj!r} template: {exc}") from None


@lru_cache(maxsize=8)
def _body_model(model_dir: str, gender: str, num_betas: int):
    from ..bodies.smpl import load_body_model
    gender = check_id(gender, "gender")
    return load_body_model(model_dir, "smplx", gender, num_betas=num_betas)


def _check_beta_capacity(model, betas: np.ndarray, body_models, gender: str, name: str) -> None:
    """OMOMO's 16 betas need SMPL-X v1.1 files (300 shape components); v1.0 files have 10,
    and ``smplx`` then silently caps ``num_betas`` at 10: refuse, naming the file and the
    layout found, when a coefficient past the model's count is non-zero."""
    nb = int(model.num_betas)
    if len(betas) <= nb or not np.any(betas[nb:] != 0):
        return
    from ..bodies.smpl import model_path
    path = model_path(body_models, "smplx", gender)
    found = f"the model has {nb} shape components"
    if path.suffix == ".npz":
        try:
            with np.load(path, allow_pickle=False, mmap_mode="r") as z:  # read-ok: the user's SMPL-X model file
                k = int(z["shapedirs"].shape[-1])
            found = (f"its shapedirs has {k} components (SMPL-X v1.0 layout: 10 shape + 10 expression)" if k < 400
                     else f"its shapedirs has {k} components")
        except Exception:
            pass
    raise SequenceError(f"{name}: betas: {len(betas)} coefficients (non-zero past the {nb}th), but {path} gives only "
                        f"{nb}: {found}; OMOMO's 16 betas need the SMPL-X v1.1 files (300 shape + 100 "
                        f"expression components) from smpl-x.is.tue.mpg.de")


def _array(seq: dict, key: str, name: str) -> np.ndarray:
    """``seq[key]`` as float64: real dtype (complex refused, never cast), finite."""
    if key not in seq:
        raise SequenceError(f"{name}: missing key {key!r}")
    try:
        return pl.real_array(seq[key], key, name)
    except ValueError as exc:
        raise SequenceError(str(exc)) from None


def _frames(a: np.ndarray, key: str, tail: tuple, name: str) -> np.ndarray:
    if a.ndim != 1 + len(tail) or a.shape[1:] != tail:
        raise SequenceError(f"{name}: {key}: expected shape (T, {', '.join(map(str, tail))}), got {a.shape}")
    return a


def _text(seq: dict, key: str, name: str) -> str:
    if key not in seq:
        raise SequenceError(f"{name}: missing key {key!r}")
    v = seq[key]
    if isinstance(v, bytes):
        v = v.decode()
    v = np.asarray(v).ravel()
    if v.size != 1:
        raise SequenceError(f"{name}: {key}: expected one string, got shape {v.shape}")
    return str(v[0])


def _texts(path: str | None, name: str) -> list[dict]:
    if not path or not Path(path).exists():
        return []
    from ..core.io import read_json_file
    try:
        data = read_json_file(path, what="OMOMO text file")
    except ValueError as exc:
        raise SequenceError(f"{name}: {exc}") from None
    value = data.get(name) if isinstance(data, dict) else None
    if value is None:
        raise SequenceError(f"{name}: {Path(path).name}: no entry for {name!r}")
    sentences = [value] if isinstance(value, str) else value
    if not isinstance(sentences, list) or not all(isinstance(x, str) for x in sentences):
        raise SequenceError(f"{name}: {Path(path).name}: {name}: expected a sentence or a list of sentences, "
                            f"got {value!r:.80}")
    return [{"text": str(s).strip(), "start": None, "end": None, "source": "omomo"}
            for s in sentences if str(s).strip()]


def _gt_contacts(path: str | None, src_t: np.ndarray, dst_t: np.ndarray, name: str) -> np.ndarray | None:
    """Per-joint contacts from a hoibench ground-truth sidecar (synthetic data only)."""
    if not path or not Path(path).exists():
        return None
    try:
        from ..core.io import load_raw_npz
        z = load_raw_npz(path, what="ground-truth sidecar")
        if "contacts" not in z:
            return None
        c = z["contacts"].astype(bool)
    except Exception as exc:
        raise SequenceError(f"{name}: {Path(path).name}: unreadable ({type(exc).__name__}: {exc})") from None
    if c.shape != (len(src_t), NUM_JOINTS):
        raise SequenceError(f"{name}: {Path(path).name}: contacts: expected ({len(src_t)}, 22), got {c.shape}")
    nearest = np.clip(np.searchsorted(src_t, dst_t - 0.5 / SOURCE_FPS), 0, len(src_t) - 1)
    return c[nearest]


def _object_pose(seq: dict, prefix: str, where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``<prefix>_rot`` (T, 3, 3), ``<prefix>_trans`` (T, 3) and ``<prefix>_scale`` (T,) or
    (1,) of one rigid part (prefix ``obj`` or ``obj_bottom``)."""
    R = _frames(_array(seq, f"{prefix}_rot", where), f"{prefix}_rot", (3, 3), where)
    t = _array(seq, f"{prefix}_trans", where)
    if t.ndim == 3 and t.shape[1:] in ((3, 1), (1, 3)):
        t = t.reshape(len(t), 3)
    if t.ndim != 2 or t.shape[1] != 3:
        raise SequenceError(f"{where}: {prefix}_trans: expected shape (T, 3, 1), got {t.shape}")
    return R, t, _array(seq, f"{prefix}_scale", where).reshape(-1)


def _per_frame(seq: dict, where: str, prefixes: tuple[str, ...] = ("obj",)
               ) -> tuple[dict[str, np.ndarray], list[tuple[np.ndarray, np.ndarray, np.ndarray]], int]:
    """The body's per-frame arrays (trans, root_orient, pose_body), each object part's
    (rot (T, 3, 3), trans (T, 3), scale (T,)) and T, the frame count they share: a field
    with another count is named (:func:`hoibench.core.plausibility.common_frame_count`), as is
    an empty one. A scale given once is repeated over the frames."""
    arr = {k: _frames(_array(seq, k, where), k, tail, where) for k, tail in _SEQ_KEYS.items() if k != "obj_rot"}
    poses = [_object_pose(seq, p, where) for p in prefixes]
    counts = {k: len(a) for k, a in arr.items()}
    for p, (R, t, scale) in zip(prefixes, poses):
        counts.update({f"{p}_rot": len(R), f"{p}_trans": len(t)})
        if scale.size != 1:
            counts[f"{p}_scale"] = len(scale)
    T = pl.common_frame_count(counts, where, pl.MIN_FRAMES)
    return arr, [(R, t, np.repeat(sc, T) if sc.size == 1 else sc) for R, t, sc in poses], T


def _rest_skeleton(seq: dict, where: str) -> tuple[np.ndarray, np.ndarray] | None:
    """(rest_offsets (22, 3), trans2joint (3,)) for the FK check, or None when either is
    absent. Real and finite, every offset and ``trans2joint`` at most
    :data:`MAX_REST_OFFSET_M` long (longer: centimetres/millimetres), else SequenceError."""
    if "rest_offsets" not in seq or "trans2joint" not in seq:
        return None
    offsets, t2j = _array(seq, "rest_offsets", where), _array(seq, "trans2joint", where)
    if offsets.ndim != 2 or offsets.shape[1] != 3 or len(offsets) < NUM_JOINTS or t2j.size != 3:
        raise SequenceError(f"{where}: rest_offsets / trans2joint: expected (>= {NUM_JOINTS}, 3) and (3,), "
                            f"got {offsets.shape} and {t2j.shape}")
    offsets, t2j = offsets[:NUM_JOINTS], t2j.reshape(3)
    norms = {"rest_offsets": np.linalg.norm(offsets, axis=-1), "trans2joint": np.linalg.norm(t2j)[None]}
    for key, lengths in norms.items():
        top = float(lengths.max())
        if top > MAX_REST_OFFSET_M:
            raise SequenceError(f"{where}: {key}: length {top:.4g} m exceeds {MAX_REST_OFFSET_M:g} m"
                                + pl.unit_hint(top, 0.01, MAX_REST_OFFSET_M, 0.3))
    return offsets, t2j


def _rest_offsets_fk(rots: np.ndarray, trans: np.ndarray, offsets: np.ndarray, trans2joint: np.ndarray):
    """OMOMO's own joints: FK over parent-relative ``rest_offsets`` with the root at
    ``trans - trans2joint`` (``process_window_data`` in omomo_release)."""
    rest = np.zeros((NUM_JOINTS, 3))
    for j in range(1, NUM_JOINTS):
        rest[j] = rest[PARENTS[j]] + offsets[j]
    joints, _ = forward_kinematics(rots, rest, trans - trans2joint)
    return joints


def _rigid_part(name: str, where: str, obj: str, part: str, pname: str, prefix: str, R_src: np.ndarray,
                o_t: np.ndarray, scale: np.ndarray, objects_root, src_t: np.ndarray, dst: np.ndarray) -> dict:
    """One rigid object part in OMOMO's z-up world, resampled to the times ``dst``: the
    centred template scaled by the mean scale, ``rot`` (T', 3, 3), ``trans`` (T', 3), and
    its provenance (see the module docstring)."""
    pl.check_track(o_t, f"{prefix}_trans", where, fps=SOURCE_FPS)
    ortho = np.abs(R_src @ R_src.swapaxes(-1, -2) - np.eye(3)).max(axis=(-2, -1))
    bad = np.flatnonzero((ortho > 1e-3) | (np.linalg.det(R_src) < 0))
    if len(bad):
        raise SequenceError(f"{where}: {prefix}_rot: not a rotation matrix at frame {int(bad[0])}")
    if not np.all(scale > 0):
        raise SequenceError(f"{where}: {prefix}_scale: expected positive scales, got {scale.min():.6g}..{scale.max():.6g}")
    template_path = object_template_path(objects_root, obj, part)
    if not template_path.exists():
        what = f"two-part object {obj!r}: missing its {part} template" if part else "missing object template"
        raise SequenceError(f"{name}: {what} {template_path.name} in {Path(objects_root)}")
    raw_v, faces, n_file = load_object_template(str(template_path), obj, name)
    mean = raw_v.mean(0)
    s0 = float(scale.mean())
    radius = float(np.linalg.norm(raw_v - mean, axis=1).max())
    spread = float(np.abs(scale - s0).max())
    dev = spread * radius
    if dev > OBJECT_SCALE_TOL_M:
        raise SequenceError(f"{where}: {prefix}_scale varies over the sequence ({scale.min():.6g}..{scale.max():.6g}): "
                            f"one template would misplace vertices by up to {dev * 1000:.2f} mm (tolerance "
                            f"{OBJECT_SCALE_TOL_M * 1000:g} mm); a per-frame object scale is not stored")
    verts = s0 * (raw_v - mean)
    try:
        pl.check_extent(verts, f"{name}: object {obj!r} template {template_path.name} scaled by {prefix}_scale {s0:.6g}")
    except ValueError as exc:
        raise SequenceError(str(exc)) from None
    o_tc = o_t + scale[:, None] * (R_src @ mean)       # each frame's own scale: the centre is exact
    rot, trans = resample_rigid(src_t, dst, R_src, o_tc)
    return {"name": pname, "vertices": verts, "faces": faces, "rot": rot, "trans": trans,
            "provenance": {"part": part or "whole", "name": pname, "template": template_path.name,
                           "pose_keys": f"{prefix}_rot, {prefix}_trans, {prefix}_scale",
                           "object_scale": s0, "object_scale_spread": spread, "object_scale_max_dev_m": dev,
                           "template_mean_subtracted": mean.tolist(), "template_vertices_in_file": int(n_file),
                           "template_vertices_merged": int(len(raw_v))}}


def load_sequence(seq: dict, objects_root: str | Path, body_models: str | Path,
                  fps: float = SOURCE_FPS, text_file: str | None = None, object_name: str | Sequence[str] | None = None,
                  source: str = "", gt_file: str | None = None) -> HOISequence:
    """Convert one OMOMO sequence dict (an entry of the joblib pickle) into a canonical
    :class:`HOISequence` at ``fps`` (see the module docstring).

    ``object_name`` overrides the template name stored with the clip (default: the object
    of ``seq_name``; a two-part object's bottom is ``<name>_bottom``); a sequence of names
    names every part (top, bottom). Raises :class:`SequenceError` naming the sequence, key or file.
    """
    if not isinstance(seq, dict):
        raise SequenceError(f"{source or 'omomo'}: expected a sequence dict, got {type(seq).__name__}")
    name = _text(seq, "seq_name", source or "omomo")
    try:
        check_id(name, "seq_name", source or None)
    except InvalidIdError as exc:
        raise SequenceError(str(exc)) from None
    where = f"{name}: {source}" if source else name
    sub, obj, _ = parse_name(name)
    fps = pl.check_fps(fps, "fps", name)
    two_part = any(str(k).startswith("obj_bottom") for k in seq)
    prefixes = ("obj", "obj_bottom") if two_part else ("obj",)
    gender = _text(seq, "gender", where).lower()
    if gender not in pl.GENDERS:
        raise SequenceError(f"{where}: gender: expected male/female/neutral, got {gender!r}")
    arr, obj_poses, T = _per_frame(seq, where, prefixes)
    betas = _array(seq, "betas", where).reshape(-1)
    if not 1 <= len(betas) <= pl.MAX_BETAS:
        raise SequenceError(f"{where}: betas: expected 1..{pl.MAX_BETAS} coefficients, got {len(betas)}")
    rest = _rest_skeleton(seq, where)
    pl.check_track(arr["trans"], "trans", where, fps=SOURCE_FPS)

    # time: resample every track by time
    src_t = np.arange(T) / SOURCE_FPS
    dst = resample_times(src_t, fps)
    named = not isinstance(object_name, str) and object_name is not None
    base = obj if named else (object_name or obj)
    parts = []
    for k, (prefix, (R_src, o_t, scale), part) in enumerate(zip(prefixes, obj_poses,
                                                              TWO_PART_SUFFIXES if two_part else ("",))):
        pname = (object_name[k] if named and k < len(object_name) else
                 base if part in ("", "top") else f"{base}_{part}")
        parts.append(_rigid_part(name, where, obj, part, pname, prefix, R_src, o_t, scale, objects_root, src_t, dst))
    pose = np.concatenate([arr["root_orient"], arr["pose_body"]], 1).reshape(T, NUM_JOINTS, 3)
    pose = _slerp_resample(src_t, dst, pose).reshape(len(dst), 3 * NUM_JOINTS)
    trans = _lerp(src_t, dst, arr["trans"])

    # SMPL-X in OMOMO's z-up world, then rotate everything to y-up (rigid: exact)
    from ..bodies.smpl import body_forward
    model = _body_model(str(Path(body_models)), gender, max(NUM_BETAS, len(betas)))
    _check_beta_capacity(model, betas, body_models, gender, name)
    joints_z, verts_z = body_forward(model, pose, betas, trans)
    joints_z = joints_z[:, :NUM_JOINTS].astype(np.float64)
    j0 = (joints_z[:, 0] - trans).mean(0)          # rest pelvis: SMPL-X's pelvis = J0 + transl
    check = {}
    if rest is not None:
        offsets, t2j = rest
        fk = _rest_offsets_fk(geo.axis_angle_to_matrix(pose.reshape(-1, NUM_JOINTS, 3)), trans, offsets, t2j)
        check = {"rest_offsets_fk_max_dev_m": float(np.abs(fk - joints_z).max()),
                 "trans2joint_vs_rest_pelvis_m": (t2j + j0).tolist()}
    F = ZUP_TO_YUP
    root, trans_y = rigid_transform_smpl(pose[:, :3], trans, j0, F, np.zeros(3))
    pose[:, :3] = root
    joints = joints_z @ F.T
    floor = float((verts_z.reshape(-1, 3) @ F[1]).min())
    joints[..., 1] -= floor
    trans_y[:, 1] -= floor
    seq_parts = []
    for p in parts:
        o_trans = p["trans"] @ F.T
        o_trans[:, 1] -= floor
        seq_parts.append(ObjectPart(p["name"], p["vertices"], p["faces"], F @ p["rot"], o_trans))
    top = seq_parts[0]
    part_prov = [p["provenance"] for p in parts]

    gt_c = _gt_contacts(gt_file, src_t, dst, name)
    return HOISequence(
        name=name, dataset="omomo", subject=f"sub{sub}", fps=float(fps),
        joints=joints.astype(np.float32), object_name=top.name,
        object_vertices=top.vertices, object_faces=top.faces, obj_rot=top.rot, obj_trans=top.trans,
        parts=seq_parts if two_part else [],
        contacts=gt_c,
        body=BodyParams("smplx", gender, betas.astype(np.float32), pose.astype(np.float32),
                        trans_y.astype(np.float32), flat_hand_mean=True),
        texts=_texts(text_file, name),
        provenance={"source": "omomo-processed", "source_file": source,
                    "source_frame": "OMOMO mocap world, z-up, metres",
                    "transform": "p_yup = [[1,0,0],[0,0,1],[0,-1,0]] p_zup (Rx(-90 deg)); y -= floor",
                    "floor_shift_m": floor, "source_fps": SOURCE_FPS, "resampled_to_fps": float(fps),
                    "source_frames": T, "body_model": "smplx", "num_betas": int(len(betas)),
                    "hands": "flat (OMOMO stores no hand pose)",
                    "object_category": obj, "template": part_prov[0]["template"],
                    "raw_source": f"{source or 'omomo pickle'} (sequence {name}), "
                                  + ", ".join(f"captured_objects/{p['template']}" for p in part_prov),
                    "object_scale": part_prov[0]["object_scale"],
                    "template_mean_subtracted": part_prov[0]["template_mean_subtracted"],
                    "object_convention": ("v = s_t R v_obj + t -> template s (v_obj - mean) with s the mean "
                                          "scale, t' = t + s_t R mean"),
                    "template_loading": ("trimesh.load_mesh as OMOMO and CHOIS do (vertices at equal positions "
                                         "merged), centred on the merged vertices' mean"),
                    **({"object_parts": part_prov} if two_part else
                       {k: v for k, v in part_prov[0].items() if k in ("template_vertices_in_file",
                                                                       "template_vertices_merged",
                                                                       "object_scale_spread",
                                                                       "object_scale_max_dev_m")}),
                    **check},
    )


# --------------------------------------------------------------------------- jobs
def _data_root(root: Path) -> Path:
    for cand in (root, root / "data"):
        if any((cand / f).exists() for f in PICKLES.values()):
            return cand
    raise FileNotFoundError(f"--root: no {' or '.join(PICKLES.values())} in {root} or {root / 'data'} "
                            "(expected OMOMO's processed release)")


def _text_dir(root: Path, data_root: Path) -> Path | None:
    for base in dict.fromkeys((root, data_root, root.parent)):
        for d in TEXT_DIRS:
            if (base / d).is_dir() and any((base / d).glob("*.json")):
                return base / d
    return None


def _sequence_sha(seq: Any, files: list[Path], extra: str) -> str:
    """sha256 over a sequence dict's arrays (key, dtype, shape, bytes) and ``files``."""
    from .store import file_sha256
    h = hashlib.sha256()
    if isinstance(seq, dict):
        for k in sorted(seq, key=str):
            a = np.asarray(seq[k])
            h.update(f"{k}|{a.dtype.str}|{a.shape}|".encode())
            h.update(np.ascontiguousarray(a).tobytes() if a.dtype != object else repr(seq[k]).encode())
    else:
        h.update(repr(type(seq)).encode())
    return file_sha256(files, extra=h.hexdigest() + extra)


def _scale_of(seq: Any, prefix: str = "obj") -> float | None:
    """The mean ``<prefix>_scale`` of a sequence, rounded to 1e-6 (None when absent or bad)."""
    try:
        s = np.asarray(seq[f"{prefix}_scale"], dtype=np.float64).reshape(-1)
        return round(float(s.mean()), 6) if s.size and np.isfinite(s).all() else None
    except Exception:
        return None


def _part_names(obj: str, seq: Any, scales: dict[tuple[str, str], set]) -> str | tuple[str, ...] | None:
    """Template names of a sequence's parts: ``<object>[_bottom]``, with ``_s<scale>`` (the
    part's own mean scale) when that part appears with several scales in the release; one
    name for a one-part object, (top, bottom) for a two-part one."""
    if not obj:
        return None
    two_part = isinstance(seq, dict) and any(str(k).startswith("obj_bottom") for k in seq)
    names = []
    for prefix, base in ((("obj", obj), ("obj_bottom", f"{obj}_bottom")) if two_part else (("obj", obj),)):
        s = _scale_of(seq, prefix) if isinstance(seq, dict) else None
        names.append(f"{base}_s{s:.6f}" if s is not None and len(scales.get((obj, prefix), ())) > 1 else base)
    return tuple(names) if two_part else names[0]


def _seq_name(seq: Any) -> str | None:
    """The ``seq_name`` of a sequence dict as the loader reads it, or None."""
    if not isinstance(seq, dict) or "seq_name" not in seq:
        return None
    try:
        return _text(seq, "seq_name", "")
    except Exception:
        return None


def _read_entries(data_root: Path, out, mode: str) -> tuple[list[tuple[str, Any, str]], list[tuple]]:
    """(clip id, sequence dict, "<pickle> entry <key>") per sequence of both pickles, and
    :func:`hoibench.datasets.store.source_failure_job` jobs for a pickle that is missing (when the
    other exists: a store without its test or train split) or unreadable."""
    from .store import source_failure_job
    entries: list[tuple[str, Any, str]] = []
    failed: list[tuple] = []
    for split, fname in PICKLES.items():
        path = data_root / fname
        if not path.exists():
            failed.append(source_failure_job(fname, f"{fname}: missing in {data_root}: the store has no "
                                             f"{split} split (OMOMO's release has both pickles)", out, mode))
            continue
        try:
            data = read_pickle(path)
        except ImportError:
            raise
        except Exception as exc:
            failed.append(source_failure_job(fname, f"{fname}: unreadable OMOMO pickle ({type(exc).__name__}: "
                                             f"{exc}): none of its sequences prepared", out, mode))
            continue
        if not isinstance(data, dict):
            failed.append(source_failure_job(fname, f"{fname}: expected a dict of sequences, got "
                                             f"{type(data).__name__}: none of its sequences prepared", out, mode))
            continue
        for key, seq in data.items():
            entries.append((_seq_name(seq) or f"{Path(fname).stem}_{key}", seq, f"{fname} entry {key!r}"))
    return entries, failed


def prepare_jobs(root: str | Path, body_models: str | Path, out: str | Path, config,
                 split_file: str | Path | None = None) -> list[tuple]:
    """One :func:`hoibench.datasets.store.run_unit` job per OMOMO sequence (both pickles).

    Reads the pickles here (``joblib.load``: the user's own download only) and passes each
    sequence dict to its unit. The split is the official subject split unless
    ``split_file`` (``{"train": [seq_name, ...], "test": [...]}``) names another; a
    sequence it does not list is an error for that sequence. Clip id = ``seq_name``, which
    must be a valid id (:func:`hoibench.core.ids.check_id`); a ``seq_name`` found twice fails
    every copy. A missing or unreadable pickle is one failing "source" job (the manifest's
    ``incomplete``), never a silent store without that split.
    """
    from .store import fail_unit, refuse_duplicates, refused_id_job, unlisted_split_jobs
    root = Path(root)
    data_root = _data_root(root)
    objects_root = data_root / "captured_objects"
    text_dir = _text_dir(root, data_root)
    splits = load_split_file(split_file) if split_file else None
    entries, source_jobs = _read_entries(data_root, out, config.mode)

    # one template name per (object, part, scale): the store keeps one template per name
    scales: dict[tuple[str, str], set] = {}
    for cid, seq, _ in entries:
        m = _NAME.match(cid)
        for prefix in ("obj", "obj_bottom"):
            s = _scale_of(seq, prefix) if isinstance(seq, dict) else None
            if m and s is not None:
                scales.setdefault((m.group(2), prefix), set()).add(s)

    jobs, sources = [], []
    for cid, seq, origin in entries:
        fname = origin.split(" ")[0]
        refused = refused_id_job(cid, "seq_name", origin, out, config.mode)
        if refused:
            jobs.append(refused)
            sources.append(origin)
            continue
        m = _NAME.match(cid)
        obj = m.group(2) if m else ""
        obj_name = _part_names(obj, seq, scales)
        text_file = str(text_dir / f"{cid}.json") if text_dir is not None and (text_dir / f"{cid}.json").exists() else None
        gt = data_root / GT_DIR / f"{cid}.npz"
        gt_file = str(gt) if gt.exists() else None
        loader, args = load_sequence, (seq, str(objects_root), str(body_models), config.fps, text_file,
                                       obj_name, fname, gt_file)
        try:
            split = splits[cid] if splits is not None else official_split(cid)
        except KeyError:
            split, loader, args = "unknown", fail_unit, (f"{cid}: not listed in split file {split_file}",)
        except SequenceError as exc:
            split, loader, args = "unknown", fail_unit, (f"{exc} (in {fname})",)
        two_part = isinstance(seq, dict) and any(str(k).startswith("obj_bottom") for k in seq)
        files = ([object_template_path(objects_root, obj, p) for p in TWO_PART_SUFFIXES] if obj and two_part else
                 [object_template_path(objects_root, obj) if obj else objects_root / "<no template>"])
        files += [Path(p) for p in (text_file, gt_file) if p]
        sha = _sequence_sha(seq, files, config.sha256() + LOADER_VERSION)
        jobs.append((cid, split, sha, str(out), loader, args, config.mode))
        sources.append(origin)
    jobs = refuse_duplicates(jobs, sources)
    if splits is not None:
        jobs += unlisted_split_jobs(jobs, splits, split_file, out, config.mode, "in neither OMOMO pickle")
    return jobs + source_jobs
