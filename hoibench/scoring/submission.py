"""Submission format: write, read safely, validate; ground-truth submissions from a store.

A submission is a directory, or a ``.zip`` of one (read in place, never extracted)::

    submission.json            {"method", "version", "url", "representation", "fps",
                                "flags": {"uses_gt_length", "samples_per_prompt",
                                          "checkpoint_selection"}}
    samples/<test_id>.npz      joints    (K, T, 22, 3) float32, metres, y-up (DESIGN section 3)
                               obj_rot   (K, T, 3, 3)  or  obj_rotvec (K, T, 3)   (one of them)
                               obj_trans (K, T, 3)     object pose v = R v_template + t
                               hml263    (K, T-1 or T, 263)  optional

The object arrays are required for test clips that have an object; a human-only store's
clips (RICH: static scenes) need ``joints`` only (object arrays there draw a warning).

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
import zlib
from dataclasses import asdict, dataclass, field
from pathlib import Path, PurePosixPath
from typing import Iterable, Mapping

import numpy as np

from .. import __version__
from ..core.ids import ID_PATTERN as _ID_PATTERN
from ..core.ids import ID_RULE, check_id, is_valid_id
from ..core.io import atomic_write_bytes, load_json_bytes, npz_bytes, read_regular_file
from ..core.plausibility import ROTATION_TOL

SUBMISSION_JSON = "submission.json"
SAMPLES_DIR = "samples"
#: fallback per-file cap when no store is known (``npz_headers`` called directly)
MAX_ARRAY_BYTES = 2 * 1024 ** 3
MAX_JSON_BYTES = 1024 ** 2
#: the id rule (:mod:`hoibench.core.ids`)
ID_PATTERN = _ID_PATTERN
KNOWN_ARRAYS = ("joints", "obj_rot", "obj_rotvec", "obj_trans", "hml263")
#: values per frame of every known array (joints 66, obj_rot 9, obj_trans 3, hml263 263);
#: obj_rotvec (3) is the alternative to obj_rot, so 9 bounds both
VALUES_PER_FRAME = 22 * 3 + 9 + 3 + 263
#: the widest accepted dtype (float64): budgets assume it
BYTES_PER_VALUE = 8
#: arrays an .npz may hold besides the known ones (warned about, never loaded)
MAX_EXTRA_ARRAYS = 8
#: slack per file for zip and .npy headers
FILE_OVERHEAD_BYTES = 1024 ** 2
#: K cap when no protocol is known
DEFAULT_MAX_SAMPLES_PER_PROMPT = 32
#: central directory of a submission .zip larger than this is refused before it is parsed
MAX_ZIP_DIRECTORY_BYTES = 64 * 1024 ** 2
ACCEPTED_DTYPES = (np.dtype("float32"), np.dtype("float64"))
REQUIRED_FIELDS = {"method": str, "version": str, "representation": str, "fps": (int, float)}
FLAG_FIELDS = {"uses_gt_length": bool, "samples_per_prompt": int, "checkpoint_selection": str}
#: height of the proxy body (the SMPL mean shape), metres; a skeleton's height is estimated as
#: this times its bone-length scale (:func:`hoibench.bodies.contact.body_scale`)
MEAN_BODY_HEIGHT_M = 1.72
BODY_HEIGHT_RANGE_M = (0.5, 3.0)
#: median object-pelvis distance above which a sample is in the wrong units
MAX_OBJECT_DISTANCE_M = 20.0
#: object-pelvis distance no single frame may exceed
MAX_OBJECT_DISTANCE_FRAME_M = 100.0
#: no joint or object coordinate may lie further than this from the origin, metres
MAX_ABS_COORD_M = 1000.0
#: root (pelvis) and object speed no frame may exceed, metres per second
MAX_SPEED_MPS = 50.0
#: bound on |obj_rotvec| (radians) and on every hml263 value
MAX_ROTVEC_RAD = 100.0
MAX_FEATURE_ABS = 1e6
#: array -> (bound on every |value|, unit named in the message)
_VALUE_BOUNDS = {"joints": (MAX_ABS_COORD_M, "m"), "obj_trans": (MAX_ABS_COORD_M, "m"),
                 "obj_rotvec": (MAX_ROTVEC_RAD, "rad"), "hml263": (MAX_FEATURE_ABS, "units")}


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


# ====================================================================== budgets
def max_frames(gt_frames: int, fps: float) -> int:
    """Longest sample accepted for a test clip of ``gt_frames`` frames:
    ``max(4 * gt_frames, gt_frames + 10 s * fps)``."""
    return int(max(4 * gt_frames, gt_frames + 10 * fps))


@dataclass(frozen=True)
class SubmissionLimits:
    """Byte budgets derived from a store's test split and a protocol's K cap.

    Per test id: ``K cap x max_frames(gt) x VALUES_PER_FRAME x 8 bytes + 1 MiB`` (every
    known array at float64, the longest accepted length, the most samples a protocol uses);
    the whole submission: the sum over test ids. The budgets bound what any header may
    claim, how many bytes are read or decompressed per file, and so peak memory: validate
    and evaluate hold one file at a time. ``max_files``: members or folder entries
    (``2 x ids + 64``)."""

    per_id_bytes: Mapping[str, int]
    total_bytes: int
    max_samples: int
    max_files: int

    def for_id(self, sid: str) -> int:
        return int(self.per_id_bytes.get(sid, 0))

    @property
    def largest_file_bytes(self) -> int:
        return max(self.per_id_bytes.values(), default=0)


def limits_for(rows: Mapping[str, Mapping], fps: float, max_samples: int) -> SubmissionLimits:
    """:class:`SubmissionLimits` for test ``rows`` (id -> manifest row with ``frames``)."""
    per = {sid: max_samples * max_frames(int(r["frames"]), fps) * VALUES_PER_FRAME * BYTES_PER_VALUE
           + FILE_OVERHEAD_BYTES for sid, r in rows.items()}
    return SubmissionLimits(per, sum(per.values()), int(max_samples), 2 * len(rows) + 64)


# ====================================================================== safe .npz reading
def _read_npy_header(f) -> tuple:
    version = np.lib.format.read_magic(f)
    if version == (1, 0):
        return np.lib.format.read_array_header_1_0(f)
    if version in ((2, 0), (3, 0)):   # 2.0 and 3.0 share the header layout
        return np.lib.format.read_array_header_2_0(f)
    raise ValueError(f"unsupported .npy format version {version}")


def npz_headers(source, max_array_bytes: int = MAX_ARRAY_BYTES) -> dict[str, ArrayHeader]:
    """Parse every member header of an ``.npz`` (path, bytes or binary file) without loading
    any data. ``SubmissionError`` when it is not a zip of ``.npy`` files, a member name
    repeats, a member holds Python objects, a dimension is negative or zero, or the claimed
    shapes need more than ``max_array_bytes`` together or more bytes than a member holds."""
    src = io.BytesIO(source) if isinstance(source, (bytes, bytearray)) else source
    try:
        zf = zipfile.ZipFile(src)
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as e:
        raise SubmissionError(f"not a valid .npz (zip) file: {e}") from None
    out: dict[str, ArrayHeader] = {}
    total = 0
    with zf:
        infos = [i for i in zf.infolist() if not i.is_dir()]
        if len(infos) > len(KNOWN_ARRAYS) + MAX_EXTRA_ARRAYS:
            raise SubmissionError(f"{len(infos)} members: an .npz holds at most "
                                  f"{len(KNOWN_ARRAYS) + MAX_EXTRA_ARRAYS} arrays")
        for info in infos:
            name = info.filename
            if not name.endswith(".npy") or "/" in name or "\\" in name or name.startswith("."):
                raise SubmissionError(f"unexpected member {name!r}: an .npz holds only NAME.npy arrays")
            key = name[:-4]
            if key in out:
                raise SubmissionError(f"array {key!r} appears twice in the .npz: refused (which copy counts "
                                      "would be up to the reader)")
            if info.flag_bits & 0x1:
                raise SubmissionError(f"array {key!r} is encrypted: not read")
            try:
                with zf.open(info) as f:
                    shape, fortran, dtype = _read_npy_header(f)
                    header_len = f.tell()
            except Exception as e:  # malformed header, unsupported compression, corrupt data
                raise SubmissionError(f"array {key!r}: not a valid .npy header ({type(e).__name__}: {e})") from None
            if dtype.hasobject:
                raise SubmissionError(
                    f"array {key!r} holds Python objects (dtype {dtype}), i.e. pickled data; hoibench "
                    "never unpickles submissions: save plain numeric arrays (np.save(..., allow_pickle=False))")
            dims = tuple(int(s) for s in shape)
            if any(d < 0 for d in dims):
                raise SubmissionError(f"array {key!r} claims a negative dimension {dims}: not a valid array")
            if any(d == 0 for d in dims):
                raise SubmissionError(f"array {key!r} has shape {dims}: an empty dimension (no samples or frames)")
            nbytes = math.prod(dims) * dtype.itemsize
            total += nbytes
            if total > max_array_bytes:
                raise SubmissionError(
                    f"array {key!r} claims shape {dims} {dtype} = {_fmt_bytes(nbytes)}; the file's arrays "
                    f"would need {_fmt_bytes(total)}, over this file's {_fmt_bytes(max_array_bytes)} limit "
                    "(not loaded; see docs/security.md for the budgets)")
            if info.file_size < header_len + nbytes:
                raise SubmissionError(f"array {key!r} is truncated: its header claims {nbytes} bytes of data, "
                                      f"the member holds {max(0, info.file_size - header_len)}")
            out[key] = ArrayHeader(key, dims, dtype, bool(fortran), nbytes)
    return out


def load_npz(source, max_array_bytes: int = MAX_ARRAY_BYTES,
             keys: Iterable[str] | None = None) -> dict[str, np.ndarray]:
    """Load an ``.npz`` safely: :func:`npz_headers` first, then ``np.load(allow_pickle=False)``
    of ``keys`` only (default: every array). ``SubmissionError`` on any failure."""
    data = source if isinstance(source, (bytes, bytearray)) else None
    headers = npz_headers(io.BytesIO(data) if data is not None else source, max_array_bytes)
    wanted = [k for k in headers if keys is None or k in set(keys)]
    try:
        with np.load(io.BytesIO(data) if data is not None else source, allow_pickle=False) as z:
            return {k: z[k] for k in wanted}
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
    if "\0" in name:
        return "contains a NUL byte"
    return None


def zip_directory_size(path: str | Path) -> tuple[int, int]:
    """(entries, central directory bytes) of a ``.zip`` from its end records, read before
    ``zipfile`` parses (and holds in memory) the whole directory; (-1, -1) when no end
    record is found (``zipfile`` then reports the archive as invalid)."""
    with open(path, "rb") as f:
        f.seek(0, 2)
        size = f.tell()
        tail_len = min(size, 22 + 65535)
        f.seek(size - tail_len)
        tail = f.read(tail_len)
        at = tail.rfind(b"PK\x05\x06")
        if at < 0 or at + 22 > len(tail):
            return -1, -1
        entries = int.from_bytes(tail[at + 10:at + 12], "little")
        cd_size = int.from_bytes(tail[at + 12:at + 16], "little")
        if entries == 0xFFFF or cd_size == 0xFFFFFFFF:       # zip64: read its end record
            loc = at - 20
            if loc >= 0 and tail[loc:loc + 4] == b"PK\x06\x07":
                f.seek(int.from_bytes(tail[loc + 8:loc + 16], "little"))
                rec = f.read(56)
                if rec[:4] == b"PK\x06\x06" and len(rec) == 56:
                    entries = int.from_bytes(rec[32:40], "little")
                    cd_size = int.from_bytes(rec[40:48], "little")
        return entries, cd_size


_READ_ERRORS = (zipfile.BadZipFile, OSError, KeyError, ValueError, EOFError, NotImplementedError, RuntimeError,
                zlib.error)


class Submission:
    """Read access to a submission directory or ``.zip`` (never extracted).

    ``problems`` lists what was wrong with the container itself (unsafe or repeated zip
    members, links leaving the folder, special files, unreadable ``submission.json``);
    ``meta`` is the parsed ``submission.json`` (None when missing or invalid); ``ids`` the
    sample ids found. Only regular files are read (a FIFO, socket or device never blocks).
    ``limits`` (:class:`SubmissionLimits`, from the store's test split) bounds what is read
    per file; without it, ``max_array_bytes`` per file. Use as a context manager, or call
    :meth:`close`.
    """

    def __init__(self, path: str | Path, max_array_bytes: int = MAX_ARRAY_BYTES,
                 limits: SubmissionLimits | None = None):
        self.path = Path(path)
        self.max_array_bytes = int(max_array_bytes)
        self.limits = limits
        self.problems: list[Problem] = []
        self.meta: dict | None = None
        self._zip: zipfile.ZipFile | None = None
        self._files: dict[str, object] = {}       # id -> Path or ZipInfo
        self._json: object = None
        self._claimed: dict[str, int] = {}       # id -> bytes its headers claim
        self._last: tuple[str, bytes] | None = None   # the last file read (id, bytes)
        try:
            st = self.path.stat()
        except OSError:
            st = None
        if st is not None and stat.S_ISDIR(st.st_mode):
            self.kind = "directory"
            self._scan_dir()
        elif st is not None and stat.S_ISREG(st.st_mode):
            self.kind = "zip"
            self._scan_zip()
        elif st is not None:
            self.kind = "special"
            self.problems.append(Problem("*", "path", f"{self.path} is neither a folder nor a regular file "
                                                      "(a FIFO, socket or device?): not read"))
        else:
            self.kind = "missing"
            self.problems.append(Problem("*", "path", f"no submission at {self.path} (expected a folder or a .zip)"))
        self._read_meta()

    @property
    def _max_files(self) -> int:
        return self.limits.max_files if self.limits is not None else 1_000_000

    def budget(self, sid: str) -> int:
        """Bytes the arrays of ``samples/<sid>.npz`` may claim (the id's budget)."""
        if self.limits is not None and sid in self.limits.per_id_bytes:
            return self.limits.for_id(sid)
        return self.max_array_bytes

    # -- containers
    def _scan_dir(self) -> None:
        root = self.path.resolve()
        js = self.path / SUBMISSION_JSON
        self._json = js if js.exists() or js.is_symlink() else None
        if self._json is not None and not self._inside(js, root):
            self.problems.append(Problem("*", SUBMISSION_JSON, "is a link leaving the submission folder: not read"))
            self._json = None
        samples = self.path / SAMPLES_DIR
        if not samples.is_dir():
            return
        if not self._inside(samples, root):
            self.problems.append(Problem("*", SAMPLES_DIR, "is a link leaving the submission folder: not read"))
            return
        for n, p in enumerate(sorted(samples.iterdir())):
            if n >= self._max_files:
                self.problems.append(Problem("*", SAMPLES_DIR, f"more than {self._max_files} entries (2 per test id "
                                                               "+ 64): the rest were not read"))
                break
            if p.name.startswith("."):
                continue
            if p.suffix != ".npz":
                self.problems.append(Problem("*", SAMPLES_DIR, f"ignored {p.name!r}: not an .npz", "warning"))
                continue
            if not self._inside(p, root):
                self.problems.append(Problem(p.stem, "file", "is a link leaving the submission folder: not read"))
                continue
            try:
                mode = p.stat().st_mode
            except OSError as e:
                self.problems.append(Problem(p.stem, "file", f"cannot be read: {e.strerror or e}"))
                continue
            if not stat.S_ISREG(mode):
                self.problems.append(Problem(p.stem, "file", "is not a regular file (a FIFO, socket, device or "
                                                             "folder): not read"))
                continue
            self._files[p.stem] = p

    @staticmethod
    def _inside(p: Path, root: Path) -> bool:
        try:
            p.resolve().relative_to(root)
            return True
        except (ValueError, OSError, RuntimeError):
            return False

    def _scan_zip(self) -> None:
        try:
            entries, cd_size = zip_directory_size(self.path)
            if cd_size > MAX_ZIP_DIRECTORY_BYTES or entries > self._max_files + 2:
                self.problems.append(Problem("*", "zip", f"{self.path.name}: {entries} entries "
                                                         f"({_fmt_bytes(max(cd_size, 0))} of directory): over the "
                                                         f"limit of {self._max_files} files; not read"))
                return
            self._zip = zipfile.ZipFile(self.path)
        except (zipfile.BadZipFile, OSError, ValueError, EOFError) as e:
            self.problems.append(Problem("*", "path", f"{self.path.name}: neither a folder nor a valid .zip ({e})"))
            self._zip = None
            return
        safe, seen = [], {}
        for info in self._zip.infolist():
            why = _unsafe_member(info.filename)
            if why is None and stat.S_ISLNK(info.external_attr >> 16):
                why = "is a symbolic link"
            if why is None and info.flag_bits & 0x1:
                why = "is encrypted"
            if why:
                self.problems.append(Problem("*", "zip", f"member {info.filename!r} {why}: rejected, not read"))
                continue
            if info.is_dir():
                continue
            seen[info.filename] = seen.get(info.filename, 0) + 1
            safe.append(info)
        dup = {n for n, c in seen.items() if c > 1}
        for name in sorted(dup):
            leaf = PurePosixPath(name).name
            sid = leaf[:-4] if leaf.endswith(".npz") else "*"
            self.problems.append(Problem(sid, "file" if sid != "*" else "zip",
                                         f"member {name!r} appears {seen[name]} times in the zip: refused (which "
                                         "copy counts would be up to the reader)"))
        safe = [i for i in safe if i.filename not in dup]
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
        if dup & {f"{prefix}{SUBMISSION_JSON}"}:
            self._json = "duplicate"

    def _read_meta(self) -> None:
        if self.kind in ("missing", "special") or (self.kind == "zip" and self._zip is None):
            return
        if self._json == "duplicate":
            return      # already reported
        if self._json is None:
            self.problems.append(Problem("*", SUBMISSION_JSON, f"missing: the submission needs a {SUBMISSION_JSON}"))
            return
        try:
            if isinstance(self._json, zipfile.ZipInfo):
                if self._json.file_size > MAX_JSON_BYTES:
                    raise SubmissionError(f"{_fmt_bytes(self._json.file_size)}, over the "
                                          f"{_fmt_bytes(MAX_JSON_BYTES)} limit")
                raw = self._zip.read(self._json)
            else:
                raw = read_regular_file(self._json, MAX_JSON_BYTES, SUBMISSION_JSON)
            meta = load_json_bytes(raw, SUBMISSION_JSON)
            if not isinstance(meta, dict):
                raise SubmissionError("expected a JSON object")
            self.meta = meta
        except _READ_ERRORS as e:
            self.problems.append(Problem("*", SUBMISSION_JSON, f"not readable: {_reason(e)}"))

    # -- access
    @property
    def ids(self) -> list[str]:
        return sorted(self._files)

    def _source(self, sid: str) -> bytes:
        """The bytes of ``samples/<sid>.npz`` within the id's budget; the last file read is
        kept, so checking its headers and then loading it reads it once."""
        if self._last is not None and self._last[0] == sid:
            return self._last[1]
        ref = self._files[sid]
        limit = self.budget(sid) + FILE_OVERHEAD_BYTES
        try:
            if isinstance(ref, zipfile.ZipInfo):
                if ref.file_size > limit:
                    raise SubmissionError(f"samples/{sid}.npz is {_fmt_bytes(ref.file_size)}, over this id's "
                                          f"{_fmt_bytes(limit)} budget: not read")
                data = self._zip.read(ref)
            else:
                data = read_regular_file(ref, limit, f"samples/{sid}.npz")
        except SubmissionError:
            raise
        except _READ_ERRORS as e:
            raise SubmissionError(f"could not read the file: {_reason(e)}") from None
        self._last = (sid, data)
        return data

    def headers(self, sid: str) -> dict[str, ArrayHeader]:
        """Array headers of ``samples/<sid>.npz`` (no data loaded); ``SubmissionError``."""
        headers = npz_headers(self._source(sid), self.budget(sid))
        if sid not in self._claimed:
            self._claimed[sid] = sum(h.nbytes for h in headers.values())
            total = sum(self._claimed.values())
            if self.limits is not None and total > self.limits.total_bytes:
                raise SubmissionError(f"the submission's arrays claim {_fmt_bytes(total)} up to this file, over "
                                      f"the whole-submission budget of {_fmt_bytes(self.limits.total_bytes)}")
        return headers

    def load(self, sid: str, keys: Iterable[str] | None = KNOWN_ARRAYS) -> dict[str, np.ndarray]:
        """Arrays of ``samples/<sid>.npz`` (safe loading, see :func:`load_npz`); by default
        only the known arrays (others are never loaded)."""
        return load_npz(self._source(sid), self.budget(sid), keys)

    def close(self) -> None:
        self._last = None
        if self._zip is not None:
            self._zip.close()
            self._zip = None

    def __enter__(self) -> "Submission":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _reason(e: BaseException) -> str:
    """One line for a read error (zip, zlib, OS, JSON)."""
    if isinstance(e, NotImplementedError):
        return f"unsupported zip feature ({e})"
    if isinstance(e, RuntimeError) and "encrypted" in str(e):
        return f"encrypted member ({e})"
    if isinstance(e, zlib.error):
        return f"corrupt compressed data ({e})"
    if isinstance(e, KeyError):
        return f"missing member {e.args[0] if e.args else ''}"
    return str(e) if isinstance(e, (ValueError, zipfile.BadZipFile)) else f"{type(e).__name__}: {e}"


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


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


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
    if _is_number(fps) and not (math.isfinite(fps) and fps > 0):
        out.append(Problem("*", SUBMISSION_JSON, f"field 'fps' must be a positive finite number, got {fps!r}"))
    elif _is_number(fps) and abs(float(fps) - store_fps) > 1e-6:
        out.append(Problem("*", SUBMISSION_JSON, f"fps {fps} but the store is evaluated at {store_fps:g} fps: "
                                                 "resample by time (not by dropping every n-th frame) first"))
    if protocol is not None and abs(protocol.fps - store_fps) > 1e-6:
        out.append(Problem("*", "protocol", f"protocol {protocol.ref} evaluates at {protocol.fps:g} fps but the "
                                            f"store holds {store_fps:g} fps clips"))
    return out


def _expect_shape(h: ArrayHeader | None, tail: tuple, name: str, sid: str, dtype: str | None = None) -> list[Problem]:
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
    elif h.dtype not in ACCEPTED_DTYPES:
        out.append(Problem(sid, name, f"expected float32 or float64, got {h.dtype} (half precision, extended "
                                      "precision, integer and complex arrays are not accepted)"))
    return out


@dataclass(frozen=True)
class ClipContext:
    """What checking one sample file needs from the store and the submission."""

    gt_frames: int
    has_object: bool
    fps: float
    uses_gt_length: bool
    max_samples: int
    mode: str = "clean"            # representation mode used to encode (hoi269 clean|legacy)


def _check_clip(sub: Submission, sid: str, ctx: ClipContext) -> tuple[list[Problem], int | None, str | None]:
    """Problems of one sample file, its K (None when unknown) and the up axis its joints
    suggest (None when y-up or undecided)."""
    try:
        headers = sub.headers(sid)
    except SubmissionError as e:
        return [Problem(sid, "file", str(e))], None, None
    probs: list[Problem] = []
    for k in headers:
        if k not in KNOWN_ARRAYS:
            probs.append(Problem(sid, k, f"unexpected array {k!r} (ignored); known: {', '.join(KNOWN_ARRAYS)}",
                                 "warning"))
    if "joints" not in headers:
        probs.append(Problem(sid, "joints", "missing: every sample file needs joints (K, T, 22, 3)"))
    if ctx.has_object:
        if "obj_trans" not in headers:
            probs.append(Problem(sid, "obj_trans", "missing: the object's translation (K, T, 3) is required"))
        if "obj_rot" not in headers and "obj_rotvec" not in headers:
            probs.append(Problem(sid, "obj_rot", "missing: give obj_rot (K, T, 3, 3) or obj_rotvec (K, T, 3)"))
        if "obj_rot" in headers and "obj_rotvec" in headers:
            probs.append(Problem(sid, "obj_rot", "both obj_rot and obj_rotvec given: give exactly one"))
    else:       # human-only clip (RICH): joints only; object arrays are checked but measure nothing
        for k in ("obj_rot", "obj_rotvec", "obj_trans"):
            if k in headers:
                probs.append(Problem(sid, k, "the ground-truth clip has no object (human-only store): this "
                                             "array is not used by any metric", "warning"))
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
    gt, fps = ctx.gt_frames, ctx.fps
    if K is not None:
        if K > ctx.max_samples:
            probs.append(Problem(sid, "joints", f"K = {K} samples per prompt, over the protocol's cap of "
                                                f"{ctx.max_samples} (no metric uses more): not loaded"))
            return probs, K, None
        if T < 2:
            probs.append(Problem(sid, "joints", f"{T} frame(s): at least 2 are needed"))
        elif ctx.uses_gt_length and T != gt:
            probs.append(Problem(sid, "joints", f"{T} frames, but submission.json says uses_gt_length and the "
                                                f"ground truth has {gt}"))
        elif T > max_frames(gt, fps):
            probs.append(Problem(sid, "joints", f"{T} frames, more than max(4x, +10 s) the ground truth's {gt} at "
                                                f"{fps:g} fps: wrong frame rate?"))
        elif not (gt / 2 <= T <= 2 * gt):
            probs.append(Problem(sid, "joints", f"{T} frames vs {gt} in the ground truth (outside 0.5x-2x)",
                                 "warning"))
    ok = [k for k in present if k not in bad]
    if not ok or K is None or any(p.severity == "error" and p.field == "joints" for p in probs):
        return probs, K, None
    try:
        arrays = sub.load(sid, ok)
    except SubmissionError as e:
        return probs + [Problem(sid, "file", str(e))], K, None
    value_probs, up = check_arrays(sid, arrays, ctx)
    return probs + value_probs, K, up


def check_arrays(sid: str, arrays: Mapping[str, np.ndarray], ctx: ClipContext) -> tuple[list[Problem], str | None]:
    """Value checks of one sample file's arrays (shapes already checked): finite values,
    plausibility bounds per sample and per frame, rotations, and that every sample encodes
    to finite features (what evaluate computes). Returns (problems, up-axis guess)."""
    probs: list[Problem] = []
    good = {}
    for k, a in arrays.items():
        nonfinite = ~np.isfinite(a)
        if nonfinite.any():
            first = np.argwhere(nonfinite)[0]
            probs.append(Problem(sid, k, f"{int(nonfinite.sum())} non-finite value(s) (NaN or inf), first at index "
                                         f"{tuple(int(i) for i in first)}"))
            continue
        bound = _VALUE_BOUNDS.get(k)          # obj_rot: checked as rotations below
        if bound is not None:
            limit, unit = bound
            big = np.abs(a) > limit
            if big.any():
                first = tuple(int(i) for i in np.argwhere(big)[0])
                probs.append(Problem(sid, k, f"{int(big.sum())} value(s) beyond +-{limit:g} ({unit}), "
                                             f"first {float(a[first]):.3g} at index {first}: implausible"))
                continue
        good[k] = a
    up = None
    finite = dict(good)          # finite and within the bounds: the object check can use the joints
    if "joints" in good:
        jp, up = _check_joints(sid, good["joints"], ctx.fps)
        probs += jp
        if any(p.severity == "error" for p in jp):
            good.pop("joints")
    if "obj_rot" in good:
        rp = _check_rotations(sid, good["obj_rot"])
        probs += rp
        if rp:
            good.pop("obj_rot")
    if "obj_trans" in good and "joints" in finite:
        tp = _check_object_trans(sid, good["obj_trans"], finite["joints"], ctx.fps)
        probs += tp
        if tp:
            good.pop("obj_trans")
    if not any(p.severity == "error" for p in probs):
        probs += _check_encodes(sid, good, ctx)
    return probs, up


def _check_joints(sid: str, joints: np.ndarray, fps: float) -> tuple[list[Problem], str | None]:
    """Units per sample (body height from bone lengths), per frame (no frame's skeleton
    outside the height range), root speed per frame; the up axis the feet suggest."""
    from ..core.skeleton import PARENTS, SMPL_REST_JOINTS
    J = joints.astype(np.float64)
    par = np.array(PARENTS[1:])
    ref = np.linalg.norm(SMPL_REST_JOINTS[1:] - SMPL_REST_JOINTS[par], axis=-1).sum()
    frame_h = MEAN_BODY_HEIGHT_M * np.linalg.norm(J[..., 1:, :] - J[..., par, :], axis=-1).sum(-1) / ref  # (K, T)
    heights = np.median(frame_h, axis=1)
    lo, hi = BODY_HEIGHT_RANGE_M
    worst_k = int(np.argmax(np.abs(np.log(np.maximum(heights, 1e-12) / MEAN_BODY_HEIGHT_M))))
    worst = heights[worst_k]
    if not (lo <= worst <= hi):
        hint = " (millimetres?)" if worst > 300 else " (centimetres?)" if worst > 30 else ""
        return [Problem(sid, "joints", f"implausible units: sample {worst_k}'s bone lengths give a body "
                                       f"{worst:.3g} m tall (expected {lo}-{hi} m){hint}")], None
    out_frames = (frame_h < lo / 2) | (frame_h > 2 * hi)
    if out_frames.any():
        k, t = (int(i) for i in np.argwhere(out_frames)[0])
        return [Problem(sid, "joints", f"{int(out_frames.sum())} frame(s) whose skeleton is implausibly sized; "
                                       f"first sample {k} frame {t}: {frame_h[k, t]:.3g} m tall (the sample's "
                                       f"median is {heights[k]:.3g} m)")], None
    if J.shape[1] > 1:
        speed = np.linalg.norm(np.diff(J[:, :, 0], axis=1), axis=-1) * fps
        if speed.max() > MAX_SPEED_MPS:
            k, t = (int(i) for i in np.unravel_index(np.argmax(speed), speed.shape))
            return [Problem(sid, "joints", f"the pelvis moves {speed[k, t]:.3g} m/s between frames {t} and {t + 1} "
                                           f"of sample {k} (limit {MAX_SPEED_MPS:g} m/s): implausible")], None
    # Up axis: along the true up axis the lowest joint is an ankle or foot in nearly every
    # frame (standing, walking, sitting, kicking); along a horizontal axis it is arbitrary.
    feet = np.array([7, 8, 10, 11])
    frac = {}
    for a, axis in enumerate("xyz"):
        for sign in (1, -1):
            frac[("" if sign > 0 else "-") + axis] = float(np.isin((sign * J[..., a]).argmin(-1), feet).mean())
    best = max(frac, key=frac.get)
    if best != "y" and frac[best] >= 0.8 and frac["y"] < 0.5:
        return [Problem(sid, "joints", f"looks {best}-up: the feet are the lowest joints along {best} in "
                                       f"{100 * frac[best]:.0f}% of frames but along y in {100 * frac['y']:.0f}%; "
                                       "hoibench is y-up", "warning")], best
    return [], None


def _check_object_trans(sid: str, trans: np.ndarray, joints: np.ndarray, fps: float) -> list[Problem]:
    """Object translation units per sample (median distance to the pelvis), per frame
    (maximum distance) and object speed per frame."""
    dist = np.linalg.norm(trans.astype(np.float64) - joints[:, :, 0].astype(np.float64), axis=-1)   # (K, T)
    med = np.median(dist, axis=1)
    if med.max() > MAX_OBJECT_DISTANCE_M:
        k = int(np.argmax(med))
        return [Problem(sid, "obj_trans", f"the object is {med[k]:.3g} m from the pelvis (median over sample {k}): "
                                          "implausible units (centimetres?)")]
    if dist.max() > MAX_OBJECT_DISTANCE_FRAME_M:
        k, t = (int(i) for i in np.unravel_index(np.argmax(dist), dist.shape))
        return [Problem(sid, "obj_trans", f"the object is {dist[k, t]:.3g} m from the pelvis at sample {k} frame "
                                          f"{t} (limit {MAX_OBJECT_DISTANCE_FRAME_M:g} m): implausible")]
    if trans.shape[1] > 1:
        speed = np.linalg.norm(np.diff(trans.astype(np.float64), axis=1), axis=-1) * fps
        if speed.max() > MAX_SPEED_MPS:
            k, t = (int(i) for i in np.unravel_index(np.argmax(speed), speed.shape))
            return [Problem(sid, "obj_trans", f"the object moves {speed[k, t]:.3g} m/s between frames {t} and "
                                              f"{t + 1} of sample {k} (limit {MAX_SPEED_MPS:g} m/s): implausible")]
    return []


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


def encode_sample(arrays: Mapping[str, np.ndarray], k: int, mode: str, fps: float) -> np.ndarray:
    """Features evaluate embeds for sample ``k``: hoi269 rows when the object pose is given,
    hml263 rows otherwise (``mode``: ``clean`` | ``legacy``)."""
    from ..representations import hml263, hoi269
    joints = arrays["joints"][k]
    if "obj_trans" in arrays and ("obj_rot" in arrays or "obj_rotvec" in arrays):
        rot = arrays["obj_rot"][k] if "obj_rot" in arrays else arrays["obj_rotvec"][k]
        return hoi269.encode(joints, rot, arrays["obj_trans"][k], mode=mode, fps=fps)
    return hml263.encode(joints, mode=mode, fps=fps)


def _check_encodes(sid: str, arrays: Mapping[str, np.ndarray], ctx: ClipContext) -> list[Problem]:
    if "joints" not in arrays or (ctx.has_object and "obj_trans" not in arrays):
        return []
    for k in range(len(arrays["joints"])):
        try:
            feats = encode_sample(arrays, k, ctx.mode, ctx.fps)
        except (ValueError, FloatingPointError, np.linalg.LinAlgError) as e:
            return [Problem(sid, "joints", f"sample {k} cannot be encoded: {e}")]
        if not np.isfinite(feats).all():
            t = int(np.argwhere(~np.isfinite(feats))[0][0])
            return [Problem(sid, "joints", f"sample {k} encodes to non-finite features from frame {t} (a "
                                           "degenerate pose: coincident hips or shoulders?)")]
    return []


def submission_context(st, protocol, split: str = "test") -> tuple[dict, float, int, str]:
    """(test rows by id, store fps, K cap, hoi269 mode) for a store and an optional protocol."""
    rows = {c["id"]: c for c in st.manifest["clips"] if c["split"] == split}
    fps = float(st.manifest["config"]["fps"])
    if protocol is None:        # the store's default protocol fixes the K cap when it exists
        from ..tracks.protocol import default_protocol
        protocol = default_protocol(st.manifest)
    cap = protocol.max_samples_per_prompt if protocol is not None else DEFAULT_MAX_SAMPLES_PER_PROMPT
    mode = "legacy" if str(st.manifest["config"].get("mode", "clean")).startswith("legacy") else "clean"
    return rows, fps, int(cap), mode


#: a submission-wide up-axis error needs at least this many clips agreeing, and a majority
UP_AXIS_MIN_CLIPS = 3


def validation_report(sub, store, split: str = "test", protocol=None,
                      max_array_bytes: int | None = None) -> ValidationReport:
    """Validate ``sub`` (path or :class:`Submission`) against ``store`` (path or
    :class:`hoibench.datasets.store.Store`); never raises on a broken submission. See :func:`validate`."""
    from ..datasets.store import Store

    st = store if isinstance(store, Store) else Store(store)
    if protocol is not None and not hasattr(protocol, "fps"):
        from ..tracks.protocol import get_protocol
        protocol = get_protocol(protocol)
    rows, fps, cap, mode = submission_context(st, protocol, split)
    limits = limits_for(rows, fps, cap)
    if max_array_bytes is not None:
        limits = SubmissionLimits({k: min(v, max_array_bytes) for k, v in limits.per_id_bytes.items()},
                                  min(limits.total_bytes, max_array_bytes * max(1, len(rows))), cap, limits.max_files)
    own = not isinstance(sub, Submission)
    s = Submission(sub, limits=limits) if own else sub
    if not own and s.limits is None:
        s.limits = limits
    try:
        problems = list(s.problems)
        problems += _check_meta(s.meta, fps, protocol)
        flags = (s.meta or {}).get("flags", {}) if isinstance((s.meta or {}).get("flags", {}), dict) else {}
        test_ids = sorted(rows)
        found = set(s.ids)
        for sid in test_ids:
            if sid not in found and not any(p.id == sid for p in problems):
                problems.append(Problem(sid, SAMPLES_DIR, f"missing: no {SAMPLES_DIR}/{sid}.npz"))
        for sid in sorted(found - set(rows)):
            why = f"not a valid id ({ID_RULE})" if not is_valid_id(sid) else \
                f"not in the {split!r} split of dataset {st.manifest.get('dataset', '?')!r}"
            problems.append(Problem(sid, SAMPLES_DIR, f"extra file: {why} (not read)"))
        refused = {p.id for p in problems if p.severity == "error" and p.id != "*"}
        valid, ks, ups = [], {}, {}
        for sid in test_ids:
            if sid not in found or sid in refused:
                continue
            ctx = ClipContext(int(rows[sid]["frames"]), bool(rows[sid].get("object")), fps,
                              bool(flags.get("uses_gt_length", False)) is True, cap, mode)
            probs, K, up = _check_clip(s, sid, ctx)
            problems += probs
            if K is not None:
                ks[sid] = K
            if up is not None:
                ups[sid] = up
            if not any(p.severity == "error" for p in probs):
                valid.append(sid)
        kvals = sorted(set(ks.values()))
        spp = flags.get("samples_per_prompt")
        if len(kvals) > 1:
            problems.append(Problem("*", SAMPLES_DIR, f"samples per prompt differ between files: K in {kvals}"))
        elif kvals and isinstance(spp, int) and not isinstance(spp, bool) and spp != kvals[0]:
            problems.append(Problem("*", SUBMISSION_JSON, f"flags.samples_per_prompt is {spp} but the files hold "
                                                          f"K = {kvals[0]}"))
        if ups:
            axis, n = max(((a, sum(1 for u in ups.values() if u == a)) for a in set(ups.values())), key=lambda x: x[1])
            if n >= min(UP_AXIS_MIN_CLIPS, len(ks)) and n > len(ks) / 2:
                problems.append(Problem("*", "joints", f"{n} of {len(ks)} sample files look {axis}-up (their feet "
                                                       f"are the lowest joints along {axis}, not y): hoibench is y-up; "
                                                       "rotate the motions (and objects) into y-up first"))
        if protocol is not None and kvals and kvals[0] <= protocol.mm_pairs:
            problems.append(Problem("*", SAMPLES_DIR, f"K = {kvals[0]} sample(s) per prompt: MultiModality needs "
                                                      f"{protocol.mm_samples} and will not be computed", "warning"))
        problems.sort(key=lambda p: (p.id != "*", p.id, p.field, p.message))
        return ValidationReport(problems, test_ids, valid, kvals[0] if len(kvals) == 1 else None)
    finally:
        if own:
            s.close()


def validate(sub, store, split: str = "test", protocol=None,
             max_array_bytes: int | None = None) -> list[Problem]:
    """Every problem of a submission at once (errors and warnings), sorted by id and field.

    Checks: the container (zip member paths, links, repeated members, special files),
    ``submission.json`` fields and types (strict JSON: no NaN), fps against the store, ids
    against the store's ``split`` (missing, extra, the id rule), per file: readable safely
    within its byte budget (no pickles, no oversized, negative or empty dimensions, no
    repeated arrays), required arrays, shapes, dtypes (joints float32; others float32 or
    float64), K within the protocol's cap, consistent K and T, finite values, plausibility
    bounds (|coordinate| <= 1 km, pelvis and object <= 50 m/s, object <= 100 m from the
    pelvis in every frame), plausible units (body height 0.5-3 m per sample and no frame
    outside 0.25-6 m; object within 20 m of the pelvis, median per sample), y-up (an error
    when most files look x- or z-up), lengths (>= 2 frames; equal to the ground truth's
    when ``uses_gt_length``; at most max(4x, +10 s); a warning outside 0.5x-2x), object
    rotation matrices (orthonormal within 1e-3, det > 0), and every sample encodes to finite
    features. A submission is complete only when no problem is an error.
    """
    return validation_report(sub, store, split, protocol, max_array_bytes).problems


# ====================================================================== writing
def check_output_free(out: str | Path, as_zip: bool) -> None:
    """``FileExistsError`` unless ``out`` is free: a ``.zip`` path that does not exist, or a
    folder that does not exist or is empty. A submission never overwrites or mixes with
    other files (a stale ``samples/`` file would join the submission)."""
    out = Path(out)
    if as_zip:
        if out.exists() or out.is_symlink():
            raise FileExistsError(f"{out}: already exists; a submission never overwrites a file: choose another --out")
    elif out.exists() or out.is_symlink():
        if not out.is_dir():
            raise FileExistsError(f"{out}: exists and is not a folder; choose another --out")
        if any(out.iterdir()):
            raise FileExistsError(f"{out}: not empty; a submission is written into a new or empty folder only "
                                  f"(delete it or choose another --out)")


def write_submission(out: str | Path, meta: Mapping, samples: Iterable[tuple[str, Mapping[str, np.ndarray]]]
                     | Mapping[str, Mapping[str, np.ndarray]], as_zip: bool = False) -> Path:
    """Write a submission folder (or ``.zip`` when ``as_zip``): ``submission.json`` and
    ``samples/<id>.npz`` (byte-reproducible, no pickles). Atomic per file (the zip as a
    whole). Returns the path written."""
    out = Path(out)
    check_output_free(out, as_zip)
    items = samples.items() if isinstance(samples, Mapping) else samples
    files: dict[str, bytes] = {SUBMISSION_JSON: (json.dumps(dict(meta), indent=2, sort_keys=True) + "\n").encode()}
    for sid, arrays in items:
        check_id(str(sid), "sample id")
        files[f"{SAMPLES_DIR}/{sid}.npz"] = npz_bytes({k: np.asarray(v) for k, v in arrays.items()})
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
    from ..datasets.store import Store

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
    p = Path(sub)
    if not (p.is_dir() or p.is_file()):
        what = "does not exist" if not p.exists() else "is neither a folder nor a regular file"
        print(f"hoibench validate: error: {sub}: {what} (expected a submission folder or .zip)", file=sys.stderr)
        return 2
    try:
        rep = validation_report(sub, data, split, protocol)
    except (FileNotFoundError, KeyError, ValueError) as e:
        print(f"hoibench validate: error: {e.args[0] if isinstance(e, KeyError) else e}", file=sys.stderr)
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
        print(f"hoibench submission: error: {e.args[0] if isinstance(e, KeyError) else e}", file=sys.stderr)
        return 2
    print(f"wrote {path} ({'zip' if as_zip else 'folder'}; ground truth of split {split!r})")
    return 0


__all__ = ["Problem", "SubmissionError", "ArrayHeader", "Submission", "ValidationReport", "npz_headers", "load_npz",
           "validate", "validation_report", "write_submission", "from_store", "main_validate",
           "main_submission_from_store", "SUBMISSION_JSON", "SAMPLES_DIR", "MAX_ARRAY_BYTES"]
