"""``hoibench import FORMAT RESULTS --data DATA --out SUB``: the outputs existing generators
already write, turned into a standard submission.

=========  ==================================================================================
format     what is read
=========  ==================================================================================
mdm        MDM's ``results.npy`` (``np.save`` of a dict -- a pickle): ``motion`` (N, 22, 3, T)
           joint positions, ``text`` (N), ``lengths`` (N), ``num_samples``, ``num_repetitions``;
           entry ``e = r * num_samples + i`` is repetition r of prompt i (repetition-major),
           frames past ``lengths[e]`` are padding; 20 fps, HumanML3D's frame (y up, metres)
hoidiff    HOI-Diff's ``results.npy``: the same plus ``motion_obj`` (N, 1, 6, T) = object
           axis-angle (3) and translation (3) in the motion's frame, and ``obj_name``
joints     a folder of ``<id>.npy`` or ``<id>_<r>.npy`` joint files (T, 22, 3) -- T2M-GPT's and
           MoMask's per-sample dumps; ``--fps`` and ``--up`` say their rate and up axis
chois      a folder of CHOIS ``.npz`` files ``<id>[_<r>].npz`` with ``global_jpos`` (T, 24, 3):
           z up, 30 fps, in CHOIS's window frame of the test clip (put back in the clip's world
           frame); the first 22 joints (SMPL-X body order) are kept
features   a folder of ``<id>.npy`` hml263 (T, 263) or hoi269 (T, 269) rows, or (K, T, D);
           ``--normalized``: de-normalised with the store's train statistics first
params     a folder of ``<id>[_<r>].npz`` per-frame SMPL / SMPL-H / SMPL-X parameters
           (``poses`` or ``root_orient`` + ``pose_body``, ``betas``, ``trans``, optional object
           pose), posed with ``--body-models`` (:mod:`hoibench.scoring.import_params`)
=========  ==================================================================================

Prompts are mapped to test ids by id (file names, ``--match id``), by text (``--match text``:
the generator's prompt equals one of the clip's captions, case and surrounding spaces
ignored; a text that several clips share goes to the first of them still without samples,
in id order) or by a user mapping file (``--map FILE``: JSON ``{"<entry index or file
stem>": "<test id>"}``). Frames are resampled by time to the store's fps (joints and object
translation linearly, object rotations by quaternion slerp); a z-up source is turned y-up
(``(x, y, z) -> (x, z, -y)``). Every conversion is recorded in ``submission.json``'s
``source.import`` block; test ids without samples and entries that matched no id are
reported (the submission is then incomplete, and ``hoibench validate`` says so).

MDM's and HOI-Diff's files are pickles: loading one can run code. They are read only with
``--trust-pickle``, for files you produced yourself.
"""
from __future__ import annotations

import sys
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from .. import __version__
from ..core.geometry import resample_frames
from ..core.registry import Registry, load_object
from ..datasets.store import Store
from .submission import write_submission


@dataclass(frozen=True)
class ImportRequest:
    """What a reader is given: the results path and the import's options (``ids``: the
    store's test ids; ``budget``: the byte budget every read is charged to)."""

    results: Path
    store: Store
    ids: list
    up: str
    normalized: bool
    trust_pickle: bool
    body_models: Any
    model_type: str
    gender: str
    budget: Any


class ResultReader(Protocol):
    """The contract of an import format's reader: ``reader(request) -> [(key, text, arrays),
    ...]`` (``key`` a file stem or index, ``text`` its prompt when the format stores one,
    ``arrays`` with ``joints`` (K, T, 22, 3) and optionally ``obj_rot``/``obj_rotvec`` and
    ``obj_trans``, at the format's frame rate, y-up)."""

    def __call__(self, request: ImportRequest) -> list[tuple[str, str, dict]]: ...


@dataclass(frozen=True)
class ImportFormat:
    """One ``hoibench import FORMAT``: its reader (a :class:`ResultReader`, ``"module:attr"``),
    how entries match test ids by default (``id`` | ``text``), its frame rate (None: the
    store's unless ``--fps``), the up axis it is always given in (None: ``--up``), whether it
    reads joints (``--up`` applies) and the files it reads (for messages)."""

    name: str
    reader: str
    match: str = "id"
    source_fps: float | None = None
    up: str | None = None
    joints: bool = False
    files: str = ".npy"

    def up_axis(self, requested: str) -> str:
        return self.up or (requested if self.joints else "y")


IMPORT_FORMATS: Registry[ImportFormat] = Registry("import format")
_SHIPPED = (ImportFormat("mdm", __name__ + ":_read_mdm", match="text", source_fps=20.0),
            ImportFormat("hoidiff", __name__ + ":_read_hoidiff", match="text", source_fps=20.0),
            ImportFormat("joints", __name__ + ":_read_joints", joints=True),
            ImportFormat("chois", __name__ + ":_read_chois", source_fps=30.0, up="z", files=".npz"),
            ImportFormat("features", __name__ + ":_read_features"),
            ImportFormat("params", "hoibench.scoring.import_params:read_params_request", joints=True, files=".npz"))
for _f in _SHIPPED:
    IMPORT_FORMATS.add(_f.name, _f)
#: the import formats, in registration order (the CLI's choices and help)
FORMATS = tuple(f.name for f in _SHIPPED)


from .import_common import ImportProblem, _group_files, pickle_refusal, pickled_members  # noqa: E402,F401


class ReadBudget:
    """Bytes the files of one import may read: each file at most the largest per-id budget of a
    submission for the store's test split, all files together at most the whole-submission
    budget (:func:`hoibench.scoring.submission.limits_for`: K cap x longest accepted sample x
    every known array at float64). A deflate bomb or a huge file is refused before it is
    inflated or read."""

    def __init__(self, per_file: int, total: int):
        self.per_file, self.left = int(per_file), int(total)

    @classmethod
    def for_store(cls, store: Store) -> "ReadBudget":
        from .validate import submission_context
        from .submission import FILE_OVERHEAD_BYTES, limits_for
        rows, fps, cap, _ = submission_context(store, None)
        limits = limits_for(rows, fps, cap)
        return cls(limits.largest_file_bytes + FILE_OVERHEAD_BYTES, limits.total_bytes + FILE_OVERHEAD_BYTES)

    def take(self, path: Path) -> int:
        """The budget for ``path`` (refused when the import as a whole is over budget)."""
        try:
            size = Path(path).stat().st_size
        except OSError as exc:
            raise ImportProblem(f"{path}: cannot read ({exc.strerror or exc})") from None
        if size > self.left:
            raise ImportProblem(f"{path}: the files read so far and this one exceed the import's budget of a "
                                f"whole submission for this store: not read")
        self.left -= size
        return min(self.per_file, max(self.left + size, 0))

    def npy(self, path: Path, what: str) -> np.ndarray:
        from ..core.io import load_npy_file
        try:
            return load_npy_file(path, self.take(path), what)
        except ImportProblem:
            raise
        except ValueError as exc:
            raise self._refusal(path, None, exc) from None

    def npz(self, path: Path, what: str, keys=None) -> dict:
        from ..core.io import load_raw_npz
        try:
            return load_raw_npz(path, self.take(path), what, keys=keys)
        except ValueError as exc:
            raise self._refusal(path, keys, exc) from None

    @staticmethod
    def _refusal(path: Path, keys, exc: ValueError) -> ImportProblem:
        """numpy's pickle refusal turned into one naming the file and member; else ``exc``'s text."""
        if "allow_pickle" in str(exc):
            pickled = pickled_members(path, keys)
            if pickled:
                return pickle_refusal(path, pickled[0])
        return ImportProblem(str(exc))


# ------------------------------------------------------------------------------ conversions
def z_up_to_y_up(x: np.ndarray) -> np.ndarray:
    """(..., 3) z-up points to y-up: ``(x, y, z) -> (x, z, -y)`` (a rotation by -90 deg about x)."""
    return np.stack([x[..., 0], x[..., 2], -x[..., 1]], -1)


#: (T, ...) arrays resampled linearly in time (:func:`hoibench.core.geometry.resample_frames`)
resample = resample_frames


def resample_rotvec(r: np.ndarray, src_fps: float, dst_fps: float) -> np.ndarray:
    """(T, 3) axis-angles resampled by quaternion slerp."""
    if abs(src_fps - dst_fps) < 1e-9:
        return r
    from ..core.geometry import axis_angle_to_quaternion, quaternion_to_axis_angle
    q = axis_angle_to_quaternion(np.asarray(r, np.float64))
    T = len(q)
    n = int(np.floor((T - 1) * dst_fps / src_fps + 1e-9)) + 1
    t = np.arange(n) * src_fps / dst_fps
    i0 = np.clip(np.floor(t).astype(int), 0, T - 1)
    i1 = np.clip(i0 + 1, 0, T - 1)
    w = (t - i0)[:, None]
    a, b = q[i0], q[i1]
    b = np.where((a * b).sum(-1, keepdims=True) < 0, -b, b)
    dot = np.clip((a * b).sum(-1, keepdims=True), -1.0, 1.0)
    theta = np.arccos(dot)
    s = np.sin(theta)
    small = s < 1e-8
    wa = np.where(small, 1 - w, np.sin((1 - w) * theta) / np.where(small, 1, s))
    wb = np.where(small, w, np.sin(w * theta) / np.where(small, 1, s))
    out = wa * a + wb * b
    return quaternion_to_axis_angle(out / np.linalg.norm(out, axis=-1, keepdims=True))


# ------------------------------------------------------------------------------ matching
def _norm(text: str) -> str:
    return " ".join(str(text).lower().split())


class Matcher:
    """Maps an entry (index, stem or text) to a test id, recording what did not match."""

    def __init__(self, store: Store, how: str, mapping: dict | None):
        from ..evaluator.text import read_captions
        self.ids = store.clip_ids("test")
        self.how, self.mapping = how, mapping or {}
        self.by_text: dict[str, list[str]] = defaultdict(list)
        if how == "text":
            for cid in self.ids:
                for c in read_captions(store.root, cid) or []:
                    if cid not in self.by_text[_norm(c.text)]:
                        self.by_text[_norm(c.text)].append(cid)
        self.taken: set[str] = set()
        self.unmatched: list[str] = []
        self.ambiguous: list[str] = []

    def __call__(self, key: str, text: str | None = None) -> str | None:
        if self.how == "map":
            cid = self.mapping.get(str(key))
        elif self.how == "id":
            cid = key if key in self.ids else None
        else:
            cands = self.by_text.get(_norm(text or ""), [])
            free = [c for c in cands if c not in self.taken]
            if len(cands) > 1:
                self.ambiguous.append(str(text))
            cid = (free or cands or [None])[0]
        if cid is None or cid not in self.ids:
            self.unmatched.append(str(key if self.how != "text" else text))
            return None
        self.taken.add(cid)
        return cid


# ------------------------------------------------------------------------------ readers
def read_mapping(path: str | Path) -> dict:
    """A ``--map`` file: a JSON object {entry: test id} (strings), read through the guarded reader."""
    from ..core.io import MAX_JSON_BYTES, read_json_file
    try:
        table = read_json_file(path, MAX_JSON_BYTES, "mapping file")
    except ValueError as exc:
        raise ImportProblem(f"{exc} (expected a JSON mapping file)") from None
    if not isinstance(table, dict):
        raise ImportProblem(f"{path}: expected a JSON object {{entry: test id}}")
    bad = [k for k, v in table.items() if not isinstance(v, str)]
    if bad:
        raise ImportProblem(f"{path}: {bad[0]!r:.60}: expected a test id (a string), got {table[bad[0]]!r:.40}")
    return table


def _load_pickled_results(path: Path, trust_pickle: bool, fmt: str, budget: ReadBudget | None = None) -> dict:
    if not trust_pickle:
        raise ImportProblem(f"{path}: {fmt}'s results.npy is a pickle (np.save of a dict): loading it can run code; "
                            f"pass --trust-pickle if you produced this file yourself")
    import io
    from ..core.io import read_regular_file
    try:
        raw = read_regular_file(path, budget.left if budget is not None else None, f"{fmt} results.npy")
    except ValueError as exc:
        raise ImportProblem(str(exc)) from None
    try:
        d = np.load(io.BytesIO(raw), allow_pickle=True)  # read-ok: --trust-pickle, bytes read through the guard
        d = d.item() if isinstance(d, np.ndarray) and d.dtype == object and d.shape == () else d
    except Exception as exc:                   # numpy raises many types for a bad file
        raise ImportProblem(f"{path}: not a readable results.npy ({type(exc).__name__})") from None
    if not isinstance(d, dict):
        raise ImportProblem(f"{path}: expected a dict saved with np.save, got {type(d).__name__}")
    for key in ("motion", "text", "lengths", "num_samples", "num_repetitions"):
        if key not in d:
            raise ImportProblem(f"{path}: field {key} missing (MDM's results.npy has motion, text, lengths, "
                                f"num_samples, num_repetitions)")
    return d


def _real(path: Path, key: str, value) -> np.ndarray:
    """``value`` as a float64 array when it holds real numbers (complex, object or text refused)."""
    a = np.asarray(value)
    if a.dtype.kind not in "fiu":
        raise ImportProblem(f"{path}: field {key}: expected real numbers, got dtype {a.dtype}")
    return a.astype(np.float64)


def _count(path: Path, key: str, value) -> int:
    a = np.asarray(value)
    if a.ndim != 0 or a.dtype.kind not in "iuf" or not np.isfinite(a) or a != np.round(a) or a < 1:
        raise ImportProblem(f"{path}: field {key}: expected a positive whole number, got {value!r:.40}")
    return int(a)


def read_mdm(path: Path, trust_pickle: bool, with_object: bool,
             budget: ReadBudget | None = None) -> list[tuple[str, str, dict]]:
    """(key, text, arrays) per prompt: K = num_repetitions samples (repetition-major entries).
    Each ``lengths`` entry must be a whole number in 1..T (the motion's frames)."""
    d = _load_pickled_results(path, trust_pickle, "HOI-Diff" if with_object else "MDM", budget)
    motion = _real(path, "motion", d["motion"])
    n, reps = _count(path, "num_samples", d["num_samples"]), _count(path, "num_repetitions", d["num_repetitions"])
    if motion.ndim != 4 or motion.shape[1:3] != (22, 3):
        raise ImportProblem(f"{path}: field motion: expected (N, 22, 3, T), got {motion.shape}")
    lengths_arr = _real(path, "lengths", d["lengths"]).ravel()
    bad = np.flatnonzero((lengths_arr < 1) | (lengths_arr > motion.shape[-1]) | (lengths_arr != np.round(lengths_arr)))
    if len(bad):
        raise ImportProblem(f"{path}: field lengths: entry {int(bad[0])} is {lengths_arr[bad[0]]:g}, expected a whole "
                            f"number of frames in 1..{motion.shape[-1]} (the motion's length)")
    if motion.shape[0] != n * reps or len(d["text"]) != n * reps or len(d["lengths"]) != n * reps:
        raise ImportProblem(f"{path}: fields motion/text/lengths: expected num_samples x num_repetitions = "
                            f"{n * reps} entries, got {motion.shape[0]}, {len(d['text'])}, {len(d['lengths'])}")
    obj = None
    if with_object:
        if "motion_obj" not in d:
            raise ImportProblem(f"{path}: field motion_obj missing (HOI-Diff's (N, 1, 6, T) object motion)")
        obj = _real(path, "motion_obj", d["motion_obj"])
        if obj.shape[0] != n * reps or obj.shape[-2] != 6:
            raise ImportProblem(f"{path}: field motion_obj: expected (N, 1, 6, T), got {obj.shape}")
        obj = obj.reshape(obj.shape[0], 6, obj.shape[-1])
    out = []
    for i in range(n):
        entries = [r * n + i for r in range(reps)]
        lengths = {int(d["lengths"][e]) for e in entries}
        T = min(lengths)
        joints = np.stack([motion[e].transpose(2, 0, 1)[:T] for e in entries])
        arrays = {"joints": joints}
        if obj is not None:
            o = np.stack([obj[e].T[:T] for e in entries])
            arrays.update(obj_rotvec=o[..., :3], obj_trans=o[..., 3:])
        out.append((str(i), str(d["text"][entries[0]]), arrays))
    return out


def read_joint_files(folder: Path, ids: list[str], up: str, chois: bool, budget: ReadBudget) -> list[tuple[str, str, dict]]:
    """(key, "", {"joints"}) per group of ``<id>[_<r>]`` files, each read within ``budget``."""
    out = []
    for key, files in _group_files(folder, ".npz" if chois else ".npy", ids).items():
        samples = []
        for p in files:
            try:
                if chois:
                    z = budget.npz(p, "CHOIS sample file", keys=("global_jpos",))
                    if "global_jpos" not in z:
                        raise ImportProblem(f"{p}: field global_jpos missing (CHOIS's (T, 24, 3) joints)")
                    j = np.asarray(z["global_jpos"])[:, :22]
                else:
                    j = budget.npy(p, "joint file")
            except ImportProblem:
                raise
            except Exception as exc:
                raise ImportProblem(f"{p}: not a readable array ({type(exc).__name__})") from None
            if j.ndim != 3 or j.shape[1:] != (22, 3):
                raise ImportProblem(f"{p}: joints: expected (T, 22, 3), got {j.shape}")
            samples.append(z_up_to_y_up(j) if up == "z" else j)
        T = min(len(s) for s in samples)
        out.append((key, "", {"joints": np.stack([s[:T] for s in samples])}))
    return out


#: feature rows are refused as the other kind when its log-likelihood per value is this much higher
FEATURE_KIND_MARGIN = {"raw": 0.5, "normalized": 2.0}


def feature_kind_score(rows: np.ndarray, mean: np.ndarray, std: np.ndarray) -> tuple[float, float, float]:
    """How much better the store's statistics explain ``rows`` (N, D) as raw features than as
    normalised ones: (log-likelihood difference per value, kappa_raw, kappa_norm).

    Each reading is a Gaussian with one fitted common scale: raw ``x_c ~ N(mean_c, (kappa std_c)^2)``,
    normalised ``x_c ~ N(0, kappa^2)``, with ``kappa^2`` the mean square of the standardised rows;
    per value ``LL = -log kappa - mean_c log J_c`` (``J = std`` for raw, 1 for normalised), so a
    generator's extra spread (a larger kappa) does not change the verdict; the wrong reading scales
    each column by its own ``std`` and fits badly. Measured on synthetic test clips: raw rows
    +1.7, normalised -3.1, raw rows with 3 std of noise +1.0, normalised with 3 of noise -3.3."""
    z_raw = (rows - mean) / std
    k_raw, k_norm = float(np.sqrt(np.mean(z_raw ** 2))), float(np.sqrt(np.mean(rows ** 2)))
    if k_raw <= 0 or k_norm <= 0:
        return 0.0, k_raw, k_norm
    return float(np.log(k_norm) - np.log(k_raw) - np.mean(np.log(std))), k_raw, k_norm


def check_feature_kind(folder: Path, rows: np.ndarray, stats, normalized: bool) -> None:
    """Refuse rows that are clearly the other kind than ``--normalized`` says (one line)."""
    score, k_raw, k_norm = feature_kind_score(rows, stats.mean.astype(np.float64), stats.std.astype(np.float64))
    plausible = lambda k: 0.1 <= k <= 10.0                      # noqa: E731  (the other reading fits at all)
    if normalized and score > FEATURE_KIND_MARGIN["raw"] and plausible(k_raw):
        raise ImportProblem(f"{folder}: the feature rows look raw, not normalised: they match the store's train "
                            f"mean/std (log-likelihood {score:+.1f} per value in favour of raw); drop --normalized")
    if not normalized and score < -FEATURE_KIND_MARGIN["normalized"] and plausible(k_norm):
        raise ImportProblem(f"{folder}: the feature rows look normalised (per-column mean ~0, std ~1; "
                            f"log-likelihood {-score:+.1f} per value in favour of normalised): pass --normalized")


def read_features(folder: Path, ids: list[str], store: Store, normalized: bool, budget: ReadBudget) -> list[tuple[str, str, dict]]:
    from ..representations import hml263, hoi269
    loaded: list[tuple[str, list[np.ndarray]]] = []
    for key, files in _group_files(folder, ".npy", ids).items():
        samples = []
        for p in files:
            try:
                f = _real(p, "features", budget.npy(p, "feature file"))
            except ImportProblem:
                raise
            except Exception as exc:
                raise ImportProblem(f"{p}: not a readable array ({type(exc).__name__})") from None
            if f.shape[-1] not in (hml263.DIM, hoi269.DIM) or f.ndim not in (2, 3):
                raise ImportProblem(f"{p}: features: expected (T, 263), (T, 269) or (K, T, D), got {f.shape}")
            samples.extend(list(f) if f.ndim == 3 else [f])
        loaded.append((key, samples))
    for dim, rep in ((hoi269.DIM, "hoi269"), (hml263.DIM, "hml263")):
        rows = [s for _, samples in loaded for s in samples if s.shape[-1] == dim]
        if not rows:
            continue
        try:
            st = store.stats(rep)
        except FileNotFoundError:
            if normalized:
                raise ImportProblem(f"{store.root}/stats: no {rep} statistics to de-normalise {folder} with") from None
            continue
        check_feature_kind(folder, np.concatenate(rows), st, normalized)
        if normalized:
            for _, samples in loaded:
                samples[:] = [s * st.std + st.mean if s.shape[-1] == dim else s for s in samples]
    out = []
    for key, samples in loaded:
        T = min(len(s) for s in samples)
        try:
            f = np.stack([s[:T] for s in samples])
        except ValueError:
            raise ImportProblem(f"{folder}: samples of {key} have different feature sizes") from None
        if f.shape[-1] == hoi269.DIM:
            j, rot, trans = hoi269.decode(f)
            out.append((key, "", {"joints": j, "obj_rot": rot, "obj_trans": trans}))
        else:
            out.append((key, "", {"joints": hml263.decode(f)}))
    return out


#: SMPL-family thigh (hip -> knee, joints 1->4 and 2->5) length in metres an adult has
THIGH_M = (0.25, 0.65)
_UNITS = ((100.0, "centimetres", 0.01), (1000.0, "millimetres", 0.001))


def joint_warnings(results: Path, entries: list, converted_from_z: bool) -> list[str]:
    """Warnings about joints that look in other units than metres or another up axis than the
    import assumed: the median thigh length (``|J_knee - J_hip|``, metres expected in
    :data:`THIGH_M`) and the median spine direction (pelvis -> neck, joints 0 -> 12; +y expected)."""
    js = [a["joints"] for _, _, a in entries if "joints" in a and np.asarray(a["joints"]).size]
    if not js:
        return []
    j = np.concatenate([np.asarray(x, np.float64).reshape(-1, 22, 3) for x in js])
    j = j[np.isfinite(j).all((1, 2))]
    if not len(j):
        return []
    out = []
    thigh = float(np.median(np.linalg.norm(j[:, [4, 5]] - j[:, [1, 2]], axis=-1)))
    for factor, unit, scale in _UNITS:
        if THIGH_M[0] * factor * 0.5 <= thigh <= THIGH_M[1] * factor * 1.5:
            out.append(f"{results}: the joints look like {unit} (median thigh {thigh:.1f} units long; an adult's is "
                       f"{THIGH_M[0]}-{THIGH_M[1]} m): multiply them by {scale:g} (metres expected) and import again")
            break
    c = np.median(j[:, 12] - j[:, 0], axis=0)
    spine = np.array([c[0], -c[2], c[1]]) if converted_from_z else c        # back in the source's frame
    axis = int(np.argmax(np.abs(spine)))
    found, assumed = ("-" if spine[axis] < 0 else "+") + "xyz"[axis], "+z" if converted_from_z else "+y"
    if np.linalg.norm(spine) > 0 and found != assumed:
        fix = {"+z": "pass --up z", "+y": "they are y up: do not pass --up z"}.get(
            found, "rotate them to y up (or z up with --up z) first")
        out.append(f"{results}: the joints' spine (pelvis -> neck) points along {found} in the source, but "
                   f"{assumed} is up for this import: {fix}")
    return out


# ------------------------------------------------------------------------------ import
def _read_mdm(req: ImportRequest) -> list:
    return read_mdm(req.results, req.trust_pickle, False, req.budget)


def _read_hoidiff(req: ImportRequest) -> list:
    return read_mdm(req.results, req.trust_pickle, True, req.budget)


def _read_joints(req: ImportRequest) -> list:
    return read_joint_files(req.results, req.ids, req.up, False, req.budget)


def _read_chois(req: ImportRequest) -> list:
    """CHOIS's saved joints are in its window frame of the test clip (frame 0's heading along
    +x, frame 0's translation at xy = 0; :mod:`hoibench.metrics.chois_inputs`): each file,
    named by its test id (``<id>[_<r>].npz``), is put back in that clip's world frame
    (:func:`~hoibench.metrics.chois_inputs.from_window`); a file named otherwise is refused,
    since no clip gives its frame."""
    from ..metrics.chois_inputs import from_window
    known = set(req.ids)
    out = []
    for key, text, arrays in read_joint_files(req.results, req.ids, "z", True, req.budget):
        if key not in known:
            raise ImportProblem(f"{req.results}: {key}[_<r>].npz: not named by a test id of {req.store.root}: CHOIS's "
                                f"joints are in the window frame of their test clip, so a file must be named "
                                f"<id>[_<r>].npz")
        gt = req.store.load(key, keys=("joints",))["joints"]
        out.append((key, text, {**arrays, "joints": np.stack([from_window(j, gt) for j in arrays["joints"]])}))
    return out


def _read_features(req: ImportRequest) -> list:
    return read_features(req.results, req.ids, req.store, req.normalized, req.budget)


def import_results(fmt: str, results: str | Path, data: str | Path, out: str | Path, *, match: str | None = None,
                   mapping: str | Path | None = None, trust_pickle: bool = False, fps: float | None = None,
                   up: str = "y", normalized: bool = False, method: str | None = None,
                   as_zip: bool = False, body_models: str | Path | None = None, model_type: str = "smplh",
                   gender: str = "neutral") -> tuple[Path, dict]:
    """Write the submission; return (path, report: matched, missing ids, unmatched entries,
    ambiguous texts, conversions)."""
    if fmt not in IMPORT_FORMATS:
        raise ImportProblem(f"format {fmt!r}: choose one of {', '.join(FORMATS)}")
    spec = IMPORT_FORMATS.get(fmt)
    if up not in ("y", "z"):
        raise ImportProblem(f"--up: expected y or z, got {up!r}")
    results, store = Path(results), Store(data)
    store_fps = float(store.manifest["config"]["fps"])
    ids = store.clip_ids("test")
    how = "map" if mapping else (match or spec.match)
    if how not in ("id", "text", "map"):
        raise ImportProblem(f"--match: expected id or text, got {how!r}")
    table = read_mapping(mapping) if mapping else None
    request = ImportRequest(results, store, ids, spec.up_axis(up), normalized, trust_pickle, body_models, model_type,
                            gender, ReadBudget.for_store(store))
    entries = load_object(spec.reader)(request)
    if not entries:
        raise ImportProblem(f"{results}: nothing to import (no {spec.files} sample files or entries found)")
    warnings = joint_warnings(results, entries, spec.up_axis(up) == "z")
    for line in warnings:
        print(f"hoibench import: warning: {line}", file=sys.stderr)
    src_fps = float(fps) if fps is not None else (spec.source_fps or store_fps)
    if not (np.isfinite(src_fps) and 1 <= src_fps <= 1000):
        raise ImportProblem(f"--fps: expected 1..1000 frames per second, got {fps!r}")
    matcher = Matcher(store, how, table)
    samples: dict[str, dict] = {}
    for key, text, arrays in entries:
        cid = matcher(key, text)
        if cid is None:
            continue
        a = {"joints": np.stack([resample(s, src_fps, store_fps) for s in arrays["joints"]]).astype(np.float32)}
        if "obj_trans" in arrays:
            rv = arrays.get("obj_rotvec")
            if rv is not None:
                a["obj_rotvec"] = np.stack([resample_rotvec(r, src_fps, store_fps) for r in rv]).astype(np.float32)
            else:
                from ..core.geometry import matrix_to_axis_angle
                a["obj_rotvec"] = np.stack([resample_rotvec(matrix_to_axis_angle(r), src_fps, store_fps)
                                            for r in arrays["obj_rot"]]).astype(np.float32)
            a["obj_trans"] = np.stack([resample(t, src_fps, store_fps) for t in arrays["obj_trans"]]).astype(np.float32)
        samples[cid] = a
    if not samples:
        raise ImportProblem(f"{results}: no entry matched a test id of {data} (by {how}; e.g. "
                            f"{(matcher.unmatched or ['-'])[0]!r})")
    K = {len(a["joints"]) for a in samples.values()}
    conversions = {"format": fmt, "match": how, "source_fps": src_fps, "store_fps": store_fps,
                   "resampled": abs(src_fps - store_fps) > 1e-9,
                   "up_axis": "z -> y" if spec.up == "z" or up == "z" else "y", "normalized_features": bool(normalized) if fmt == "features" else None,
                   **({"body_model": model_type, "default_gender": gender} if fmt == "params" else {}),
                   **({"frame": "CHOIS's window frame -> the test clip's world frame"} if fmt == "chois" else {})}
    report = {"matched": len(samples), "test_ids": len(ids), "missing_ids": sorted(set(ids) - set(samples)),
              "unmatched_entries": matcher.unmatched, "ambiguous_texts": sorted(set(matcher.ambiguous)),
              "samples_per_prompt": sorted(K), "conversions": conversions, "warnings": warnings}
    gt_len = {cid: len(store.load(cid, keys=("joints",))["joints"]) for cid in samples}
    has_object = {c["id"] for c in store.manifest["clips"] if c.get("object")}
    without = sorted(c for c in samples if c in has_object and "obj_trans" not in samples[c])
    human_only = bool(without)
    if human_only and len(without) < sum(c in has_object for c in samples):
        raise ImportProblem(f"{results}: {len(without)} entries carry no object motion (e.g. {without[0]}) and "
                            f"others do; a submission is human-only for every clip or for none")
    report["human_only"] = human_only
    meta = {"method": method or f"imported {fmt} results", "version": "", "url": "",
            "representation": store.manifest.get("representations", {}).get("hml263", ""), "fps": store_fps,
            "flags": {"uses_gt_length": all(len(a["joints"][0]) == gt_len[c] for c, a in samples.items()),
                      "samples_per_prompt": max(K), "checkpoint_selection": "unknown",
                      **({"human_only": True} if human_only else {})},
            "source": {"import": {**conversions, "results": str(results), "missing_ids": len(report["missing_ids"]),
                                  "unmatched_entries": len(matcher.unmatched), "warnings": warnings}, "toolkit_version": __version__}}
    if len(K) > 1:
        raise ImportProblem(f"{results}: prompts have different numbers of samples ({sorted(K)}); a submission "
                            f"has one K")
    path = write_submission(out, meta, sorted(samples.items()), as_zip=as_zip)
    return path, report
