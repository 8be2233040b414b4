"""CORE4D-Real -> :class:`~hoibench.bodies.multibody.MultiBodyClip` (two humans, one object).

CORE4D (Liu, Zhang et al., "CORE4D: A 4D Human-Object-Human Interaction Dataset for
Collaborative Object REarrangement", arXiv 2406.19353, CVPR 2025) captures two people
moving one object together. hoibench reads the **CORE4D-Real** release; CORE4D-Synthetic
(``<seq>/human_poses.npy``, ``object_poses.npy``, ``object_mesh.obj``, whose array layout
is not documented) is not read. hoibench also writes this layout with license-free data:
:func:`hoibench.datasets.core4d_layout.write_core4d_layout`.

Raw layout (``ROOT`` is ``CORE4D_Real`` or the folder holding it)::

    ROOT/human_object_motions/<date>/<seq>/person1_poses.npz    SMPL-X parameters, person 1
    ROOT/human_object_motions/<date>/<seq>/person2_poses.npz    SMPL-X parameters, person 2
    ROOT/human_object_motions/<date>/<seq>/smooth_objposes.npy  (T, 4, 4) object poses
        (releases documented before July 2024: object_poses_<object name>.npy)
    ROOT/human_object_motions/<date>/<seq>/object_metadata.json {"obj_name", "obj_model_path"}
    ROOT/human_object_motions/<date>/<seq>/aligned_frame_ids.txt  (not read, see below)
    ROOT/object_models/<category>/<object name>_m.obj            object meshes, metres
    ROOT/action_labels.json                                       action label per sequence

``<date>`` is a capture session (``20231002``, ``20231003_1``, ...), ``<seq>`` a take
(``004``; a few are ``tst`` or ``0-1``). The clip id is ``<date>.<seq>``, the form of
CORE4D's own split lists.

Facts and where they come from (all from leolyliu/CORE4D-Instructions unless named):

* folder layout, file names, the 4x4 pose matrices (numpy float64, "transformation matrix
  of the object model", world frame), object meshes "in the canonical space of the object
  category", unit metre: ``docs/file_definitions.md``; the pose file was renamed from
  ``object_poses_<object name>.npy`` to ``smooth_objposes.npy`` in that file's history
  (July 2024) and ``dataset_utils/visualize_human_object_motion.py`` reads the latter.
* a person file is ``np.savez`` of one dict: ``np.load(path, allow_pickle=True)["arr_0"]
  .item()`` holds ``betas`` (T, 10), ``global_orient`` (T, 3), ``transl`` (T, 3),
  ``body_pose`` (T, 21, 3) axis-angle, ``left_hand_pose`` / ``right_hand_pose`` (T, 12)
  hand PCA coefficients, ``joints`` (T, 127, 3), ``vertices`` (T, 10475, 3), float32
  (``docs/file_definitions.md``), and ``expression`` (T, 10)
  (``benchmarks/data_processing/utils/load_smplx_params.py``). ``betas`` is the same in
  every frame (``docs/file_definitions.md``).
* the bodies are posed with ``smplx.create(model_type="smplx", gender="neutral",
  num_betas=10, num_expression_coeffs=10, use_pca=True, num_pca_comps=12,
  flat_hand_mean=True, ext="npz")`` (``benchmarks/data_processing/optimization/
  bvh2smplx.py`` ``create_SMPLX_model``; the same call in ``docs/file_definitions.md`` and
  the visualisation script): gender neutral for both people.
* object pose: ``v_world = R v_model + t`` with ``R = P[:3, :3]``, ``t = P[:3, 3]`` and no
  scale (``visualize_human_object_motion.py`` and the motion-forecasting benchmark's
  ``prepare_hho.py`` pose vertices so; the interaction-synthesis benchmark's
  ``hho_dataset.py`` sets ``obj_scale`` to one). Mesh file: ``object_metadata.json["obj_name"]``
  lower-cased, category = the name without its last three characters, file
  ``object_models/<category>/<name>_m.obj`` (``benchmarks/data_processing/utils/
  VTS_object.py`` ``get_obj_info``), loaded with ``trimesh.load`` (default processing).
* world frame: **y-up**, metres. The interaction-synthesis benchmark canonicalises CORE4D
  with ``floor_z=False`` ("the floor is on y = ...", ``manip/data/hho_dataset.py`` with
  ``manip/lafan1/utils.py``), ``prepare_hho.py`` picks the foot in contact by the lower
  y coordinate, and the visualisation camera's image-down axis points mostly along world
  -y. The floor height is not documented.
* frame rate: **15 fps** for the processed SMPL-X motions (leolyliu/CORE4D_toolkit
  ``README.md``: raw mocap 90 fps, processed motions 15 fps); the RGB frames the motions
  are aligned to are extracted at 15 fps (``benchmarks/data_processing/utils/
  avi2depth.py``). ``aligned_frame_ids.txt`` lists, per aligned frame, the indices of the
  four RGB cameras' and the mocap streams' frames (``utils/time_align.py``); that its
  line i is frame i of the released motion is not documented, so it is not read and the
  motions are taken as uniformly sampled at 15 fps.
* action labels: ``action_labels.json`` (``README.md``); the label vocabulary (move1,
  move2, raise*, rot, raise*_rot, pass1, pass2, join, leave, strike, notify; obstacle
  annotations obs0/obs1/obs3) is in ``docs/file_definitions.md``. The file's structure is
  not documented; it is read as the JSON object ``{"<date>/<seq>": "<label>"}`` that
  ``load_action_info`` of ``benchmarks/interaction_synthesis/FID_score/dataset.py`` reads
  from the authors' annotation file (``<date>.<seq>`` keys are accepted too). CORE4D has
  no text descriptions and releases no contact labels (its benchmarks derive contact from
  geometry): clips get no texts and no contacts.
* split: the official split is three lists in ``benchmarks/dataset_statistics/``:
  ``train_sequence_names.json`` (482), ``test_sequence_names_seen_obj.json`` (225) and
  ``test_sequence_names_unseen_obj.json`` (255), by object (``train_test_split.py``); the
  benchmarks test on both test lists. They are embedded here (:data:`OFFICIAL_SPLIT`) as
  ``train`` and ``test``; the list a clip came from is in its provenance
  (``core4d_split_list``). A sequence in none of them is refused (name a ``split_file``
  to prepare it).

.. warning::
   The person files are pickles inside ``.npz`` (``allow_pickle=True`` is how CORE4D
   reads them): loading unpickles them, which can run code. Only point hoibench at the
   CORE4D files you downloaded yourself.

Conversion (per sequence):

1. Bodies: both people through SMPL-X neutral on the user's model files (or hoibench's
   proxy in the SMPL-X file structure) with every released parameter: 10 betas, the
   expression, body pose and the hands (the 12 PCA coefficients times the model's own
   hand components, flat hand mean: what ``use_pca=True`` does). The file's own
   ``joints[:, :22]`` are compared with the model's at the source frames; the largest
   difference is recorded as ``stored_joints_max_dev_m`` and one above
   :data:`STORED_JOINTS_TOL_M` is refused (the model files are not the ones CORE4D used).
2. Frame: already y-up metres, so no rotation. y is shifted so the lowest body-surface
   vertex of either person over the source frames sits at y = 0 (as for BEHAVE and
   OMOMO; computed before resampling, so the shift does not depend on ``fps``); the shift
   is recorded (``floor_shift_m``).
3. Object: the 3x3 block of each pose must be a rotation within
   :data:`hoibench.core.plausibility.ROTATION_TOL` (it is replaced by the nearest rotation; the
   largest correction is recorded) and the bottom row ``(0, 0, 0, 1)``; the template is
   centred on its vertex mean ``m`` and the translation becomes ``t + R m``, so
   ``R (v - m) + t + R m`` is exactly CORE4D's ``R v + t``.
4. Time: source frame i at i / 15 s, resampled by time to ``fps`` (rotations -- every
   SMPL-X joint and the object -- by quaternion slerp; translations, betas and expression
   linearly; the object's centred translation linearly), never by an index step.
5. Clip: bodies ``person1``, ``person2`` (22 SMPL-order joints, ``rot`` = global
   orientation, ``trans`` = pelvis) and the object (named after its template), the raw
   action label as ``action``, ``subject`` = the capture session (CORE4D releases no
   participant ids).

Refused, naming the sequence, file and key: a missing file or key, a wrong shape, a
non-real or non-finite value, frame counts that differ between the files, fewer than two
frames, a pose that is not rigid, a missing or degenerate mesh, implausible tracks (see
:mod:`hoibench.core.plausibility`), stored joints far from the model's, a sequence outside the
split.
"""
from __future__ import annotations

import json
import re
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from ..core import geometry as geo
from ..core import plausibility as pl
from ..core.ids import InvalidIdError, check_id
from ..core.skeleton import NUM_JOINTS
from .behave import SequenceError, _lerp, _slerp_resample, load_split_file, read_mesh, resample_rigid, resample_times

__all__ = ["SOURCE_FPS", "PERSONS", "POSE_FILE", "LEGACY_POSE_FILE", "STORED_JOINTS_TOL_M", "OFFICIAL_SPLIT",
           "SequenceError", "official_lists", "official_split", "object_template_path", "object_pose_path",
           "read_person_file", "read_object_poses", "read_object_name", "read_action_labels", "load_sequence",
           "prepare_jobs"]

SOURCE_FPS = 15.0
PERSONS = ("person1", "person2")
POSE_FILE = "smooth_objposes.npy"
LEGACY_POSE_FILE = "object_poses_{}.npy"
METADATA_FILE = "object_metadata.json"
ACTION_FILE = "action_labels.json"
MOTIONS_DIR = "human_object_motions"
OBJECTS_DIR = "object_models"
#: CORE4D's SMPL-X settings (``create_SMPLX_model`` in bvh2smplx.py).
NUM_BETAS, NUM_EXPRESSION, NUM_HAND_PCA = 10, 10, 12
#: Largest accepted distance, metres, between a person file's own ``joints[:, :22]`` and the
#: joints the model files give for its parameters; more means other model files than CORE4D's.
STORED_JOINTS_TOL_M = 0.05
#: A person file is read whole (its vertices are most of it): at most this many bytes.
MAX_PERSON_FILE_BYTES = 4 * 1024 ** 3
MAX_POSE_FILE_BYTES = 256 * 1024 ** 2
#: Largest accepted deviation of a pose's bottom row from (0, 0, 0, 1).
BOTTOM_ROW_TOL = 1e-6
_FORWARD_CHUNK = 256
_RANGE = re.compile(r"^(\d{3})-(\d{3})$")

#: CORE4D's official split (leolyliu/CORE4D-Instructions, benchmarks/dataset_statistics/
#: train_sequence_names.json, test_sequence_names_seen_obj.json,
#: test_sequence_names_unseen_obj.json; CC BY 4.0), per list and capture date: the takes,
#: ``a-b`` a run of three-digit takes. :func:`official_lists` expands it to ``<date>.<seq>``.
OFFICIAL_SPLIT: dict[str, dict[str, str]] = {
    "train": {
        "20231002": "002-005 007 015 018-020 024 028-029 031 033 046",
        "20231003_1": "000-006 008 012-017 021 023-025 027-028 040-041 043 046-048",
        "20231003_2": "001 003-004 006 009 011-013 015 018-023 025-026 028 037 039 041 044-045 048-049 054 056 "
                      "058-059 061-062 064 067 069 082-084 086-087 089 tst",
        "20231008": "000-002 004-008 011-015 018-021 024-025 027 029-030 033 045-047 055-060 062-066 068 070-071 tst",
        "20231011": "000 004 007-013 016 018-019 023-025 035-036 038-040 042 045-051 053-056 059 071 073 075-080 "
                    "082-086 088-089 091 115-116 tst",
        "20231018": "000-002 004-010 012-019 021 025-031 033-035 037 057-061 063 065 070-076 079-081 083 085-087 091 "
                    "093-094 096-097 099-100 102 105-106 108-111 114-115 tst",
        "20231020": "001-004 008 010 012-016 018-019 021-022 025-028 030-031 033-039 042-044 047-052 054-057 060-063 "
                    "065-066 069-072 074-076 078 080-082 084-085 088 090-092 096-099 102-104 116-118 120-121 123 "
                    "125-127 130",
        "20231023": "000-002 005-007 036-040 042-044 064-067 069 071-072 075-076 078-082 084-090 093-099 102-104 "
                    "106-107 111-115 117-122 124-132 tst",
        "20231030": "000 002-007 010-011 013-015 020 022 025-026 051 053-055 057-058 060-063 075 077 081 095 097-101",
        "20231108": "000-001 003-004 007-010 012 015-017 036-037 039-042 044-046 048-052 054-055 057 059-062 064 066 "
                    "069 071 090-092 094 101 105-106 108 110-111 113-115 118 120-122 125",
    },
    "test_seen_obj": {
        "20231002": "001 017 021-023 034-036 048 055",
        "20231003_1": "007 010-011 018-020 022 026 039 042 044-045 tst",
        "20231003_2": "000 002 005 007-008 010 014 016 024 027 038 043 046 055 057 065 068 070 072 085",
        "20231008": "003 009-010 016-017 022-023 026 028 031-032 044 049-054 061 067 069",
        "20231011": "002 005-006 014 017 021-022 034 037 041 043 052 057-058 072 074 081 087 090 092",
        "20231018": "003 011 020 022-024 032 036 062 064 066-069 082 084 088-090 092 095 098 101 103-104 107 "
                    "112-113 116",
        "20231020": "000 009 011 017 020 023 029 040-041 045-046 058-059 064 067-068 073 077 079 083 086-087 089 "
                    "093-094 100 115 122 128-129 131-132 tst",
        "20231023": "003-004 008 041 063 068 070 073-074 077 083 092 100-101 105 108-110 116 123",
        "20231030": "001 008-009 012 016 019 021 023-024 052 056 059 064 074 076 078 080 082-083 093-094 096 tst",
        "20231108": "002 005-006 011 013-014 038 043 047 053 056 058 063 065 067-068 070 093 095-100 102-104 107 "
                    "109 112 116-117 119 123-124 0-1",
    },
    "test_unseen_obj": {
        "20231002": "009 011-012 014 037-044 056-063",
        "20231003_1": "029-037",
        "20231003_2": "029-036 073 076-079",
        "20231008": "035-043",
        "20231011": "026-028 030-032 060-069",
        "20231018": "038-056 077-078",
        "20231020": "105-113 133-135 137-141",
        "20231023": "009-035 045-062 133-141",
        "20231030": "027-044 046-050 065-073 084-092",
        "20231108": "018-035 072-089 126-144",
    },
}
#: official list -> hoibench split (the benchmarks test on both test lists).
OFFICIAL_SPLIT_OF_LIST = {"train": "train", "test_seen_obj": "test", "test_unseen_obj": "test"}


# --------------------------------------------------------------------------- split
@lru_cache(maxsize=1)
def official_lists() -> dict[str, tuple[str, ...]]:
    """The official lists expanded to sorted ``<date>.<seq>`` ids."""
    out = {}
    for name, dates in OFFICIAL_SPLIT.items():
        ids = []
        for date, takes in dates.items():
            for tok in takes.split():
                m = _RANGE.match(tok)
                seqs = [f"{k:03d}" for k in range(int(m.group(1)), int(m.group(2)) + 1)] if m else [tok]
                ids += [f"{date}.{s}" for s in seqs]
        out[name] = tuple(sorted(ids))
    return out


@lru_cache(maxsize=1)
def _list_of() -> dict[str, str]:
    return {cid: name for name, ids in official_lists().items() for cid in ids}


def official_split(clip_id: str) -> tuple[str, str]:
    """(hoibench split, official list name) of ``<date>.<seq>``; KeyError when no official
    list holds it."""
    name = _list_of()[clip_id]
    return OFFICIAL_SPLIT_OF_LIST[name], name


# --------------------------------------------------------------------------- files
def _rel(path: Path, seq_dir: Path) -> str:
    """``human_object_motions/<date>/<seq>/<file>`` for messages."""
    return f"{MOTIONS_DIR}/{seq_dir.parent.name}/{seq_dir.name}/{Path(path).name}"


def read_object_name(seq_dir: str | Path, where: str) -> str:
    """``object_metadata.json["obj_name"]`` lower-cased (as ``get_obj_info`` does), a valid
    id of more than three characters (the last three are the object's number)."""
    seq_dir = Path(seq_dir)
    path = seq_dir / METADATA_FILE
    rel = _rel(path, seq_dir)
    if not path.exists():
        raise SequenceError(f"{where}: missing file {rel}")
    from ..core.io import read_json_file
    try:
        meta = read_json_file(path, 1024 ** 2, METADATA_FILE)
    except ValueError as exc:
        raise SequenceError(f"{where}: {rel}: {exc}") from None
    if not isinstance(meta, dict) or "obj_name" not in meta:
        raise SequenceError(f"{where}: {rel}: missing key 'obj_name'")
    name = meta["obj_name"]
    if not isinstance(name, str) or len(name) < 4:
        raise SequenceError(f"{where}: {rel}: obj_name: expected a name like 'box001', got {name!r:.60}")
    try:
        return check_id(name.lower(), "obj_name", rel)
    except InvalidIdError as exc:
        raise SequenceError(f"{where}: {exc}") from None


def object_template_path(objects_root: str | Path, obj_name: str) -> Path:
    """``object_models/<category>/<name>_m.obj``, category = the name less its last three
    characters (lower case, as ``get_obj_info``)."""
    name = str(obj_name).lower()
    return Path(objects_root) / name[:-3] / f"{name}_m.obj"


def object_pose_path(seq_dir: str | Path, obj_name: str = "") -> Path:
    """``smooth_objposes.npy``, or the earlier ``object_poses_<object name>.npy`` when only
    that exists (returns the former when neither does: the loader reports it missing)."""
    seq_dir = Path(seq_dir)
    path = seq_dir / POSE_FILE
    if not path.exists() and obj_name:
        for cand in dict.fromkeys((obj_name, obj_name.lower())):
            legacy = seq_dir / LEGACY_POSE_FILE.format(cand)
            if legacy.exists():
                return legacy
    return path


def _size_checked(path: Path, rel: str, limit: int, where: str) -> None:
    from ..core.io import check_regular_file
    if not path.exists():
        raise SequenceError(f"{where}: missing file {rel}")
    try:
        check_regular_file(path, rel)
    except ValueError as exc:
        raise SequenceError(f"{where}: {exc}") from None
    size = path.stat().st_size
    if size > limit:
        raise SequenceError(f"{where}: {rel}: {size} bytes, over the {limit}-byte limit: not read")


def _guarded_bytes(path: Path, limit: int, rel: str, where: str):
    """The file's bytes (regular file, at most ``limit``) as a stream for ``np.load``."""
    import io
    from ..core.io import read_regular_file
    try:
        return io.BytesIO(read_regular_file(path, limit, rel))
    except ValueError as exc:
        raise SequenceError(f"{where}: {exc}") from None


def _key(data: dict, key: str, rel: str, where: str) -> np.ndarray:
    if key not in data:
        raise SequenceError(f"{where}: {rel}: missing key {key!r}")
    try:
        return pl.real_array(data[key], key, f"{where}: {rel}")
    except ValueError as exc:
        raise SequenceError(str(exc)) from None


def _shape(a: np.ndarray, key: str, tails: tuple[tuple, ...], rel: str, where: str) -> np.ndarray:
    """``a`` when its shape is (T, *tail) for one of ``tails`` (a ``None`` entry: any size
    >= 1); else a SequenceError naming the key and the shapes expected."""
    for tail in tails:
        if a.ndim == 1 + len(tail) and all(t is None and s >= 1 or s == t for s, t in zip(a.shape[1:], tail)):
            return a
    want = " or ".join("(T, " + ", ".join("k" if t is None else str(t) for t in tail) + ")" for tail in tails)
    raise SequenceError(f"{where}: {rel}: {key}: expected shape {want}, got {a.shape}")


def read_person_file(path: str | Path, where: str = "") -> dict[str, np.ndarray]:
    """One person's SMPL-X parameters (float64): ``betas`` (T, k), ``global_orient`` (T, 3),
    ``transl`` (T, 3), ``body_pose`` (T, 21, 3), ``left_hand_pose`` / ``right_hand_pose``
    (T, k) PCA coefficients, ``expression`` (T, k) (zeros (T, 10) when absent) and, when
    the file has them, ``joints`` (T, J >= 22, 3). Unpickles the file (own downloads only).
    SequenceError naming ``where``, the file and the key otherwise."""
    path = Path(path)
    rel = _rel(path, path.parent)
    where = where or f"{path.parent.parent.name}.{path.parent.name}"
    _size_checked(path, rel, MAX_PERSON_FILE_BYTES, where)
    try:
        with np.load(_guarded_bytes(path, MAX_PERSON_FILE_BYTES, rel, where), allow_pickle=True) as z:  # read-ok: CORE4D person files are pickles (own download, docs/security.md)
            if "arr_0" not in z.files:
                raise SequenceError(f"{where}: {rel}: missing key 'arr_0' (CORE4D's person files are np.savez "
                                    f"of one dict; members: {z.files[:6]})")
            item = z["arr_0"]
    except SequenceError:
        raise
    except Exception as exc:   # zip/format errors of a truncated file, unpickling errors
        raise SequenceError(f"{where}: {rel}: unreadable ({type(exc).__name__}: {str(exc)[:160]})") from None
    data = item.item() if isinstance(item, np.ndarray) and item.dtype == object and item.ndim == 0 else None
    if not isinstance(data, dict):
        raise SequenceError(f"{where}: {rel}: arr_0: expected a pickled dict of SMPL-X parameters, got "
                            f"{type(data if data is not None else item).__name__}")
    out = {
        "betas": _shape(_key(data, "betas", rel, where), "betas", ((None,),), rel, where),
        "global_orient": _shape(_key(data, "global_orient", rel, where), "global_orient", ((3,),), rel, where),
        "transl": _shape(_key(data, "transl", rel, where), "transl", ((3,),), rel, where),
    }
    bp = _shape(_key(data, "body_pose", rel, where), "body_pose", ((21, 3), (63,)), rel, where)
    out["body_pose"] = bp.reshape(len(bp), 21, 3)
    for k in ("left_hand_pose", "right_hand_pose"):
        h = _shape(_key(data, k, rel, where), k, ((None,),), rel, where)
        if h.shape[1] > 45:
            raise SequenceError(f"{where}: {rel}: {k}: {h.shape[1]} hand coefficients, at most 45")
        out[k] = h
    if out["betas"].shape[1] > pl.MAX_BETAS:
        raise SequenceError(f"{where}: {rel}: betas: {out['betas'].shape[1]} coefficients, at most {pl.MAX_BETAS}")
    if "expression" in data:
        out["expression"] = _shape(_key(data, "expression", rel, where), "expression", ((None,),), rel, where)
    if "joints" in data:
        j = _shape(_key(data, "joints", rel, where), "joints", ((None, 3),), rel, where)
        if j.shape[1] < NUM_JOINTS:
            raise SequenceError(f"{where}: {rel}: joints: expected (T, J, 3) with J >= {NUM_JOINTS}, got {j.shape}")
        out["joints"] = j[:, :NUM_JOINTS]
    if "expression" not in out:
        out["expression"] = np.zeros((len(out["transl"]), NUM_EXPRESSION))
    return out


def read_object_poses(path: str | Path, where: str = "") -> tuple[np.ndarray, np.ndarray, float]:
    """(R (T, 3, 3) rotations, t (T, 3), largest correction to the nearest rotation) of a
    (T, 4, 4) pose file; SequenceError naming the file and the frame for a non-rigid pose."""
    path = Path(path)
    rel = _rel(path, path.parent)
    where = where or f"{path.parent.parent.name}.{path.parent.name}"
    _size_checked(path, rel, MAX_POSE_FILE_BYTES, where)
    try:
        raw = np.load(_guarded_bytes(path, MAX_POSE_FILE_BYTES, rel, where), allow_pickle=False)  # read-ok: bytes read by _guarded_bytes
    except Exception as exc:
        raise SequenceError(f"{where}: {rel}: unreadable ({type(exc).__name__}: {str(exc)[:160]})") from None
    if not isinstance(raw, np.ndarray):
        raise SequenceError(f"{where}: {rel}: expected one (T, 4, 4) array, got {type(raw).__name__}")
    try:
        P = pl.real_array(raw, "object poses", f"{where}: {rel}")
    except ValueError as exc:
        raise SequenceError(str(exc)) from None
    if P.ndim != 3 or P.shape[1:] != (4, 4):
        raise SequenceError(f"{where}: {rel}: object poses: expected shape (T, 4, 4), got {P.shape}")
    bottom = np.abs(P[:, 3] - np.array([0.0, 0.0, 0.0, 1.0])).max(-1)
    bad = np.flatnonzero(bottom > BOTTOM_ROW_TOL)
    if len(bad):
        f = int(bad[0])
        raise SequenceError(f"{where}: {rel}: object poses: frame {f}: bottom row {P[f, 3].tolist()}, expected "
                            "[0, 0, 0, 1] (not a rigid transform)")
    R = P[:, :3, :3]
    err = np.abs(R @ R.swapaxes(-1, -2) - np.eye(3)).max(axis=(-2, -1))
    det = np.linalg.det(R)
    bad = np.flatnonzero((err > pl.ROTATION_TOL) | (np.abs(det - 1.0) > pl.ROTATION_TOL))
    if len(bad):
        f = int(bad[0])
        raise SequenceError(f"{where}: {rel}: object poses: frame {f}: the 3x3 block is not a rotation "
                            f"(|R R^T - I| = {err[f]:.3g}, det {det[f]:.6g}; a scaled or mirrored pose?)")
    U, _, Vt = np.linalg.svd(R)
    Rn = U @ Vt
    return Rn, P[:, :3, 3].copy(), float(np.abs(Rn - R).max()) if len(R) else 0.0


def read_action_labels(path: str | Path) -> dict[str, Any]:
    """``action_labels.json`` -> {``<date>.<seq>``: value} (keys ``<date>/<seq>`` or
    ``<date>.<seq>``; values are checked per sequence by the loader). ValueError naming the
    file when it is not a JSON object."""
    from ..core.io import read_json_file
    data = read_json_file(path, 64 * 1024 ** 2, ACTION_FILE)
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a JSON object {{\"<date>/<seq>\": label}}, got {type(data).__name__}")
    return {str(k).replace("/", ".").strip(): v for k, v in data.items()}


def _check_action(value: Any, cid: str) -> str:
    if not isinstance(value, str) or not value.strip():
        raise SequenceError(f"{cid}: {ACTION_FILE}: entry {cid.replace('.', '/', 1)!r}: expected an action label "
                            f"(a non-empty string), got {value!r:.60}")
    return value.strip()


# --------------------------------------------------------------------------- body model
@lru_cache(maxsize=8)
def _body_model(model_dir: str, num_betas: int, num_expr: int, num_pca: int):
    from ..bodies.smpl import load_body_model
    return load_body_model(model_dir, "smplx", "neutral", num_betas=num_betas, num_expression_coeffs=num_expr,
                           use_pca=False, flat_hand_mean=True, num_pca_comps=num_pca)


def _hand_axis_angle(pca: np.ndarray, components: np.ndarray, key: str, rel: str, where: str) -> np.ndarray:
    """(T, k) PCA coefficients -> (T, 45) axis-angle with the model's first k components
    (flat hand mean: no mean added), what ``smplx`` does with ``use_pca=True``."""
    comp = np.asarray(components, dtype=np.float64)
    k = pca.shape[1]
    if comp.ndim != 2 or comp.shape[0] < k or comp.shape[1] != 45:
        raise SequenceError(f"{where}: {rel}: {key}: {k} PCA coefficients, the model gives "
                            f"{comp.shape[0] if comp.ndim == 2 else 0} hand components")
    return pca @ comp[:k]


def _pose55(p: dict, model, rel: str, where: str) -> np.ndarray:
    T = len(p["transl"])
    pose = np.zeros((T, 55, 3))
    pose[:, 0] = p["global_orient"]
    pose[:, 1:22] = p["body_pose"]
    pose[:, 25:40] = _hand_axis_angle(p["left_hand_pose"], model.np_left_hand_components, "left_hand_pose",
                                      rel, where).reshape(T, 15, 3)
    pose[:, 40:55] = _hand_axis_angle(p["right_hand_pose"], model.np_right_hand_components, "right_hand_pose",
                                      rel, where).reshape(T, 15, 3)
    return pose


def _forward(model, pose55: np.ndarray, betas: np.ndarray, expr: np.ndarray, transl: np.ndarray,
             vertices: bool) -> tuple[np.ndarray, float]:
    """(22 body joints (T, 22, 3) float64, lowest vertex y (inf without ``vertices``)), in
    chunks so a long sequence never holds all its vertices."""
    from ..bodies.smpl import body_forward
    joints, low = [], np.inf
    for s in range(0, len(pose55), _FORWARD_CHUNK):
        e = min(len(pose55), s + _FORWARD_CHUNK)
        j, v = body_forward(model, pose55[s:e].reshape(e - s, 165), betas[s:e], transl[s:e],
                            return_vertices=vertices, expression=expr[s:e])
        joints.append(j[:, :NUM_JOINTS].astype(np.float64))
        if vertices:
            low = min(low, float(v[..., 1].min()))
    return np.concatenate(joints), low


@lru_cache(maxsize=64)
def _template(path: str, mtime_ns: int, size: int) -> tuple[np.ndarray, np.ndarray]:
    name = Path(path).name
    return pl.check_template(*read_mesh(path, name, process=True), name)


def load_template(path: str | Path, obj: str, where: str) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) float64 (as in the file, not centred) and faces (F, 3) of an object
    mesh loaded as CORE4D loads it (``trimesh.load``: vertices at equal positions merged)
    that passes :func:`hoibench.core.plausibility.check_template`."""
    path = Path(path)
    if not path.exists():
        raise SequenceError(f"{where}: object {obj!r}: missing mesh {OBJECTS_DIR}/{path.parent.name}/{path.name}")
    try:
        st = path.stat()
        return _template(str(path), st.st_mtime_ns, st.st_size)
    except ValueError as exc:
        raise SequenceError(f"{where}: object {obj!r} ({OBJECTS_DIR}/{path.parent.name}/{path.name}): {exc}") from None


# --------------------------------------------------------------------------- one sequence
def load_sequence(seq_dir: str | Path, objects_root: str | Path, body_models: str | Path,
                  fps: float = SOURCE_FPS, action: Any = None, split_list: str | None = None):
    """Read one CORE4D-Real sequence folder into a
    :class:`~hoibench.bodies.multibody.MultiBodyClip` at ``fps`` (see the module docstring).

    ``action``: the sequence's entry of ``action_labels.json`` (None: none); ``split_list``:
    the official list holding it (recorded in the provenance). Raises
    :class:`SequenceError` naming the sequence, the file and the key."""
    from ..bodies.multibody import Body, MultiBodyClip
    seq_dir = Path(seq_dir)
    date = check_id(seq_dir.parent.name, "date folder", seq_dir.parent.parent)
    seq = check_id(seq_dir.name, "sequence folder", seq_dir.parent)
    cid = check_id(f"{date}.{seq}", "clip id", seq_dir)
    fps = pl.check_fps(fps, "fps", cid)
    label = _check_action(action, cid) if action is not None else None

    persons = {p: read_person_file(seq_dir / f"{p}_poses.npz", cid) for p in PERSONS}
    obj = read_object_name(seq_dir, cid)
    pose_path = object_pose_path(seq_dir, obj)
    R_src, t_src, rot_fix = read_object_poses(pose_path, cid)
    rel = {p: _rel(seq_dir / f"{p}_poses.npz", seq_dir) for p in PERSONS}
    pose_rel = _rel(pose_path, seq_dir)
    counts = {f"{rel[p]}: {k}": len(a) for p in PERSONS for k, a in persons[p].items()}
    counts[f"{pose_rel}: poses"] = len(R_src)
    T = pl.common_frame_count(counts, cid, pl.MIN_FRAMES)
    for p in PERSONS:
        pl.check_track(persons[p]["transl"], "transl", f"{cid}: {rel[p]}", fps=SOURCE_FPS)
    pl.check_track(t_src, "object translation", f"{cid}: {pose_rel}", fps=SOURCE_FPS)
    tpath = object_template_path(objects_root, obj)
    raw_v, faces = load_template(tpath, obj, cid)
    mean = raw_v.mean(0)

    # bodies at the source frames: the stored-joints check and the floor
    src_t = np.arange(T) / SOURCE_FPS
    dst = resample_times(src_t, fps)
    same = len(dst) == T and np.allclose(dst, src_t, rtol=0.0, atol=1e-12)
    nb = max(NUM_BETAS, *(persons[p]["betas"].shape[1] for p in PERSONS))
    ne = max(NUM_EXPRESSION, *(persons[p]["expression"].shape[1] for p in PERSONS))
    npca = max(NUM_HAND_PCA, *(persons[p][k].shape[1] for p in PERSONS for k in ("left_hand_pose", "right_hand_pose")))
    model = _body_model(str(Path(body_models)), nb, ne, npca)
    pose_src, joints_src, devs, floor = {}, {}, {}, np.inf
    for p in PERSONS:
        d = persons[p]
        pose_src[p] = _pose55(d, model, rel[p], cid)
        joints_src[p], low = _forward(model, pose_src[p], d["betas"], d["expression"], d["transl"], True)
        floor = min(floor, low)
        if "joints" in d:
            dev = float(np.linalg.norm(joints_src[p] - d["joints"], axis=-1).max())
            devs[p] = dev
            if dev > STORED_JOINTS_TOL_M:
                raise SequenceError(
                    f"{cid}: {rel[p]}: joints: the file's own joints are up to {dev:.4g} m from those the model "
                    f"files in {Path(body_models)} give for its parameters (tolerance {STORED_JOINTS_TOL_M:g} m): "
                    "CORE4D posed its bodies with SMPL-X neutral (smplx/SMPLX_NEUTRAL.npz), 10 betas, 10 expression "
                    "coefficients, 12-component hand PCA, flat hand mean; check the model files")

    # resample by time, then the clip in hoibench's world (y-up already: y -= floor)
    bodies = []
    for p in PERSONS:
        d = persons[p]
        if same:
            pose, joints = pose_src[p], joints_src[p]
        else:
            pose = _slerp_resample(src_t, dst, pose_src[p])
            betas, expr, transl = (_lerp(src_t, dst, d[k]) for k in ("betas", "expression", "transl"))
            joints, _ = _forward(model, pose, betas, expr, transl, False)
        joints = joints.copy()
        joints[..., 1] -= floor
        try:
            pl.check_body_height(joints, f"{cid}: {p}")
        except ValueError as exc:
            raise SequenceError(str(exc)) from None
        bodies.append(Body(p, "human", joints[:, 0].copy(), geo.axis_angle_to_matrix(pose[:, 0]), joints))
    t_centred = t_src + R_src @ mean
    if same:
        o_rot, o_trans = R_src, t_centred.copy()
    else:
        o_rot, o_trans = resample_rigid(src_t, dst, R_src, t_centred)
    o_trans[:, 1] -= floor
    bodies.append(Body(obj, "object", o_trans, o_rot, None, obj))

    files = [rel[p] for p in PERSONS] + [pose_rel, _rel(seq_dir / METADATA_FILE, seq_dir),
                                         f"{OBJECTS_DIR}/{tpath.parent.name}/{tpath.name}"]
    prov = {
        "source": "core4d-real", "source_files": files, "raw_source": f"{MOTIONS_DIR}/{date}/{seq}/ ("
        + ", ".join(Path(f).name for f in files[:4]) + f"), {files[4]}",
        "source_frame": "CORE4D-Real world: y-up, metres", "transform": "none (already y-up); y -= floor",
        "floor_shift_m": float(floor), "floor": "lowest body-surface vertex of either person over the source frames",
        "source_fps": SOURCE_FPS, "resampled_to_fps": float(fps), "source_frames": int(T),
        "body_model": "smplx neutral", "num_betas": int(nb), "num_expression_coeffs": int(ne),
        "hands": f"{persons['person1']['left_hand_pose'].shape[1]}-component PCA with the model's components, "
                 "flat hand mean (CORE4D's use_pca=True, flat_hand_mean=True)",
        "stored_joints_max_dev_m": {p: devs.get(p) for p in PERSONS},
        "object_name": obj, "object_category": obj[:-3], "template": tpath.name,
        "object_pose_file": Path(pose_path).name, "object_rotation_max_correction": rot_fix,
        "template_mean_subtracted": mean.tolist(),
        "object_convention": "v = R v_model + t -> template v_model - mean, t' = t + R mean",
        "capture_date": date, "subject": "capture session (CORE4D releases no participant ids)",
        "action_label": label, "core4d_split_list": split_list,
        "contacts": "none (CORE4D releases no contact labels)",
    }
    return MultiBodyClip(name=cid, dataset="core4d", subject=date, fps=float(fps), bodies=bodies,
                         templates={obj: (raw_v - mean, faces)}, contacts={}, action=label, texts=[],
                         provenance=prov)


# --------------------------------------------------------------------------- jobs
def _real_root(root: Path) -> Path:
    for cand in (root, root / "CORE4D_Real"):
        if (cand / MOTIONS_DIR).is_dir():
            return cand
    raise FileNotFoundError(f"--root: no {MOTIONS_DIR}/ in {root} or {root / 'CORE4D_Real'} "
                            "(expected CORE4D-Real's release layout)")


def _subdirs(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.is_dir())


def _safe_template(seq_dir: Path, objects_root: Path) -> tuple[str, Path]:
    """(object name, mesh path) for the checksum; placeholders when unreadable (the unit
    reports why)."""
    try:
        obj = read_object_name(seq_dir, seq_dir.name)
        return obj, object_template_path(objects_root, obj)
    except Exception:
        return "", seq_dir / "<no template>"


def prepare_jobs(root: str | Path, body_models: str | Path, out: str | Path, config,
                 split_file: str | Path | None = None) -> list[tuple]:
    """One :func:`hoibench.datasets.store.run_unit` job per sequence folder
    ``human_object_motions/<date>/<seq>``; clip id ``<date>.<seq>``.

    The split is CORE4D's official one (:data:`OFFICIAL_SPLIT`: train, and test = seen-
    plus unseen-object test lists) unless ``split_file`` (``{"train": [...], "test":
    [...]}``) names another; a sequence the split does not list is an error for that
    sequence (and, with ``split_file``, a listed id without a folder too). Folder names
    must be valid ids. An unreadable ``action_labels.json`` is a failing "source" job (the
    manifest's ``incomplete``) and its sequences are prepared without labels.
    """
    from .store import (fail_unit, file_sha256, invalid_id_job, refuse_duplicates, source_failure_job, unlisted_split_jobs)
    root = Path(root)
    real = _real_root(root)
    motions, objects_root = real / MOTIONS_DIR, real / OBJECTS_DIR
    splits = load_split_file(split_file) if split_file else None
    labels: dict[str, Any] = {}
    extra_jobs = []
    action_path = real / ACTION_FILE
    if action_path.exists():
        try:
            labels = read_action_labels(action_path)
        except ValueError as exc:
            extra_jobs.append(source_failure_job(ACTION_FILE, f"{ACTION_FILE}: unreadable ({exc}): sequences "
                                                 "prepared without action labels", out, config.mode))
    jobs, sources = [], []
    for date_dir in _subdirs(motions):
        seq_dirs = _subdirs(date_dir)
        try:
            check_id(date_dir.name, "date folder", motions)
        except InvalidIdError as exc:
            for s in seq_dirs or [date_dir]:
                jobs.append(invalid_id_job(f"{date_dir.name}/{s.name}", str(exc), out, config.mode))
                sources.append(str(s))
            continue
        for seq_dir in seq_dirs:
            cid = f"{date_dir.name}.{seq_dir.name}"
            try:
                check_id(seq_dir.name, "sequence folder", date_dir)
                check_id(cid, "clip id", seq_dir)
            except InvalidIdError as exc:
                jobs.append(invalid_id_job(cid, str(exc), out, config.mode))
                sources.append(str(seq_dir))
                continue
            split_list = None
            action = labels.get(cid)
            loader, args = load_sequence, None
            try:
                if splits is not None:
                    split = splits[cid]
                else:
                    split, split_list = official_split(cid)
            except KeyError:
                where = (f"split file {split_file}" if splits is not None else
                         "CORE4D's official split (benchmarks/dataset_statistics/*_sequence_names*.json); "
                         "name a split file to prepare it")
                split, loader, args = "unknown", fail_unit, (f"{cid}: not listed in {where}",)
            if args is None:
                args = (str(seq_dir), str(objects_root), str(body_models), config.fps, action, split_list)
            obj, template = _safe_template(seq_dir, objects_root)
            files = [seq_dir / f"{p}_poses.npz" for p in PERSONS] + [object_pose_path(seq_dir, obj),
                                                                      seq_dir / METADATA_FILE, template]
            extra = json.dumps({"action": action, "split_list": split_list}, sort_keys=True, default=repr)
            sha = file_sha256(files, extra=config.sha256() + extra)
            jobs.append((cid, split, sha, str(out), loader, args, config.mode))
            sources.append(str(seq_dir))
    if not jobs:
        raise FileNotFoundError(f"--root: no sequence folders in {motions} (expected <date>/<seq>/ folders)")
    jobs = refuse_duplicates(jobs, sources)
    if splits is not None:
        jobs += unlisted_split_jobs(jobs, splits, split_file, out, config.mode, f"no folder in {MOTIONS_DIR}/")
    return jobs + extra_jobs
