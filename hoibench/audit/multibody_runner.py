"""The audit of a multi-body track: score controlled corruptions of the ground-truth test
clips with the multi-body scorer's own stages (:class:`hoibench.scoring.multibody.MultiBodyScorer`)
and the track's recognizer.

Every (family, severity) of :data:`~hoibench.audit.multibody_families.MULTIBODY_FAMILIES`
corrupts the test split (clip ``c`` draws from ``clip_stream(seed, family, severity index,
c)``), which is then scored as an in-memory K = 1 submission: the per-clip units (contacts,
penetration, wrists) of inputs already seen are computed once, on the executor; the
recognizer's RA and FID and the reductions run in this process in a fixed order, so every
executor gives the same numbers. ``action_swap`` changes the action labels RA is scored
against, not the motion. :func:`score_multibody_conditions` returns what
:func:`hoibench.audit.runner.score_conditions` returns for single-body stores.
"""
from __future__ import annotations

import hashlib
from contextlib import nullcontext
from typing import Any, Sequence

import numpy as np

from ..scoring.multibody import MultiBodyScorer, ground_truth_unit, samples_unit
from ..scoring.multibody_samples import sample_arrays
from ..scoring.submission_read import MemorySubmission
from .multibody_families import MULTIBODY_FAMILIES
from .streams import clip_stream


class MultiBodyAuditScorer(MultiBodyScorer):
    """The ``multibody`` scorer over corrupted clips held in memory; ``actions`` (id -> label)
    replaces the action labels RA is scored against."""

    def __init__(self, store, proto, ev, track, samples: dict, actions: dict, label: str, options: dict):
        super().__init__(store, proto, ev, track, f"audit:{label}", dict(options, clip_data=None))
        self.samples, self.actions, self.label = samples, actions, label

    def open_submission(self):
        return nullcontext(MemorySubmission(self.samples, self.label))

    def stream(self, sub, ids: list[str]):
        jobs = []
        for job in super().stream(sub, ids):
            cid, arrays = job[0], job[1]
            if self.actions.get(cid, str(arrays.get("action", ""))) != str(arrays.get("action", "")):
                arrays = dict(arrays, action=np.array(self.actions[cid]))
            jobs.append((cid, arrays, *job[2:]))
        self.jobs = jobs
        return list(jobs)


def _job_digest(job: tuple) -> str:
    """sha256 of what a per-clip unit reads that differs between conditions (its samples)."""
    h = hashlib.sha256(job[0].encode())
    for k in sorted(job[2]):
        a = np.ascontiguousarray(job[2][k])
        h.update(f"{k}{a.dtype}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _unit_job(job: tuple) -> tuple[str, Any]:
    key, fn, inp = job
    return key, fn(inp)


def score_multibody_conditions(setup, conds: Sequence, seed: int = 0, executor: str = "serial") -> dict:
    """``{condition: (result, per-clip arrays)}`` for every condition of ``conds``
    (:class:`~hoibench.audit.runner.Condition`: family, severity, index; module docstring);
    ``setup``: :func:`hoibench.audit.runner.load_setup` of a multi-body store."""
    from ..bodies.multibody import MultiBodyClip
    from ..core.parallel import map_units
    store, proto, ev = setup.store, setup.proto, setup.ev
    ids = store.clip_ids(proto.split)
    gt = {cid: MultiBodyClip.from_arrays(store.load(cid), store.object_template) for cid in ids}
    actions = {cid: str(c.action) for cid, c in gt.items()}
    scorers: list[tuple[Any, MultiBodyAuditScorer]] = []
    for cond in conds:
        spec = MULTIBODY_FAMILIES[cond.family]
        if spec.scope == "split":
            clips, labels = gt, spec.fn(actions, cond.severity, seed, None, severity_index=cond.index)
        else:
            clips = {cid: spec.fn(c, cond.severity, clip_stream(seed, cond.family, cond.index, cid))
                     for cid, c in gt.items()}
            labels = actions
        samples = {cid: sample_arrays([c]) for cid, c in clips.items()}
        scorer = MultiBodyAuditScorer(store, proto, ev, setup.track, samples, labels,
                                      f"{cond.family}@{cond.severity:g}", setup.options)
        scorer.prepare()
        with scorer.open_submission() as sub:
            scorer.stream(sub, scorer.validate(sub))
        scorers.append((cond, scorer))
    # the ground truth's part of each clip once (key "gt:<id>"), each distinct sample's once
    jobs: dict[str, tuple] = {}
    for _, scorer in scorers:
        for job in scorer.jobs:
            jobs.setdefault(f"gt:{job[0]}", (f"gt:{job[0]}", ground_truth_unit, job))
            d = _job_digest(job)
            jobs.setdefault(d, (d, samples_unit, job))
    units = dict(map_units(_unit_job, [jobs[d] for d in sorted(jobs)], executor, progress="audit: physical"))

    def finish(item) -> tuple:
        cond, scorer = item
        for job in scorer.jobs:
            scorer.update({**units[_job_digest(job)], "gt": units[f"gt:{job[0]}"]})
        rows = scorer.replications()
        return cond, (scorer.summary(rows), scorer.clip_arrays)

    return dict(map_units(finish, scorers, "serial", progress="audit: recognizer"))


__all__ = ["MultiBodyAuditScorer", "score_multibody_conditions"]
