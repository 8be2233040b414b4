"""Evaluation protocols: versioned YAML files that fix everything a number depends on.

One :class:`Protocol` type for every track, of three kinds. A protocol file
(``hoibench/tracks/protocols/<id>.yaml``, shipped with the package) names its ``track``
(:mod:`hoibench.tracks.registry`), which gives its kind. A ``multibody`` protocol fixes the
contact thresholds, voxel size, pair reduction, diversity frames and the recognizer's split
(docs/multibody.md). An ``interact-task`` protocol fixes one of InterAct's conditioned tasks
(``o2h``: the human from the object's motion; ``h2o``: the object from the human's), the
samples per sequence K, the metric that selects one of them and the contact threshold. A ``hoi`` protocol fixes the dataset and split, ``legacy|clean`` mode, frame rate, representation version, replications (20), seeds,
R-precision pools (32, drawn from a seeded permutation of the sorted test ids, independent
of compute batch size), diversity pairs (300; 200 on BEHAVE as HOI-Diff), MultiModality
(100 texts x 30 samples x 10 pairs) and the physical metrics' settings (body surface for
PS, contact-threshold mode, FSR thresholds). Results carry the protocol id, version and
sha256, and report every metric as the mean over replications with the 95% confidence
interval ``1.96 * std / sqrt(replications)`` (population std, as text-to-motion's
``get_metric_statistics``) -- see :func:`summarize`.

Registry: :func:`list_protocols`, :func:`get_protocol` (``"behave-clean"``,
``"behave-clean@1.1"`` or a path to a YAML file). CLI: :func:`main_protocols`
(``hoibench protocols ls`` / ``hoibench protocols show behave-clean``).

Seeds are derived, never taken from worker rank: :meth:`Protocol.seed_for` hashes
(protocol seed, purpose, replication) with ``numpy.random.SeedSequence``.
"""
from __future__ import annotations

import hashlib
import json
import sys
import copy
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Hashable, Iterable, Sequence

import numpy as np

from ..metrics import make_pools
from ..metrics.catalog import metrics_for
from ..metrics import legacy_rules
from ..metrics.physical import CD_EDGES, PS_SIGNS, PhysicalConfig

PROTOCOLS_DIR = Path(__file__).resolve().parent / "protocols"
MODES: tuple[str, ...] = ("legacy", "clean")
CI_Z = 1.96


#: the fields each kind of protocol has, in the order results list them (``to_dict``)
KIND_FIELDS: dict[str, tuple[str, ...]] = {
    "hoi": ("id", "version", "dataset", "split", "mode", "fps", "representation", "replications", "seed",
            "r_precision_pool_size", "r_precision_top_k", "r_precision_drop_last", "diversity_pairs", "mm_texts",
            "mm_samples", "mm_pairs", "physical", "metrics", "description", "changelog"),
    "multibody": ("id", "version", "dataset", "split", "fps", "representation", "samples_per_prompt", "surfaces",
                  "csr_threshold_m", "crr_threshold_m", "csiou_empty_union", "voxel_m", "pair_reduction",
                  "diversity_frames", "recognizer_split", "metrics", "description"),
    "interact-task": ("id", "version", "dataset", "split", "fps", "representation", "task", "samples_per_prompt",
                      "selection", "contact_threshold_m", "metrics", "description", "changelog"),
}
#: InterAct's tasks besides text-to-interaction: what a protocol of the ``interact-task`` kind scores
INTERACT_TASKS = ("o2h", "h2o")


@dataclass(frozen=True)
class Protocol:
    """A parsed, validated protocol file of one of two kinds (see the module docstring and
    docs/protocol.md): ``hoi`` (single-body and human-only tracks: replications, R-precision
    pools, diversity, MultiModality, physical settings) or ``multibody`` (contact thresholds,
    voxel size, pair reduction, diversity frames, recognizer split). ``track`` names the
    registry entry (:mod:`hoibench.tracks.registry`) the protocol belongs to; the content
    hash (:attr:`sha256`) covers the kind's settings (``KIND_FIELDS``)."""

    id: str
    version: str
    dataset: str
    split: str
    fps: float
    representation: str
    metrics: tuple
    kind: str = "hoi"
    track: str = ""
    description: str = ""
    changelog: tuple = ()
    source: str = field(default="", compare=False)
    # --- hoi
    mode: str | None = None
    replications: int | None = None
    seed: int | None = None
    r_precision_pool_size: int | None = None
    r_precision_top_k: int | None = None
    r_precision_drop_last: bool | None = None
    diversity_pairs: int | None = None
    mm_texts: int | None = None
    mm_samples: int | None = None
    mm_pairs: int | None = None
    physical: dict | None = None
    embedding_loop: str = "hoibench"
    #: the evaluator embeds what the physical metrics see: each clip cut to its replication-0
    #: window of ``physical.length_crop`` (ChainHOI's data loader feeds its evaluator the
    #: cropped motions); absent = whole clips
    crop_embeddings: bool = False
    #: ``{"frames": N, "drop_shorter": bool}``: every scored clip is its first N frames (ground
    #: truth and generated, for every metric); with ``drop_shorter`` a test clip of fewer than N
    #: frames is not scored (CHOIS's 120-frame windows); None = whole clips
    clip_window: dict | None = None
    #: optional top-level mappings metrics read (``physics``: :func:`hoibench.metrics.catalog.settings_keys`)
    settings: dict = field(default_factory=dict, compare=False)
    #: a preview version: scored only when named with its version (``id@version``), never the
    #: default of its id (not a setting: not hashed)
    preview: bool = field(default=False, compare=False)
    # --- multibody
    samples_per_prompt: int | None = None
    surfaces: str | None = None
    csr_threshold_m: float | None = None
    crr_threshold_m: float | None = None
    csiou_empty_union: float | None = None
    voxel_m: float | None = None
    pair_reduction: str | None = None
    diversity_frames: int | None = None
    recognizer_split: str | None = None
    # --- interact-task (samples_per_prompt above: the K the selection rule picks from)
    task: str | None = None
    #: the metric whose best value (by its catalogue direction) picks each sequence's sample
    selection: str | None = None
    contact_threshold_m: float | None = None

    # ------------------------------------------------------------------ identity
    def to_dict(self) -> dict:
        """The kind's settings (``KIND_FIELDS``), JSON-ready: what the content hash covers and
        what a worker process receives (:meth:`from_plain`)."""
        d = {k: getattr(self, k) for k in KIND_FIELDS[self.kind]}
        if self.kind == "hoi" and self.embedding_loop != "hoibench":
            d["embedding_loop"] = self.embedding_loop    # absent = hoibench's loop (older hashes unchanged)
        if self.kind == "hoi" and self.crop_embeddings:
            d["crop_embeddings"] = True                  # absent = whole clips (older hashes unchanged)
        if self.kind == "hoi" and self.clip_window:
            d["clip_window"] = dict(self.clip_window)    # absent = whole clips (older hashes unchanged)
        for key, mapping in sorted(self.settings.items()):   # absent = none (older hashes unchanged)
            d[key] = copy.deepcopy(mapping)
        d["metrics"] = list(self.metrics)
        if "changelog" in d:
            d["changelog"] = list(self.changelog)
        if "physical" in d:
            d["physical"] = copy.deepcopy(self.physical)
        return d

    @classmethod
    def from_plain(cls, d: dict, kind: str, track: str = "") -> "Protocol":
        """The protocol from its :meth:`to_dict` (what a worker process receives)."""
        from ..metrics.catalog import settings_keys
        extra = {"changelog": tuple(d["changelog"])} if "changelog" in d else {}
        settings = {k: d[k] for k in settings_keys() if k in d}
        plain = {k: v for k, v in d.items() if k not in settings}
        return cls(**{**plain, "metrics": tuple(d["metrics"]), **extra}, kind=kind, track=track, settings=settings)

    def settings_for(self, key: str) -> dict:
        """The protocol's optional ``key`` mapping (``{}`` when absent or ``key`` is empty)."""
        return copy.deepcopy(self.settings.get(key, {})) if key else {}

    @property
    def sha256(self) -> str:
        """sha256 of the canonical JSON of every field (the protocol's content hash)."""
        return hashlib.sha256(json.dumps(self.to_dict(), sort_keys=True).encode()).hexdigest()

    @property
    def ref(self) -> str:
        return f"{self.id}@{self.version}"

    def result_header(self) -> dict:
        """What a result records about its protocol."""
        head = {"protocol": self.id, "protocol_version": self.version, "protocol_sha256": self.sha256,
                "mode": self.mode, "representation": self.representation, "fps": self.fps,
                "replications": self.replications}
        if self.preview:
            head["protocol_preview"] = True
        return head

    # ------------------------------------------------------------------ seeds and draws
    def seed_for(self, purpose: str, replication: int = 0) -> int:
        """A 32-bit seed for ``purpose`` ("r_precision", "diversity", "multimodality", ...) in
        ``replication``: ``SeedSequence([seed, sha256(purpose)[:4], replication])``."""
        tag = int.from_bytes(hashlib.sha256(purpose.encode()).digest()[:4], "little")
        return int(np.random.SeedSequence([int(self.seed), tag, int(replication)]).generate_state(1)[0])

    def pools(self, ids: Sequence[Hashable], replication: int = 0) -> list[list]:
        """R-precision pools of ``replication`` (:func:`hoibench.metrics.make_pools`)."""
        return make_pools(ids, self.r_precision_pool_size, self.seed_for("r_precision", replication),
                          self.r_precision_drop_last)

    def multimodality_ids(self, ids: Sequence[Hashable], replication: int = 0) -> list:
        """The ``mm_texts`` test ids whose samples MultiModality uses (sorted; all ids when
        there are fewer)."""
        items = sorted(ids, key=lambda x: (type(x).__name__, x))
        if len(items) <= self.mm_texts:
            return items
        rng = np.random.default_rng(self.seed_for("multimodality_ids", replication))
        return sorted((items[i] for i in rng.choice(len(items), self.mm_texts, replace=False)),
                      key=lambda x: (type(x).__name__, x))

    def effective_diversity_pairs(self, n: int) -> int:
        """Pairs actually drawn from ``n`` motions: ``min(pairs, n - 1)`` (Diversity needs
        more motions than pairs); results record it next to the value."""
        return max(0, min(self.diversity_pairs, int(n) - 1))

    @property
    def max_samples_per_prompt(self) -> int:
        """K cap for submissions: ``max(replications, mm_samples)``. Replication r uses
        sample ``r mod K`` and MultiModality the first ``mm_samples``, so no metric reads a
        sample beyond this; larger files are refused before loading (docs/security.md)."""
        if self.kind == "interact-task":       # best of K: no sample beyond the protocol's K is read
            return int(self.samples_per_prompt)
        return max(int(self.replications), int(self.mm_samples))

    @staticmethod
    def sample_index(replication: int, samples_per_prompt: int) -> int:
        """Which of a submission's K samples per prompt replication r uses: ``r mod K``.
        With K = 1 every replication sees the same motions (only the pools and pairs vary)."""
        if samples_per_prompt < 1:
            raise ValueError(f"samples_per_prompt: expected >= 1, got {samples_per_prompt}")
        return int(replication) % int(samples_per_prompt)

    def physical_config(self) -> PhysicalConfig:
        """The physical settings; the optional keys (ChainHOI's rules,
        :data:`hoibench.metrics.legacy_rules.PHYSICAL_OPTIONS` and ``contact_gt_threshold_m``)
        default to the clean rules."""
        p = self.physical
        options = {k: p[k] for k in legacy_rules.PHYSICAL_OPTIONS if k in p}
        if p.get("contact_gt_threshold_m") is not None:
            options["contact_gt_threshold_m"] = float(p["contact_gt_threshold_m"])
        return PhysicalConfig(
            mode=self.mode, contact_mode=p["contact_thresholds"], body_surface=p["body_surface"],
            ocd_length_tolerance=int(p["ocd_length_tolerance_frames"]),
            fsr_height_m=float(p["fsr"]["height_m"]), fsr_displacement_m=float(p["fsr"]["displacement_m"]),
            gmd_height_m=float(p["fsr_gmd"]["height_m"]), gmd_speed_mps=float(p["fsr_gmd"]["speed_mps"]),
            gmd_window_frames=int(p["fsr_gmd"]["window_frames"]),
            vertex_contact_m=float(p["vertex_contact_m"]), floor_tolerance_m=float(p["floor_tolerance_m"]),
            floor_shift=bool(p["floor_shift"]), **options,
            **{k: p[k] for k in _PHYSICAL_OPTIONAL if k in p})   # optional keys; absent: hoibench's


# ====================================================================== loading
def _need(d: dict, key: str, kind, where: str):
    if key not in d:
        raise ValueError(f"{where}: missing field {key!r}")
    v = d[key]
    if kind is float and isinstance(v, int) and not isinstance(v, bool):
        v = float(v)
    if kind is str and isinstance(v, (int, float)) and not isinstance(v, bool):
        v = str(v)
    if not isinstance(v, kind) or (kind is int and isinstance(v, bool)):
        raise ValueError(f"{where}: field {key!r} must be {getattr(kind, '__name__', kind)}, got {v!r}")
    return v


def _crop_embeddings(d: dict, phys: dict, where: str) -> bool:
    """The optional ``crop_embeddings`` flag: a bool, and only with a ``physical.length_crop``."""
    v = d.get("crop_embeddings", False)
    if not isinstance(v, bool):
        raise ValueError(f"{where}: field 'crop_embeddings' must be true or false, got {v!r}")
    if v and phys.get("length_crop", "none") == "none":
        raise ValueError(f"{where}: field 'crop_embeddings' needs a physical.length_crop other than none")
    return v


def _clip_window(d: dict, where: str) -> dict | None:
    """The optional ``clip_window`` mapping: ``frames`` (a positive int) and ``drop_shorter``
    (a bool), nothing else."""
    if "clip_window" not in d:
        return None
    v = d["clip_window"]
    if not isinstance(v, dict) or set(v) != {"frames", "drop_shorter"}:
        raise ValueError(f"{where}: field 'clip_window' must map exactly 'frames' and 'drop_shorter', got {v!r}")
    frames = _positive(_need(v, "frames", int, f"{where}: clip_window"), "clip_window.frames", where)
    return {"frames": frames, "drop_shorter": _need(v, "drop_shorter", bool, f"{where}: clip_window")}


def _embedding_loop(d: dict, where: str) -> str:
    """The ``embedding_loop`` a protocol names: ``hoibench`` (default: seeded pools and draws,
    :mod:`hoibench.metrics.embedding`) or a paper's released loop
    (:data:`hoibench.metrics.legacy_loops.LOOPS`)."""
    from ..metrics.legacy_loops import LOOPS
    loop = d.get("embedding_loop", "hoibench")
    known = ("hoibench", *sorted(LOOPS))
    if loop not in known:
        raise ValueError(f"{where}: field 'embedding_loop' must be one of {known}, got {loop!r}")
    return loop


def _listed_metrics(d: dict, known: list, where: str) -> tuple:
    """The protocol's ``metrics`` list, each one of ``known``."""
    metrics = tuple(_need(d, "metrics", list, where))
    unknown = [m for m in metrics if m not in known]
    if unknown:
        raise ValueError(f"{where}: field 'metrics' names unknown metrics {unknown}; known: {known}")
    return metrics


#: optional keys of a protocol's ``physical`` mapping: (type, allowed values or None); absent
#: keys take :class:`PhysicalConfig`'s defaults (hoibench's rules), so files without them keep
#: their meaning and hash
_PHYSICAL_OPTIONAL: dict[str, tuple[type, tuple | None]] = {
    "ps_sign": (str, PS_SIGNS), "cd_edge": (str, CD_EDGES), "mesh_repair": (bool, None)}


def _physical_optional(phys: dict, where: str) -> None:
    """Check the optional physical keys present; ValueError naming the file and the field."""
    for key, (kind, allowed) in _PHYSICAL_OPTIONAL.items():
        if key in phys:
            v = _need(phys, key, kind, where)
            if allowed is not None and v not in allowed:
                raise ValueError(f"{where}: field {key!r} must be one of {allowed}, got {v!r}")


def _positive(v, key: str, where: str):
    if not v > 0:
        raise ValueError(f"{where}: field {key!r} must be positive, got {v!r}")
    return v


def protocol_from_dict(d: dict, source: str = "<dict>") -> Protocol:
    """Validate a parsed protocol of either kind; ``ValueError`` naming the file and the field
    otherwise. The kind comes from the ``track`` the file names (:mod:`hoibench.tracks.registry`),
    else from its settings (``r_precision``: hoi; ``contact``: multibody)."""
    w = str(source)
    if not isinstance(d, dict):
        raise ValueError(f"{w}: expected a mapping at the top level")
    track = d.get("track", "")
    if not isinstance(track, str):
        raise ValueError(f"{w}: field 'track' must be a track name, got {track!r}")
    if track:
        from .registry import get_track
        try:
            kind = get_track(track).protocol_kind
        except KeyError as e:
            raise ValueError(f"{w}: field 'track': {e.args[0]}") from None
    else:
        kind = "multibody" if "contact" in d and "r_precision" not in d else "hoi"
    parse = {"multibody": _parse_multibody, "interact-task": _parse_interact_task}.get(kind, _parse_hoi)
    proto = parse(d, w, track)
    if "preview" in d:
        if not isinstance(d["preview"], bool):
            raise ValueError(f"{w}: field 'preview' must be true or false, got {d['preview']!r}")
        proto = replace(proto, preview=d["preview"])
    from ..metrics.catalog import check_settings, settings_keys
    settings = {}
    for key in settings_keys():
        if key in d:
            check_settings(key, d[key], w)
            settings[key] = copy.deepcopy(d[key])
    return replace(proto, settings=settings) if settings else proto


def _parse_hoi(d: dict, w: str, track: str) -> Protocol:
    """The ``hoi`` kind's settings, validated."""
    mode = _need(d, "mode", str, w)
    if mode not in MODES:
        raise ValueError(f"{w}: field 'mode' must be one of {MODES}, got {mode!r}")
    rp = _need(d, "r_precision", dict, w)
    div = _need(d, "diversity", dict, w)
    mm = _need(d, "multimodality", dict, w)
    phys = _need(d, "physical", dict, w)
    for key, kind in (("body_surface", str), ("contact_thresholds", str), ("ocd_length_tolerance_frames", int),
                      ("fsr", dict), ("fsr_gmd", dict), ("vertex_contact_m", float),
                      ("floor_tolerance_m", float), ("floor_shift", bool)):
        _need(phys, key, kind, f"{w}: physical")
    _physical_optional(phys, f"{w}: physical")
    for key in ("height_m", "displacement_m"):
        _need(phys["fsr"], key, float, f"{w}: physical.fsr")
    _check_reference_rules(phys, f"{w}: physical")
    for key, kind in (("height_m", float), ("speed_mps", float), ("window_frames", int)):
        _need(phys["fsr_gmd"], key, kind, f"{w}: physical.fsr_gmd")
    metrics = _listed_metrics(d, sorted(metrics_for("hoi")), w)
    proto = Protocol(
        id=_need(d, "id", str, w), version=_need(d, "version", str, w), dataset=_need(d, "dataset", str, w),
        split=_need(d, "split", str, w), mode=mode, fps=_positive(_need(d, "fps", float, w), "fps", w),
        representation=_need(d, "representation", str, w),
        replications=_positive(_need(d, "replications", int, w), "replications", w),
        seed=_need(d, "seed", int, w),
        r_precision_pool_size=_positive(_need(rp, "pool_size", int, f"{w}: r_precision"), "pool_size", w),
        r_precision_top_k=_positive(_need(rp, "top_k", int, f"{w}: r_precision"), "top_k", w),
        r_precision_drop_last=_need(rp, "drop_last", bool, f"{w}: r_precision"),
        diversity_pairs=_positive(_need(div, "pairs", int, f"{w}: diversity"), "pairs", w),
        mm_texts=_positive(_need(mm, "texts", int, f"{w}: multimodality"), "texts", w),
        mm_samples=_positive(_need(mm, "samples", int, f"{w}: multimodality"), "samples", w),
        mm_pairs=_positive(_need(mm, "pairs", int, f"{w}: multimodality"), "pairs", w),
        physical=phys, metrics=metrics, description=str(d.get("description", "")).strip(),
        changelog=tuple(str(c) for c in d.get("changelog", []) or []), source=w, kind="hoi", track=track,
        embedding_loop=_embedding_loop(d, w), crop_embeddings=_crop_embeddings(d, phys, w),
        clip_window=_clip_window(d, w))
    if proto.mm_samples <= proto.mm_pairs:
        raise ValueError(f"{w}: multimodality.samples must exceed multimodality.pairs")
    proto.physical_config()          # the physical settings must be valid too
    return proto


def _check_reference_rules(phys: dict, where: str) -> None:
    """The optional ``physical`` keys of ChainHOI's rules (docs/metrics.md), validated."""
    for key in legacy_rules.PHYSICAL_OPTIONS:
        if key in phys:
            try:
                legacy_rules.check_option(key, phys[key])
            except ValueError as e:
                raise ValueError(f"{where}: {e}") from None
    v = phys.get("contact_gt_threshold_m")
    if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not v > 0):
        raise ValueError(f"{where}: field 'contact_gt_threshold_m' must be a positive number or null, got {v!r}")


def _parse_multibody(d: dict, w: str, track: str) -> Protocol:
    """The ``multibody`` kind's settings, validated."""
    need = _need
    c, p, dv, r = (need(d, k, dict, w) for k in ("contact", "penetration", "diversity", "recognizer"))
    metrics = _listed_metrics(d, list(metrics_for("multibody")), w)
    proto = Protocol(
        id=need(d, "id", str, w), version=need(d, "version", str, w), dataset=need(d, "dataset", str, w),
        split=need(d, "split", str, w), fps=need(d, "fps", float, w),
        representation=need(d, "representation", str, w),
        samples_per_prompt=need(d, "samples_per_prompt", int, w), surfaces=need(d, "surfaces", str, w),
        csr_threshold_m=need(c, "csr_threshold_m", float, f"{w}: contact"),
        crr_threshold_m=need(c, "crr_threshold_m", float, f"{w}: contact"),
        csiou_empty_union=need(c, "csiou_empty_union", float, f"{w}: contact"),
        voxel_m=need(p, "voxel_m", float, f"{w}: penetration"),
        pair_reduction=need(p, "pair_reduction", str, f"{w}: penetration"),
        diversity_frames=need(dv, "frames", int, f"{w}: diversity"),
        recognizer_split=need(r, "split", str, f"{w}: recognizer"),
        metrics=metrics, description=str(d.get("description", "")).strip(), source=w, kind="multibody",
        track=track)
    for name in ("fps", "csr_threshold_m", "crr_threshold_m", "voxel_m"):
        if not getattr(proto, name) > 0:
            raise ValueError(f"{w}: field {name!r} must be positive")
    if proto.recognizer_split not in ("train", "all"):
        raise ValueError(f"{w}: recognizer.split: expected 'train' or 'all', got {proto.recognizer_split!r}")
    if proto.pair_reduction not in ("sum", "max", "mean"):
        raise ValueError(f"{w}: penetration.pair_reduction: expected sum, max or mean")
    return proto


def _parse_interact_task(d: dict, w: str, track: str) -> Protocol:
    """The ``interact-task`` kind's settings (InterAct's object-to-human and human-to-object
    evaluation, :mod:`hoibench.metrics.interact_tasks`), validated: ``task`` (o2h | h2o),
    ``samples_per_prompt`` (K, the samples per sequence the selection picks from),
    ``selection`` (a listed metric whose best value keeps a sample; not one best at the
    ground truth's value) and ``contact_threshold_m``."""
    from ..metrics.catalog import METRICS
    task = _need(d, "task", str, w)
    if task not in INTERACT_TASKS:
        raise ValueError(f"{w}: field 'task' must be one of {INTERACT_TASKS}, got {task!r}")
    metrics = _listed_metrics(d, [m for m in metrics_for("interact-task") if m.startswith(task + "_")], w)
    selection = _need(d, "selection", str, w)
    if selection not in metrics or METRICS[selection].direction == "gt":
        raise ValueError(f"{w}: field 'selection' must be a listed metric with a lower or higher direction, "
                         f"got {selection!r}")
    return Protocol(
        id=_need(d, "id", str, w), version=_need(d, "version", str, w), dataset=_need(d, "dataset", str, w),
        split=_need(d, "split", str, w), fps=_positive(_need(d, "fps", float, w), "fps", w),
        representation=_need(d, "representation", str, w), task=task,
        samples_per_prompt=_positive(_need(d, "samples_per_prompt", int, w), "samples_per_prompt", w),
        selection=selection,
        contact_threshold_m=_positive(_need(d, "contact_threshold_m", float, w), "contact_threshold_m", w),
        metrics=metrics, description=str(d.get("description", "")).strip(),
        changelog=tuple(str(c) for c in d.get("changelog", []) or []), source=w, kind="interact-task", track=track)


def read_protocol_yaml(path: str | Path):
    """The parsed content of a protocol YAML file (single-body or multi-body); errors name
    the file."""
    import yaml

    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"protocol: no file at {p}")
    try:
        from ..core.io import read_text_file
        return yaml.safe_load(read_text_file(p, 1024 ** 2, "protocol file"))  # read-ok: text read by read_text_file
    except yaml.YAMLError as e:
        raise ValueError(f"{p}: not valid YAML: {e}") from None


def load_protocol(path: str | Path) -> Protocol:
    """Read and validate one protocol YAML file."""
    return protocol_from_dict(read_protocol_yaml(path), str(path))


def list_protocols() -> list[Protocol]:
    """Every protocol shipped with the package, sorted by id."""
    return sorted((load_protocol(p) for p in PROTOCOLS_DIR.glob("*.yaml")), key=lambda x: (x.id, x.version))


def get_protocol(name: str | Path | Protocol) -> Protocol:
    """A protocol by id (``"behave-clean"``: its newest version that is not a preview), id
    and version (``"behave-clean@1.1"``) or path to a YAML file. ``KeyError`` listing the
    known ids otherwise."""
    if isinstance(name, Protocol):
        return name
    s = str(name)
    if s.endswith((".yaml", ".yml")) or Path(s).is_file():
        return load_protocol(s)
    pid, _, version = s.partition("@")
    found = [p for p in list_protocols() if p.id == pid and (not version or p.version == version)]
    if not found:
        known = ", ".join(p.ref for p in list_protocols())
        raise KeyError(f"unknown protocol {s!r}; known: {known}")
    return ([p for p in found if not p.preview] or found)[-1]


def default_protocol_id(manifest: dict) -> str:
    """The protocol a store is scored under by default: ``<dataset>-<legacy|clean>`` when one
    ships under that id, else the one shipped protocol for the store's dataset and mode
    (a ``rich`` store: ``rich-cat-clean``), else ``<dataset>-<legacy|clean>`` (not shipped)."""
    mode = "legacy" if str(manifest.get("config", {}).get("mode", "clean")).startswith("legacy") else "clean"
    dataset = manifest.get("dataset", "?")
    pid = f"{dataset}-{mode}"
    shipped = list_protocols()
    if any(p.id == pid for p in shipped):
        return pid
    ids = sorted({p.id for p in shipped if p.dataset == dataset and p.mode in (mode, None)})   # None: multibody
    return ids[0] if len(ids) == 1 else pid


def default_protocol(manifest: dict) -> Protocol | None:
    """The shipped protocol a store is scored under by default (:func:`default_protocol_id`),
    or None when none ships for it."""
    try:
        return get_protocol(default_protocol_id(manifest))
    except (KeyError, ValueError, FileNotFoundError):
        return None


def protocol_mismatches(protocol: Protocol, manifest: dict) -> list[str]:
    """Why ``protocol`` does not fit the store ``manifest`` (dataset, mode, fps,
    representation); empty when it fits."""
    mode = "legacy" if str(manifest.get("config", {}).get("mode", "clean")).startswith("legacy") else "clean"
    out = []
    if protocol.dataset != manifest.get("dataset"):
        out.append(f"protocol {protocol.ref} is for dataset {protocol.dataset!r}, the store holds "
                   f"{manifest.get('dataset')!r}")
    if protocol.mode != mode:
        out.append(f"protocol {protocol.ref} is a {protocol.mode} protocol, the store was prepared in {mode} mode")
    fps = manifest.get("config", {}).get("fps")
    if isinstance(fps, (int, float)) and abs(protocol.fps - float(fps)) > 1e-6:
        out.append(f"protocol {protocol.ref} evaluates at {protocol.fps:g} fps, the store holds {fps:g} fps clips")
    rep = manifest.get("representations", {}).get("hml263")
    if rep and protocol.representation != rep:
        out.append(f"protocol {protocol.ref} names representation {protocol.representation}, the store holds {rep}")
    return out


# ====================================================================== results
def summarize(values: Iterable, replications: int | None = None) -> dict:
    """Mean and 95% CI over replications: ``ci95 = 1.96 * std / sqrt(n)``, ``std`` the
    population standard deviation (``np.std``, ddof 0), ``n`` = ``replications`` (default:
    the number of values); equal values (the physical metrics, computed once) give exactly 0.
    Works per component for vector values (R-precision top-1..3).
    Returns ``{"mean", "ci95", "std", "n"}`` (floats or lists)."""
    v = np.asarray(list(values), dtype=np.float64)
    if v.size == 0:
        raise ValueError("values: need at least one replication")
    n = len(v) if replications is None else int(replications)
    mean, std = v.mean(axis=0), v.std(axis=0)
    std = np.where(np.all(v == v[0], axis=0), 0.0, std)    # equal values: exactly 0, not 1e-17
    ci = CI_Z * std / np.sqrt(n)
    tolist = (lambda x: x.tolist()) if v.ndim > 1 else float
    return {"mean": tolist(mean), "ci95": tolist(ci), "std": tolist(std), "n": int(n)}


def summarize_replications(per_replication: Sequence[dict], replications: int | None = None) -> dict:
    """``[{metric: value}, ...]`` (one dict per replication) -> ``{metric: summarize(...)}``;
    a metric missing (or NaN) in some replication is summarised over the others and records
    its own ``n``."""
    names = sorted({k for r in per_replication for k in r})
    out = {}
    for k in names:
        vals = [r[k] for r in per_replication if k in r and r[k] is not None
                and not np.any(np.isnan(np.asarray(r[k], dtype=np.float64)))]
        if vals:
            out[k] = summarize(vals, replications if len(vals) == len(per_replication) else None)
    return out


# ====================================================================== CLI
def format_table(protocols: Sequence[Protocol]) -> str:
    """The ``hoi`` protocols as a table (one line each)."""
    head = (f"{'id':18s} {'version':>7s} {'dataset':10s} {'mode':6s} {'fps':>4s} {'reps':>4s} "
            f"{'pool':>4s} {'div':>4s} {'mm':>10s} {'contact':8s} body")
    rows = [head]
    for p in protocols:
        if p.kind != "hoi":
            continue
        rows.append(f"{p.id:18s} {p.version:>7s} {p.dataset:10s} {p.mode:6s} {p.fps:4g} {p.replications:4d} "
                    f"{p.r_precision_pool_size:4d} {p.diversity_pairs:4d} "
                    f"{f'{p.mm_texts}x{p.mm_samples}x{p.mm_pairs}':>10s} "
                    f"{p.physical['contact_thresholds']:8s} {p.physical_config().body_label}")
    return "\n".join(rows)


def format_multibody_table(protocols: Sequence[Protocol]) -> str:
    """The ``multibody`` protocols, one line each."""
    return "\n".join(
        f"{p.id:22s} {p.version:>7s} {p.dataset:20s} fps {p.fps:g}  CSR {p.csr_threshold_m * 1000:g} mm  "
        f"CRR {p.crr_threshold_m * 100:g} cm  voxel {p.voxel_m * 1000:g} mm  recognizer on {p.recognizer_split}"
        for p in protocols if p.kind == "multibody")


def format_task_table(protocols: Sequence[Protocol]) -> str:
    """The ``interact-task`` protocols, one line each."""
    return "\n".join(
        f"{p.id:22s} {p.version:>7s} {p.dataset:10s} task {p.task}  K {p.samples_per_prompt}  best {p.selection}  "
        f"contact {p.contact_threshold_m * 100:g} cm" for p in protocols if p.kind == "interact-task")


def main_protocols(action: str = "ls", name: str | None = None) -> int:
    """``hoibench protocols ls`` (table of the shipped protocols) or ``hoibench protocols show
    NAME`` (the YAML file, its path and sha256). Returns an exit status."""
    try:
        if action == "ls":
            shipped = list_protocols()
            print(format_table(shipped))
            print("\nmulti-body (docs/multibody.md):")
            print(format_multibody_table(shipped))
            print("\nInterAct's object-to-human and human-to-object tasks (docs/metrics.md):")
            print(format_task_table(shipped))
            return 0
        if action == "show":
            if not name:
                print("hoibench protocols: error: show needs a protocol id, e.g. behave-clean", file=sys.stderr)
                return 2
            p = get_protocol(name)
            print(f"# {p.ref}  sha256 {p.sha256}\n# file: {p.source}")
            from ..core.io import read_text_file
            print(read_text_file(p.source, 1024 ** 2, "protocol file").rstrip())
            return 0
        print(f"hoibench protocols: error: unknown action {action!r}; expected 'ls' or 'show'", file=sys.stderr)
        return 2
    except (KeyError, ValueError, FileNotFoundError) as e:
        print(f"hoibench protocols: error: {e.args[0] if isinstance(e, KeyError) else e}", file=sys.stderr)
        return 2


__all__ = ["format_multibody_table", "format_task_table", "INTERACT_TASKS", "KIND_FIELDS", "default_protocol_id", "protocol_mismatches", "Protocol", "PROTOCOLS_DIR", "protocol_from_dict", "load_protocol", "list_protocols", "get_protocol",
           "summarize", "summarize_replications", "format_table", "main_protocols"]
