"""Atomic file writes and the one guarded reader.

Writes go to a temporary file in the target folder, then a rename: a crash never leaves a
half-written file under the final name, so interrupted runs can resume by checking which
outputs exist. Files are created with the usual ``0666 & ~umask`` permissions.

Reads of files a user names or raw data holds go through :func:`read_regular_file` (and the
helpers built on it): regular files only, opened without blocking, within a byte budget per
kind of file (the ``MAX_*`` constants below). ``tests/test_guarded_reads.py`` fails on a read
elsewhere in the package that does not say why it may bypass them.
"""
from __future__ import annotations

import io
import json
import os
import stat
import tempfile
import zipfile
from pathlib import Path
from typing import Sequence

import numpy as np


#: prefix of every temporary file the toolkit writes (``.hoibench-<name>.<random>.tmp``):
#: stale-temp cleanup removes only names with it, never another program's ``.*.tmp``
TMP_PREFIX = ".hoibench-"


def current_umask() -> int:
    """The process umask, read without changing it where the platform says it
    (``/proc/self/status``), else by the set-and-restore idiom."""
    try:
        for line in read_regular_file("/proc/self/status", 1 << 20, "process status").decode().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (ValueError, IndexError):
        pass
    mask = os.umask(0o22)
    os.umask(mask)
    return mask


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` through a temporary file renamed into place; the file gets
    ``0666 & ~umask`` (``mkstemp`` alone would leave it ``0600``)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f"{TMP_PREFIX}{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        if hasattr(os, "fchmod"):
            os.fchmod(fd, 0o666 & ~current_umask())
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path


def is_atomic_tmp(name: str) -> bool:
    """Whether ``name`` is a temporary file of :func:`atomic_write_bytes`
    (``.hoibench-<name>.<random>.tmp``); another program's ``.<name>.tmp`` is not."""
    return name.startswith(TMP_PREFIX) and name.endswith(".tmp") and len(name) > len(TMP_PREFIX) + len(".tmp")


def clean_stale_tmp(*folders: str | os.PathLike) -> list[Path]:
    """Remove the temporary files an interrupted :func:`atomic_write_bytes` left in
    ``folders`` (not recursive; missing folders are skipped); returns what was removed.
    Call it when a command starts, before it writes there: a command still writing into the
    same folder would lose its temporary file."""
    removed = []
    for folder in folders:
        try:
            entries = list(os.scandir(folder))
        except (FileNotFoundError, NotADirectoryError):
            continue
        for entry in entries:
            if is_atomic_tmp(entry.name) and entry.is_file(follow_symlinks=False):
                try:
                    os.unlink(entry.path)
                except FileNotFoundError:
                    continue
                removed.append(Path(entry.path))
    return removed


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    return atomic_write_bytes(path, text.encode("utf-8"))


def strict_json_dumps(obj, **kwargs) -> str:
    """``json.dumps`` that refuses NaN and infinities (``allow_nan=False``): the JSON
    standard has no such tokens, and a number that is not finite must be caught where it
    is made, not written as ``NaN``/``Infinity`` for another tool to choke on."""
    try:
        return json.dumps(obj, allow_nan=False, **kwargs)
    except ValueError as e:
        raise ValueError(f"refusing to write JSON with a non-finite number ({e}): {_first_nonfinite(obj)}") from None


def _first_nonfinite(obj, path: str = "$") -> str:
    """Where the first NaN/inf sits in a JSON-like object (for the error message)."""
    import math
    if isinstance(obj, float) and not math.isfinite(obj):
        return f"{path} = {obj}"
    if isinstance(obj, dict):
        for k, v in obj.items():
            hit = _first_nonfinite(v, f"{path}.{k}")
            if hit:
                return hit
    elif isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            hit = _first_nonfinite(v, f"{path}[{i}]")
            if hit:
                return hit
    return ""


def atomic_write_json(path: str | os.PathLike, obj) -> Path:
    """Write ``obj`` as strict JSON (no NaN/Infinity tokens), atomically."""
    return atomic_write_text(path, strict_json_dumps(obj, indent=2, sort_keys=True) + "\n")


def atomic_save_npy(path: str | os.PathLike, array: np.ndarray) -> Path:
    buf = io.BytesIO()
    np.save(buf, np.asarray(array), allow_pickle=False)
    return atomic_write_bytes(path, buf.getvalue())


def npz_bytes(arrays: dict[str, np.ndarray], compressed: bool = True) -> bytes:
    """A byte-reproducible .npz: members in the given order, fixed 1980-01-01 timestamps
    (``numpy.savez`` stamps the current time, so its bytes change from run to run), no
    pickled objects (``np.load(..., allow_pickle=False)`` reads it)."""
    buf = io.BytesIO()
    method = zipfile.ZIP_DEFLATED if compressed else zipfile.ZIP_STORED
    with zipfile.ZipFile(buf, "w", compression=method) as zf:
        for name, value in arrays.items():
            member = io.BytesIO()
            np.save(member, np.asarray(value), allow_pickle=False)
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = method
            info.external_attr = 0o644 << 16
            zf.writestr(info, member.getvalue())
    return buf.getvalue()


def atomic_save_npz(path: str | os.PathLike, compressed: bool = True, **arrays) -> Path:
    """Write :func:`npz_bytes` atomically."""
    return atomic_write_bytes(path, npz_bytes(arrays, compressed))


def _refuse_special(mode: int, path, what: str) -> None:
    """``ValueError`` naming the kind of file when ``mode`` is not a regular file's."""
    if stat.S_ISREG(mode):
        return
    kind = ("a FIFO" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode)
            else "a device" if (stat.S_ISCHR(mode) or stat.S_ISBLK(mode))
            else "a folder" if stat.S_ISDIR(mode) else "not a regular file")
    raise ValueError(f"{path}: {what} is {kind}, not a regular file: not read")


def read_regular_file(path: str | os.PathLike, max_bytes: int | None = None, what: str = "file") -> bytes:
    """The bytes of ``path`` when it is a regular file of at most ``max_bytes``.

    Opened without blocking (``O_NONBLOCK``) and checked with ``fstat`` on the open
    descriptor, so a FIFO, socket or device never hangs the reader and cannot be swapped in
    between the check and the read. ``ValueError`` naming the path otherwise."""
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0)
    try:
        fd = os.open(path, flags)
    except OSError as e:
        raise ValueError(f"{path}: cannot open {what}: {e.strerror or e}") from None
    try:
        st = os.fstat(fd)
        _refuse_special(st.st_mode, path, what)
        if max_bytes is not None and st.st_size > max_bytes:
            raise ValueError(f"{path}: {what} is {st.st_size} bytes, over the {max_bytes}-byte limit: not read")
        chunks, left = [], st.st_size if max_bytes is None else max_bytes + 1
        while True:
            chunk = os.read(fd, min(1 << 20, max(left, 1)))
            if not chunk:
                break
            chunks.append(chunk)
            left -= len(chunk)
            if max_bytes is not None and left <= 0:
                raise ValueError(f"{path}: {what} grew past the {max_bytes}-byte limit while reading: not read")
        return b"".join(chunks)
    finally:
        os.close(fd)


def load_json_bytes(raw: bytes | str, source: str | os.PathLike) -> object:
    """Strict JSON from bytes (or text): UTF-8, no ``NaN``/``Infinity`` tokens, no key twice
    in one object, bounded nesting.
    ``ValueError`` naming ``source`` otherwise (deep nesting raises ``RecursionError`` in
    the standard parser; reported as such, never as a traceback)."""
    def _no_constants(tok: str):
        raise ValueError(f"the token {tok} is not JSON (numbers must be finite)")

    def _finite(text: str) -> float:
        value = float(text)
        if value in (float("inf"), float("-inf")):
            raise ValueError(f"the number {text[:40]} overflows a float (numbers must be finite)")
        return value
    def _unique(pairs: list) -> dict:
        out = {}
        for key, value in pairs:
            if key in out:
                raise ValueError(f"duplicate key {key!r:.60} (a JSON object names each key once)")
            out[key] = value
        return out
    try:
        text = raw.decode("utf-8") if isinstance(raw, (bytes, bytearray)) else str(raw)
        return json.loads(text, parse_constant=_no_constants, parse_float=_finite, object_pairs_hook=_unique)
    except RecursionError:
        raise ValueError(f"{source}: JSON nested too deeply: not read") from None
    except UnicodeDecodeError as e:
        raise ValueError(f"{source}: not UTF-8 text ({e.reason} at byte {e.start})") from None
    except ValueError as e:
        raise ValueError(f"{source}: not valid JSON: {e}") from None


#: budgets of the guarded reader per kind of file (bytes)
MAX_JSON_BYTES = 64 * 1024 ** 2          # manifests, split files, label files, indexes
MAX_SMALL_JSON_BYTES = 1024 ** 2         # one record: info.json, multicam2world, cards, configs, annotations
MAX_TEXT_BYTES = 16 * 1024 ** 2          # split lists, caption files, a track's about.md
MAX_CLIP_BYTES = 256 * 1024 ** 2         # one clip or sample array file of a store or export


def read_json_file(path: str | os.PathLike, max_bytes: int = MAX_JSON_BYTES, what: str = "JSON file") -> object:
    """:func:`read_regular_file` + :func:`load_json_bytes`."""
    return load_json_bytes(read_regular_file(path, max_bytes, what), path)


def read_json_object(path: str | os.PathLike, max_bytes: int = MAX_JSON_BYTES, what: str = "JSON file",
                     fields: Sequence[tuple[str, type]] = ()) -> dict:
    """The JSON object of :func:`read_json_file` with every ``(name, type)`` of ``fields``
    present and of that type; ``ValueError`` naming the file (and the field) otherwise."""
    obj = read_json_file(path, max_bytes, what)
    if not isinstance(obj, dict):
        raise ValueError(f"{path}: expected a JSON object")
    for key, t in fields:
        if not isinstance(obj.get(key), t):
            raise ValueError(f"{path}: field {key}: missing or not a JSON {t.__name__}")
    return obj


def read_text_file(path: str | os.PathLike, max_bytes: int = MAX_TEXT_BYTES, what: str = "text file") -> str:
    """UTF-8 text of a regular file of at most ``max_bytes``; ``ValueError`` naming the file."""
    raw = read_regular_file(path, max_bytes, what)
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ValueError(f"{path}: {what} is not UTF-8 text ({e.reason} at byte {e.start})") from None


def load_npy_file(path: str | os.PathLike, max_bytes: int = MAX_CLIP_BYTES, what: str = "array file"):
    """One plain ``.npy`` array (no pickles) of a regular file of at most ``max_bytes``."""
    raw = read_regular_file(path, max_bytes, what)
    try:
        arr = np.load(io.BytesIO(raw), allow_pickle=False)
    except Exception as e:  # not an .npy, pickled objects, truncated
        raise ValueError(f"{path}: {what} is not a plain .npy array ({type(e).__name__}: "
                         f"{str(e).split('.')[0][:120]})") from None
    if not isinstance(arr, np.ndarray):
        raise ValueError(f"{path}: {what} is an .npz archive, not one .npy array")
    return arr


def sha256_regular_file(path: str | os.PathLike, h=None, what: str = "file"):
    """Feed the bytes of a regular file to ``h`` (a new sha256 when None) in 1 MiB chunks,
    without a size budget (hashing holds no more than a chunk); refuses special files."""
    import hashlib
    h = hashlib.sha256() if h is None else h
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    try:
        _refuse_special(os.fstat(fd).st_mode, path, what)
        while True:
            chunk = os.read(fd, 1 << 20)
            if not chunk:
                return h
            h.update(chunk)
    finally:
        os.close(fd)


#: raw capture arrays (.npz) may hold at most this much, compressed or not: a BEHAVE
#: sequence of one hour at 30 fps holds about 70 MB
MAX_RAW_NPZ_BYTES = 512 * 1024 ** 2
#: raw mesh files (object templates)
MAX_RAW_MESH_BYTES = 1024 ** 3


def check_regular_file(path: str | os.PathLike, what: str = "file") -> Path:
    """``path`` when it is a regular file (links followed); ``ValueError`` for a FIFO,
    socket, device or folder (reading those would hang or never end)."""
    try:
        st = os.stat(path)
    except OSError as e:
        raise ValueError(f"{path}: cannot read {what}: {e.strerror or e}") from None
    _refuse_special(st.st_mode, path, what)
    return Path(path)


def load_raw_npz(path: str | os.PathLike, max_bytes: int = MAX_RAW_NPZ_BYTES, what: str = "file",
                 keys=None) -> dict:
    """Arrays of a raw ``.npz`` (no pickles) read within ``max_bytes``: the file must be
    regular and no larger, and its members' declared uncompressed sizes together no larger
    (a deflate bomb is refused before anything is inflated). ``keys``: only those members.
    ``ValueError`` naming the file."""
    raw = read_regular_file(path, max_bytes, what)
    try:
        with zipfile.ZipFile(io.BytesIO(raw)) as zf:
            infos = zf.infolist()
            claimed = sum(i.file_size for i in infos)
    except (zipfile.BadZipFile, ValueError, EOFError) as e:
        raise ValueError(f"{path}: not a valid .npz ({e})") from None
    names = [i.filename for i in infos]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ValueError(f"{path}: member {twice[0]!r} appears twice (which copy counts would be up to the "
                         "reader): not read")
    if claimed > max_bytes:
        raise ValueError(f"{path}: its arrays would inflate to {claimed} bytes, over the {max_bytes}-byte "
                         "limit for a raw file: not read")
    with np.load(io.BytesIO(raw), allow_pickle=False) as z:
        return {k: z[k] for k in z.files if keys is None or k in keys}


def atomic_save_figure(fig, path: str | os.PathLike, dpi: int = 100) -> Path:
    """A matplotlib figure as PNG, written atomically; the figure is closed."""
    import matplotlib.pyplot as plt
    buf = io.BytesIO()
    fig.savefig(buf, dpi=dpi, format="png")
    plt.close(fig)
    return atomic_write_bytes(path, buf.getvalue())


def atomic_torch_save(obj, path: str | os.PathLike) -> Path:
    """``torch.save`` through :func:`atomic_write_bytes` (a ``.<name>.*.tmp`` file renamed into
    place; leftovers are cleaned by :func:`clean_stale_tmp` when the command runs again)."""
    import torch
    buf = io.BytesIO()
    torch.save(obj, buf)
    return atomic_write_bytes(path, buf.getvalue())


def finished_output(out: str | os.PathLike, marker: str, leftovers: set[str], folders: set[str], what: str,
                    error: type[Exception]) -> bool:
    """Whether the output folder ``out`` of a training command already holds a finished result.

    True when ``out/marker`` exists (the caller verifies it); False when ``out`` is free:
    missing, empty, or holding only an interrupted run's ``leftovers`` (and ``.tmp`` files).
    ``error`` otherwise, naming what is there: ``out`` is not a folder, holds other files,
    or one of ``folders`` (leftovers that must be folders) is not one."""
    out = Path(out)
    if not out.exists():
        return False
    if not out.is_dir():
        raise error(f"{out}: exists and is not a folder; choose another --out")
    if (out / marker).exists():
        return True
    extra = sorted(p.name for p in out.iterdir() if p.name not in leftovers and ".tmp" not in p.name)
    extra = [f"{name} (a file)" for name in sorted(folders) if (out / name).exists() and not (out / name).is_dir()] \
        + extra
    if extra:
        raise error(f"{out}: not empty and not {what} (holds {', '.join(extra[:3])}{'...' if len(extra) > 3 else ''}); "
                    f"choose another --out")
    return False

