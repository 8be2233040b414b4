"""What every ``hoibench import`` format shares: its error type, the grouping of
per-sample files (``<id>.ext`` / ``<id>_<r>.ext``) and the refusal of pickled members."""
from __future__ import annotations

import re
import zipfile
from collections import defaultdict
from pathlib import Path

import numpy as np

_REP = re.compile(r"^(.*?)(?:_(\d+))?$")


class ImportProblem(ValueError):
    """An input that cannot be imported (names the file and the field)."""


def _group_files(folder: Path, ext: str, ids: list[str]) -> dict[str, list[Path]]:
    """``<id>.ext`` / ``<id>_<r>.ext`` files grouped by stem (the id when it is a test id)."""
    if not folder.is_dir():
        raise ImportProblem(f"{folder}: not a folder of {ext} files")
    idset = set(ids)
    groups: dict[str, list[tuple[int, Path]]] = defaultdict(list)
    for p in sorted(folder.glob(f"*{ext}")):
        stem = p.name[:-len(ext)]
        if stem in idset:
            groups[stem].append((0, p))
            continue
        m = _REP.match(stem)
        base, rep = m.group(1), m.group(2)
        groups[base if rep is not None else stem].append((int(rep or 0), p))
    return {k: [p for _, p in sorted(v)] for k, v in groups.items()}


def _header_dtype(f) -> np.dtype:
    """The dtype an ``.npy`` stream declares (its header only; nothing is unpickled)."""
    version = np.lib.format.read_magic(f)
    read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
    return read(f, max_header_size=1 << 20)[2]


def pickled_members(path: Path, keys=None) -> list[str]:
    """Members of the ``.npy``/``.npz`` file ``path`` whose dtype holds Python objects (read
    from the headers; ``[""]`` for a plain ``.npy``). ``keys``: only those members."""
    try:
        if zipfile.is_zipfile(path):
            with zipfile.ZipFile(path) as zf:  # read-ok: each member's .npy header only (its dtype)
                out = []
                for info in zf.infolist():
                    name = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
                    if keys is None or name in keys:
                        with zf.open(info) as f:  # read-ok: the header, not the data
                            if _header_dtype(f).hasobject:
                                out.append(name)
                return out
        with open(path, "rb") as f:  # read-ok: the .npy header only (its dtype)
            return [""] if _header_dtype(f).hasobject else []
    except (OSError, ValueError, zipfile.BadZipFile, EOFError):
        return []


def pickle_refusal(path: Path, member: str) -> ImportProblem:
    """The one-line refusal of a pickled (object-dtype) array."""
    where = f"{path}: member {member!r}" if member else f"{path}"
    how = (f"np.savez(..., {member}=np.asarray(x, dtype=np.float32))" if member
           else "np.save(..., np.asarray(x, dtype=np.float32))")
    return ImportProblem(f"{where} holds Python objects (dtype object, stored as a pickle): not read, since "
                         f"unpickling a file can run code; save it as a plain numeric array, e.g. {how}")


__all__ = ["ImportProblem", "pickled_members", "pickle_refusal"]
