"""Metrics: FID, R-precision, MM-Dist, Diversity, MultiModality (evaluator embeddings) and
CD, OCD, PS, FSR plus extras (joints and object), each a functional core and a stateful,
mergeable class (torchmetrics-style; see :mod:`hoibench.metrics.state`).

Modules (find a metric by its file):

* :mod:`~hoibench.metrics.embedding` -- FID, R-precision, MM-Dist, Diversity, MultiModality;
* :mod:`~hoibench.metrics.legacy_loops` -- the papers' released evaluation loops for those
  metrics (text-to-motion, MDM, ChainHOI, InterAct), replayed exactly on fixed embeddings;
* :mod:`~hoibench.metrics.contact_metrics` -- CD, OCD, PS, penetration depth, contact IoU,
  hand-object contact ratio, object floating (one clip, from signed distances);
* :mod:`~hoibench.metrics.motion` -- foot skating (ChainHOI legacy / clean, GMD) and jitter;
* :mod:`~hoibench.metrics.body_surface` -- the proxy body fitted to joints (for PS);
* :mod:`~hoibench.metrics.physical` -- per-clip units mapped by an executor, pooled;
* :mod:`~hoibench.metrics.legacy_rules` -- ChainHOI's released CD/OCD/FSR rules and evaluated
  lengths (legacy protocols);
* :mod:`~hoibench.metrics.state` -- the mergeable-state base class.

:data:`METRICS` is the registry of what a result may report: name -> :class:`MetricInfo`
(``higher_is_better``, units, thresholds, the paper column it reproduces and the
implementation as a lazy ``"module:attr"`` string). Leaderboards read ``higher_is_better``
from here instead of guessing. docs/metrics.md is the catalogue.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

from .embedding import (FID, Diversity, MultiModality, RPrecision, activation_statistics, diversity,
                        euclidean_distance_matrix, fid, frechet_distance, make_pools, mm_dist, multimodality,
                        pool_hits, r_precision)
from .state import Metric


@dataclass(frozen=True)
class MetricInfo:
    """What a reported metric is. ``higher_is_better`` None: best when closest to the real
    motion's value. ``impl``: ``"module:attr"`` of the functional core."""

    name: str
    kind: str                     # "embedding" | "physical" | "multibody"
    higher_is_better: bool | None
    units: str
    paper_column: str | None
    thresholds: str
    summary: str
    impl: str

    def load(self):
        """Import and return the implementation named by ``impl``."""
        from ..core.registry import load_object
        return load_object(self.impl)

    def to_dict(self) -> dict:
        return asdict(self)


METRICS: dict[str, MetricInfo] = {}


def register(info: MetricInfo) -> MetricInfo:
    """Add a metric to :data:`METRICS` (``ValueError`` if the name is taken)."""
    if info.name in METRICS:
        raise ValueError(f"metric {info.name!r} is already registered")
    METRICS[info.name] = info
    return info


def get_metric_info(name: str) -> MetricInfo:
    try:
        return METRICS[name]
    except KeyError:
        raise KeyError(f"unknown metric {name!r}; known: {', '.join(sorted(METRICS))}") from None


_E = "hoibench.metrics.embedding"
_C = "hoibench.metrics.contact_metrics"
_M = "hoibench.metrics.motion"
for _k in (1, 2, 3):
    register(MetricInfo(f"r_precision_top{_k}", "embedding", True, "fraction", f"R Precision Top {_k}",
                        "pools of 32 (protocol), drop the incomplete last pool",
                        f"text i retrieves its own motion among the {_k} nearest of its pool",
                        f"{_E}:r_precision"))
register(MetricInfo("fid", "embedding", False, "squared embedding distance", "FID",
                    "sqrtm retried with 1e-6 on the diagonal; |imag| <= 1e-3 dropped",
                    "Frechet distance between real and generated motion embeddings", f"{_E}:fid"))
register(MetricInfo("mm_dist", "embedding", False, "embedding distance", "MM Dist",
                    "pools as R-precision", "mean distance between a text and its motion", f"{_E}:mm_dist"))
register(MetricInfo("diversity", "embedding", None, "embedding distance", "Diversity",
                    "300 pairs (200 on BEHAVE)", "mean distance between random pairs of motions",
                    f"{_E}:diversity"))
register(MetricInfo("multimodality", "embedding", True, "embedding distance", "MultiModality",
                    "100 texts x 30 samples x 10 pairs", "mean distance between samples of one text",
                    f"{_E}:multimodality"))
register(MetricInfo("cd", "physical", False, "m^2", "CD (ChainHOI)",
                    "mask: ground-truth joint contact labels",
                    "mean squared signed distance of the 22 joints to the object where GT touches",
                    f"{_C}:contact_distance"))
register(MetricInfo("ocd", "physical", False, "m^2", "OCD (ChainHOI)",
                    "group members within +-8 frames of the generated length",
                    "CD minimised over the contact maps of the clip's semantic group",
                    f"{_C}:optimal_contact_distance"))
register(MetricInfo("ps", "physical", False, "fraction", "PS (ChainHOI)",
                    "vertex penetrates when its signed distance < 0",
                    "penetrating body-surface vertex-frames / all vertex-frames (proxy body by default)",
                    f"{_C}:penetration_counts"))
register(MetricInfo("penetration_depth_max_m", "physical", False, "m", None, "signed distance < 0",
                    "deepest penetration of any frame (max over vertices of -d)", f"{_C}:penetration_depth_stats"))
register(MetricInfo("penetration_depth_mean_m", "physical", False, "m", None, "signed distance < 0",
                    "mean over penetrating frames of the frame's deepest penetration",
                    f"{_C}:penetration_depth_stats"))
register(MetricInfo("fsr", "physical", False, "fraction", "FSR (ChainHOI)",
                    "feet 10, 11; height < 0.05 m at t+1; step > 0.025 m (legacy: |dx|; clean: xz, 0.5 m/s)",
                    "skating foot-frames / ground-contact foot-frames", f"{_M}:foot_skating_counts"))
register(MetricInfo("fsr_gmd", "physical", False, "fraction", "Foot skating ratio (GMD, HOI-Diff)",
                    "feet 10, 11; height < 0.05 m at t and t+1; xz speed and its 5-frame mean > 0.5 m/s",
                    "skating frames / (T - 1) per clip, averaged over clips", f"{_M}:gmd_skating_counts"))
register(MetricInfo("contact_iou", "physical", True, "fraction", None,
                    "predicted label: d < per-object threshold (protocol contact mode)",
                    "IoU of generated vs ground-truth joint contact labels", f"{_C}:contact_iou_counts"))
register(MetricInfo("hand_contact_ratio", "physical", None, "fraction", None,
                    "wrist 20/21 label on (protocol contact mode)",
                    "frames where a hand touches the object", f"{_C}:hand_contact_frames"))
register(MetricInfo("object_floating_ratio", "physical", False, "fraction", None,
                    "lowest object point > 0.02 m, no body vertex within 0.02 m",
                    "frames where the object is off the floor and untouched", f"{_C}:floating_frames"))
register(MetricInfo("jitter_mps3", "physical", False, "m/s^3", None, "third finite difference x fps^3",
                    "mean jerk magnitude of the joints", f"{_M}:jitter_sums"))
# multi-body track (SyncDiff, paper 004 section 4.2; docs/multibody_metrics.md)
_MB = "hoibench.metrics.multibody"
register(MetricInfo("csr", "multibody", None, "fraction", "CSR (SyncDiff)", "hand surface within 5 mm of an object",
                    "frames where a hand touches an object, mean over hands then clips", f"{_MB}:CSR"))
register(MetricInfo("crr", "multibody", None, "fraction", "CRR (SyncDiff)", "both hand roots within 5 cm of one object",
                    "frames where a human holds an object with both hands", f"{_MB}:CRR"))
register(MetricInfo("csiou", "multibody", True, "fraction", "CSIoU (SyncDiff)", "contact frames by the CSR/CRR rules",
                    "IoU of generated vs ground-truth contact frames", f"{_MB}:CSIoU"))
register(MetricInfo("iv_cm3", "multibody", False, "cm^3", "IV (SyncDiff)", "5 mm voxels inside both bodies",
                    "interpenetration volume per frame, summed over body pairs", f"{_MB}:interpenetration_volume"))
register(MetricInfo("id_mm", "multibody", False, "mm", "ID (SyncDiff)", "deepest probe inside the other body",
                    "interpenetration depth per frame, summed over body pairs", f"{_MB}:interpenetration_depth"))
register(MetricInfo("sd", "multibody", True, "m", "SD (SyncDiff)", "wrists at 15 frames (DiffH2O)",
                    "wrist-trajectory diversity between the samples of a prompt", f"{_MB}:SampleDiversity"))
register(MetricInfo("od", "multibody", None, "m", "OD (SyncDiff)", "wrists at 15 frames (DiffH2O)",
                    "wrist-trajectory diversity across the split", f"{_MB}:OverallDiversity"))
register(MetricInfo("ra", "multibody", True, "fraction", "RA (SyncDiff)", "the track's action recognizer",
                    "recognition accuracy of the generated clips' actions",
                    "hoibench.evaluator.recognizer:Recognizer"))
del _k

__all__ = [
    "METRICS", "MetricInfo", "register", "get_metric_info", "Metric",
    "FID", "RPrecision", "Diversity", "MultiModality",
    "euclidean_distance_matrix", "activation_statistics", "frechet_distance", "fid", "pool_hits",
    "r_precision", "mm_dist", "make_pools", "diversity", "multimodality",
]
