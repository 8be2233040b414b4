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

:data:`METRICS` (:mod:`~hoibench.metrics.catalog`) is the one catalogue of what a result may
report: name -> :class:`MetricInfo` (unit, direction, group, column title, per-clip column,
failure end, thresholds, the paper column it reproduces, the implementation as a lazy
``"module:attr"`` string). docs/metrics.md describes each.
"""
from __future__ import annotations

from .catalog import METRICS, MetricInfo, get_metric_info, metric_names, register
from .embedding import (FID, Diversity, MultiModality, RPrecision, activation_statistics, diversity,
                        euclidean_distance_matrix, fid, frechet_distance, make_pools, mm_dist, multimodality,
                        pool_hits, r_precision)
from .state import Metric

__all__ = [
    "METRICS", "MetricInfo", "register", "get_metric_info", "metric_names", "Metric",
    "FID", "RPrecision", "Diversity", "MultiModality",
    "euclidean_distance_matrix", "activation_statistics", "frechet_distance", "fid", "pool_hits",
    "r_precision", "mm_dist", "make_pools", "diversity", "multimodality",
]
