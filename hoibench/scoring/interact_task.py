"""The scorer of InterAct's conditioned tasks (tracks ``interact-o2h``, ``interact-h2o``;
protocols of the ``interact-task`` kind), as InterAct's ``eval_saved.py`` scores them.

Per test sequence and per sample k of its K (:mod:`hoibench.metrics.interact_tasks`, every
value in the catalogue's units):

* ``o2h``: the sample's markers (T, 77, 3) against the clip's markers and its object points
  posed per frame (``R_t p + t_t``): hand JPE (cm), MPVPE (m), foot sliding and, per marker
  group (full, hand, non-hand, foot), JPE (cm) and contact precision, recall, accuracy, F1 and
  distances at the protocol's threshold (0.05 m);
* ``h2o``: the object points posed by the sample's poses against those posed by the
  ground truth's, with the clip's markers for contact: MPVPE and MPMPE (m), ``t_err`` (m, the
  translation of InterAct's object-file origin, ``t + R o``), ``o_err`` (Frobenius) and the
  contact scores.

The sample whose ``selection`` metric is best (lowest JPE of all markers for o2h, lowest
MPVPE for h2o; the first on ties) is kept, and every metric is read from it. A metric's value
is the mean over the scored sequences, ``mean_i v_i``; its 95% interval is the 2.5 and 97.5
percentiles of that mean over 1,000 seeded clip-bootstrap draws
(:func:`hoibench.scoring.paired.mean_intervals`, as the single-body scorer's clip intervals), recorded as ``clips.ci95`` with the
half-width ``(hi - lo) / 2`` as ``ci95``. No evaluator is read. Units run on any executor and
are reduced in sorted id order, so every executor gives the same numbers.
"""
from __future__ import annotations

import platform
import time
from typing import Iterator

import numpy as np

from .. import __version__
from ..metrics.catalog import METRICS
from ..metrics.interact_tasks import best_sample, human2object_metrics, object2human_metrics
from .interact_task_files import ground_truth, posed, sample_poses
from .paired import CLIP_RESAMPLES, mean_intervals
from .pipeline import EvaluationRefused, Scorer
from .results import RESULT_FORMAT, metric_entry

_RENAME = {"contact_f1_score": "contact_f1"}


def task_values(task: str, out: dict) -> dict[str, float]:
    """One sample's output of :mod:`hoibench.metrics.interact_tasks` as catalogue names:
    ``<task>_<key>``, and for o2h's marker groups ``o2h_jpe_<group>`` and
    ``o2h_<contact key>_<group>``."""
    flat = {}
    for key, v in out.items():
        if isinstance(v, dict):
            for k, x in v.items():
                name = _RENAME.get(k, k)
                flat[f"{task}_{name}_{key}"] = float(x)
        else:
            flat[f"{task}_{_RENAME.get(key, key)}"] = float(v)
    return flat


def sample_values(task: str, arrays: dict[str, np.ndarray], k: int, gt: dict[str, np.ndarray],
                  threshold: float) -> dict[str, float]:
    """The metrics of sample ``k`` of one clip (module docstring)."""
    obj = posed(gt["points"], gt["obj_rot"], gt["obj_trans"])
    if task == "o2h":
        return task_values(task, object2human_metrics(arrays["markers"][k], gt["markers"], obj, threshold))
    rot, trans = sample_poses(arrays)
    origin = gt["origin"]
    out = human2object_metrics(posed(gt["points"], rot[k], trans[k]), obj, gt["markers"], threshold,
                               pred_trans=trans[k] + rot[k] @ origin, gt_trans=gt["obj_trans"] + gt["obj_rot"] @ origin,
                               pred_rot=rot[k], gt_rot=gt["obj_rot"])
    return task_values(task, out)


def score_clip(job: tuple) -> tuple[str, dict]:
    """The executor's unit: ``(id, task, arrays, gt, threshold, selection)`` ->
    ``(id, {"sample": kept k, "values": {metric: value}, "selection_values": [one per k]})``."""
    cid, task, arrays, gt, threshold, selection = job
    K = len(next(iter(arrays.values())))
    per = [sample_values(task, arrays, k, gt, threshold) for k in range(K)]
    picks = [p[selection] for p in per]
    k = best_sample(picks, higher_is_better=METRICS[selection].direction == "higher")
    return cid, {"sample": k, "values": per[k], "selection_values": picks}


def ground_truth_values(metrics: dict) -> dict[str, float]:
    """The ground truth's own value of each metric best at it (foot sliding, contact distance):
    the mean of its ``gt_`` twin, which ``format_result`` prints beside the metric."""
    out = {}
    for name, m in metrics.items():
        task, _, rest = name.partition("_")
        twin = f"{task}_gt_{rest}"
        if twin in metrics:
            out[name] = metrics[twin]["mean"]
    return out


class InteractTaskScorer(Scorer):
    """The stages of :mod:`hoibench.scoring.pipeline` for InterAct's o2h and h2o tracks."""

    name = "interact-task"
    evaluator_options: dict = {}
    map_options = {"progress": "evaluate"}

    @classmethod
    def check_fit(cls, store, protocol, card: dict, options: dict) -> None:
        """Refuse a protocol for another dataset or frame rate (unless allowed)."""
        fps = float(store.manifest.get("config", {}).get("fps", 0.0))
        why = [f"protocol {protocol.ref} is for dataset {protocol.dataset!r}, the store holds "
               f"{store.manifest.get('dataset')!r}"] if protocol.dataset != store.manifest.get("dataset") else []
        if abs(protocol.fps - fps) > 1e-6:
            why.append(f"protocol {protocol.ref} evaluates at {protocol.fps:g} fps, the store holds {fps:g} fps clips")
        if why and not options.get("allow_protocol_mismatch", False):
            raise EvaluationRefused("; ".join(why) + " (pass --allow-protocol-mismatch to score anyway)")

    def prepare(self) -> None:
        from .validate import submission_context
        self.rows, self.fps, self.cap, _ = submission_context(self.store, self.proto)
        self.test_ids = sorted(self.rows)
        if not self.test_ids:
            raise EvaluationRefused(f"{self.store.root}: the test split has no clips")
        ground_truth(self.store, self.test_ids[0])           # a store without markers is refused here
        self.outputs: dict[str, dict] = {}

    def open_submission(self):
        from .submission_read import Submission, limits_for
        return Submission(self.submission, limits=limits_for(self.rows, self.fps, self.cap))

    def validate(self, sub) -> list[str]:
        from .validate import validation_report
        t0 = time.perf_counter()
        self.report = validation_report(sub, self.store, protocol=self.proto)
        ids = sorted(self.report.valid_ids)
        if not ids:
            first = self.report.errors[0] if self.report.errors else None
            raise EvaluationRefused(f"{self.submission}: no valid test id to score ({len(self.report.errors)} "
                                    f"error(s){f', e.g. {first.id}: {first.field}: {first.message}' if first else ''})")
        self.meta = dict(sub.meta or {})
        self.K = int(self.report.samples_per_prompt or 1)
        self.ids = ids
        self.timings["validate_s"] = time.perf_counter() - t0
        return ids

    def stream(self, sub, ids: list[str]) -> Iterator:
        from .interact_task_files import TASK_ARRAYS
        self.unit = score_clip
        self.t_stream = time.perf_counter()
        task, keys = self.proto.task, tuple(TASK_ARRAYS[self.proto.task])
        threshold, selection = float(self.proto.contact_threshold_m), self.proto.selection
        return ((cid, task, sub.load(cid, keys), ground_truth(self.store, cid), threshold, selection) for cid in ids)

    def update(self, out) -> None:
        cid, value = out
        self.outputs[cid] = value

    def replications(self) -> list[dict]:
        """One row per scored sequence (sorted ids): ``{"id", "sample", <metric>: value}``."""
        self.timings["stream_s"] = time.perf_counter() - self.t_stream
        return [{"id": cid, "sample": self.outputs[cid]["sample"], **self.outputs[cid]["values"]}
                for cid in sorted(self.outputs)]

    def _metrics(self, rows: list[dict]) -> dict:
        values = {name: np.array([r[name] for r in rows], np.float64) for name in self.proto.metrics}
        intervals = mean_intervals(values, CLIP_RESAMPLES, seed=0)   # fixed draws: same ids, same intervals
        out = {}
        for name, v in values.items():
            clips = intervals.get(name)
            extra = {"clips": clips} if clips else {}
            half = None if clips is None else (clips["ci95"][1] - clips["ci95"][0]) / 2
            out[name] = metric_entry(name, float(v.mean()), half, len(v), "clips", **extra)
        return out

    def summary(self, rows: list[dict]) -> dict:
        proto, report, store, meta = self.proto, self.report, self.store, self.meta
        flags = meta.get("flags") if isinstance(meta.get("flags"), dict) else {}
        notes = [f"{proto.task}: per sequence the sample with the best {proto.selection} of K = {self.K} is kept "
                 f"(the protocol takes up to {proto.samples_per_prompt}); rows of different K are not comparable"]
        if self.ev is not None:
            notes.append("no evaluator is read by this track: the --evaluator folder was not used")
        self.timings["total_s"] = time.perf_counter() - self.started
        return {
            "format": RESULT_FORMAT, "kind": self.name, "track": self.track.name, **proto.result_header(),
            "task": proto.task, "selection": proto.selection, "contact_threshold_m": proto.contact_threshold_m,
            "complete": bool(report.complete), "submission_complete": bool(report.complete), "overrides": [],
            "evaluator_id": None, "evaluator_backend": "none",
            "representation": store.manifest.get("representations"), "toolkit": "hoibench",
            "toolkit_version": __version__, "dataset": store.manifest.get("dataset"),
            "store_config_sha256": store.manifest.get("config_sha256"),
            "submission": {"path": str(self.submission), "method": meta.get("method"), "version": meta.get("version"),
                           "flags": {k: flags[k] for k in ("uses_gt_length", "samples_per_prompt",
                                                           "checkpoint_selection") if k in flags}},
            "counts": {"test_ids": len(report.test_ids), "scored_ids": len(rows), "samples_per_prompt": self.K,
                       "missing_ids": report.missing_ids, "errors": len(report.errors),
                       "warnings": len(report.warnings)},
            "metrics": (metrics := self._metrics(rows)), "ground_truth": ground_truth_values(metrics),
            "undefined_metrics": {},
            "per_clip": {"sample": "selected", "clips": len(rows), "rows": rows}, "notes": notes,
            "timings_s": {k: round(v, 3) for k, v in self.timings.items()},
            "platform": {"python": platform.python_version(), "numpy": np.__version__},
        }


__all__ = ["InteractTaskScorer", "task_values", "sample_values", "score_clip"]
