"""Reading a submission safely: the format's file names and byte budgets, safe ``.npz``
parsing, and the guarded reader :class:`Submission` (a folder or a ``.zip`` read in place).

Nothing here unpickles or trusts sizes: every member's ``.npy`` header is parsed before any
data is loaded (:func:`npz_headers`), and what is read per file and per submission is bounded
by :class:`SubmissionLimits`. The format itself is described in
:mod:`hoibench.scoring.submission`.
"""
from __future__ import annotations

import io
import math
import re
import stat
import zipfile
import zlib
from dataclasses import asdict, dataclass
from pathlib import Path, PurePosixPath
from typing import Iterable, Mapping

import numpy as np

from ..core.ids import ID_PATTERN as _ID_PATTERN
from ..core.io import load_json_bytes, read_regular_file

SUBMISSION_JSON = "submission.json"
SAMPLES_DIR = "samples"
#: fallback per-file cap when no store is known (``npz_headers`` called directly)
MAX_ARRAY_BYTES = 2 * 1024 ** 3
MAX_JSON_BYTES = 1024 ** 2
#: the id rule (:mod:`hoibench.core.ids`)
ID_PATTERN = _ID_PATTERN
KNOWN_ARRAYS = ("joints", "obj_rot", "obj_rotvec", "obj_trans", "hml263", "markers")
#: values per frame of every known array (joints 66, obj_rot 9, obj_trans 3, hml263 263,
#: markers 231); obj_rotvec (3) is the alternative to obj_rot, so 9 bounds both
VALUES_PER_FRAME = 22 * 3 + 9 + 3 + 263 + 77 * 3
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
        from ..core.errors import printable
        return printable(f"{self.severity}: {self.id}: {self.field}: {self.message}")

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


def limits_for(rows: Mapping[str, Mapping], fps: float, max_samples: int,
               values_per_frame: Mapping[str, int] | None = None) -> SubmissionLimits:
    """:class:`SubmissionLimits` for test ``rows`` (id -> manifest row with ``frames``);
    ``values_per_frame``: per id, for a layout other than the single-body arrays (a
    multi-body clip: 12 per rigid body, 3 per joint of an articulated one)."""
    vpf = values_per_frame or {}
    per = {sid: max_samples * max_frames(int(r["frames"]), fps) * int(vpf.get(sid, VALUES_PER_FRAME))
           * BYTES_PER_VALUE + FILE_OVERHEAD_BYTES for sid, r in rows.items()}
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
        zf = zipfile.ZipFile(src)  # read-ok: bytes read within a budget by the caller
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
                with zf.open(info) as f:  # read-ok: a member of the in-memory archive, headers only
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
        with np.load(io.BytesIO(data) if data is not None else source, allow_pickle=False) as z:  # read-ok: headers checked above
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
    with open(path, "rb") as f:  # read-ok: the caller checked it is a regular file; reads the last 64 KiB only
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


def _check_starts_at_zero(zf: zipfile.ZipFile) -> None:
    """BadZipFile when the directory zipfile found does not describe the file from its first
    byte: a truncated submission zip ends inside one of its stored ``.npz`` members, whose own
    directory zipfile then finds at the cut (its members would read as the submission's)."""
    first = min((i.header_offset for i in zf.infolist()), default=0)
    if first != 0:
        raise zipfile.BadZipFile(f"truncated: the last directory in the file starts a member {first} bytes in, "
                                 "so it is an inner archive's, not the submission's")


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
    def unreadable(self) -> bool:
        """The submission itself could not be opened (no such path, a special file, not a zip):
        said once by its ``path`` problem, not once per test id."""
        return any(p.id == "*" and p.field == "path" for p in self.problems)

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
            self._zip = zipfile.ZipFile(self.path)  # read-ok: a regular file whose directory size was checked
            _check_starts_at_zero(self._zip)
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


class MemorySubmission:
    """A K = 1 submission held in memory, read through :class:`Submission`'s API: ``ids``,
    ``meta``, ``problems`` (none) and ``load(id, keys=None)`` (a copy of the id's arrays). What
    the metric audit scores its corrupted ground truth as."""

    problems: tuple = ()

    def __init__(self, samples: Mapping[str, Mapping[str, np.ndarray]], method: str):
        self.samples = samples
        self.ids = sorted(samples)
        self.meta = {"method": method, "flags": {"samples_per_prompt": 1, "uses_gt_length": True}}

    def load(self, sid: str, keys=None) -> dict[str, np.ndarray]:
        return dict(self.samples[sid])
