"""``hoibench audit``: score controlled corruptions of a store's ground-truth test clips.

For every corruption family (:data:`hoibench.audit.corruptions.FAMILIES`) and each of its
severities, the test split's ground truth is corrupted (:func:`~hoibench.audit.corruptions.apply`,
seeded) and scored as an in-memory submission (K = 1) by the single-body scorer's own stages
(:class:`hoibench.scoring.hoi.HOIScorer`): motion families change the joints and object poses,
from which the evaluator's hoi269 rows and the physical metrics are recomputed exactly as for
a submission (an ``object_swap`` also swaps the template the physical metrics pose, a
``mirror`` mirrors it: :func:`~hoibench.audit.motion.mirror_template`); text
families change the caption lines the evaluator encodes. The ground truth's statistics
(embeddings, caption embeddings, the gate) are computed once; a condition whose corrupted
arrays and captions equal the ground truth's (every severity 0) is scored once; per-clip
physical work with identical inputs runs once, on the executor. Everything else runs in
this process in a fixed order, so every executor gives the same numbers.

:func:`score_conditions` returns, per (family, severity), the result (``hoibench-result-2``)
and its per-clip data (:mod:`hoibench.scoring.clip_data`); :mod:`hoibench.audit.analysis`
turns them into the audit's statistics and :mod:`hoibench.audit.report` into its files.
"""
from __future__ import annotations

import dataclasses
import hashlib
from contextlib import nullcontext
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from ..scoring.hoi import HOIScorer
from ..scoring.pipeline import EvaluationRefused
from .corruptions import FAMILIES, apply, split_context
from .motion import follow_markers, mirror_template
from .streams import selected

#: the default seed of the corruptions and the paired bootstrap
DEFAULT_SEED = 0
#: sample arrays besides joints and object poses that the corruptions carry along: the body's
#: markers follow the corrupted joints (:func:`~hoibench.audit.motion.follow_markers`)
FOLLOWING_ARRAYS = ("markers",)


@dataclass(frozen=True)
class Condition:
    """One scored corruption: ``family`` at ``severity`` (its ``index`` in the family's list)."""

    family: str
    severity: float
    index: int


@dataclass
class Corrupted:
    """A corrupted test split as the scorer reads it: ``samples`` (id -> K = 1 sample arrays),
    ``templates`` (id -> (object name, vertices, faces) where the object was swapped or mirrored),
    ``captions`` (id -> caption lines)."""

    samples: dict
    captions: dict
    templates: dict = field(default_factory=dict)

    def digest(self) -> str:
        """sha256 of everything the scorer reads (equal digests: equal scores)."""
        h = hashlib.sha256()
        for cid in sorted(self.samples):
            h.update(cid.encode())
            for k in sorted(self.samples[cid]):
                a = np.ascontiguousarray(self.samples[cid][k])
                h.update(f"{k}{a.dtype}{a.shape}".encode())
                h.update(a.tobytes())
            for part in self.templates.get(cid, ()):
                h.update(part.encode() if isinstance(part, str) else np.ascontiguousarray(part).tobytes())
            h.update(repr([(c.text, c.tokens) for c in self.captions.get(cid, [])]).encode())
        return h.hexdigest()


class AuditScorer(HOIScorer):
    """The ``hoi`` scorer over an in-memory submission. With ``base`` (a prepared scorer's
    state) it takes the ground truth's statistics from it instead of recomputing them, and
    ``text_sets`` (caption embeddings per test clip, in test-split order) replaces the
    captions' embeddings; ``templates`` replaces the object template of swapped or mirrored clips."""

    def __init__(self, store, proto, ev, track, corrupted: Corrupted, label: str, options: dict,
                 base: HOIScorer | None = None, text_sets: list | None = None):
        super().__init__(store, proto, ev, track, f"audit:{label}", dict(options, clip_data=None))
        self.corrupted, self.label, self.base, self.text_sets = corrupted, label, base, text_sets

    def prepare(self) -> None:
        if self.base is None:
            super().prepare()
            return
        for name in ("overrides", "rows", "fps", "cap", "mode", "test_ids", "real_all", "sets_all", "gate"):
            setattr(self.st, name, getattr(self.base.st, name))
        self.st.overrides = list(self.base.st.overrides)
        if self.text_sets is not None:
            self.st.sets_all = self.text_sets

    def open_submission(self):
        from ..scoring.submission_read import MemorySubmission
        return nullcontext(MemorySubmission(self.corrupted.samples, self.label))

    def validate(self, sub) -> list[str]:
        """Every test id (the corrupted ground truth is scored whatever a submission check
        would say of it: the audit measures the metrics, not the validator)."""
        from ..scoring.validate import ValidationReport
        proto = self.proto
        ids = sorted(sub.ids)
        missing = sorted(set(self.st.test_ids) - set(ids))
        if missing:
            raise EvaluationRefused(f"audit {self.label}: no corrupted sample for test clip {missing[0]}")
        self.st.report = ValidationReport([], list(self.st.test_ids), ids, 1, ids)
        self.st.meta = dict(sub.meta)
        self.st.cache = None
        self.st.K = 1
        self.st.ks_physical = sorted({proto.sample_index(r, 1) for r in range(proto.replications)})
        self.st.mm_ok = 1 >= proto.mm_samples
        self.st.ks_embed = sorted(set(self.st.ks_physical) | ({0} if self.st.mm_ok else set()))
        self.st.ids = ids
        return ids

    def stream(self, sub, ids: list[str]) -> Iterable:
        """The scorer's units, with a swapped object's template and name in its inputs."""
        units = super().stream(sub, ids)
        swaps = self.corrupted.templates
        if not swaps:
            return units
        return (dataclasses.replace(u, object_name=swaps[u.key[0]][0], template_vertices=swaps[u.key[0]][1],
                                    template_faces=swaps[u.key[0]][2]) if u.key[0] in swaps else u for u in units)


# ---------------------------------------------------------------------------- the split
def ground_truth(store, test_ids: Sequence[str], body_arrays: Sequence[str] = ()) -> tuple[dict, dict]:
    """``(clips, captions)`` of the test split: each clip's ``joints``, ``obj_rot``,
    ``obj_trans`` as float32 (what ``hoibench submission from-store`` writes), the
    ``body_arrays`` the track's submissions carry (``markers``) and ``object_name``; its
    whole-clip caption lines (what the scorer reads)."""
    from ..scoring.hoi import _caption_lines
    clips, captions = {}, {}
    for cid in test_ids:
        clip = store.load(cid, keys=("joints", "obj_rot", "obj_trans", "object_name", *body_arrays))
        arrays = {"joints": np.asarray(clip["joints"], np.float32)}
        for key in body_arrays:
            arrays[key] = np.asarray(clip[key], np.float32)
        if "obj_rot" in clip and "obj_trans" in clip:
            arrays["obj_rot"] = np.asarray(clip["obj_rot"], np.float32)
            arrays["obj_trans"] = np.asarray(clip["obj_trans"], np.float32)
        if "object_name" in clip:
            arrays["object_name"] = np.array(str(clip["object_name"]))
        clips[cid] = arrays
        captions[cid] = _caption_lines(store.root, cid)
    return clips, captions


def annotator_spec():
    """The default annotator spec (the object nouns a noun swap uses), or None when it cannot be read."""
    try:
        from ..text.spec import load_spec
        return load_spec()
    except (OSError, ValueError, KeyError):
        return None


def corrupted_split(store, clips: Mapping[str, Mapping], captions: Mapping, family: str, severity: float,
                    seed: int, ctx, template_cache: dict) -> Corrupted:
    """The split after ``family`` at ``severity``: K = 1 samples (float32), the swapped
    objects' templates (read once into ``template_cache``), the caption lines."""
    new_clips, new_caps = apply(family, severity, clips, captions, seed, ctx)
    samples, templates = {}, {}
    # a mirrored clip's object is its mirrored template posed by the mirrored pose (mirror_arrays)
    mirrored = set(selected(clips, severity, seed, "mirror")) if family == "mirror" else set()
    for cid, arrays in new_clips.items():
        samples[cid] = {k: np.asarray(arrays[k], np.float32)[None] for k in ("joints", "obj_rot", "obj_trans")
                        if k in arrays}
        if "markers" in clips[cid]:       # markers follow the corrupted joints (follow_markers)
            markers = follow_markers(clips[cid]["markers"], clips[cid]["joints"], arrays["joints"])
            samples[cid]["markers"] = markers[None]
        name = str(arrays.get("object_name", ""))
        if name and (name != str(clips[cid].get("object_name", "")) or cid in mirrored):
            if name not in template_cache:
                template_cache[name] = store.object_template(name)
            v, f = template_cache[name]
            templates[cid] = (name, *(mirror_template(v, f) if cid in mirrored else (v, f)))
    return Corrupted(samples, {cid: list(v) for cid, v in new_caps.items()}, templates)


def caption_sets(ev, test_ids: Sequence[str], lines: Mapping[str, Sequence], known: dict) -> list[np.ndarray]:
    """Caption embeddings per test clip (the scorer's rule: a text's HumanML3D tokens are
    those of its first line); texts already in ``known`` (text -> embedding) keep their
    embedding, new ones are embedded in one sorted batch and added to it."""
    toks: dict[str, tuple] = {}
    for cid in test_ids:
        for c in lines[cid]:
            if c.tokens:
                toks.setdefault(c.text, c.tokens)
    new = sorted({c.text for cid in test_ids for c in lines[cid]} - set(known))
    if new:
        known.update(zip(new, ev.embed_text(new, tokens=[toks.get(t) for t in new])))
    return [np.stack([known[c.text] for c in lines[cid]]) for cid in test_ids]


def _physical_job(job: tuple) -> tuple[str, Any]:
    """``(digest, stats)`` of one per-clip physical unit (the scorer's ``unit``)."""
    digest, fn, inp = job
    return digest, fn(inp)[1]


def _unit_digest(inp) -> str:
    """sha256 of what a physical unit reads that can differ between conditions."""
    h = hashlib.sha256(repr((inp.key, inp.object_name, inp.windows)).encode())
    for a in (inp.joints, inp.obj_rot, inp.obj_trans, inp.template_vertices, inp.template_faces):
        if a is not None:
            a = np.ascontiguousarray(a)
            h.update(f"{a.dtype}{a.shape}".encode())
            h.update(a.tobytes())
    return h.hexdigest()


# ---------------------------------------------------------------------------- scoring
@dataclass
class Setup:
    """What every condition's scorer shares: store, protocol, evaluator, track, options, and
    the layout whose families apply (``single`` | ``multibody``)."""

    store: Any
    proto: Any
    ev: Any
    track: Any
    options: dict
    layout: str = "single"


def load_setup(data: str | Path, evaluator: str | Path, protocol=None, allow_failed_gate: bool = False,
               allow_protocol_mismatch: bool = False) -> Setup:
    """The store, its track, the protocol (the store's default when None), the evaluator:
    what ``hoibench evaluate`` loads, checked the same way (a protocol of another mode or
    representation only with ``allow_protocol_mismatch``, recorded). A multi-body store gets
    its recognizer and ``layout="multibody"``."""
    from ..datasets.store import Store
    from ..evaluator.backends import backend_of, load_evaluator, peek_card
    from ..tracks.protocol import default_protocol_id, get_protocol
    from ..tracks.registry import track_for_store
    store = Store(Path(data))
    track = track_for_store(store)
    if track.scorer not in ("hoi", "multibody"):
        raise EvaluationRefused(f"--data {data}: a store of the {track.name} track ({track.scorer} scorer); the audit "
                                f"corrupts single-body and multi-body clips (tracks scored by the hoi and multibody "
                                f"scorers)")
    proto = get_protocol(protocol or default_protocol_id(store.manifest))
    if track.scorer == "multibody":
        if proto.kind != track.protocol_kind:
            raise EvaluationRefused(f"--protocol {proto.ref}: a {proto.kind} protocol; {data} is scored under "
                                    f"{track.protocol_kind} protocols ({', '.join(track.protocols)})")
        from ..scoring.multibody import MultiBodyScorer
        rec = load_evaluator(evaluator, kind=track.evaluator_kind, **MultiBodyScorer.evaluator_options)
        return Setup(store, proto, rec, track, {"evaluator_backend": track.evaluator_kind}, "multibody")
    from ..scoring.validate import required_arrays
    extra = [a for a in required_arrays(proto) if a not in FOLLOWING_ARRAYS]
    if extra:
        raise EvaluationRefused(f"--data {data}: the {track.name} track's submissions carry {', '.join(extra)}; the "
                                f"audit corrupts joints and object poses and cannot move {extra[0]} with them yet")
    if proto.kind != track.protocol_kind:
        raise EvaluationRefused(f"--protocol {proto.ref}: a {proto.kind} protocol; {data} is scored under "
                                f"{track.protocol_kind} protocols ({', '.join(track.protocols)})")
    backend = backend_of(evaluator)
    options = {"allow_failed_gate": allow_failed_gate, "allow_protocol_mismatch": allow_protocol_mismatch,
               "allow_evaluator_mismatch": False,
               "evaluator_backend": backend.name if backend else track.evaluator_kind}
    HOIScorer.check_fit(store, proto, peek_card(evaluator, track.evaluator_kind), options)
    ev = load_evaluator(evaluator, kind=track.evaluator_kind, **HOIScorer.evaluator_options)
    return Setup(store, proto, ev, track, options)


def object_families(families: Sequence[str]) -> list[str]:
    """The families of ``families`` that move or swap the object (:mod:`hoibench.audit.objects`)."""
    from . import objects
    return [f for f in families if FAMILIES[f].fn.__module__ == objects.__name__]


def check_objects(store, families: Sequence[str], explicit: bool) -> list[str]:
    """``families`` less the object families when a test clip has no object (a human-only
    store): ValueError naming the clip when they were asked for by name."""
    lacking = [c["id"] for c in store.manifest["clips"] if c["split"] == "test" and not c.get("object")]
    need = object_families(families)
    if not lacking or not need:
        return list(families)
    if explicit:
        raise ValueError(f"--families {need[0]}: test clip {lacking[0]} of {store.root} has no object (the object "
                         f"families need one on every test clip)")
    return [f for f in families if f not in need]


def conditions(families: Sequence[str], layout: str = "single") -> list[Condition]:
    """Every (family, severity) of ``families`` (of ``layout``'s registry), in the families'
    and severities' order."""
    from .families import registry
    specs = registry(layout)
    return [Condition(f, float(s), i) for f in families for i, s in enumerate(specs[f].severities)]


def score_conditions(setup: Setup, families: Sequence[str], seed: int = DEFAULT_SEED, executor: str = "serial",
                     ) -> dict[Condition, tuple[dict, dict]]:
    """``{condition: (result, per-clip arrays)}`` for every severity of ``families`` (module
    docstring). The result is the ``hoibench-result-2`` dict ``evaluate`` would return for a
    submission of the corrupted clips (a multi-body store:
    :func:`hoibench.audit.multibody_runner.score_multibody_conditions`)."""
    from ..core.parallel import map_units
    if setup.layout == "multibody":
        from .multibody_runner import score_multibody_conditions
        return score_multibody_conditions(setup, conditions(families, "multibody"), seed, executor)
    store, proto, ev = setup.store, setup.proto, setup.ev
    base = AuditScorer(store, proto, ev, setup.track, Corrupted({}, {}), "ground truth", setup.options)
    base.prepare()
    test_ids = list(base.st.test_ids)
    from ..scoring.validate import required_arrays
    clips, captions = ground_truth(store, test_ids, [a for a in required_arrays(proto) if a in FOLLOWING_ARRAYS])
    ctx = split_context(clips, captions, fps=base.st.fps, spec=annotator_spec())
    known = _known_captions(base, captions)
    templates: dict = {}
    plan: dict[str, list[Condition]] = {}
    corrupted: dict[str, Corrupted] = {}

    def corrupt(cond: Condition) -> Condition:
        c = corrupted_split(store, clips, captions, cond.family, cond.severity, seed, ctx, templates)
        key = c.digest()
        plan.setdefault(key, []).append(cond)
        corrupted.setdefault(key, c)
        return cond

    for _ in map_units(corrupt, conditions(families), "serial", progress="audit: corrupt"):
        pass
    gt_lines = {cid: list(captions[cid]) for cid in test_ids}

    def stream(key: str) -> tuple[str, AuditScorer, list]:
        c = corrupted[key]
        cond = plan[key][0]
        sets = None if _same_lines(c.captions, gt_lines) else caption_sets(ev, test_ids, c.captions, known)
        scorer = AuditScorer(store, proto, ev, setup.track, c, f"{cond.family}@{cond.severity:g}", setup.options,
                             base=base, text_sets=sets)
        scorer.prepare()
        with scorer.open_submission() as sub:
            units = list(scorer.stream(sub, scorer.validate(sub)))     # embeds the motions here
        return key, scorer, units

    streamed = list(map_units(stream, sorted(plan), "serial", progress="audit: embed"))
    jobs: dict[str, tuple] = {}
    for _, scorer, units in streamed:
        for u in units:
            d = _unit_digest(u)
            jobs.setdefault(d, (d, scorer.unit, u))
    stats = dict(map_units(_physical_job, [jobs[d] for d in sorted(jobs)], executor, progress="audit: physical"))

    def finish(item) -> tuple[str, tuple[dict, dict]]:
        key, scorer, units = item
        for u in units:
            scorer.update((u.key, stats[_unit_digest(u)]))
        rows = scorer.replications()
        arrays, scorer.st.clip_arrays = scorer.st.clip_arrays, {}   # no clip intervals: the audit draws its own
        return key, (scorer.summary(rows), arrays)

    done = dict(map_units(finish, streamed, "serial", progress="audit: replications"))
    return {cond: done[key] for key, conds in plan.items() for cond in conds}


def _known_captions(base: AuditScorer, captions: Mapping[str, Sequence]) -> dict[str, np.ndarray]:
    """text -> embedding of every ground-truth caption (from the base scorer's caption sets)."""
    known = {}
    for i, cid in enumerate(base.st.test_ids):
        for c, e in zip(captions[cid], base.st.sets_all[i]):
            known.setdefault(c.text, e)
    return known


def _same_lines(a: Mapping, b: Mapping) -> bool:
    return all([(c.text, c.tokens) for c in a[k]] == [(c.text, c.tokens) for c in b[k]] for k in b)


__all__ = ["Condition", "Corrupted", "AuditScorer", "Setup", "load_setup", "conditions", "score_conditions",
           "object_families", "check_objects",
           "ground_truth", "corrupted_split", "caption_sets", "DEFAULT_SEED"]
