"""GRAB (Taheri et al., ECCV 2020) -> :class:`~hoibench.bodies.multibody.MultiBodyClip` clips.

GRAB is whole-body grasping: one SMPL-X body, two MANO hands fitted on their own, one object
and a table, captured with markers at 120 fps. Each sequence becomes one multi-body clip:
the human (22 SMPL-order joints), the left and the right hand (21 joints each, owned by the
human), the object and, with ``with_table=True``, the table as a second object.

Raw layout (the extracted release; ``hoibench`` also writes it, license-free, with
:func:`hoibench.datasets.grab_layout.write_grab_layout`)::

    ROOT/grab/s1 .. s10/<object>_<action>[_<n>][_Retake].npz   one sequence per file
    ROOT/tools/subject_meshes/{male,female}/s<k>.ply            SMPL-X template of subject k
    ROOT/tools/subject_meshes/{male,female}/s<k>_{lhand,rhand}.ply   its MANO hand templates
    ROOT/tools/object_meshes/contact_meshes/<object>.ply        object meshes (and table.ply)

``ROOT`` may also be the ``grab/`` folder itself (GRAB's own scripts take that folder and
resolve mesh paths from its parent). GRAB also ships ``tools/object_settings``,
``subject_settings``, ``smplx_correspondence`` and ``*_betas.npy`` beside the subject meshes;
hoibench reads none of them. Files ``*_verts_{body,lhand,rhand,object}.npz`` that GRAB's
``save_grab_vertices.py`` writes next to the sequences are skipped.

Facts and where they come from (GRAB's code is otaheri/GRAB; third-party readers named):

* Layout: ``README.md`` (``GRAB/grab/s1..s10``, ``GRAB/tools/{object_meshes,
  subject_meshes, ...}``, 5 male and 5 female subjects). Sequences are globbed as
  ``grab/*/*.npz``; the subject is the folder, the object the file name up to its first
  ``_`` (``grab/grab_preprocessing.py``, ``process_sequences``). In the 1335-sequence index
  of HOIDiNi (hoidini/HOIDiNi ``hoidini/datasets/resources/grab_index.csv``) every object
  name is one token and equals that prefix, and every sequence has fps 120.
* File format: ``tools/utils.py`` ``parse_npz`` loads the ``.npz`` with
  ``allow_pickle=True`` and takes ``.item()`` of every entry: each entry is a 0-d array, a
  string or number, or a pickled ``dict``. Keys read by GRAB's scripts: ``gender``,
  ``n_comps``, ``n_frames`` (``grab/save_grab_vertices.py``, ``examples/visualize_grab.py``),
  ``obj_name``, ``sbj_id`` (``grab_preprocessing.py``), ``motion_intent`` (IMoS,
  anindita127/IMoS ``src/data_loader/dataset_preprocess.py``), ``framerate`` (HOIDiNi
  ``hoidini/datasets/grab/grab_utils.py``, ``reduce_seq_data``); the dicts ``body``,
  ``lhand``, ``rhand`` (``params``, ``vtemp``), ``object`` (``params``,
  ``object_mesh``), ``table`` (``params``, ``table_mesh``) and ``contact`` (``body``,
  ``object``) (``examples/render_grab.py``, ``visualize_grab.py``).
* Shapes (HOIDiNi ``grab_utils.py`` module notes, a 2310-frame sequence): ``body/params``
  ``transl``, ``global_orient``, ``jaw_pose``, ``leye_pose``, ``reye_pose`` (T, 3),
  ``body_pose`` (T, 63), ``left_hand_pose`` / ``right_hand_pose`` (T, 24), ``fullpose``
  (T, 165), ``expression`` (T, 10); ``lhand``/``rhand`` ``params`` ``global_orient``,
  ``transl`` (T, 3), ``hand_pose`` (T, 24), ``fullpose`` (T, 45); ``object`` / ``table``
  ``params`` ``global_orient``, ``transl`` (T, 3); ``contact/body`` (T, 10475) (one label
  per SMPL-X vertex), ``contact/object`` (T, V) (one per object-mesh vertex). The dtypes are
  not stated by any public reader (GRAB's own cast the parameters to float32): any real
  dtype is accepted.
* Body: ``save_grab_vertices.py`` / ``visualize_grab.py`` pose it with
  ``smplx.create(model_type='smplx', gender=gender, num_pca_comps=n_comps,
  v_template=<vertices of body.vtemp>)`` and ``model(**body.params)``: hand poses are
  ``n_comps`` PCA coefficients, ``flat_hand_mean`` is smplx's default (False), no betas
  are passed -- the subject's shape is the ``vtemp`` mesh, which replaces the model's
  template. ``vtemp`` is a path relative to the GRAB folder (the scripts open
  ``grab_path/../vtemp``; e.g. ``tools/subject_meshes/male/s2_rhand.ply`` in third-party
  scripts). Meshes are read with ``trimesh.load(process=False)`` (``tools/meshviewer.py``
  ``Mesh``): vertex order as in the file.
* Hands: the same scripts pose ``lhand`` / ``rhand`` with ``smplx.create(model_type='mano',
  is_rhand=..., v_template=<vertices of vtemp>, num_pca_comps=n_comps,
  flat_hand_mean=True)`` and their ``params``. ``fullpose`` (T, 45) is the finger pose as
  axis-angle (HOIDiNi feeds it to SMPL-X hands with ``flat_hand_mean=True``).
* Objects: ``tools/objectmodel.py`` ``ObjectModel`` poses the mesh of ``object_mesh``
  (``table_mesh`` for the table) as row vectors, ``v @ rodrigues(global_orient) +
  transl``: as column vectors the rotation is ``R(global_orient)^T``.
* Contacts: ``tools/utils.py`` ``contact_ids`` maps label values to SMPL-X body parts
  (1 Body ... 21 L_Hand, 22 R_Hand, 26-40 the left fingers, 41-55 the right fingers);
  ``visualize_grab.py`` marks object vertices with ``contact['object'][t] > 0`` and body
  vertices with ``contact['body'][t] > 0``; ``grab_preprocessing.py`` calls a frame in
  contact when any object vertex is. Right-hand labels are 22 and 41-55 (cf. GRAB issue
  #10: "values greater than 40" for the right fingers).
* World: metres, z up: GRAB's viewer puts its camera 1.5 m up the z axis looking
  horizontally (``tools/meshviewer.py``), HOIDiNi checks the table top's normal along +z
  and animates the raw parameters in Blender (z up) unchanged.
* Frame rate: ``framerate`` (120 for every sequence of HOIDiNi's index); read per file.

.. warning::
   GRAB's ``.npz`` entries are pickled dicts. hoibench unpickles them with an unpickler
   that rebuilds only numpy arrays, numpy scalars and dtypes (every other global is
   refused, naming the file), but a pickle is still code-bearing data: only point hoibench
   at the GRAB files you downloaded yourself. Everything read is then checked like
   untrusted input (shapes, finite values, frame counts, mesh paths inside ``ROOT``).

Conversion (per sequence):

1. Time: source times ``k / framerate``; every track is resampled by time to ``fps``
   (:func:`hoibench.datasets.behave.resample_times`): rotations (body, hand, object
   orientations, every joint's axis-angle) by quaternion slerp, translations and
   expression linearly. Hand PCA coefficients are turned into per-joint axis-angle with the
   model's own components first, then slerped. Contacts take the nearest source frame.
2. Human: SMPL-X of the file's gender with ``v_template`` = the subject mesh, hands as PCA
   with ``flat_hand_mean=False`` (GRAB's call), jaw, eyes and expression passed: the mesh
   is GRAB's. The clip keeps the 22 body joints; ``trans`` is the pelvis, ``rot`` the
   global orientation.
3. Hands: MANO with ``v_template`` = the subject's hand mesh, ``flat_hand_mean=True``:
   MANO's 16 joints plus the finger tips at smplx's MANO tip vertices 744, 320, 443, 554,
   671 (thumb, index, middle, ring, pinky). ``trans`` is the wrist joint, ``rot`` the
   wrist orientation, ``owner`` the human. The largest difference between ``fullpose`` and
   the PCA pose is recorded (``hand_fullpose_max_dev_rad``).
4. Objects: the template is the ``object_mesh`` file as read (``process=False``) centred
   on its vertex mean ``m``; ``rot = R(global_orient)^T`` and ``trans = transl + rot m``,
   so ``rot v + trans`` is GRAB's posed vertex exactly. The table likewise (body and
   template ``table``), only with ``with_table``.
5. Frame: z-up -> y-up by :data:`hoibench.datasets.omomo.ZUP_TO_YUP` (-90 degrees about x,
   a proper rotation), then y is shifted so the lowest vertex of the SMPL-X mesh over
   *all source frames* sits at y = 0 (so every fps gives the same floor); recorded as
   ``floor_shift_m``.
6. Contacts, from ``contact['object']``: (right_hand, object) when any object vertex has a
   right-hand label, (left_hand, object) likewise, (human, object) when any has a label
   > 0 (any body part). ``contact['body']`` is checked (shape, finite) but not read.
   Positive labels outside ``contact_ids`` are counted in the provenance.
7. Split: no official one. Default: the unseen-subject split of IMoS
   (``dataset_preprocess.py``: test s10, val s1, train s2-s9), the split SyncDiff cites
   (paper 004, section 4.1; appendix D.1: 992 / 198 / 144 sequences). HOIDiNi's index
   counts 992 / 198 / 145 for those subjects. ``split_file`` overrides it (e.g. GRAB's own
   object split from ``grab_preprocessing.py``: test mug, wineglass, camera, binoculars,
   fryingpan, toothpaste; val apple, toothbrush, elephant, hand).

Refused (the sequence fails, naming file, sequence and key): an unreadable file or a
pickle naming anything but numpy arrays; a missing key; a parameter of the wrong shape,
non-real or non-finite; per-frame fields with different frame counts or ``n_frames``
disagreeing; ``sbj_id`` not the folder's subject; a gender other than male / female /
neutral; ``n_comps`` outside 1..45; a mesh path that is absolute-outside-``tools``, leaves
``ROOT`` or is not one of GRAB's conventional files for the sequence (the store's
checksum covers those); a subject mesh without SMPL-X's 10475 / MANO's 778 vertices; an
object mesh failing :func:`hoibench.core.plausibility.check_template`; contact arrays of the
wrong shape. A missing subject folder ``grab/s<k>`` is one failing source (the manifest's
``incomplete``).
"""
from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path, PurePosixPath

import numpy as np

from ..core import geometry as geo
from ..core import plausibility as pl
from ..core.ids import InvalidIdError, check_id
from ..bodies.multibody import Body, MultiBodyClip
from .behave import SequenceError, _lerp, _slerp_resample, load_object_template, load_split_file, read_mesh, \
    resample_rigid, resample_times
from .grab_npz import read_sequence_npz
from .omomo import ZUP_TO_YUP

__all__ = ["SOURCE_FPS", "SUBJECTS", "IMOS_SPLIT", "LEFT_HAND_LABELS", "RIGHT_HAND_LABELS", "SequenceError",
           "read_sequence_npz", "official_split", "clip_id", "conventional_assets", "load_sequence",
           "prepare_jobs"]

SOURCE_FPS = 120.0
SUBJECTS = tuple(f"s{k}" for k in range(1, 11))
#: IMoS's unseen-subject split (anindita127/IMoS ``src/data_loader/dataset_preprocess.py``).
IMOS_SPLIT = {**{f"s{k}": "train" for k in range(2, 10)}, "s1": "val", "s10": "test"}
SMPLX_NUM_VERTICES = 10475
MANO_NUM_VERTICES = 778
#: ``tools/utils.py`` ``contact_ids``: L_Hand 21, left fingers 26-40; R_Hand 22, right fingers 41-55.
LEFT_HAND_LABELS = (21,) + tuple(range(26, 41))
RIGHT_HAND_LABELS = (22,) + tuple(range(41, 56))
MAX_CONTACT_LABEL = 55
#: MANO tip vertices (smplx ``vertex_ids['mano']``): thumb, index, middle, ring, pinky.
MANO_TIPS = (744, 320, 443, 554, 671)
#: outputs of GRAB's save_grab_vertices.py written beside the sequences
VERTS_SUFFIXES = ("_verts_body", "_verts_lhand", "_verts_rhand", "_verts_object")
LOADER_VERSION = "grab-1.0"
_SUBJECT = re.compile(r"^s\d+$")
_BODY_WIDTH = {"transl": 3, "global_orient": 3, "body_pose": 63}
_BODY_OPTIONAL = {"jaw_pose": 3, "leye_pose": 3, "reye_pose": 3}
_HAND_WIDTH = {"transl": 3, "global_orient": 3}
_CHUNK = 256


# --------------------------------------------------------------------------- ids, splits, paths
def clip_id(subject: str, stem: str) -> str:
    """The clip id of ``grab/<subject>/<stem>.npz``: ``<subject>_<stem>`` (names repeat across
    subjects), e.g. ``s1_airplane_fly_1``."""
    return f"{subject}_{stem}"


def official_split(subject: str) -> str:
    """IMoS's unseen-subject split: s10 test, s1 val, s2-s9 train (KeyError otherwise)."""
    return IMOS_SPLIT[subject]


def _roots(root: Path) -> tuple[Path, Path]:
    """(the folder holding s1..s10, the GRAB folder holding tools/)."""
    if (root / "grab").is_dir():
        return root / "grab", root
    if root.name == "grab" and any(_SUBJECT.match(p.name) for p in root.iterdir() if p.is_dir()):
        return root, root.parent
    raise FileNotFoundError(f"--root: no 'grab' folder in {root} (expected GRAB's extracted release: "
                            "GRAB/grab/s1..s10 and GRAB/tools)")


def conventional_assets(asset_root: str | Path, subject: str, obj: str, with_table: bool = False) -> list[Path]:
    """The mesh files a GRAB sequence of ``subject`` and object ``obj`` refers to, at GRAB's
    conventional paths: the subject's body and hand templates in both gender folders (one
    of each pair exists), the object's contact mesh and, with ``with_table``, the table's.
    They are the sequence's checksum inputs and the only meshes its unit may read."""
    sm = Path(asset_root) / "tools" / "subject_meshes"
    out = [sm / g / f"{subject}{suffix}.ply" for suffix in ("", "_lhand", "_rhand") for g in ("male", "female")]
    cm = Path(asset_root) / "tools" / "object_meshes" / "contact_meshes"
    out.append(cm / f"{obj}.ply")
    if with_table:
        out.append(cm / "table.ply")
    return out


def _resolve_asset(asset_root: Path, stored, key: str, where: str, allowed: tuple[str, ...] | None) -> Path:
    """The file a stored mesh path (``body/vtemp``...) names under ``asset_root``: from its
    ``tools`` component on when it has one, else as given; never absolute, never ``..``;
    one of ``allowed`` when given."""
    text = str(stored).replace("\\", "/")
    parts = PurePosixPath(text).parts
    if "tools" in parts:
        parts = parts[parts.index("tools"):]
    elif PurePosixPath(text).is_absolute():
        raise SequenceError(f"{where}: {key}: absolute path {text!r} outside a 'tools' folder: refused")
    if not parts or any(p in ("..", "") for p in parts) or ":" in parts[0]:
        raise SequenceError(f"{where}: {key}: path {text!r} leaves the GRAB folder: refused")
    path = asset_root.joinpath(*parts)
    if allowed is not None and str(path) not in allowed:
        own = ", ".join(Path(a).relative_to(asset_root).as_posix() for a in allowed if Path(a).exists())
        raise SequenceError(f"{where}: {key}: {text!r} is not one of GRAB's files for this sequence ({own}): "
                            "not read (the store's checksum covers those only)")
    if not path.is_file():
        raise SequenceError(f"{where}: {key}: missing file {path}")
    return path


# --------------------------------------------------------------------------- field checks
def _entry(seq: dict, key: str, where: str):
    if key not in seq:
        raise SequenceError(f"{where}: missing key {key!r}")
    return seq[key]


def _dict(seq: dict, key: str, where: str) -> dict:
    v = _entry(seq, key, where)
    if not isinstance(v, dict):
        raise SequenceError(f"{where}: {key}: expected a dict, got {type(v).__name__}")
    return v


def _text(seq: dict, key: str, where: str) -> str:
    v = _entry(seq, key, where)
    if isinstance(v, bytes):
        v = v.decode("utf-8", "replace")
    if isinstance(v, np.ndarray) and v.size == 1:
        v = v.reshape(()).item()
    if not isinstance(v, str):
        raise SequenceError(f"{where}: {key}: expected a string, got {type(v).__name__}")
    return v


def _number(seq: dict, key: str, where: str) -> float:
    v = _entry(seq, key, where)
    try:
        a = pl.real_array(v, key, where).reshape(-1)
    except ValueError as exc:
        raise SequenceError(str(exc)) from None
    if a.size != 1:
        raise SequenceError(f"{where}: {key}: expected one number, got shape {np.shape(v)}")
    return float(a[0])


def _integer(seq: dict, key: str, where: str, lo: int, hi: int) -> int:
    x = _number(seq, key, where)
    if x != int(x) or not lo <= x <= hi:
        raise SequenceError(f"{where}: {key}: expected an integer in {lo}..{hi}, got {x:g}")
    return int(x)


def _array(d: dict, key: str, path: str, where: str, width: int | None = None) -> np.ndarray:
    """``d[key]`` as float64 (T, width) (any width when None): named ``path`` in errors."""
    if key not in d:
        raise SequenceError(f"{where}: missing key {path!r}")
    try:
        a = pl.real_array(d[key], path, where)
    except ValueError as exc:
        raise SequenceError(str(exc)) from None
    if a.ndim != 2 or (width is not None and a.shape[1] != width) or a.shape[1] == 0:
        want = f"(T, {width})" if width is not None else "(T, D)"
        raise SequenceError(f"{where}: {path}: expected shape {want}, got {a.shape}")
    return a


def _params(part: dict, name: str, where: str) -> dict:
    p = part.get("params")
    if "params" not in part:
        raise SequenceError(f"{where}: missing key {name + '/params'!r}")
    if not isinstance(p, dict):
        raise SequenceError(f"{where}: {name}/params: expected a dict, got {type(p).__name__}")
    return p


def _read_params(seq: dict, where: str, n_comps: int, with_table: bool) -> tuple[dict, dict]:
    """All per-frame arrays read by the loader, keyed by their path in the file
    (``body/params/transl``...), and the mesh paths stored in the file."""
    arrays: dict[str, np.ndarray] = {}
    meshes: dict[str, object] = {}
    body = _dict(seq, "body", where)
    bp = _params(body, "body", where)
    for k, w in _BODY_WIDTH.items():
        arrays[f"body/params/{k}"] = _array(bp, k, f"body/params/{k}", where, w)
    for k, w in _BODY_OPTIONAL.items():
        if k in bp:
            arrays[f"body/params/{k}"] = _array(bp, k, f"body/params/{k}", where, w)
    for k in ("left_hand_pose", "right_hand_pose"):
        if k in bp:
            arrays[f"body/params/{k}"] = _array(bp, k, f"body/params/{k}", where, n_comps)
    if "expression" in bp:
        e = _array(bp, "expression", "body/params/expression", where)
        if e.shape[1] > 100:
            raise SequenceError(f"{where}: body/params/expression: {e.shape[1]} coefficients, SMPL-X has at most 100")
        arrays["body/params/expression"] = e
    if "vtemp" not in body:
        raise SequenceError(f"{where}: missing key 'body/vtemp'")
    meshes["body/vtemp"] = body["vtemp"]
    for side in ("lhand", "rhand"):
        hand = _dict(seq, side, where)
        hp = _params(hand, side, where)
        for k, w in _HAND_WIDTH.items():
            arrays[f"{side}/params/{k}"] = _array(hp, k, f"{side}/params/{k}", where, w)
        arrays[f"{side}/params/hand_pose"] = _array(hp, "hand_pose", f"{side}/params/hand_pose", where, n_comps)
        if "fullpose" in hp:
            arrays[f"{side}/params/fullpose"] = _array(hp, "fullpose", f"{side}/params/fullpose", where, 45)
        if "vtemp" not in hand:
            raise SequenceError(f"{where}: missing key {side + '/vtemp'!r}")
        meshes[f"{side}/vtemp"] = hand["vtemp"]
    for part, mesh_key in (("object", "object_mesh"),) + ((("table", "table_mesh"),) if with_table else ()):
        d = _dict(seq, part, where)
        op = _params(d, part, where)
        for k in ("global_orient", "transl"):
            arrays[f"{part}/params/{k}"] = _array(op, k, f"{part}/params/{k}", where, 3)
        if mesh_key not in d:
            raise SequenceError(f"{where}: missing key {part + '/' + mesh_key!r}")
        meshes[f"{part}/{mesh_key}"] = d[mesh_key]
    contact = _dict(seq, "contact", where)
    for k in ("object", "body"):
        arrays[f"contact/{k}"] = _labels(contact, k, f"contact/{k}", where)
    return arrays, meshes


def _labels(d: dict, key: str, path: str, where: str) -> np.ndarray:
    """A (T, V) contact-label array in its own dtype (a GRAB object can have 48k vertices
    over thousands of frames: never copied to float64): real, finite (checked by chunks)."""
    if key not in d:
        raise SequenceError(f"{where}: missing key {path!r}")
    a = np.asarray(d[key])
    if a.dtype.kind not in "biuf":
        raise SequenceError(f"{where}: {path}: expected real numbers, got dtype {a.dtype}")
    if a.ndim != 2 or a.shape[1] == 0:
        raise SequenceError(f"{where}: {path}: expected shape (T, V), got {a.shape}")
    if a.dtype.kind == "f":
        for s in range(0, len(a), _CHUNK):
            bad = np.argwhere(~np.isfinite(a[s:s + _CHUNK]))
            if len(bad):
                t, v = int(bad[0, 0]) + s, int(bad[0, 1])
                raise SequenceError(f"{where}: {path}: non-finite value {a[t, v]} at frame {t}, vertex {v}")
    return a


# --------------------------------------------------------------------------- models
@lru_cache(maxsize=16)
def _mesh_vertices(path: str) -> np.ndarray:
    v, _ = read_mesh(path, Path(path).name)
    v = np.asarray(v, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3 or not np.isfinite(v).all():
        raise SequenceError(f"{Path(path).name}: expected finite (V, 3) vertices")
    return v


def _template_vertices(path: Path, count: int, key: str, where: str) -> np.ndarray:
    try:
        v = _mesh_vertices(str(path))
    except SequenceError as exc:
        raise SequenceError(f"{where}: {key}: {exc}") from None
    if len(v) != count:
        raise SequenceError(f"{where}: {key}: {path.name} has {len(v)} vertices, the model has {count}")
    return v


@lru_cache(maxsize=2)      # a real SMPL-X model is ~100 MB; jobs come subject by subject
def _smplx(model_dir: str, gender: str, vtemp: str, n_comps: int, n_expr: int):
    from ..bodies.smpl import load_body_model
    return load_body_model(model_dir, "smplx", gender, use_pca=False, flat_hand_mean=False, num_pca_comps=n_comps,
                           num_expression_coeffs=n_expr, v_template=_mesh_vertices(vtemp))


@lru_cache(maxsize=4)
def _mano(model_dir: str, side: str, vtemp: str, n_comps: int):
    from ..bodies.proxy_hand import load_mano_model
    return load_mano_model(model_dir, side, use_pca=False, flat_hand_mean=True, num_pca_comps=n_comps,
                           v_template=_mesh_vertices(vtemp))


def _components(model, attr: str, n_comps: int, where: str) -> np.ndarray:
    c = np.asarray(getattr(model, attr), dtype=np.float64)
    if c.ndim != 2 or c.shape != (n_comps, 45):
        raise SequenceError(f"{where}: the model's hand PCA components have shape {c.shape}, expected ({n_comps}, 45)")
    return c


def _mano_joints(model, go: np.ndarray, pose: np.ndarray, transl: np.ndarray) -> np.ndarray:
    """(T, 21, 3) MANO joints plus finger tips (smplx's MANO forward, axis-angle fingers)."""
    import torch
    buf = next(model.buffers())
    nb = int(model.num_betas)

    def tens(x):
        return torch.from_numpy(np.ascontiguousarray(x, dtype=np.float64)).to(device=buf.device, dtype=buf.dtype)

    out = []
    threads = torch.get_num_threads()
    torch.set_num_threads(1)        # float32 reductions depend on the thread count
    try:
        with torch.no_grad():
            for s in range(0, len(go), _CHUNK):
                e = min(len(go), s + _CHUNK)
                r = model(global_orient=tens(go[s:e]), hand_pose=tens(pose[s:e]), transl=tens(transl[s:e]),
                          betas=tens(np.zeros((e - s, nb))))
                v = r.vertices.detach().cpu().numpy().astype(np.float64)
                j = r.joints.detach().cpu().numpy().astype(np.float64)[:, :16]
                out.append(np.concatenate([j, v[:, list(MANO_TIPS)]], 1))
    finally:
        torch.set_num_threads(threads)
    return np.concatenate(out)


def _body_floor(model, pose: np.ndarray, transl: np.ndarray, expr: np.ndarray | None) -> float:
    """Lowest z of the SMPL-X mesh over all frames (chunked: a GRAB sequence has thousands)."""
    from ..bodies.smpl import body_forward
    low = np.inf
    for s in range(0, len(pose), _CHUNK):
        e = min(len(pose), s + _CHUNK)
        _, v = body_forward(model, pose[s:e], None, transl[s:e], expression=None if expr is None else expr[s:e])
        low = min(low, float(v[..., 2].min()))
    return low


# --------------------------------------------------------------------------- one sequence
def _contacts(labels: np.ndarray) -> tuple[dict[str, np.ndarray], int]:
    """Per-frame (right, left, human) contact from object-vertex labels, and the number of
    positive labels that are not ``contact_ids`` values."""
    out = {k: np.zeros(len(labels), bool) for k in ("right", "left", "human")}
    unknown = 0
    for s in range(0, len(labels), _CHUNK):       # by chunks: bounded memory
        x = labels[s:s + _CHUNK]
        pos = x > 0
        out["right"][s:s + _CHUNK] = np.isin(x, RIGHT_HAND_LABELS).any(1)
        out["left"][s:s + _CHUNK] = np.isin(x, LEFT_HAND_LABELS).any(1)
        out["human"][s:s + _CHUNK] = pos.any(1)
        unknown += int((pos & ~np.isin(x, np.arange(1, MAX_CONTACT_LABEL + 1))).sum())
    return out, unknown


def _rigid(R_grab: np.ndarray, t: np.ndarray, mean: np.ndarray, src_t, dst) -> tuple[np.ndarray, np.ndarray]:
    """GRAB's row-vector pose of a mesh (``v @ R + t``) -> column rotation ``R^T`` and the
    translation of the mean-centred template, resampled to ``dst`` (z-up)."""
    Rc = R_grab.swapaxes(-1, -2)
    tc = t + Rc @ mean
    return resample_rigid(src_t, dst, Rc, tc)


def _read_checked(path: Path, subject: str, rel: str, where: str,
                  with_table: bool) -> tuple[str, str, str, float, int, dict, dict, int]:
    """Read one sequence file and check its header and per-frame arrays (one frame count,
    finite tracks). Returns ``(gender, obj, intent, src_fps, n_comps, arrays, meshes, T)``."""
    try:
        seq = read_sequence_npz(path)
    except ValueError as exc:
        raise SequenceError(f"{where}: unreadable GRAB sequence ({exc})") from None

    gender = _text(seq, "gender", where).lower()
    if gender not in pl.GENDERS:
        raise SequenceError(f"{where}: gender: expected male/female/neutral, got {gender!r}")
    sbj = _text(seq, "sbj_id", where)
    if sbj != subject:
        raise SequenceError(f"{where}: sbj_id {sbj!r} but the file is in folder {subject!r}")
    obj = _text(seq, "obj_name", where)
    try:
        check_id(obj, "obj_name", rel)
    except InvalidIdError as exc:
        raise SequenceError(f"{where}: {exc}") from None
    intent = _text(seq, "motion_intent", where)
    src_fps = pl.check_fps(_number(seq, "framerate", where), "framerate", where)
    n_frames = _integer(seq, "n_frames", where, 0, 10 ** 8)
    n_comps = _integer(seq, "n_comps", where, 1, 45)
    arrays, meshes = _read_params(seq, where, n_comps, with_table)
    T = pl.common_frame_count({k: len(a) for k, a in arrays.items()}, where, pl.MIN_FRAMES)
    if n_frames != T:
        raise SequenceError(f"{where}: n_frames is {n_frames} but the per-frame arrays have {T} frames")
    for k in ("body", "lhand", "rhand", "object") + (("table",) if with_table else ()):
        try:
            pl.check_track(arrays[f"{k}/params/transl"], f"{k}/params/transl", where, fps=src_fps)
        except ValueError as exc:
            raise SequenceError(str(exc)) from None
    return gender, obj, intent, src_fps, n_comps, arrays, meshes, T


def _load_assets(asset_root: Path, meshes: dict, assets: tuple[str, ...] | None, obj: str, with_table: bool,
                 arrays: dict, where: str) -> tuple[dict[str, Path], list[tuple[str, str, str]], dict]:
    """Resolve the sequence's mesh files, check the subject templates' vertex counts, load the
    object (and table) templates and check the contact labels against them. Returns
    ``(files, parts, templates)``: ``parts`` = (part, template name, mesh key),
    ``templates[part]`` = (template name, vertices, faces, subtracted mean)."""
    files = {k: _resolve_asset(asset_root, v, k, where, assets) for k, v in meshes.items()}
    vtemp = _template_vertices(files["body/vtemp"], SMPLX_NUM_VERTICES, "body/vtemp", where)
    for side in ("lhand", "rhand"):
        _template_vertices(files[f"{side}/vtemp"], MANO_NUM_VERTICES, f"{side}/vtemp", where)
    parts = [("object", obj, "object/object_mesh")] + ([("table", "table", "table/table_mesh")] if with_table else [])
    templates = {}
    for part, tname, key in parts:
        v, f, mean = load_object_template(str(files[key]), tname, f"{where}: {key}")
        templates[part] = (tname, v, f, mean)
    n_obj = len(templates["object"][1])
    if arrays["contact/object"].shape[1] != n_obj:
        raise SequenceError(f"{where}: contact/object: {arrays['contact/object'].shape[1]} labels per frame, "
                            f"{files['object/object_mesh'].name} has {n_obj} vertices")
    if arrays["contact/body"].shape[1] != len(vtemp):
        raise SequenceError(f"{where}: contact/body: {arrays['contact/body'].shape[1]} labels per frame, "
                            f"SMPL-X has {len(vtemp)} vertices")
    return files, parts, templates


def _human_body(body_models: str | Path, gender: str, files: dict[str, Path], n_comps: int, arrays: dict,
                T: int, src_t: np.ndarray, dst: np.ndarray, where: str) -> tuple[Body, float]:
    """The human at the output times and the floor height (lowest SMPL-X vertex over all
    source frames) that every body and object is lowered by."""
    F = ZUP_TO_YUP
    # human: SMPL-X with the subject template, hands as PCA with the model's components
    zeros3 = np.zeros((T, 3))
    expr = arrays.get("body/params/expression")
    smplx_model = _smplx(str(Path(body_models)), gender, str(files["body/vtemp"]), n_comps,
                         expr.shape[1] if expr is not None else 10)
    hand_aa = {}
    for side, attr in (("left", "np_left_hand_components"), ("right", "np_right_hand_components")):
        pca = arrays.get(f"body/params/{side}_hand_pose")
        comps = _components(smplx_model, attr, n_comps, where)
        hand_aa[side] = np.zeros((T, 45)) if pca is None else pca @ comps
    full = np.concatenate([arrays["body/params/global_orient"], arrays["body/params/body_pose"]]
                          + [arrays.get(f"body/params/{k}", zeros3) for k in _BODY_OPTIONAL]
                          + [hand_aa["left"], hand_aa["right"]], 1)
    floor = _body_floor(smplx_model, full, arrays["body/params/transl"], expr)
    from ..bodies.smpl import body_forward
    pose = _slerp_resample(src_t, dst, full[:, :66].reshape(T, 22, 3)).reshape(len(dst), 66)
    b_trans = _lerp(src_t, dst, arrays["body/params/transl"])
    b_expr = _lerp(src_t, dst, expr) if expr is not None else None
    joints, _ = body_forward(smplx_model, pose, None, b_trans, return_vertices=False, expression=b_expr)
    human_j = joints[:, :22].astype(np.float64) @ F.T
    human_j[..., 1] -= floor
    try:
        pl.check_body_height(human_j, f"{where}: human")
    except ValueError as exc:
        raise SequenceError(str(exc)) from None
    return Body("human", "human", human_j[:, 0].copy(), F @ geo.axis_angle_to_matrix(pose[:, :3]), human_j), floor


def _hand_bodies(body_models: str | Path, files: dict[str, Path], n_comps: int, arrays: dict, T: int,
                 src_t: np.ndarray, dst: np.ndarray, floor: float, asset_root: Path,
                 where: str) -> tuple[list[Body], dict]:
    """The left and the right hand at the output times, and their provenance."""
    F = ZUP_TO_YUP
    # hands: MANO with the subject's hand templates
    bodies, hand_prov = [], {}
    for side, key in (("left", "lhand"), ("right", "rhand")):
        mano = _mano(str(Path(body_models)), side, str(files[f"{key}/vtemp"]), n_comps)
        aa = arrays[f"{key}/params/hand_pose"] @ _components(mano, "np_hand_components", n_comps, where)
        dev = (float(np.abs(arrays[f"{key}/params/fullpose"] - aa).max())
               if f"{key}/params/fullpose" in arrays else None)
        rots = _slerp_resample(src_t, dst, np.concatenate([arrays[f"{key}/params/global_orient"], aa], 1)
                               .reshape(T, 16, 3))
        go, fingers = rots[:, 0], rots[:, 1:].reshape(len(dst), 45)
        hj = _mano_joints(mano, go, fingers, _lerp(src_t, dst, arrays[f"{key}/params/transl"])) @ F.T
        hj[..., 1] -= floor
        bodies.append(Body(f"{side}_hand", "hand", hj[:, 0].copy(), F @ geo.axis_angle_to_matrix(go), hj,
                           side=side, owner="human"))
        hand_prov[side] = {"vtemp": files[f"{key}/vtemp"].relative_to(asset_root).as_posix(),
                           "hand_fullpose_max_dev_rad": dev}
    return bodies, hand_prov


def _object_bodies(templates: dict, parts: list[tuple[str, str, str]], arrays: dict, files: dict[str, Path],
                   src_t: np.ndarray, dst: np.ndarray, floor: float,
                   asset_root: Path) -> tuple[list[Body], dict, dict]:
    """The object (and table) at the output times, their templates and their provenance."""
    F = ZUP_TO_YUP
    # objects: GRAB's row-vector pose, template centred on its vertex mean
    bodies, clip_templates, obj_prov = [], {}, {}
    for part, key in zip(templates, [p[2] for p in parts]):
        tname, v, f, mean = templates[part]
        R_grab = geo.axis_angle_to_matrix(arrays[f"{part}/params/global_orient"])
        rot, trans = _rigid(R_grab, arrays[f"{part}/params/transl"], mean, src_t, dst)
        trans = trans @ F.T
        trans[:, 1] -= floor
        bodies.append(Body(tname, "object", trans, F @ rot, template=tname))
        clip_templates[tname] = (v, f)
        obj_prov[part] = {"template": tname, "mesh": files[key].relative_to(asset_root).as_posix(),
                          "template_mean_subtracted": mean.tolist(), "template_vertices": int(len(v))}
    return bodies, clip_templates, obj_prov


def load_sequence(path: str | Path, body_models: str | Path, fps: float = SOURCE_FPS, root: str | Path | None = None,
                  with_table: bool = False, name: str | None = None,
                  assets: tuple[str, ...] | None = None) -> MultiBodyClip:
    """Convert one GRAB sequence file into a :class:`MultiBodyClip` at ``fps`` (see the
    module docstring).

    ``root``: the GRAB folder holding ``tools/`` (default: two levels above the subject
    folder). ``name``: the clip id (default ``<subject>_<stem>``). ``assets``: when given,
    the only mesh files the sequence may read (:func:`conventional_assets`).
    ``body_models`` holds ``smplx/`` and ``mano/`` (the user's files or hoibench's
    proxies). Raises :class:`SequenceError` naming the sequence, the file and the key.
    """
    path = Path(path)
    subject, stem = path.parent.name, path.stem
    asset_root = Path(root) if root is not None else path.parent.parent.parent
    try:
        name = check_id(name or clip_id(subject, stem), "clip id", path)
    except InvalidIdError as exc:
        raise SequenceError(str(exc)) from None
    rel = f"grab/{subject}/{path.name}"
    where = f"{name}: {rel}"
    fps = pl.check_fps(fps, "fps", name)
    gender, obj, intent, src_fps, n_comps, arrays, meshes, T = _read_checked(path, subject, rel, where, with_table)
    files, parts, templates = _load_assets(asset_root, meshes, assets, obj, with_table, arrays, where)

    src_t = np.arange(T) / src_fps
    dst = resample_times(src_t, fps)
    human, floor = _human_body(body_models, gender, files, n_comps, arrays, T, src_t, dst, where)
    hands, hand_prov = _hand_bodies(body_models, files, n_comps, arrays, T, src_t, dst, floor, asset_root, where)
    objects, clip_templates, obj_prov = _object_bodies(templates, parts, arrays, files, src_t, dst, floor,
                                                       asset_root)
    bodies = [human] + hands + objects

    # contacts from the object-vertex labels, nearest source frame
    flags, unknown = _contacts(arrays["contact/object"])
    nearest = np.clip(np.searchsorted(src_t, dst - 0.5 / src_fps), 0, T - 1)
    contacts = {("right_hand", obj): flags["right"][nearest], ("left_hand", obj): flags["left"][nearest],
                ("human", obj): flags["human"][nearest]}

    prov = {
        "source": "grab", "source_file": rel, "sequence": stem, "subject": subject, "gender": gender,
        "object": obj, "motion_intent": intent, "n_comps": n_comps,
        "raw_source": f"{rel} ({', '.join(p.relative_to(asset_root).as_posix() for p in files.values())})",
        "source_frame": "GRAB mocap world, z-up, metres",
        "transform": "p_yup = [[1,0,0],[0,0,1],[0,-1,0]] p_zup (Rx(-90 deg)); y -= floor",
        "floor_shift_m": floor, "floor": "lowest SMPL-X vertex over all source frames",
        "source_fps": src_fps, "resampled_to_fps": float(fps), "source_frames": T,
        "body_model": f"smplx {gender}, v_template {files['body/vtemp'].relative_to(asset_root).as_posix()}, "
                      f"hand PCA {n_comps} (flat_hand_mean=False)",
        "hand_model": f"mano, v_template per hand, hand PCA {n_comps} (flat_hand_mean=True)",
        "hands": hand_prov, "objects": obj_prov,
        "object_convention": "GRAB ObjectModel v @ R(global_orient) + transl -> rot = R^T, trans = transl + rot mean",
        "contacts": "contact['object'] labels (tools/utils.py contact_ids): right hand 22, 41-55; left hand 21, "
                    "26-40; human any > 0; nearest source frame",
        "contact_labels_outside_contact_ids": unknown,
        "loader": LOADER_VERSION,
    }
    return MultiBodyClip(name=name, dataset="grab", subject=subject, fps=float(fps), bodies=bodies,
                         templates=clip_templates, contacts=contacts, action=intent, provenance=prov)


# --------------------------------------------------------------------------- jobs
def _is_sequence_file(p: Path) -> bool:
    return p.suffix == ".npz" and not any(p.stem.endswith(s) for s in VERTS_SUFFIXES)


def prepare_jobs(root: str | Path, body_models: str | Path, out: str | Path, config,
                 split_file: str | Path | None = None, with_table: bool = False) -> list[tuple]:
    """One :func:`hoibench.datasets.store.run_unit` job per GRAB sequence file (``grab/s<k>/*.npz``).

    Clip id ``<subject>_<stem>`` (must pass :func:`hoibench.core.ids.check_id`; a file whose id
    comes twice, e.g. names differing in case only, fails every copy). The split is IMoS's
    subject split (:data:`IMOS_SPLIT`) unless ``split_file`` (``{"train": [clip id, ...],
    "val": [...], "test": [...]}``) names another; a sequence it does not list, or a
    subject folder IMoS does not name, is an error for that sequence. Each job's checksum
    covers the sequence file, the meshes at GRAB's conventional paths
    (:func:`conventional_assets`), the config and ``with_table``. A missing subject folder
    ``s1``..``s10`` is one failing source job (the manifest's ``incomplete``), except in
    hoibench's synthetic GRAB layout (``hoibench_synthetic.json``), which writes a few.
    """
    from .store import (fail_unit, file_sha256, refuse_duplicates, refused_id_job, source_failure_job, unlisted_split_jobs)
    data_root, asset_root = _roots(Path(root))
    splits = load_split_file(split_file) if split_file else None
    source_jobs = [source_failure_job(f"grab_{s}", f"grab/{s}: missing in {data_root}: the store has no sequences "
                                                   f"of subject {s} (GRAB's release has s1..s10)", out, config.mode)
                   for s in SUBJECTS if not (data_root / s).is_dir()
                   and not (Path(root) / "hoibench_synthetic.json").exists()]   # a synthetic set has some only
    folders = sorted((p for p in data_root.iterdir() if p.is_dir() and _SUBJECT.match(p.name)),
                     key=lambda p: int(p.name[1:]))
    jobs, sources = [], []
    extra = f"{config.sha256()}|with_table={bool(with_table)}|{LOADER_VERSION}"
    for folder in folders:
        subject = folder.name
        for f in sorted(p for p in folder.iterdir() if _is_sequence_file(p)):
            cid = clip_id(subject, f.stem)
            origin = f"grab/{subject}/{f.name}"
            refused = refused_id_job(cid, "clip id", origin, out, config.mode)
            if refused:
                jobs.append(refused)
                sources.append(origin)
                continue
            files = conventional_assets(asset_root, subject, f.stem.split("_")[0], with_table)
            loader, args = load_sequence, (str(f), str(body_models), config.fps, str(asset_root), bool(with_table),
                                           cid, tuple(str(p) for p in files))
            try:
                split = splits[cid] if splits is not None else official_split(subject)
            except KeyError:
                where = f"split file {split_file}" if splits is not None else "IMoS's subject split (s1..s10)"
                split, loader, args = "unknown", fail_unit, (f"{cid}: {origin}: not listed in {where}",)
            sha = file_sha256([f] + files, extra=extra)
            jobs.append((cid, split, sha, str(out), loader, args, config.mode))
            sources.append(origin)
    jobs = refuse_duplicates(jobs, sources)
    if splits is not None:
        jobs += unlisted_split_jobs(jobs, splits, split_file, out, config.mode, f"no sequence file under {data_root}")
    return jobs + source_jobs
