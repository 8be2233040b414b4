"""Pickled ``torch.Tensor`` values read (and written) without torch and without running code.

TACO's hand files and OAKINK2's annotation files are plain pickles whose leaves include
torch tensors. A pickled CPU tensor is (``torch/_tensor.py`` ``_reduce_ex_internal``,
``torch/storage.py`` ``__reduce__``)::

    torch._utils._rebuild_tensor_v2(storage, offset, size, stride, requires_grad, hooks[, metadata])
    storage = torch.storage._load_from_bytes(<bytes of a legacy torch.save of the storage>)

and the legacy ``torch.save`` bytes are five consecutive pickles and raw data: the magic
number ``0x1950a86a20f9469cfc6c``, the protocol ``1001``, a system-info dict, the storage as a
persistent id ``('storage', torch.<Type>Storage, key, location, numel, view)``, the list of
keys, then per key an int64 element count and ``count * itemsize`` little-endian bytes.

:func:`load` unpickles with an allow-list: those two torch globals (mapped to numpy
rebuilders), ``collections.OrderedDict`` (an empty hooks argument only), ``_codecs.encode``
and numpy's array globals; any other global is refused, naming the file and the global.
The storage's ``location`` (``cpu``, ``cuda:0``) is ignored. Tensors come back as numpy
arrays (a copy in the pickled stride order). :func:`dumps` writes such pickles from numpy
arrays wrapped in :class:`Tensor` (hoibench's license-free fixtures use it).
"""
from __future__ import annotations

import codecs
import io
import pickle
import struct
from collections import OrderedDict
from pathlib import Path

import numpy as np

__all__ = ["TorchPickleError", "Tensor", "load", "loads", "dumps", "STORAGE_DTYPES"]

MAGIC_NUMBER = 0x1950A86A20F9469CFC6C
LEGACY_PROTOCOL = 1001
#: torch storage class name -> numpy dtype (little-endian).
STORAGE_DTYPES = {"FloatStorage": "<f4", "DoubleStorage": "<f8", "HalfStorage": "<f2", "LongStorage": "<i8",
                  "IntStorage": "<i4", "ShortStorage": "<i2", "ByteStorage": "u1", "CharStorage": "i1",
                  "BoolStorage": "?"}
#: largest storage accepted, bytes.
MAX_STORAGE_BYTES = 1 << 31


class TorchPickleError(ValueError):
    """A pickle that is not plain data plus torch tensors (or a malformed tensor)."""


class _StorageType:
    def __init__(self, name: str):
        self.name, self.dtype = name, np.dtype(STORAGE_DTYPES[name])


class _StorageRef:
    def __init__(self, key: str, dtype: np.dtype, numel: int, location: str):
        self.key, self.dtype, self.numel, self.location = key, dtype, numel, location


def _numpy_globals() -> dict:
    from .grab_npz import _numpy_globals as g
    return g()


class _StorageUnpickler(pickle.Unpickler):
    """The storage pickle inside a legacy blob: only ``torch.<Type>Storage`` names."""

    def find_class(self, module, name):
        if module == "torch" and name in STORAGE_DTYPES:
            return _StorageType(name)
        raise pickle.UnpicklingError(f"refused global {module}.{name} in a tensor storage")

    def persistent_load(self, pid):
        if not (isinstance(pid, tuple) and len(pid) in (5, 6) and pid[0] == "storage"
                and isinstance(pid[1], _StorageType) and isinstance(pid[2], str) and isinstance(pid[4], int)):
            raise pickle.UnpicklingError(f"unexpected persistent id {pid!r:.80}")
        return _StorageRef(pid[2], pid[1].dtype, int(pid[4]), str(pid[3]))


class _PlainUnpickler(pickle.Unpickler):
    def find_class(self, module, name):
        raise pickle.UnpicklingError(f"refused global {module}.{name} in a tensor storage header")


def _load_from_bytes(blob: bytes) -> np.ndarray:
    """A legacy ``torch.save`` blob of one storage -> 1-D numpy array."""
    if not isinstance(blob, (bytes, bytearray)):
        raise pickle.UnpicklingError("a tensor storage is not bytes")
    f = io.BytesIO(blob)
    if _PlainUnpickler(f).load() != MAGIC_NUMBER:
        raise pickle.UnpicklingError("tensor storage: wrong magic number")
    if _PlainUnpickler(f).load() != LEGACY_PROTOCOL:
        raise pickle.UnpicklingError("tensor storage: unknown protocol version")
    info = _PlainUnpickler(f).load()
    if not isinstance(info, dict) or info.get("little_endian") is not True:
        raise pickle.UnpicklingError("tensor storage: not little-endian")
    ref = _StorageUnpickler(f).load()
    keys = _PlainUnpickler(f).load()
    if not isinstance(ref, _StorageRef) or keys != [ref.key]:
        raise pickle.UnpicklingError("tensor storage: expected exactly one storage")
    head = f.read(8)
    if len(head) != 8:
        raise pickle.UnpicklingError("tensor storage: truncated element count")
    (numel,) = struct.unpack("<q", head)
    nbytes = numel * ref.dtype.itemsize
    if numel != ref.numel or numel < 0 or nbytes > MAX_STORAGE_BYTES:
        raise pickle.UnpicklingError(f"tensor storage: element count {numel} (header says {ref.numel})")
    data = f.read(nbytes)
    if len(data) != nbytes:
        raise pickle.UnpicklingError(f"tensor storage: {len(data)} bytes present, {nbytes} expected")
    return np.frombuffer(data, dtype=ref.dtype).copy()


def _rebuild_tensor_v2(storage, offset, size, stride, requires_grad=False, hooks=None, metadata=None):
    if not isinstance(storage, np.ndarray) or storage.ndim != 1:
        raise pickle.UnpicklingError("a tensor without a storage")
    if hooks:
        raise pickle.UnpicklingError("a tensor with backward hooks")
    size, stride, offset = tuple(int(s) for s in size), tuple(int(s) for s in stride), int(offset)
    if any(s < 0 for s in size) or any(s < 0 for s in stride) or offset < 0:
        raise pickle.UnpicklingError("a tensor with a negative size, stride or offset")
    last = offset + sum((n - 1) * s for n, s in zip(size, stride)) if all(size) else offset - 1
    if last >= len(storage):
        raise pickle.UnpicklingError(f"a tensor reaching element {last} of a storage of {len(storage)}")
    if not all(size):
        return np.zeros(size, storage.dtype)
    item = storage.dtype.itemsize
    view = np.lib.stride_tricks.as_strided(storage[offset:], size, tuple(s * item for s in stride), writeable=False)
    return np.array(view)


def _ordered_dict(*args):
    if args:
        raise pickle.UnpicklingError("collections.OrderedDict with contents (only empty tensor hooks are read)")
    return OrderedDict()


class _TensorUnpickler(pickle.Unpickler):
    _allowed: dict | None = None

    def find_class(self, module, name):
        if _TensorUnpickler._allowed is None:
            _TensorUnpickler._allowed = {**_numpy_globals(), ("torch._utils", "_rebuild_tensor_v2"): _rebuild_tensor_v2,
                                         ("torch.storage", "_load_from_bytes"): _load_from_bytes,
                                         ("collections", "OrderedDict"): _ordered_dict,
                                         ("_codecs", "encode"): codecs.encode}
        try:
            return _TensorUnpickler._allowed[(module, name)]
        except KeyError:
            raise pickle.UnpicklingError(f"refused global {module}.{name} (allowed: plain data, numpy arrays and "
                                         "torch tensors)") from None


def loads(data: bytes, source: str = "<bytes>"):
    """Unpickle ``data`` (see the module docstring); TorchPickleError naming ``source``."""
    try:
        return _TensorUnpickler(io.BytesIO(data), encoding="latin1").load()
    except (pickle.UnpicklingError, EOFError, ValueError, TypeError, struct.error, IndexError, KeyError,
            AttributeError) as exc:
        raise TorchPickleError(f"{source}: {exc}") from None


def load(path: str | Path, max_bytes: int = 1 << 32):
    """:func:`loads` of a file (at most ``max_bytes``)."""
    from ..core.io import read_regular_file
    path = Path(path)
    size = path.stat().st_size
    if size > max_bytes:
        raise TorchPickleError(f"{path}: {size} bytes, more than the {max_bytes} accepted")
    return loads(read_regular_file(path, max_bytes, "torch pickle"), path.name)


# --------------------------------------------------------------------------- writing
class Tensor:
    """A numpy array to be pickled as a torch tensor by :func:`dumps` (C-contiguous,
    ``location`` recorded in the storage's persistent id)."""

    def __init__(self, array, location: str = "cpu"):
        self.array, self.location = np.ascontiguousarray(array), location


class _Global:
    def __init__(self, module: str, name: str):
        self.module, self.name = module, name

    def __call__(self, *args):  # pragma: no cover - a name only (pickle requires a callable)
        raise TypeError(f"{self.module}.{self.name} is a pickle reference, not a function")


_REBUILD = _Global("torch._utils", "_rebuild_tensor_v2")
_FROM_BYTES = _Global("torch.storage", "_load_from_bytes")
_ORDERED = _Global("collections", "OrderedDict")
_STORAGE_NAME = {np.dtype(v): k for k, v in STORAGE_DTYPES.items()}


class _Writer(pickle._Pickler):  # the pure-Python pickler: GLOBAL opcodes for names torch would own
    def __init__(self, f, pid=None):
        super().__init__(f, protocol=2)
        self._pid = pid

    def persistent_id(self, obj):
        return self._pid if (self._pid is not None and obj is _STORAGE_MARK) else None

    def save(self, obj, save_persistent_id=True):
        if isinstance(obj, _Global):
            self.write(pickle.GLOBAL + f"{obj.module}\n{obj.name}\n".encode())
            return
        super().save(obj, save_persistent_id)

    def reducer_override(self, obj):
        if isinstance(obj, Tensor):
            a = obj.array
            stride = tuple(int(s // a.itemsize) for s in a.strides) if a.size else (1,) * a.ndim
            return (_REBUILD, (_storage_obj(a.reshape(-1), obj.location), 0, tuple(a.shape), stride, False,
                               _HooksArg()))
        if isinstance(obj, _HooksArg):
            return (_ORDERED, ())
        if isinstance(obj, _StorageObj):
            return (_FROM_BYTES, (obj.blob,))
        return NotImplemented


class _HooksArg:
    pass


class _StorageObj:
    def __init__(self, blob: bytes):
        self.blob = blob


_STORAGE_MARK = object()


def _dump(obj, pid=None) -> bytes:
    f = io.BytesIO()
    _Writer(f, pid).dump(obj)
    return f.getvalue()


def _storage_obj(flat: np.ndarray, location: str) -> _StorageObj:
    dt = flat.dtype.newbyteorder("<") if flat.dtype.byteorder == ">" else flat.dtype
    name = _STORAGE_NAME[np.dtype(dt)]
    key = "0"
    info = {"protocol_version": LEGACY_PROTOCOL, "little_endian": True,
            "type_sizes": {"short": 2, "int": 4, "long": 4}}
    blob = (_dump(MAGIC_NUMBER) + _dump(LEGACY_PROTOCOL) + _dump(info)
            + _dump(_STORAGE_MARK, ("storage", _Global("torch", name), key, location, int(flat.size), None))
            + _dump([key]) + struct.pack("<q", int(flat.size)) + flat.astype(dt, copy=False).tobytes())
    return _StorageObj(blob)


def dumps(obj) -> bytes:
    """Pickle ``obj`` (dicts, lists, tuples, strings, numbers, numpy arrays and :class:`Tensor`)
    as torch would pickle it with tensors in place of the :class:`Tensor` values
    (protocol 2), without importing torch. Deterministic."""
    return _dump(obj)
