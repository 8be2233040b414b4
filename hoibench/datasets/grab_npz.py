"""GRAB's sequence files (``.npz`` whose entries are pickled dicts of arrays) read without
running code: plain ``.npy`` members directly, pickled ones by an unpickler that allows
numpy's array rebuilders only (:mod:`hoibench.datasets.grab`, "Refused")."""
from __future__ import annotations

import io
import pickle
import zipfile
from pathlib import Path

import numpy as np

__all__ = ["MAX_NPZ_BYTES", "read_sequence_npz"]

#: the largest sequence file read, and the most its members may inflate to (bytes)
MAX_NPZ_BYTES = 4 * 1024 ** 3


def _numpy_globals() -> dict[tuple[str, str], object]:
    """The only globals a GRAB pickle may name: numpy's array / scalar rebuilders (under
    numpy 1's and numpy 2's module names), ``ndarray``, ``dtype`` and ``_codecs.encode``
    (protocol-2 pickles of bytes)."""
    import codecs
    try:
        from numpy._core import multiarray as ma, numeric as nm
    except ImportError:  # pragma: no cover - numpy 1
        from numpy.core import multiarray as ma, numeric as nm
    out: dict[tuple[str, str], object] = {("numpy", "ndarray"): np.ndarray, ("numpy", "dtype"): np.dtype,
                                          ("_codecs", "encode"): codecs.encode}
    for mod in ("numpy.core", "numpy._core"):
        out[(f"{mod}.multiarray", "_reconstruct")] = ma._reconstruct
        out[(f"{mod}.multiarray", "scalar")] = ma.scalar
        if hasattr(nm, "_frombuffer"):
            out[(f"{mod}.numeric", "_frombuffer")] = nm._frombuffer
    return out


class _ArrayUnpickler(pickle.Unpickler):
    """Unpickles numpy arrays, dicts, lists, strings and numbers; refuses every other global."""

    _allowed = None

    def find_class(self, module, name):
        if _ArrayUnpickler._allowed is None:
            _ArrayUnpickler._allowed = _numpy_globals()
        try:
            return _ArrayUnpickler._allowed[(module, name)]
        except KeyError:
            raise pickle.UnpicklingError(f"refused global {module}.{name} (a GRAB file holds numpy arrays, "
                                         "dicts, strings and numbers only)") from None


def _read_member(raw: bytes) -> np.ndarray:
    f = io.BytesIO(raw)
    version = np.lib.format.read_magic(f)
    header = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}
    if version not in header:
        raise ValueError(f".npy format version {version} not supported")
    _, _, dtype = header[version](f)
    if not dtype.hasobject:
        f.seek(0)
        return np.lib.format.read_array(f, allow_pickle=False)
    arr = _ArrayUnpickler(f, encoding="latin1").load()
    if not isinstance(arr, np.ndarray):
        raise ValueError(f"an object member unpickled to {type(arr).__name__}, not an array")
    return arr


def read_sequence_npz(path: str | Path, max_bytes: int = MAX_NPZ_BYTES) -> dict:
    """The entries of a GRAB sequence file as GRAB's ``parse_npz`` sees them: each 0-d entry
    ``.item()``-ed (strings, numbers, dicts of arrays), others as arrays. Pickled entries
    are rebuilt by an unpickler that allows numpy arrays only (see the module warning).
    The file must be a regular file of at most ``max_bytes``, its members inflating to at
    most that. ``ValueError`` naming the file otherwise."""
    from ..core.io import read_regular_file
    raw = read_regular_file(path, max_bytes, "GRAB sequence")
    out: dict = {}
    try:
        with zipfile.ZipFile(io.BytesIO(raw)) as zf:
            infos = zf.infolist()
            claimed = sum(i.file_size for i in infos)
            if claimed > max_bytes:
                raise ValueError(f"its arrays would inflate to {claimed} bytes, over the {max_bytes}-byte limit")
            for info in infos:
                if not info.filename.endswith(".npy"):
                    continue
                key = info.filename[:-4]
                try:
                    arr = _read_member(zf.read(info))
                except Exception as exc:
                    raise ValueError(f"entry {key!r}: {type(exc).__name__}: {exc}") from None
                out[key] = arr.item() if arr.shape == () else arr
    except (zipfile.BadZipFile, EOFError) as exc:
        raise ValueError(f"not a valid .npz ({exc})") from None
    return out
