"""Multi-body evaluation protocols (``hoibench/protocols/multibody/*.yaml``): the thresholds,
voxel size, pairs, diversity frames and recognizer split a multi-body result was scored
under. Validated on load; a result records the id, version and sha256."""
from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

__all__ = ["MultiBodyProtocol", "load", "get", "list_all", "from_dict", "from_dict_plain", "METRICS", "PROTOCOLS_DIR"]

PROTOCOLS_DIR = Path(__file__).resolve().parent / "protocols" / "multibody"
METRICS = ("csr", "crr", "csiou", "iv_cm3", "id_mm", "sd", "od", "ra", "fid")


@dataclass(frozen=True)
class MultiBodyProtocol:
    id: str
    version: str
    dataset: str
    split: str
    fps: float
    representation: str
    samples_per_prompt: int
    surfaces: str
    csr_threshold_m: float
    crr_threshold_m: float
    csiou_empty_union: float
    voxel_m: float
    pair_reduction: str
    diversity_frames: int
    recognizer_split: str
    metrics: tuple
    description: str = ""
    source: str = ""

    @property
    def ref(self) -> str:
        return f"{self.id}@{self.version}"

    def to_dict(self) -> dict:
        d = {k: getattr(self, k) for k in self.__dataclass_fields__ if k != "source"}
        d["metrics"] = list(self.metrics)
        return d

    def sha256(self) -> str:
        return hashlib.sha256(json.dumps(self.to_dict(), sort_keys=True).encode()).hexdigest()


def _need(d: dict, key: str, kind, where: str):
    if key not in d:
        raise ValueError(f"{where}: missing field {key!r}")
    v = d[key]
    if kind is float and isinstance(v, int) and not isinstance(v, bool):
        v = float(v)
    if not isinstance(v, kind) or isinstance(v, bool) and kind is not bool:
        raise ValueError(f"{where}: field {key!r}: expected {kind.__name__}, got {v!r}")
    return v


def from_dict(d: dict, source: str = "<dict>") -> MultiBodyProtocol:
    w = str(source)
    if not isinstance(d, dict):
        raise ValueError(f"{w}: expected a mapping at the top level")
    c, p, dv, r = (_need(d, k, dict, w) for k in ("contact", "penetration", "diversity", "recognizer"))
    metrics = tuple(_need(d, "metrics", list, w))
    unknown = [m for m in metrics if m not in METRICS]
    if unknown:
        raise ValueError(f"{w}: field 'metrics' names unknown metrics {unknown}; known: {list(METRICS)}")
    proto = MultiBodyProtocol(
        id=_need(d, "id", str, w), version=_need(d, "version", str, w), dataset=_need(d, "dataset", str, w),
        split=_need(d, "split", str, w), fps=_need(d, "fps", float, w),
        representation=_need(d, "representation", str, w),
        samples_per_prompt=_need(d, "samples_per_prompt", int, w), surfaces=_need(d, "surfaces", str, w),
        csr_threshold_m=_need(c, "csr_threshold_m", float, f"{w}: contact"),
        crr_threshold_m=_need(c, "crr_threshold_m", float, f"{w}: contact"),
        csiou_empty_union=_need(c, "csiou_empty_union", float, f"{w}: contact"),
        voxel_m=_need(p, "voxel_m", float, f"{w}: penetration"),
        pair_reduction=_need(p, "pair_reduction", str, f"{w}: penetration"),
        diversity_frames=_need(dv, "frames", int, f"{w}: diversity"),
        recognizer_split=_need(r, "split", str, f"{w}: recognizer"),
        metrics=metrics, description=str(d.get("description", "")).strip(), source=w)
    for name in ("fps", "csr_threshold_m", "crr_threshold_m", "voxel_m"):
        if not getattr(proto, name) > 0:
            raise ValueError(f"{w}: field {name!r} must be positive")
    if proto.recognizer_split not in ("train", "all"):
        raise ValueError(f"{w}: recognizer.split: expected 'train' or 'all', got {proto.recognizer_split!r}")
    if proto.pair_reduction not in ("sum", "max", "mean"):
        raise ValueError(f"{w}: penetration.pair_reduction: expected sum, max or mean")
    return proto


def from_dict_plain(d: dict) -> MultiBodyProtocol:
    """The protocol from its :meth:`MultiBodyProtocol.to_dict` (what a worker receives)."""
    return MultiBodyProtocol(**{**d, "metrics": tuple(d["metrics"])})


def load(path: str | Path) -> MultiBodyProtocol:
    from .protocol import read_protocol_yaml
    return from_dict(read_protocol_yaml(path), str(path))


def list_all() -> list[MultiBodyProtocol]:
    return sorted((load(p) for p in PROTOCOLS_DIR.glob("*.yaml")), key=lambda x: (x.id, x.version))


def get(name: str | Path | None, dataset: str = "") -> MultiBodyProtocol:
    """By id (``multibody-synthetic``), id@version or YAML path; None: the one for
    ``dataset``."""
    if name is not None and (str(name).endswith((".yaml", ".yml")) or Path(str(name)).is_file()):
        return load(name)
    pid, _, version = str(name or dataset).partition("@")
    found = [p for p in list_all() if (p.id == pid if name else p.dataset == dataset)
             and (not version or p.version == version)]
    if not found:
        known = ", ".join(p.ref for p in list_all())
        raise KeyError(f"unknown multi-body protocol {str(name or dataset)!r}; known: {known}")
    return found[-1]
