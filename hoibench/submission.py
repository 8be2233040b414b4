"""Submission format: write, read safely, validate; ground-truth submissions from a store.

A submission is a directory, or a ``.zip`` of one (read in place, never extracted)::

    submission.json            {"method", "version", "url", "representation", "fps",
                                "flags": {"uses_gt_length", "samples_per_prompt",
                                          "checkpoint_selection"}}
    samples/<test_id>.npz      joints    (K, T, 22, 3) float32, metres, y-up (DESIGN section 3)
                               obj_rot   (K, T, 3, 3)  or  obj_rotvec (K, T, 3)   (one of them)
                               obj_trans (K, T, 3)     object pose v = R v_template + t
                               hml263    (K, T-1 or T, 263)  optional

K samples per prompt (1 is enough for every metric but MultiModality, which needs the
protocol's 30), T frames at the submission's ``fps`` (must equal the store's).

Safety (nothing here unpickles or trusts sizes): ``.npz`` files are read with
``allow_pickle=False`` after every member's ``.npy`` header has been parsed without loading
data (:func:`npz_headers`): an object array (pickled Python objects) is rejected with a
message, and so is a header whose claimed shape needs more than ``max_array_bytes`` (2 GiB by
default) or more bytes than the member holds. Zip members with absolute paths, ``..``
components, backslashes, drive letters or symlinks are rejected and never read.

:func:`validate` reports *every* problem at once as :class:`Problem` ``(id, field, message)``:
missing or extra ids against the store's test split, shapes, dtypes, non-finite values,
implausible units (e.g. centimetres: a body taller than 3 m), lengths out of range, object
rotations that are not rotations, ``submission.json`` fields. A broken or partial submission
never raises and is never scored as complete (:class:`ValidationReport` ``complete``).
"""
from __future__ import annotations

import io
import json
import math
import re
import stat
import sys
import zipfile
from dataclasses import asdict, dataclass, field
from pathlib import Path, PurePosixPath
from typing import Iterable, Mapping

import numpy as np

from . import __version__
from .io import atomic_write_bytes, npz_bytes

SUBMISSION_JSON = "submission.json"
SAMPLES_DIR = "samples"
MAX_ARRAY_BYTES = 2 * 1024 ** 3            # per .npz file, all its arrays together
MAX_JSON_BYTES = 1024 ** 2
ID_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.\-]{0,199}$")
KNOWN_ARRAYS = ("joints", "obj_rot", "obj_rotvec", "obj_trans", "hml263")
REQUIRED_FIELDS = {"method": str, "version": str, "representation": str, "fps": (int, float)}
FLAG_FIELDS = {"uses_gt_length": bool, "samples_per_prompt": int, "checkpoint_selection": str}
#: height of the proxy body (the SMPL mean shape), metres; a skeleton's height is estimated as
#: this times its bone-length scale (:func:`hoibench.contact.body_scale`)
MEAN_BODY_HEIGHT_M = 1.72
BODY_HEIGHT_RANGE_M = (0.5, 3.0)
ROTATION_TOL = 1e-3
MAX_OBJECT_DISTANCE_M = 20.0


@dataclass(frozen=True)
class Problem:
    """One problem found in a submission: ``id`` (a test id, or ``"*"`` for the submission as
    a whole), ``field`` (``submission.json``, ``samples``, ``file``, an array name, ...),
    ``message`` and ``severity`` (``"error"`` makes the submission incomplete; ``"warning"``
    does not)."""

    id: str
    field: str
    message: str
    severity: str = "error"

    def __str__(self) -> str:
        return f"{self.severity}: {self.id}: {self.field}: {self.message}"

    def to_dict(self) -> dict:
        return asdict(self)


class SubmissionError(ValueError):
    """A submission file that cannot be read safely (the message says why)."""


@dataclass(frozen=True)
class ArrayHeader:
    """What a ``.npy`` header claims, read without loading the data."""

    name: str
    shape: tuple
    dtype: np.dtype
    fortran_order: bool
    nbytes: int


def _fmt_bytes(n: int) -> str:
    return f"{n / 1024 ** 3:.1f} GiB" if n >= 1024 ** 3 else f"{n / 1024 ** 2:.1f} MiB"


# ====================================================================== safe .npz reading
def npz_headers(source, max_array_bytes: int = MAX_ARRAY_BYTES) -> dict[str, ArrayHeader]:
    """Parse every member header of an ``.npz`` (path, bytes or binary file) without loading
    any data. ``SubmissionError`` when it is not a zip of ``.npy`` files, a member holds
    Python objects, or the claimed shapes need more than ``max_array_bytes`` together or
    more bytes than a member holds."""
    src = io.BytesIO(source) if isinstance(source, (bytes, bytearray)) else source
    try:
        zf = zipfile.ZipFile(src)
    except (zipfile.BadZipFile, OSError) as e:
        raise SubmissionError(f"not a valid .npz (zip) file: {e}") from None
    out: dict[str, ArrayHeader] = {}
    total = 0
    with zf:
        for info in zf.infolist():
            name = info.filename
            if info.is_dir():
                continue
            if not name.endswith(".npy") or "/" in name or "\\" in name or name.startswith("."):
                raise SubmissionError(f"unexpected member {name!r}: an .npz holds only NAME.npy arrays")
            key = name[:-4]
            try:
                with zf.open(info) as f:
                    version = np.lib.format.read_magic(f)
                    if version == (1, 0):
                        shape, fortran, dtype = np.lib.format.read_array_header_1_0(f)
                    else:  # 2.0 and 3.0 share the header layout
                        shape, fortran, dtype = np.lib.format.read_array_header_2_0(f)
                    header_len = f.tell() if hasattr(f, "tell") else 0
            except Exception as e:  # malformed header of any kind
                raise SubmissionError(f"array {key!r}: not a valid .npy header ({e})") from None
            if dtype.hasobject:
                raise SubmissionError(
                    f"array {key!r} holds Python objects (dtype {dtype}), i.e. pickled data; hoibench "
                    "never unpickles submissions: save plain numeric arrays (np.save(..., allow_pickle=False))")
            nbytes = math.prod(int(s) for s in shape) * dtype.itemsize
            total += nbytes
            if total > max_array_bytes:
                raise SubmissionError(
                    f"array {key!r} claims shape {tuple(shape)} {dtype} = {_fmt_bytes(nbytes)}; the file's "
                    f"arrays would need {_fmt_bytes(total)}, over the {_fmt_bytes(max_array_bytes)} limit "
                    "(not loaded)")
            if header_len and info.file_size < header_len + nbytes:
                raise SubmissionError(f"array {key!r} is truncated: its header claims {nbytes} bytes of data, "
                                      f"the member holds {max(0, info.file_size - header_len)}")
            out[key] = ArrayHeader(key, tuple(int(s) for s in shape), dtype, bool(fortran), nbytes)
    return out


def load_npz(source, max_array_bytes: int = MAX_ARRAY_BYTES) -> dict[str, np.ndarray]:
    """Load an ``.npz`` safely: :func:`npz_headers` first, then ``np.load(allow_pickle=False)``.
    ``SubmissionError`` on any failure."""
    data = source if isinstance(source, (bytes, bytearray)) else None
    headers = npz_headers(io.BytesIO(data) if data is not None else source, max_array_bytes)
    try:
        with np.load(io.BytesIO(data) if data is not None else source, allow_pickle=False) as z:
            return {k: z[k] for k in headers}
    except Exception as e:
        raise SubmissionError(f"could not read the arrays: {type(e).__name__}: {e}") from None


# ====================================================================== reading submissions
def _unsafe_member(name: str) -> str | None:
    if "\\" in name:
        return "contains a backslash"
    if name.startswith("/"):
        return "is an absolute path"
    if re.match(r"^[A-Za-z]:", name):
        return "starts with a drive letter"
    if any(part == ".." for part in PurePosixPath(name).parts):
        return "contains '..' (path traversal)"
    return None


class Submission:
    """Read access to a submission directory or ``.zip`` (never extracted).

    ``problems`` lists what was wrong with the container itself (unsafe zip members,
    symlinks leaving the folder, unreadable ``submission.json``); ``meta`` is the parsed
    ``submission.json`` (None when missing or invalid); ``ids`` the sample ids found.
    Use as a context manager, or call :meth:`close`.
    """

    def __init__(self, path: str | Path, max_array_bytes: int = MAX_ARRAY_BYTES):
        self.path = Path(path)
        self.max_array_bytes = int(max_array_bytes)
        self.problems: list[Problem] = []
        self.meta: dict | None = None
        self._zip: zipfile.ZipFile | None = None
        self._files: dict[str, object] = {}       # id -> Path or ZipInfo
        self._json: object = None
        if self.path.is_dir():
            self.kind = "directory"
            self._scan_dir()
        elif self.path.is_file():
            self.kind = "zip"
            self._scan_zip()
        else:
            self.kind = "missing"
            self.problems.append(Problem("*", "path", f"no submission at {self.path} (expected a folder or a .zip)"))
        self._read_meta()

    # -- containers
    def _scan_dir(self) -> None:
        root = self.path.resolve()
        js = self.path / SUBMISSION_JSON
        self._json = js if js.exists() else None
        if self._json is not None and not self._inside(js, root):
            self.problems.append(Problem("*", SUBMISSION_JSON, "is a link leaving the submission folder: not read"))
            self._json = None
        samples = self.path / SAMPLES_DIR
        if not samples.is_dir():
            return
        for p in sorted(samples.iterdir()):
            if p.name.startswith("."):
                continue
            if p.suffix != ".npz":
                self.problems.append(Problem("*", SAMPLES_DIR, f"ignored {p.name!r}: not an .npz", "warning"))
                continue
            if not self._inside(p, root) or not p.is_file():
                self.problems.append(Problem(p.stem, "file", "is a link leaving the submission folder or not a "
                                                              "regular file: not read"))
                continue
            self._files[p.stem] = p

    @staticmethod
    def _inside(p: Path, root: Path) -> bool:
        try:
            p.resolve().relative_to(root)
            return True
        except (ValueError, OSError):
            return False

    def _scan_zip(self) -> None:
        try:
            self._zip = zipfile.ZipFile(self.path)
        except (zipfile.BadZipFile, OSError) as e:
            self.problems.append(Problem("*", "path", f"{self.path.name}: neither a folder nor a valid .zip ({e})"))
            return
        safe = []
        for info in self._zip.infolist():
            why = _unsafe_member(info.filename)
            if why is None and stat.S_ISLNK(info.external_attr >> 16):
                why = "is a symbolic link"
            if why:
                self.problems.append(Problem("*", "zip", f"member {info.filename!r} {why}: rejected, not read"))
                continue
            if not info.is_dir():
                safe.append(info)
        names = {i.filename for i in safe}
        prefix = ""
        if SUBMISSION_JSON not in names:   # allow one top-level folder around everything
            tops = {i.filename.split("/", 1)[0] for i in safe if "/" in i.filename}
            cands = [t for t in tops if f"{t}/{SUBMISSION_JSON}" in names]
            if len(cands) == 1:
                prefix = cands[0] + "/"
        for info in safe:
            rel = info.filename[len(prefix):] if info.filename.startswith(prefix) else None
            if rel == SUBMISSION_JSON:
                self._json = info
            elif rel is not None and rel.startswith(SAMPLES_DIR + "/"):
                leaf = rel[len(SAMPLES_DIR) + 1:]
                if "/" in leaf or not leaf.endswith(".npz"):
                    self.problems.append(Problem("*", SAMPLES_DIR, f"ignored member {info.filename!r}", "warning"))
                    continue
                self._files[leaf[:-4]] = info

    def _read_meta(self) -> None:
        if self.kind == "missing" or (self.kind == "zip" and self._zip is None):
            return
        if self._json is None:
            self.problems.append(Problem("*", SUBMISSION_JSON, f"missing: the submission needs a {SUBMISSION_JSON}"))
            return
        try:
            size = self._json.file_size if isinstance(self._json, zipfile.ZipInfo) else self._json.stat().st_size
            if size > MAX_JSON_BYTES:
                raise SubmissionError(f"{_fmt_bytes(size)}, over the {_fmt_bytes(MAX_JSON_BYTES)} limit")
            raw = self._zip.read(self._json) if isinstance(self._json, zipfile.ZipInfo) else self._json.read_bytes()
            meta = json.loads(raw.decode("utf-8"))
            if not isinstance(meta, dict):
                raise SubmissionError("expected a JSON object")
            self.meta = meta
        except (SubmissionError, ValueError, OSError, zipfile.BadZipFile) as e:
            self.problems.append(Problem("*", SUBMISSION_JSON, f"not readable: {e}"))

    # -- access
    @property
    def ids(self) -> list[str]:
        return sorted(self._files)

    def _source(self, sid: str):
        ref = self._files[sid]
        if isinstance(ref, zipfile.ZipInfo):
            if ref.file_size > self.max_array_bytes + 1024 ** 2:
                raise SubmissionError(f"samples/{sid}.npz is {_fmt_bytes(ref.file_size)}, over the limit")
            return self._zip.read(ref)
        return ref

    def headers(self, sid: str) -> dict[str, ArrayHeader]:
        """Array headers of ``samples/<sid>.npz`` (no data loaded); ``SubmissionError``."""
        try:
            src = self._source(sid)
        except (zipfile.BadZipFile, OSError, KeyError) as e:
            raise SubmissionError(f"could not read the file: {e}") from None
        return npz_headers(src, self.max_array_bytes)

    def load(self, sid: str) -> dict[str, np.ndarray]:
        """Arrays of ``samples/<sid>.npz`` (safe loading, see :func:`load_npz`)."""
        try:
            src = self._source(sid)
        except (zipfile.BadZipFile, OSError, KeyError) as e:
            raise SubmissionError(f"could not read the file: {e}") from None
        return load_npz(src, self.max_array_bytes)

    def close(self) -> None:
        if self._zip is not None:
            self._zip.close()
            self._zip = None

    def __enter__(self) -> "Submission":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


# ====================================================================== validation
@dataclass
class ValidationReport:
    """Outcome of :func:`validation_report`: every problem, and what can be scored.
    ``complete`` is True only when there is no error at all; ``valid_ids`` are the test ids
    whose file has no error; ``missing_ids`` the test ids without a valid file."""

    problems: list
    test_ids: list
    valid_ids: list
    samples_per_prompt: int | None
    complete: bool = field(init=False)

    def __post_init__(self):
        self.complete = not any(p.severity == "error" for p in self.problems)

    @property
    def missing_ids(self) -> list:
        ok = set(self.valid_ids)
        return [i for i in self.test_ids if i not in ok]

    @property
    def errors(self) -> list:
        return [p for p in self.problems if p.severity == "error"]

    @property
    def warnings(self) -> list:
        return [p for p in self.problems if p.severity == "warning"]

    def to_dict(self) -> dict:
        return {"complete": self.complete, "test_ids": len(self.test_ids), "valid_ids": len(self.valid_ids),
                "missing_ids": self.missing_ids, "samples_per_prompt": self.samples_per_prompt,
                "problems": [p.to_dict() for p in self.problems]}


def _check_meta(meta: dict | None, store_fps: float, protocol) -> list[Problem]:
    if meta is None:
        return []
    out = []
    for key, kind in REQUIRED_FIELDS.items():
        if key not in meta:
            out.append(Problem("*", SUBMISSION_JSON, f"missing field {key!r}"))
        elif not isinstance(meta[key], kind) or isinstance(meta[key], bool):
            want = "a number" if key == "fps" else "a string"
            out.append(Problem("*", SUBMISSION_JSON, f"field {key!r} must be {want}, got {meta[key]!r}"))
    if "url" in meta and not isinstance(meta["url"], str):
        out.append(Problem("*", SUBMISSION_JSON, f"field 'url' must be a string, got {meta['url']!r}"))
    flags = meta.get("flags", {})
    if not isinstance(flags, dict):
        out.append(Problem("*", SUBMISSION_JSON, f"field 'flags' must be an object, got {flags!r}"))
    else:
        for key, kind in FLAG_FIELDS.items():
            if key in flags and (not isinstance(flags[key], kind) or (kind is int and isinstance(flags[key], bool))):
                out.append(Problem("*", SUBMISSION_JSON, f"flags.{key} must be {kind.__name__}, got {flags[key]!r}"))
        if isinstance(flags.get("samples_per_prompt"), int) and flags["samples_per_prompt"] < 1:
            out.append(Problem("*", SUBMISSION_JSON, "flags.samples_per_prompt must be >= 1"))
    fps = meta.get("fps")
    if isinstance(fps, (int, float)) and not isinstance(fps, bool) and abs(float(fps) - store_fps) > 1e-6:
        out.append(Problem("*", SUBMISSION_JSON, f"fps {fps} but the store is evaluated at {store_fps:g} fps: "
                                                 "resample by time (not by dropping every n-th frame) first"))
    if protocol is not None and abs(protocol.fps - store_fps) > 1e-6:
        out.append(Problem("*", "protocol", f"protocol {protocol.ref} evaluates at {protocol.fps:g} fps but the "
                                            f"store holds {store_fps:g} fps clips"))
    return out


def _expect_shape(h: ArrayHeader | None, tail: tuple, name: str, sid: str, floating: bool = True,
                  dtype: str | None = None) -> list[Problem]:
    if h is None:
        return []
    out = []
    ndim = 2 + len(tail)
    if len(h.shape) != ndim or tuple(h.shape[2:]) != tail:
        want = "(K, T" + "".join(f", {t}" for t in tail) + ")"
        out.append(Problem(sid, name, f"expected shape {want}, got {h.shape}"))
    if dtype is not None and h.dtype != np.dtype(dtype):
        out.append(Problem(sid, name, f"expected dtype {dtype}, got {h.dtype} "
                                      f"(convert with .astype(np.{dtype}))"))
    elif floating and not np.issubdtype(h.dtype, np.floating):
        out.append(Problem(sid, name, f"expected a floating-point dtype, got {h.dtype}"))
    return out


def _check_clip(sub: Submission, sid: str, gt_frames: int, has_object: bool, fps: float,
                uses_gt_length: bool) -> tuple[list[Problem], int | None]:
    """Problems of one sample file and its K (None when unknown)."""
    try:
        headers = sub.headers(sid)
    except SubmissionError as e:
        return [Problem(sid, "file", str(e))], None
    probs: list[Problem] = []
    for k in headers:
        if k not in KNOWN_ARRAYS:
            probs.append(Problem(sid, k, f"unexpected array {k!r} (ignored); known: {', '.join(KNOWN_ARRAYS)}",
                                 "warning"))
    if "joints" not in headers:
        probs.append(Problem(sid, "joints", "missing: every sample file needs joints (K, T, 22, 3)"))
    if has_object:
        if "obj_trans" not in headers:
            probs.append(Problem(sid, "obj_trans", "missing: the object's translation (K, T, 3) is required"))
        if "obj_rot" not in headers and "obj_rotvec" not in headers:
            probs.append(Problem(sid, "obj_rot", "missing: give obj_rot (K, T, 3, 3) or obj_rotvec (K, T, 3)"))
        if "obj_rot" in headers and "obj_rotvec" in headers:
            probs.append(Problem(sid, "obj_rot", "both obj_rot and obj_rotvec given: give exactly one"))
    shape_probs = (_expect_shape(headers.get("joints"), (22, 3), "joints", sid, dtype="float32")
                   + _expect_shape(headers.get("obj_rot"), (3, 3), "obj_rot", sid)
                   + _expect_shape(headers.get("obj_rotvec"), (3,), "obj_rotvec", sid)
                   + _expect_shape(headers.get("obj_trans"), (3,), "obj_trans", sid)
                   + _expect_shape(headers.get("hml263"), (263,), "hml263", sid))
    probs += shape_probs
    bad = {p.field for p in shape_probs}
    present = [k for k in KNOWN_ARRAYS if k in headers and k not in bad]
    K = T = None
    if "joints" in present:
        K, T = headers["joints"].shape[:2]
    for k in present:
        if k == "joints" or K is None:
            continue
        kk, tt = headers[k].shape[:2]
        if kk != K:
            probs.append(Problem(sid, k, f"{kk} samples but joints has {K}"))
            bad.add(k)
        if k == "hml263":
            if tt not in (T - 1, T):
                probs.append(Problem(sid, k, f"{tt} frames; expected T - 1 = {T - 1} or T = {T} (joints has T = {T})"))
                bad.add(k)
        elif tt != T:
            probs.append(Problem(sid, k, f"{tt} frames but joints has {T}"))
            bad.add(k)
    if K is not None:
        if K < 1:
            probs.append(Problem(sid, "joints", "no samples (K = 0)"))
        if T < 2:
            probs.append(Problem(sid, "joints", f"{T} frame(s): at least 2 are needed"))
        elif uses_gt_length and T != gt_frames:
            probs.append(Problem(sid, "joints", f"{T} frames, but submission.json says uses_gt_length and the "
                                                f"ground truth has {gt_frames}"))
        elif T > max(4 * gt_frames, gt_frames + 10 * fps):
            probs.append(Problem(sid, "joints", f"{T} frames, more than 4x the ground truth's {gt_frames} at "
                                                f"{fps:g} fps: wrong frame rate?"))
        elif not (gt_frames / 2 <= T <= 2 * gt_frames):
            probs.append(Problem(sid, "joints", f"{T} frames vs {gt_frames} in the ground truth (outside 0.5x-2x)",
                                 "warning"))
    ok = [k for k in present if k not in bad]
    if not ok or K is None or K < 1:
        return probs, K
    try:
        arrays = sub.load(sid)
    except SubmissionError as e:
        return probs + [Problem(sid, "file", str(e))], K
    for k in ok:
        a = arrays[k]
        nonfinite = int((~np.isfinite(a)).sum())
        if nonfinite:
            first = np.argwhere(~np.isfinite(a))[0]
            probs.append(Problem(sid, k, f"{nonfinite} non-finite value(s) (NaN or inf), first at index "
                                         f"{tuple(int(i) for i in first)}"))
            bad.add(k)
    if "joints" in ok and "joints" not in bad:
        probs += _check_joints(sid, arrays["joints"])
    if "obj_rot" in ok and "obj_rot" not in bad:
        probs += _check_rotations(sid, arrays["obj_rot"])
    if "obj_trans" in ok and "obj_trans" not in bad and "joints" in ok and "joints" not in bad:
        dist = np.linalg.norm(arrays["obj_trans"].astype(np.float64) - arrays["joints"][:, :, 0], axis=-1)
        med = float(np.median(dist))
        if med > MAX_OBJECT_DISTANCE_M:
            probs.append(Problem(sid, "obj_trans", f"the object is {med:.3g} m from the pelvis (median): "
                                                   "implausible units (centimetres?)"))
    return probs, K


def _check_joints(sid: str, joints: np.ndarray) -> list[Problem]:
    from .contact import body_scale
    out = []
    J = joints.astype(np.float64)
    heights = np.array([MEAN_BODY_HEIGHT_M * body_scale(J[k]) for k in range(len(J))])
    lo, hi = BODY_HEIGHT_RANGE_M
    worst = heights[np.argmax(np.abs(np.log(np.maximum(heights, 1e-12) / MEAN_BODY_HEIGHT_M)))]
    if not (lo <= worst <= hi):
        hint = " (millimetres?)" if worst > 300 else " (centimetres?)" if worst > 30 else ""
        out.append(Problem(sid, "joints", f"implausible units: the skeleton's bone lengths give a body "
                                          f"{worst:.3g} m tall (expected {lo}-{hi} m){hint}"))
        return out
    # Up axis: along the true up axis the lowest joint is an ankle or foot in nearly every
    # frame (standing, walking, sitting, kicking); along a horizontal axis it is arbitrary.
    feet = np.array([7, 8, 10, 11])
    frac = {}
    for a, axis in enumerate("xyz"):
        for sign in (1, -1):
            frac[("" if sign > 0 else "-") + axis] = float(np.isin((sign * J[..., a]).argmin(-1), feet).mean())
    best = max(frac, key=frac.get)
    if best != "y" and frac[best] >= 0.8 and frac["y"] < 0.5:
        out.append(Problem(sid, "joints", f"looks {best}-up: the feet are the lowest joints along {best} in "
                                          f"{100 * frac[best]:.0f}% of frames but along y in {100 * frac['y']:.0f}%; "
                                          "hoibench is y-up", "warning"))
    return out


def _check_rotations(sid: str, R: np.ndarray) -> list[Problem]:
    R = R.astype(np.float64)
    orth = np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)).max(axis=(-1, -2))
    det = np.linalg.det(R)
    bad = (orth > ROTATION_TOL) | (det < 0)
    if not bad.any():
        return []
    k, t = (int(i) for i in np.argwhere(bad)[0])
    what = "a reflection (det < 0)" if det[k, t] < 0 else f"max |R^T R - I| = {orth[k, t]:.3g}"
    return [Problem(sid, "obj_rot", f"{int(bad.sum())} of {bad.size} matrices are not rotations; first at "
                                    f"sample {k} frame {t}: {what}")]


def validation_report(sub, store, split: str = "test", protocol=None,
                      max_array_bytes: int = MAX_ARRAY_BYTES) -> ValidationReport:
    """Validate ``sub`` (path or :class:`Submission`) against ``store`` (path or
    :class:`hoibench.store.Store`); never raises on a broken submission. See :func:`validate`."""
    from .store import Store

    st = store if isinstance(store, Store) else Store(store)
    if protocol is not None and not hasattr(protocol, "fps"):
        from .protocol import get_protocol
        protocol = get_protocol(protocol)
    own = not isinstance(sub, Submission)
    s = Submission(sub, max_array_bytes) if own else sub
    try:
        problems = list(s.problems)
        fps = float(st.manifest["config"]["fps"])
        problems += _check_meta(s.meta, fps, protocol)
        flags = (s.meta or {}).get("flags", {}) if isinstance((s.meta or {}).get("flags", {}), dict) else {}
        rows = {c["id"]: c for c in st.manifest["clips"] if c["split"] == split}
        test_ids = sorted(rows)
        found = set(s.ids)
        for sid in test_ids:
            if sid not in found:
                problems.append(Problem(sid, SAMPLES_DIR, f"missing: no {SAMPLES_DIR}/{sid}.npz"))
        for sid in sorted(found - set(rows)):
            why = "not a valid id" if not ID_PATTERN.match(sid) else \
                f"not in the {split!r} split of dataset {st.manifest.get('dataset', '?')!r}"
            problems.append(Problem(sid, SAMPLES_DIR, f"extra file: {why}"))
        valid, ks = [], {}
        for sid in test_ids:
            if sid not in found:
                continue
            probs, K = _check_clip(s, sid, int(rows[sid]["frames"]), bool(rows[sid].get("object")), fps,
                                   bool(flags.get("uses_gt_length", False)))
            problems += probs
            if K is not None:
                ks[sid] = K
            if not any(p.severity == "error" for p in probs):
                valid.append(sid)
        kvals = sorted(set(ks.values()))
        spp = flags.get("samples_per_prompt")
        if len(kvals) > 1:
            problems.append(Problem("*", SAMPLES_DIR, f"samples per prompt differ between files: K in {kvals}"))
        elif kvals and isinstance(spp, int) and not isinstance(spp, bool) and spp != kvals[0]:
            problems.append(Problem("*", SUBMISSION_JSON, f"flags.samples_per_prompt is {spp} but the files hold "
                                                          f"K = {kvals[0]}"))
        if protocol is not None and kvals and kvals[0] <= protocol.mm_pairs:
            problems.append(Problem("*", SAMPLES_DIR, f"K = {kvals[0]} sample(s) per prompt: MultiModality needs "
                                                      f"{protocol.mm_samples} and will not be computed", "warning"))
        problems.sort(key=lambda p: (p.id != "*", p.id, p.field, p.message))
        return ValidationReport(problems, test_ids, valid, kvals[0] if len(kvals) == 1 else None)
    finally:
        if own:
            s.close()


def validate(sub, store, split: str = "test", protocol=None,
             max_array_bytes: int = MAX_ARRAY_BYTES) -> list[Problem]:
    """Every problem of a submission at once (errors and warnings), sorted by id and field.

    Checks: the container (zip member paths, links), ``submission.json`` fields and types,
    fps against the store, ids against the store's ``split`` (missing, extra), per file:
    readable safely (no pickles, no oversized claims), required arrays, shapes, dtypes
    (joints float32), consistent K and T, finite values, plausible units (body height
    0.5-3 m from bone lengths; object within 20 m of the pelvis), y-up (warning), lengths
    (>= 2 frames; equal to the ground truth's when ``uses_gt_length``; at most 4x it; a
    warning outside 0.5x-2x), object rotation matrices (orthonormal within 1e-3, det > 0).
    A submission is complete only when no problem is an error.
    """
    return validation_report(sub, store, split, protocol, max_array_bytes).problems


# ====================================================================== writing
def write_submission(out: str | Path, meta: Mapping, samples: Iterable[tuple[str, Mapping[str, np.ndarray]]]
                     | Mapping[str, Mapping[str, np.ndarray]], as_zip: bool = False) -> Path:
    """Write a submission folder (or ``.zip`` when ``as_zip``): ``submission.json`` and
    ``samples/<id>.npz`` (byte-reproducible, no pickles). Atomic per file (the zip as a
    whole). Returns the path written."""
    items = samples.items() if isinstance(samples, Mapping) else samples
    files: dict[str, bytes] = {SUBMISSION_JSON: (json.dumps(dict(meta), indent=2, sort_keys=True) + "\n").encode()}
    for sid, arrays in items:
        if not ID_PATTERN.match(str(sid)):
            raise ValueError(f"samples: invalid id {sid!r} (letters, digits, '_', '-', '.')")
        files[f"{SAMPLES_DIR}/{sid}.npz"] = npz_bytes({k: np.asarray(v) for k, v in arrays.items()})
    out = Path(out)
    if as_zip:
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_STORED) as zf:
            for name, data in files.items():
                info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))
                info.external_attr = 0o644 << 16
                zf.writestr(info, data)
        return atomic_write_bytes(out, buf.getvalue())
    for name, data in files.items():
        atomic_write_bytes(out / name, data)
    return out


def from_store(data: str | Path, out: str | Path, split: str = "test", as_zip: bool = False,
               method: str = "ground truth (real motion)") -> Path:
    """A ground-truth submission: K = 1 sample per test clip, the clip itself -- the "real
    motion" row of every table, scored by the same code path as any model."""
    from .store import Store

    st = Store(data)
    manifest = st.manifest
    meta = {"method": method, "version": __version__, "url": "",
            "representation": manifest.get("representations", {}).get("hml263", ""),
            "fps": float(manifest["config"]["fps"]),
            "flags": {"uses_gt_length": True, "samples_per_prompt": 1, "checkpoint_selection": "n/a"},
            "source": {"store": manifest.get("dataset", ""), "split": split, "toolkit_version": __version__}}

    def samples():
        for sid in st.clip_ids(split):
            clip = st.load(sid)
            arrays = {"joints": clip["joints"][None].astype(np.float32)}
            if "obj_rot" in clip:
                arrays["obj_rot"] = clip["obj_rot"][None].astype(np.float32)
                arrays["obj_trans"] = clip["obj_trans"][None].astype(np.float32)
            if "hml263" in clip:
                arrays["hml263"] = clip["hml263"][None]
            yield sid, arrays

    return write_submission(out, meta, samples(), as_zip=as_zip)


# ====================================================================== CLI entry points
def main_validate(sub: str | Path, data: str | Path, protocol: str | None = None, split: str = "test",
                  as_json: bool = False) -> int:
    """``hoibench validate SUB --data DATA``: print every problem; exit status 0 when the
    submission is complete (warnings allowed), 1 when it has errors, 2 when the store or
    protocol cannot be read."""
    try:
        rep = validation_report(sub, data, split, protocol)
    except (FileNotFoundError, KeyError, ValueError) as e:
        print(f"validate: {e.args[0] if isinstance(e, KeyError) else e}", file=sys.stderr)
        return 2
    if as_json:
        print(json.dumps(rep.to_dict(), indent=2, sort_keys=True))
    else:
        for p in rep.problems:
            print(p)
        state = "complete" if rep.complete else "INCOMPLETE (will not be scored as complete)"
        print(f"{sub}: {len(rep.errors)} error(s), {len(rep.warnings)} warning(s); "
              f"{len(rep.valid_ids)} of {len(rep.test_ids)} test ids valid; {state}")
    return 0 if rep.complete else 1


def main_submission_from_store(data: str | Path, out: str | Path, split: str = "test", as_zip: bool = False,
                               method: str = "ground truth (real motion)") -> int:
    """``hoibench submission from-store DATA --out OUT [--zip]``: write the ground-truth
    submission; exit status 0, or 2 when the store cannot be read."""
    try:
        path = from_store(data, out, split, as_zip, method)
    except (FileNotFoundError, KeyError, ValueError) as e:
        print(f"submission from-store: {e}", file=sys.stderr)
        return 2
    print(f"wrote {path} ({'zip' if as_zip else 'folder'}; ground truth of split {split!r})")
    return 0


__all__ = ["Problem", "SubmissionError", "ArrayHeader", "Submission", "ValidationReport", "npz_headers", "load_npz",
           "validate", "validation_report", "write_submission", "from_store", "main_validate",
           "main_submission_from_store", "SUBMISSION_JSON", "SAMPLES_DIR", "MAX_ARRAY_BYTES"]
