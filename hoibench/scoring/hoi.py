"""The single-body scorer (tracks of kind ``hoi`` and ``human``): R-precision, FID,
MM-Dist, Diversity and MultiModality from a contrastive evaluator, and the physical metrics
(CD, OCD, PS, FSR, extras) per clip on the executor.

Stages (:mod:`hoibench.scoring.pipeline`; docs/protocol.md):

1. ``prepare``: check that the protocol and the evaluator fit the store (dataset, mode, fps,
   representation; refused unless overridden, and every override is recorded in the
   result); re-measure the evaluator's sanity gate on this store's ground truth (the card's
   own record is not trusted): a failing gate refuses the evaluation unless
   ``allow_failed_gate``, which the result records;
2. ``validate``: the submission against the store's test split (:mod:`hoibench.scoring.submission`,
   within byte budgets, one file at a time); only valid ids are scored and every missing id
   is listed in the result, which is marked incomplete;
3. ``stream``: the valid ids one file at a time: each sample the protocol uses is encoded
   with the store's representation (hoi269 rows; a ``human`` evaluator reads their first 263
   columns) and embedded, and its physical metrics are mapped on the executor (identical for
   every executor); peak memory holds one file, the embeddings and the per-clip statistics,
   whatever the submission's size;
4. ``replications``: per replication r: sample ``r mod K``, a caption per clip drawn with the
   protocol's seed, R-precision top-1/2/3 and MM-Dist over the protocol's pools, FID against
   the ground-truth embeddings, Diversity, MultiModality (only when K >= the protocol's
   samples); the physical metrics of sample ``r mod K`` -- per replication when the protocol
   crops the evaluated lengths (``length_crop``: each clip and replication draws its window,
   :func:`hoibench.metrics.legacy_rules.replication_windows`);
5. ``summary``: every value is checked finite: an infinite value stops the run naming the
   metric; a 0/0 (e.g. no clip has ground-contact frames) is reported as undefined, never as
   NaN; on a human-only store (no test clip has an object: RICH) the object metrics (CD,
   OCD, PS, penetration, contact IoU, hand contact, object floating) are undefined as "not
   applicable", while the embedding metrics, FSR and jitter are scored. Mean and 95% CI over
   replications are written as strict JSON with the protocol, evaluator, representation and
   toolkit versions, sample counts, missing ids, flags and timings.
"""
from __future__ import annotations

import platform
import time
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any, Callable, Iterator, Sequence

import numpy as np

from .. import __version__
from ..datasets.store import Store
from .pipeline import EvaluationRefused, Scorer
from .results import RESULT_FORMAT, metric_entry

#: motions embedded per batch while streaming
EMBED_BATCH = 64


@dataclass
class HOIState:
    """What the single-body scorer's stages hand on (one typed object instead of attributes
    set across five methods). ``prepare`` fills the ground truth, ``validate`` what is scored,
    ``stream`` the embeddings and physical metric states, ``replications`` the notes and the
    per-clip table."""

    # prepare: fit checks and the ground truth
    overrides: list = field(default_factory=list)
    rows: dict = field(default_factory=dict)          # test clip rows of the manifest, by id
    fps: float = 0.0
    cap: int = 0                                      # samples per prompt read at most
    mode: str = "clean"                               # hoi269 mode of the store
    test_ids: list = field(default_factory=list)
    window_dropped: list = field(default_factory=list)  # test ids shorter than the protocol's clip_window
    real_all: np.ndarray | None = None                # GT embeddings of every test clip
    sets_all: list = field(default_factory=list)      # caption embeddings per test clip
    gate: dict = field(default_factory=dict)
    # validate: what is scored
    report: Any = None
    cache: Any = None                                 # what validation read and encoded
    meta: dict = field(default_factory=dict)
    human_only: bool = False
    K: int = 1
    ks_physical: list = field(default_factory=list)
    ks_embed: list = field(default_factory=list)
    mm_ok: bool = False
    ids: list = field(default_factory=list)
    ahead: dict = field(default_factory=dict)         # (id, k) -> physical unit started during validation
    objects: bool = True                              # the protocol lists an object metric: computed
    # stream
    windowed: bool = False
    physical: dict = field(default_factory=dict)      # PhysicalMetrics per sample index or replication
    gen: np.ndarray | None = None                     # (K, ids, dim) generated embeddings
    not_computed: dict = field(default_factory=dict)  # catalogue metrics that cannot run here, and why
    t3: float = 0.0
    # replications
    t4: float = 0.0
    notes: list = field(default_factory=list)
    per_clip: dict | None = None
    clip_arrays: dict = field(default_factory=dict)   # the per-clip data (scoring.clip_data)
    fid_method: str = ""


def _caption_lines(data: Path, clip_id: str) -> list:
    """Whole-clip caption lines of a test clip (start = end = 0; timed captions describe a
    segment, not the clip), all lines when there is no whole-clip one: their
    :class:`~hoibench.evaluator.text.Caption` (text and HumanML3D tokens)."""
    from ..evaluator.text import parse_text_file
    from ..core.ids import check_id
    from ..core.io import read_regular_file
    path = data / "texts" / f"{check_id(clip_id, 'clip id', data / 'manifest.json')}.txt"
    if not path.exists():
        return []
    caps = parse_text_file(read_regular_file(path, 1024 ** 2, "caption file").decode("utf-8", "replace"))
    whole = [c for c in caps if c.whole_clip]
    return whole or caps


def _check_fit(proto, store: Store, ev, allow_protocol_mismatch: bool, allow_evaluator_mismatch: bool) -> list[dict]:
    """Refuse a protocol or evaluator that does not fit the store, or record the override."""
    from ..evaluator import store_mismatches
    from ..tracks.protocol import protocol_mismatches
    overrides = []
    for kind, reasons, allowed, flag in (
            ("protocol_mismatch", protocol_mismatches(proto, store.manifest), allow_protocol_mismatch,
             "--allow-protocol-mismatch"),
            ("evaluator_mismatch", store_mismatches(ev, store.manifest), allow_evaluator_mismatch,
             "--allow-evaluator-mismatch")):
        if not reasons:
            continue
        if not allowed:
            raise EvaluationRefused("; ".join(reasons) + f" (pass {flag} to score anyway: the result records it)")
        overrides.append({"override": kind, "reasons": reasons})
    return overrides


def _stream(sub, ids: Sequence[str], ks_physical: Sequence[int], ks_embed: Sequence[int], ev, store: Store,
            groups, proto, mode: str, fps: float, gen: np.ndarray, windows=None, cache=None, crop=None,
            ground_truth: bool = False, ahead: dict | None = None) -> Iterator:
    """Yield the physical-metric inputs of every (id, sample) in ``ks_physical``, loading one
    file at a time; as a side effect fill ``gen[k, i]`` with the embeddings of ``ks_embed``.
    ``windows(id, k)``: the legacy length windows of the replications using sample k;
    ``cache``: what validation read and encoded (:class:`~hoibench.scoring.read_cache.ReadCache`),
    used instead of reading and encoding again; ``crop(id, rows)``: the rows the evaluator
    embeds (None: all); ``ground_truth``: the inputs carry their test clip's ground truth. Under
    a protocol's ``clip_window`` every sample is cut to its first frames before it is encoded
    and measured. ``ahead``: ``{(id, k): future}`` of units already started on the pool,
    yielded as they are (:func:`hoibench.core.parallel.map_units` waits for them)."""
    from ..metrics.physical import clip_input_factory
    from .submission import encode_sample

    cfg = proto.physical_config()
    window = clip_window_frames(proto)
    make_input = clip_input_factory(store, ids, groups, proto.physical["contact_thresholds"], fps,
                                    cfg.contact_gt_rule, cfg.contact_gt_threshold_m, ground_truth, window)
    pending: list[tuple[int, int, np.ndarray]] = []

    def flush():
        if pending:
            emb = ev.embed_motion([f for _, _, f in pending])
            for (k, i, _), e in zip(pending, emb):
                gen[k, i] = e
            pending.clear()

    rows_of = getattr(ev, "sample_rows", None)     # evaluators with their own motion input (interact)
    for i, cid in enumerate(ids):
        arrays = _window_arrays((cache.take_arrays(cid) if cache is not None else None) or sub.load(cid), window)
        for k in ks_embed:
            kept = cache.take_features(cid, k) if cache is not None and not rows_of and window is None else None
            feats = kept if kept is not None else (rows_of(arrays, k, store, cid) if rows_of else
                                                    encode_sample(arrays, k, mode, fps))
            if not np.isfinite(feats).all():      # validate refuses these; never embed them
                raise ValueError(f"{cid}: sample {k} encodes to non-finite features")
            if crop is not None:
                feats = crop(cid, feats)
            pending.append((k, i, feats))
            if len(pending) >= EMBED_BATCH:
                flush()
        for k in ks_physical:
            if ahead and (cid, k) in ahead:
                yield ahead.pop((cid, k))
                continue
            inp = make_input(cid, {key: v[k] for key, v in arrays.items() if key != "hml263"}, k)
            if windows is not None:
                inp.windows = windows(cid, k)
            yield inp
        del arrays
    flush()


#: fewest test clips the evaluator's sanity gate reads (its ground-truth FID halves)
MIN_GATE_CLIPS = 4


def clip_window_frames(proto) -> int | None:
    """The frames a protocol's ``clip_window`` keeps of every clip (None: whole clips)."""
    window = getattr(proto, "clip_window", None)
    return int(window["frames"]) if window else None


def windowed_ids(proto, rows: dict, ids: Sequence[str]) -> tuple[list[str], list[str]]:
    """(kept, dropped) test ids: under a ``clip_window`` with ``drop_shorter`` the clips of
    fewer frames than the window are dropped (``rows[id]["frames"]``, the store manifest)."""
    window = getattr(proto, "clip_window", None)
    if not window or not window["drop_shorter"]:
        return list(ids), []
    n = int(window["frames"])
    return ([c for c in ids if int(rows[c]["frames"]) >= n], [c for c in ids if int(rows[c]["frames"]) < n])


def _window_arrays(arrays: dict, window: int | None) -> dict:
    """The first ``window`` frames of every per-sample frame array ``(K, T, ...)``."""
    if window is None:
        return arrays
    return {k: (v[:, :window] if np.ndim(v) >= 2 else v) for k, v in arrays.items()}


def embedded_rows(proto, cid: str, frames: int, feats: np.ndarray) -> np.ndarray:
    """The rows of clip ``cid`` the evaluator embeds: under a protocol with ``crop_embeddings``
    its replication-0 window of ``physical.length_crop`` (the physical metrics' own seeded
    draw, :func:`hoibench.metrics.legacy_rules.replication_windows`), else (or when the window
    starts past the rows) all of ``feats``."""
    if not getattr(proto, "crop_embeddings", False):
        return feats
    from ..metrics.legacy_rules import replication_windows
    rule = proto.physical_config().length_crop
    (_, start, length), = replication_windows(cid, int(frames), rule, [0], proto.seed_for)
    return feats[start:start + length] if start < len(feats) else feats


def _text_encoder(ev) -> dict:
    """The evaluator's pretrained text encoder (name and weights' sha256) as its card names it:
    a leaderboard flags a generator conditioned on the same weights."""
    te = getattr(ev, "card", {}).get("text_encoder") if isinstance(getattr(ev, "card", None), dict) else None
    if not isinstance(te, dict):
        return {}
    return {k: te[k] for k in ("name", "weights_sha256", "fine_tuned") if k in te}


def _shares_text_encoder(meta: dict, ev) -> str:
    """The shared encoder's name when the submission says (``source.training.text_encoder``) its
    generator was conditioned on the pretrained text-encoder weights the evaluator reads captions
    with (sha256 equal), else ""."""
    src = meta.get("source") if isinstance(meta.get("source"), dict) else {}
    training = src.get("training") if isinstance(src.get("training"), dict) else {}
    mine = training.get("text_encoder") if isinstance(training.get("text_encoder"), dict) else {}
    theirs = _text_encoder(ev)
    if mine.get("weights_sha256") and mine.get("weights_sha256") == theirs.get("weights_sha256"):
        return str(theirs.get("name") or mine.get("encoder"))
    return ""


def _finite_rows(per_rep: list[dict]) -> tuple[list[dict], dict]:
    """Drop undefined (NaN: 0/0) values from the replication rows, recording which; an
    infinite value raises naming the metric and the replication."""
    undefined: dict[str, list[int]] = {}
    rows = []
    for r, row in enumerate(per_rep):
        clean = {}
        for name, value in row.items():
            arr = np.asarray(value, dtype=np.float64)
            if np.isinf(arr).any():
                raise ValueError(f"metric {name!r} is infinite in replication {r}: refusing to write a result "
                                 "(an input escaped the plausibility checks; please report it)")
            if np.isnan(arr).any():
                undefined.setdefault(name, []).append(r)
                continue
            clean[name] = value
        rows.append(clean)
    notes = {name: (f"undefined (0/0: no qualifying frames or clips) in {len(reps)} of {len(per_rep)} "
                    "replications") for name, reps in undefined.items()}
    return rows, notes


def _loop_settings(proto) -> dict:
    """The protocol's numbers in a reference loop's own keywords: replications, R-precision
    batch (``r_size`` in ChainHOI's, ``batch_size`` in the others), top-k and diversity pairs
    (InterAct's loop fixes its own: 300, or 50 under 300 rows); text-to-motion's also the
    MultiModality texts, samples and pairs."""
    batch = "r_size" if proto.embedding_loop == "chainhoi" else "batch_size"
    out = {"replications": int(proto.replications), batch: int(proto.r_precision_pool_size),
           "top_k": int(proto.r_precision_top_k)}
    if proto.embedding_loop != "interact":
        out["diversity_times"] = int(proto.diversity_pairs)
    if proto.embedding_loop == "t2m":            # text-to-motion's loop takes MultiModality's sizes too
        out.update(mm_texts=int(proto.mm_texts), mm_repeats=int(proto.mm_samples), mm_times=int(proto.mm_pairs))
    return out


class HOIScorer(Scorer):
    """The ``hoi`` scorer (see the module docstring for its stages)."""

    name = "hoi"
    evaluator_options = {"allow_failed_gate": True}     # the gate is measured in prepare, on this store
    fills_clip_data = True
    map_options = {"window": EMBED_BATCH, "progress": "evaluate"}

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.st = HOIState()

    @classmethod
    def check_fit(cls, store, protocol, card: dict, options: dict) -> None:
        """The fit checks of :meth:`prepare` on the card alone (before the weights load)."""
        try:
            _check_fit(protocol, store, card, options.get("allow_protocol_mismatch", False),
                       options.get("allow_evaluator_mismatch", False))
        except (AttributeError, TypeError):     # a malformed card: the loader names its field
            return

    @classmethod
    def warm_up(cls, store, protocol) -> tuple | None:
        """Each worker builds the signed-distance fields of the test split's objects
        (:func:`hoibench.metrics.physical.warm_fields`) while the ground truth is embedded."""
        from ..metrics.physical import warm_fields
        names = sorted({str(c["object"]) for c in store.manifest.get("clips", [])
                        if c.get("split") == "test" and c.get("object")})
        return (warm_fields, (str(store.root), names, protocol.physical_config())) if names else None

    def prepare(self) -> None:
        """Fit checks, then the ground truth: captions, embeddings, the sanity gate on this store."""
        from ..evaluator.gate import gate_from_embeddings
        from .submission import submission_context
        store, proto, ev, opts = self.store, self.proto, self.ev, self.options
        self.st.overrides = _check_fit(proto, store, ev, opts.get("allow_protocol_mismatch", False),
                                    opts.get("allow_evaluator_mismatch", False))
        self.st.rows, self.st.fps, self.st.cap, self.st.mode = submission_context(store, proto)
        t1 = time.perf_counter()
        data = store.root
        test_ids, self.st.window_dropped = windowed_ids(proto, self.st.rows, store.clip_ids("test"))
        if self.st.window_dropped and len(test_ids) < MIN_GATE_CLIPS:
            raise EvaluationRefused(f"{data}: protocol {proto.ref}'s clip_window of {clip_window_frames(proto)} frames "
                                    f"keeps {len(test_ids)} of {len(test_ids) + len(self.st.window_dropped)} test clips "
                                    f"(shorter ones are not scored); the evaluator's gate needs {MIN_GATE_CLIPS}")
        self.st.test_ids = test_ids
        lines = {cid: _caption_lines(data, cid) for cid in test_ids}
        captions = {cid: [c.text for c in caps] for cid, caps in lines.items()}
        no_text = [cid for cid, c in captions.items() if not c]
        if no_text:
            raise EvaluationRefused(f"{data}: no texts for {len(no_text)} test clip(s) (e.g. {no_text[0]}); "
                                    f"run hoibench annotate first")
        from .reference_cache import load_reference, reference_key, save_reference
        # only an evaluator identified by its content (a loaded folder's verified id) is cached
        key = reference_key(store, proto, ev.id, test_ids, lines, self.st.mode, self.st.fps) if ev.id else None
        cached = load_reference(key, len(test_ids)) if key else None
        if cached is not None:
            self.st.real_all, self.st.sets_all, self.st.gate = cached
        else:
            self.st.real_all, self.st.sets_all = self._ground_truth_embeddings(test_ids, lines)
            # the gate from the weights, on this store
            self.st.gate = gate_from_embeddings(self.st.real_all, self.st.sets_all, test_ids, proto)
            if key:
                save_reference(key, self.st.real_all, self.st.sets_all, self.st.gate)
        gate = self.st.gate
        if not gate["passed"]:
            if not opts.get("allow_failed_gate", False):
                raise EvaluationRefused(f"evaluator {str(ev.id)[:12]} fails the sanity gate on {data}'s test split: "
                                        + "; ".join(gate["reasons"])
                                        + " (pass --allow-failed-gate to score anyway: the result is marked)")
            self.st.overrides.append({"override": "failed_gate", "reasons": list(gate["reasons"])})
        self.timings["ground_truth_s"] = time.perf_counter() - t1

    def _ground_truth_embeddings(self, test_ids: list[str], lines: dict) -> tuple[np.ndarray, list[np.ndarray]]:
        """The evaluator's embeddings of the test clips (N, D) and of each clip's captions."""
        store, ev = self.store, self.ev
        window = clip_window_frames(self.proto)
        real = ev.embed_motion([self._embedded(cid, _real_features(store, cid, ev, window, self.st.mode))
                                for cid in test_ids])
        captions = {cid: [c.text for c in caps] for cid, caps in lines.items()}
        all_caps = sorted({c for caps in captions.values() for c in caps})
        # the store's HumanML3D tokens of each caption (first line wins), for evaluators that read them
        toks: dict[str, tuple] = {}
        for caps in lines.values():
            for c in caps:
                if c.tokens:
                    toks.setdefault(c.text, c.tokens)
        cap_emb = dict(zip(all_caps, ev.embed_text(all_caps, tokens=[toks.get(c) for c in all_caps])))
        return real, [np.stack([cap_emb[c] for c in captions[cid]]) for cid in test_ids]

    def open_submission(self):
        from .submission import Submission, limits_for
        return Submission(self.submission, limits=limits_for(self.st.rows, self.st.fps, self.st.cap))

    def validate(self, sub) -> list[str]:
        from .submission import validation_report
        proto = self.proto
        t2 = time.perf_counter()
        from .read_cache import ReadCache
        self.st.cache = ReadCache(on_keep=self._start_ahead())
        self.st.report = report = validation_report(sub, self.store, protocol=proto, keep=self.st.cache)
        kept = set(self.st.test_ids)
        ids = sorted(i for i in report.valid_ids if i in kept)
        if not ids:
            first = report.errors[0] if report.errors else None
            raise EvaluationRefused(f"{self.submission}: no valid test id to score ({len(report.errors)} error(s)"
                                    f"{f', the first: {first.id}: {first.field}: {first.message}' if first else ''}); "
                                    f"run hoibench validate for the list")
        self.st.meta = dict(sub.meta or {})
        flags = self.st.meta.get("flags") if isinstance(self.st.meta.get("flags"), dict) else {}
        self.st.human_only = flags.get("human_only") is True
        if self.st.human_only and getattr(self.ev, "variant", "human") == "hoi":
            raise EvaluationRefused(f"{self.submission}: submission.json: flags.human_only is set, but evaluator "
                                    f"{self.ev.id} embeds human and object channels (variant 'hoi'); score a "
                                    f"human-only submission with a 'human' evaluator (train-evaluator --variant human)")
        self.timings["validate_s"] = time.perf_counter() - t2
        self.st.K = K = int(report.samples_per_prompt or 1)
        self.st.ks_physical = sorted({proto.sample_index(r, K) for r in range(proto.replications)})
        self.st.mm_ok = K >= proto.mm_samples
        mm = set(range(proto.mm_samples)) if self.st.mm_ok else set()
        self.st.ks_embed = sorted(set(self.st.ks_physical) | mm)
        self.st.ids = ids
        self._keep_ahead(ids)
        return ids

    def _physical_unit(self) -> tuple[Callable, bool]:
        """The per-clip physical function (the protocol's catalogue metrics with a per-clip
        function included; the object metrics only when the protocol lists one of them) and
        whether its inputs carry the ground truth; notes in ``st.not_computed`` the metrics
        that cannot run here."""
        from ..metrics.catalog import METRICS, object_metrics, unavailable
        from ..metrics.physical import _unit
        proto, cfg = self.proto, self.proto.physical_config()
        self.st.objects = bool(set(proto.metrics) & set(object_metrics()))
        extra, self.st.not_computed = [], {}
        for n in proto.metrics:
            if n in METRICS and METRICS[n].clip_fn:
                why = unavailable(n)
                if why:
                    self.st.not_computed[n] = why
                else:
                    extra.append((n, proto.settings_for(METRICS[n].settings_key)))
        unit = partial(_unit, config=cfg, **({"extra": tuple(extra)} if extra else {}),
                       **({} if self.st.objects else {"objects": False}))
        return unit, any(METRICS[n].needs_ground_truth for n, _ in extra)

    def _start_ahead(self) -> Callable | None:
        """A hook that starts each validated file's physical units on the pool at once, while
        this process validates the rest (the pool would idle otherwise), assuming every test id
        is scored with the file's own sample count; :meth:`_keep_ahead` keeps them only if that
        holds. None (nothing started) without a process pool, or when the protocol cuts windows
        or clips (their units depend on more than the file)."""
        import concurrent.futures as cf
        from ..core.parallel import submit_ahead
        from ..metrics.physical import clip_input_factory, load_groups
        proto, st = self.proto, self.st
        cfg = proto.physical_config()
        if not isinstance(self.pool, cf.ProcessPoolExecutor) or cfg.length_crop != "none" \
                or clip_window_frames(proto) is not None:
            return None
        unit, ground_truth = self._physical_unit()
        make = clip_input_factory(self.store, st.test_ids, load_groups(self.store.root),
                                  proto.physical["contact_thresholds"], st.fps, cfg.contact_gt_rule,
                                  cfg.contact_gt_threshold_m, ground_truth)
        test = set(st.test_ids)

        def start(sid: str, arrays: dict) -> None:
            if sid not in test or "joints" not in arrays:
                return
            K = int(arrays["joints"].shape[0])
            for k in sorted({proto.sample_index(r, K) for r in range(proto.replications)}):
                inp = make(sid, {key: v[k] for key, v in arrays.items() if key != "hml263"}, k)
                st.ahead[(sid, k)] = (K, submit_ahead(self.pool, unit, inp))
        return start

    def _keep_ahead(self, ids: list[str]) -> None:
        """Keep the units started during validation when what they assumed holds (every test id
        scored, each with the submission's sample count); else drop them all (cancelled, or
        their results ignored) and score every unit in the stream."""
        ahead, self.st.ahead = self.st.ahead, {}
        if not ahead:
            return
        if ids == sorted(self.st.test_ids) and all(K == self.st.K for K, _ in ahead.values()):
            self.st.ahead = {key: future for key, (_, future) in ahead.items()}
            return
        for _, future in ahead.values():
            future.cancel()

    def stream(self, sub, ids: list[str]) -> Iterator:
        """One streaming pass: embeddings in this process, physical metrics on the executor."""
        from ..metrics.legacy_rules import replication_windows
        from ..metrics.physical import PhysicalMetrics, load_groups
        self.st.t3 = time.perf_counter()
        proto, K = self.proto, self.st.K
        cfg = proto.physical_config()
        # physical metrics per sample index, or per replication when lengths are cropped
        self.st.windowed = cfg.length_crop != "none"
        slots = range(proto.replications) if self.st.windowed else self.st.ks_physical
        self.st.physical = {s: PhysicalMetrics(cfg.mode, cfg.body_label) for s in slots}
        self.st.gen = np.zeros((self.st.K, len(ids), self.ev.embed_dim), np.float32)
        self.unit, ground_truth = self._physical_unit()
        windows = None
        if self.st.windowed:
            reps = {k: [r for r in range(proto.replications) if proto.sample_index(r, K) == k]
                    for k in self.st.ks_physical}
            windows = lambda cid, k: replication_windows(  # noqa: E731
                cid, int(self.st.rows[cid]["frames"]), cfg.length_crop, reps[k], proto.seed_for)
        st = self.st
        crop = self._embedded if proto.crop_embeddings else None
        return _stream(sub, ids, st.ks_physical, st.ks_embed, self.ev, self.store, load_groups(self.store.root),
                       proto, st.mode, st.fps, st.gen, windows, st.cache, crop, ground_truth, st.ahead)

    def update(self, out) -> None:
        key, stats = out
        if self.st.windowed:
            for r, st in stats["replications"].items():
                self.st.physical[r].update(key, st)
        else:
            self.st.physical[key[1]].update(key, stats)

    def replications(self) -> list[dict]:
        from ..metrics import embedding as em
        physical = {k: m.compute() for k, m in self.st.physical.items()}
        self.st.cache = None                     # every kept file was scored
        self.timings["stream_s"] = time.perf_counter() - self.st.t3
        t4 = time.perf_counter()
        proto, ids, K, gen = self.proto, self.st.ids, self.st.K, self.st.gen
        where_all = {cid: i for i, cid in enumerate(self.st.test_ids)}
        real = self.st.real_all[[where_all[c] for c in ids]]
        text_sets = [self.st.sets_all[where_all[c]] for c in ids]
        per_rep, self.st.notes = [], []
        if clip_window_frames(proto) is not None:
            dropped = self.st.window_dropped
            self.st.notes.append(f"clip_window: the first {clip_window_frames(proto)} frames of every clip are scored"
                                 + (f"; {len(dropped)} test clip(s) shorter than that are not (e.g. {dropped[0]})"
                                    if dropped else ""))
        if not proto.pools(ids, 0):
            self.st.notes.append(f"fewer valid test ids ({len(ids)}) than the pool size ({proto.r_precision_pool_size}): "
                              f"R-precision and MM-Dist use one pool of all ids (easier than the protocol's pools)")
        if not self.st.mm_ok:
            self.st.notes.append(f"MultiModality not computed: {K} sample(s) per prompt, the protocol needs "
                              f"{proto.mm_samples}")
        where = {cid: i for i, cid in enumerate(ids)}
        phys = self._physical_per_clip()
        k0 = proto.sample_index(0, K)
        from .clip_data import clip_arrays
        from .per_clip import per_clip_table
        self.st.per_clip = per_clip_table(ids, gen[k0], real, text_sets, phys[k0], k0)
        self.st.clip_arrays = clip_arrays(ids, gen, real, text_sets, phys)
        if isinstance(self.options.get("clip_data"), dict):
            self.options["clip_data"].update(self.st.clip_arrays)
        self.st.fid_method = "sqrtm" if proto.mode == "legacy" else "eigh"
        if proto.embedding_loop != "hoibench":
            self.st.t4 = t4
            return self._reference_loop_rows(real, text_sets, physical)
        pools_for = lambda r: [[where[c] for c in p] for p in proto.pools(ids, r)]  # noqa: E731
        retrieval, fid_by_sample = {}, {}
        real_stats = em.activation_statistics(real)               # once, for every sample index
        fid_method = self.st.fid_method
        for k in self.st.ks_physical:
            retrieval[k] = em.retrieval_replications(text_sets, gen[k], pools_for,
                                                     lambda r: proto.seed_for("caption", r),
                                                     proto.replications, proto.r_precision_top_k)
            fid_by_sample[k] = em.fid(real_stats, gen[k], method=fid_method)
        for r in range(proto.replications):
            k = proto.sample_index(r, K)
            tops, mm = retrieval[k]
            row = {f"r_precision_top{i + 1}": float(v) for i, v in enumerate(tops[r])}
            row["mm_dist"] = float(mm[r])
            row["fid"] = fid_by_sample[k]
            pairs = proto.effective_diversity_pairs(len(ids))
            if pairs > 0:
                row["diversity"] = em.diversity(gen[k], pairs, proto.seed_for("diversity", r))
            if self.st.mm_ok:
                sel = [where[c] for c in proto.multimodality_ids(ids, r)]
                row["multimodality"] = em.multimodality(gen[:proto.mm_samples, sel].transpose(1, 0, 2),
                                                        proto.mm_pairs, proto.seed_for("multimodality", r))
            row.update(self._physical_row(physical, r))
            per_rep.append(row)
        self.st.t4 = t4
        return per_rep

    def _reference_loop_rows(self, real: np.ndarray, text_sets: list[np.ndarray], physical: dict) -> list[dict]:
        """Per-replication rows from a paper's released loop (the protocol's ``embedding_loop``,
        :func:`hoibench.metrics.legacy_loops.run_loop`) on this submission's embeddings: one
        caption per clip drawn with the protocol's seed, sample 0 as the generated motions,
        the first ``mm_samples`` samples for MultiModality when K allows, the protocol's
        replications; the physical metrics of replication r are those of its own length windows
        (a length-cropping protocol) or of sample ``r mod K``."""
        from ..metrics.legacy_loops import LOOPS, LoopRefused, run_loop
        proto = self.proto
        rng = np.random.default_rng(proto.seed_for("caption", 0))
        text = np.stack([t[int(rng.integers(len(t)))] for t in text_sets])
        samples = self.st.gen[:proto.mm_samples] if self.st.mm_ok else None
        spec = LOOPS[proto.embedding_loop]
        clips = {"ids": list(self.st.ids), "lengths": [int(self.st.rows[c]["frames"]) for c in self.st.ids]} \
            if spec.clip_ids else {}
        try:
            result = run_loop(proto.embedding_loop, text, self.st.gen[0], real, samples, seed=int(proto.seed),
                              **_loop_settings(proto), **clips)
        except LoopRefused as exc:                # the loop's own selection leaves too little to score
            raise EvaluationRefused(f"protocol {proto.ref}: {exc}") from None
        self.st.fid_method = "sqrtm (the reference loop's)"
        self.st.notes.append(f"embedding metrics: the {spec.name} loop as released ({spec.source}), "
                          f"{proto.replications} replication(s)"
                          + ("; a single replication has no CI (shown as 0)" if proto.replications == 1 else ""))
        self.st.notes += [f"{proto.embedding_loop} loop: {n}" for n in result.notes]
        rows = []
        for r, row in enumerate(result.rows()):
            row.update(self._physical_row(physical, r))
            rows.append(row)
        return rows

    def _embedded(self, cid: str, feats: np.ndarray) -> np.ndarray:
        """The rows of ``cid`` the evaluator embeds (:func:`embedded_rows`)."""
        return embedded_rows(self.proto, cid, self.st.rows[cid]["frames"], feats)

    def _physical_per_clip(self) -> dict[int, dict[str, dict]]:
        """``{sample: {id: per-clip physical values}}`` for each scored sample: what the
        per-clip table (sample of replication 0) and the per-clip data (every sample) show;
        under a length-cropping protocol, replication 0's windows."""
        st = self.st
        sources: dict[int, dict] = {}
        out = {}
        for k in st.ks_physical:
            slot = 0 if st.windowed else k
            if slot not in sources:
                sources[slot] = st.physical[slot].per_clip()
            out[k] = {key[0]: row for key, row in sources[slot].items() if isinstance(key, tuple) and key[1] == k}
        return out

    def _physical_row(self, physical: dict, r: int) -> dict:
        """Replication r's physical metrics: its own length windows' (a length-cropping
        protocol) or sample ``r mod K``'s, numbers only."""
        m = physical[r if self.st.windowed else self.proto.sample_index(r, self.st.K)]
        return {key: float(v) for key, v in m.items() if isinstance(v, (int, float)) and not isinstance(v, bool)}

    def summary(self, rows: list[dict]) -> dict:
        from ..tracks.protocol import summarize_replications
        proto, ids, report, ev, store, meta = self.proto, self.st.ids, self.st.report, self.ev, self.store, self.st.meta
        per_rep, undefined = _finite_rows(rows)
        undefined.update(self.st.not_computed)
        if not self.st.objects:           # none listed, none computed: no "undefined" line for them
            from ..metrics.catalog import object_metrics
            for name in object_metrics():
                undefined.pop(name, None)
        human_store = not any(self.st.rows[cid].get("object") for cid in ids)
        if human_store or self.st.human_only:      # no object to measure against, or none generated
            from ..metrics.catalog import object_metrics
            why = ("not applicable: the scored clips have no object (human-only store, e.g. RICH's static scenes); "
                   "object metrics need an object mesh and pose" if human_store else
                   "not applicable: human-only submission (flags.human_only: the method generates no object "
                   "motion); the embedding metrics, FSR and jitter are scored on the human")
            for name in object_metrics():
                if name in undefined:
                    undefined[name] = why
        notes = self.st.notes + [f"{name}: {why}" for name, why in sorted(undefined.items())]
        shared = _shares_text_encoder(meta, ev)
        if shared:
            notes.append(f"the submission's generator is conditioned on the evaluator's own text encoder ({shared}): "
                         "R-precision and MM-Dist may be inflated; score it with an evaluator whose text branch "
                         "is independent of the conditioner")
        if proto.physical_config().ps_sign == "closest_face" and "ps" not in undefined:
            from ..metrics.physical import LEGACY_PS_NOTE
            notes.append(LEGACY_PS_NOTE)
        timings = self.timings
        timings["replications_s"] = time.perf_counter() - self.st.t4
        timings["total_s"] = time.perf_counter() - self.started
        flags = meta.get("flags") if isinstance(meta.get("flags"), dict) else {}
        overrides = self.st.overrides
        listed = set(proto.metrics) | {"clips", "clips_with_contact"}
        summary = summarize_replications(per_rep, proto.replications)
        over_clips = {}
        if self.st.K == 1 and self.st.clip_arrays:       # K = 1: replications resample captions and pools only
            from .paired import clip_intervals
            over_clips = clip_intervals(self.st.clip_arrays, proto, seed=int(proto.seed or 0))
        return {
            "format": RESULT_FORMAT, "kind": "hoi", "track": self.track.name,
            **proto.result_header(),
            "complete": bool(report.complete) and not overrides,
            "submission_complete": bool(report.complete),
            "overrides": overrides,
            "evaluator_id": ev.id, "evaluator_variant": ev.variant,
            "evaluator_text_encoder": _text_encoder(ev),
            "evaluator_backend": self.options.get("evaluator_backend", "contrastive"), "evaluator_gate": self.st.gate,
            "representation": store.manifest["representations"], "toolkit": "hoibench",
            "toolkit_version": __version__,
            "dataset": store.manifest["dataset"], "store_config_sha256": store.manifest.get("config_sha256"),
            "submission": {"path": str(self.submission), "method": meta.get("method"), "version": meta.get("version"),
                           "flags": {k: flags[k] for k in ("uses_gt_length", "samples_per_prompt",
                                                           "checkpoint_selection", "human_only") if k in flags}},
            "human_only": bool(self.st.human_only),
            "counts": {"test_ids": len(report.test_ids), "scored_ids": len(ids), "samples_per_prompt": self.st.K,
                       "missing_ids": report.missing_ids, "errors": len(report.errors),
                       "warnings": len(report.warnings),
                       **({"window_dropped_ids": len(self.st.window_dropped)} if self.st.window_dropped else {})},
            "body_surface": proto.physical_config().body_label,
            "numerics": {"fid": self.st.fid_method},
            "metric_variants": {"embedding_loop": proto.embedding_loop,
                                "physical": proto.physical_config().to_dict()},
            "metrics": {k: metric_entry(k, v["mean"], v["ci95"], v["n"], "replications", std=v["std"],
                                        **({"clips": over_clips[k]} if k in over_clips else {}))
                        for k, v in summary.items() if k in listed},
            "undefined_metrics": undefined,
            "per_replication": per_rep, "per_clip": self.st.per_clip, "notes": notes,
            "timings_s": {k: round(v, 3) for k, v in timings.items()},
            "platform": {"python": platform.python_version(), "numpy": np.__version__},
        }



def _real_features(store: Store, cid: str, ev=None, window: int | None = None, mode: str = "clean") -> np.ndarray:
    """A test clip's evaluator input: the evaluator's own rows when it defines ``store_rows``
    (interact: markers + object BPS; CHOIS: joints24), else the stored hoi269 (or hml263) rows.
    Under a ``window`` (frames), the rows of the clip's first ``window`` frames: the evaluator's
    own rows cut there, or the first frames encoded as a generated sample is (``mode``)."""
    if hasattr(ev, "store_rows"):
        rows = ev.store_rows(store, cid)
        return rows if window is None else rows[:window]
    if window is not None:
        from .submission import encode_sample
        clip = store.load(cid, keys=("joints", "obj_rot", "obj_trans", "fps"))
        arrays = {k: np.asarray(clip[k])[None, :window] for k in ("joints", "obj_rot", "obj_trans") if k in clip}
        return encode_sample(arrays, 0, mode, float(clip["fps"]))
    clip = store.load(cid, keys=("hoi269", "hml263"))
    return clip["hoi269"] if "hoi269" in clip else clip["hml263"]


__all__ = ["HOIScorer", "EMBED_BATCH"]
