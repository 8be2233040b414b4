"""Score a multi-body submission: SyncDiff's metrics (paper 004, section 4.2) under a
multi-body protocol.

Submission (the same container as single-body ones: ``submission.json`` +
``samples/<test id>.npz``, read without pickles), one array per body of the store's clip,
named by the body:

    <body>__joints   (K, T, J, 3)  humans (J = 22) and hands (J = 21), metres, y-up
    <body>__rot      (K, T, 3, 3)  objects: v = rot @ template + trans
    <body>__trans    (K, T, 3)

T equals the ground truth's (the protocol's fps). Per clip and sample (a unit, run on any
executor; results are keyed by clip id and reduced in sorted order, so serial and process
runs give identical numbers):

* contact frames per hand (capsule surface within ``csr_threshold_m`` of an object) and per
  human (both hand roots within ``crr_threshold_m`` of one object); CSR and CRR are their
  ratios (mean over hands / humans, then clips), CSIoU their IoU with the ground truth's
  frames computed by the same rule;
* IV (cm^3) and ID (mm) per frame over every pair of bodies (a hand and its own human
  excluded), reduced over pairs by the protocol (sum), then averaged over frames and clips;
* wrist trajectories (hands: the wrist; humans: both wrists) for SD (between the K samples
  of a prompt; undefined for K = 1) and OD (between all samples of the split);
* RA and FID from the recognizer (:mod:`hoibench.evaluator.recognizer`): accuracy of its
  predicted action on the generated clips, Frechet distance between its features of the
  ground-truth and generated clips;
* the catalogue metrics with a multi-body per-clip function (``multibody_fn``: the physics
  tier, :mod:`hoibench.metrics.physics_multibody`) that the protocol lists, per sample and for
  the ground truth; the mean over samples with a value (NaN: undefined for that clip), or
  "not computed: ..." where the function's extra is not installed.

``ci95`` gives the half-width of a 95% normal interval ``1.96 std / sqrt(n)`` for the metrics
that are means of per-clip or per-sample values (CSR, CRR, CSIoU per clip and sample; IV, ID
per sample; RA per sample's correctness); SD, OD and FID are set-level and get none.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from .. import __version__
from ..bodies.multibody import MultiBodyClip
from ..bodies.capsules import object_fields, pair_contact_frames, pair_penetration
from .multibody_samples import clip_from_sample, multibody_limits, sample_arrays
from .pipeline import EvaluationRefused, Scorer
from .results import RESULT_FORMAT, half_width_95, metric_entry

__all__ = ["write_multibody_submission", "MultiBodyScorer", "REFERENCE_KINDS", "clip_functions"]

REFERENCE_KINDS = ("gt", "gt-noise", "desync", "lost_contact", "interpenetration", "static")


# --------------------------------------------------------------------------- submissions
def write_multibody_submission(data, out, kind: str = "gt", samples: int = 1, method: str | None = None,
                               as_zip: bool = False, sigma: float = 0.01, seed: int = 0) -> Path:
    """A reference submission from a multi-body store's test split: ``gt`` (the ground
    truth), ``gt-noise`` (each of ``samples`` samples: every position plus i.i.d. Gaussian
    noise of ``sigma`` metres, seeded), ``desync`` / ``lost_contact`` / ``interpenetration``
    (its defective copies, :func:`hoibench.datasets.synthetic_multibody.inject`) or ``static``
    (every body held at its first frame)."""
    from ..datasets.store import Store
    from .submission import write_submission
    from ..datasets import synthetic_multibody as syn
    if kind not in REFERENCE_KINDS:
        raise ValueError(f"--kind: expected one of {REFERENCE_KINDS}, got {kind!r}")
    store = Store(data)
    items = []
    for cid in store.clip_ids("test"):
        gt = MultiBodyClip.from_arrays(store.load(cid), store.object_template)
        if kind == "gt":
            clip = gt
        elif kind == "static":
            clip = replace(gt, bodies=[replace(b, trans=np.repeat(b.trans[:1], gt.num_frames, 0),
                                               rot=None if b.rot is None else np.repeat(b.rot[:1], gt.num_frames, 0),
                                               joints=None if b.joints is None else
                                               np.repeat(b.joints[:1], gt.num_frames, 0)) for b in gt.bodies])
        elif kind == "gt-noise":
            rng = np.random.default_rng([int(seed), int.from_bytes(cid.encode()[:8].ljust(8, b"\0"), "little")])
            versions = []
            for _ in range(int(samples)):
                versions.append(replace(gt, bodies=[replace(
                    b, trans=b.trans + rng.normal(0, sigma, b.trans.shape),
                    joints=None if b.joints is None else b.joints + rng.normal(0, sigma, b.joints.shape))
                    for b in gt.bodies]))
            items.append((cid, sample_arrays(versions)))
            continue
        else:
            clip = syn.inject(gt, kind)
        items.append((cid, sample_arrays([clip] * int(samples))))
    label = f"reference: {kind}" + (f" ({sigma * 100:g} cm, K = {samples})" if kind == "gt-noise" else "")
    meta = {"method": method or label, "version": __version__, "representation": "multibody-joints",
            "fps": float(store.manifest["config"]["fps"]),
            "flags": {"uses_gt_length": True, "samples_per_prompt": int(samples), "checkpoint_selection": "none"}}
    return write_submission(out, meta, items, as_zip=as_zip)


# --------------------------------------------------------------------------- per clip
def _contacts(clip: MultiBodyClip, fields, proto) -> dict[str, np.ndarray]:
    """Contact frames per skeleton, keyed by body name: in contact with any object by the
    protocol's thresholds (:func:`hoibench.bodies.capsules.pair_contact_frames`)."""
    out: dict[str, np.ndarray] = {}
    for (skel, _), frames in pair_contact_frames(clip, fields, proto.csr_threshold_m, proto.crr_threshold_m).items():
        out[skel] = out[skel] | frames if skel in out else frames
    return out


def _pairs(clip: MultiBodyClip) -> list[tuple[int, int]]:
    out = []
    for i in range(len(clip.bodies)):
        for j in range(i + 1, len(clip.bodies)):
            a, b = clip.bodies[i], clip.bodies[j]
            if a.owner == b.name or b.owner == a.name:
                continue
            out.append((i, j))
    return out


def _wrists(clip: MultiBodyClip) -> np.ndarray:
    """(T, W, 3) wrist trajectories: hands' wrists, humans' two wrists."""
    parts = []
    for b in clip.bodies:
        if b.kind == "hand":
            parts.append(b.joints[:, :1])
        elif b.kind == "human":
            parts.append(b.joints[:, [20, 21]])
    return np.concatenate(parts, 1) if parts else np.zeros((clip.num_frames, 0, 3))


def clip_functions(proto) -> list[tuple[str, tuple[str, ...], dict]]:
    """The listed catalogue metrics with a multi-body per-clip function that can run here,
    grouped by function: ``(function "module:attr", metric names, the protocol's settings)``."""
    from ..metrics.catalog import METRICS, unavailable
    groups: dict[tuple[str, str], list[str]] = {}
    for n in proto.metrics:
        info = METRICS.get(n)
        if info is not None and info.multibody_fn and unavailable(n) is None:
            groups.setdefault((info.multibody_fn, info.settings_key), []).append(n)
    return [(fn, tuple(names), proto.settings_for(key)) for (fn, key), names in groups.items()]


def _clip_function_values(clip: MultiBodyClip, functions) -> dict[str, float]:
    from ..core.registry import load_object
    out: dict[str, float] = {}
    for fn, names, settings in functions:
        got = load_object(fn)(clip, settings)
        got = got if isinstance(got, dict) else {names[0]: got}
        out.update({n: float(got[n]) for n in names})
    return out


def _clip_unit(job: tuple, measure_gt: bool = True) -> dict:
    """One test clip: GT (unless ``measure_gt`` is False: ``gt`` None) and every sample's
    contact frames, penetration per frame, wrists and catalogue per-clip values."""
    cid, gt_arrays, sample, proto_dict, templates, K = job
    from ..tracks.protocol import Protocol
    proto = Protocol.from_plain(proto_dict, "multibody")
    functions = clip_functions(proto)
    gt = MultiBodyClip.from_arrays(gt_arrays)
    gt.templates = templates
    fields = object_fields(gt)
    pairs = _pairs(gt)
    red = {"sum": np.sum, "max": np.max, "mean": np.mean}[proto.pair_reduction]

    def measure(clip):
        pen_v = np.zeros((clip.num_frames, max(1, len(pairs))))
        pen_d = np.zeros_like(pen_v)
        for n, (i, j) in enumerate(pairs):
            pen_v[:, n], pen_d[:, n] = pair_penetration(clip, i, j, fields, voxel_m=proto.voxel_m)
        return {"contacts": _contacts(clip, fields, proto),
                "iv_cm3": float(red(pen_v, axis=1).mean() * 1e6), "id_mm": float(red(pen_d, axis=1).mean() * 1e3),
                "wrists": _wrists(clip), "values": _clip_function_values(clip, functions)}

    out = {"id": cid, "gt": measure(gt) if measure_gt else None, "samples": []}
    for k in range(K):
        out["samples"].append(measure(clip_from_sample(gt, sample, k, cid)))
    return out


def samples_unit(job: tuple) -> dict:
    """:func:`_clip_unit` of the samples only (``gt`` None): for callers that score many
    submissions of one ground truth and measure it once (:func:`ground_truth_unit`)."""
    return _clip_unit(job, measure_gt=False)


def ground_truth_unit(job: tuple) -> dict:
    """The ground truth's part of :func:`_clip_unit` (its ``gt`` entry) of a clip's job."""
    return _clip_unit(tuple(job[:5]) + (0,))["gt"]


# --------------------------------------------------------------------------- the scorer
class MultiBodyScorer(Scorer):
    """The ``multibody`` scorer: per-clip contact, penetration and wrist units on the
    executor, then SyncDiff's metrics and the recognizer's RA and FID (module docstring)."""

    name = "multibody"
    unit = staticmethod(_clip_unit)
    map_options = {"progress": "evaluate multibody"}
    fills_clip_data = True

    def prepare(self) -> None:
        store, proto, rec = self.store, self.proto, self.ev
        self.notes = []
        if rec.card.get("trained_on_split") != proto.recognizer_split:
            self.notes.append(f"the recognizer was trained on split {rec.card.get('trained_on_split')!r}, the protocol "
                              f"names {proto.recognizer_split!r}")
        from ..datasets.store import legacy_manifest_sha256
        if rec.card.get("store_manifest_sha256") not in (store.manifest_sha256(),
                                                         legacy_manifest_sha256(store.manifest)):
            self.notes.append("the recognizer was trained on another store (manifest sha256 differs)")
        self.ids = store.clip_ids(proto.split)
        from .submission_read import DEFAULT_MAX_SAMPLES_PER_PROMPT     # the cap validation uses too
        self.limits = multibody_limits(store, self.ids, max(int(proto.samples_per_prompt),
                                                            DEFAULT_MAX_SAMPLES_PER_PROMPT))

    def open_submission(self):
        from .submission import Submission
        return Submission(self.submission, limits=self.limits)

    def validate(self, sub) -> list[str]:
        """A multi-body result is scored complete only: every test id must have samples."""
        ids = self.ids
        if sub.problems:
            raise EvaluationRefused(f"{self.submission}: {sub.problems[0]}")
        self.meta = sub.meta or {}
        missing = [i for i in ids if i not in set(sub.ids)]
        if missing:
            raise EvaluationRefused(f"{self.submission}: samples/{missing[0]}.npz: missing ({len(missing)} of {len(ids)} "
                             f"test ids missing); a multi-body result is scored complete only")
        return ids

    def stream(self, sub, ids: list[str]):
        """One job per test clip: its arrays, the sample's arrays, the protocol, the templates."""
        store, proto = self.store, self.proto
        self.jobs = []
        for cid in ids:
            arrays = store.load(cid)
            try:
                sample = sub.load(cid, keys=None)
            except ValueError as exc:
                raise ValueError(f"{self.submission}: samples/{cid}.npz: {exc}") from None
            first = next(iter(sample.values()), None)
            K = int(len(first)) if first is not None else 0
            if K < 1:
                raise ValueError(f"{self.submission}: samples/{cid}.npz: no arrays")
            names = [str(t) for t in arrays["body_templates"] if str(t)]
            templates = {n: store.object_template(n) for n in names}
            self.jobs.append((cid, arrays, sample, proto.to_dict(), templates, K))
        self.units = []
        return list(self.jobs)

    def update(self, out) -> None:
        self.units.append(out)

    def replications(self) -> list[dict]:
        """One replication: the protocol fixes K samples per prompt, every one is scored."""
        metrics, reference, self.counts, self.clip_arrays = _multibody_metrics(self.units, self.jobs, self.proto,
                                                                               self.ev)
        self.reference = reference
        if isinstance(self.options.get("clip_data"), dict):
            self.options["clip_data"].update(self.clip_arrays)
        return [metrics]

    def summary(self, rows: list[dict]) -> dict:
        metrics = dict(rows[0])
        ci = metrics.pop("ci95", {})
        proto, store, rec, meta = self.proto, self.store, self.ev, self.meta
        listed = set(proto.metrics)
        per_clip_fn = {n for _, names, _ in clip_functions(proto) for n in names}
        undefined = {k: ("no hands in the split" if k in ("csr",) else "no humans in the split" if k == "crr" else
                         "needs K >= 2 samples per prompt" if k == "sd" else
                         "no objects in the split" if k in per_clip_fn else "undefined")
                     for k, v in metrics.items() if v is None and k in listed}
        from ..metrics.catalog import unavailable
        undefined.update({k: why for k in proto.metrics if (why := unavailable(k))})
        n = len(self.ids)
        over_clips = {}
        if self.counts == n:             # K = 1: a clip-bootstrap interval of every per-clip metric and FID
            from .paired import clip_intervals
            over_clips = clip_intervals(self.clip_arrays, proto, seed=int(proto.seed or 0))
        return {
            "format": RESULT_FORMAT, "kind": "multibody", "track": self.track.name,
            "toolkit": "hoibench", "toolkit_version": __version__,
            "protocol": proto.id, "protocol_version": proto.version, "protocol_sha256": proto.sha256,
            "protocol_settings": proto.to_dict(),
            "evaluator_id": rec.id, "evaluator_backend": self.options.get("evaluator_backend", "recognizer"),
            "evaluator_trained_on_split": rec.card.get("trained_on_split"),
            "store": str(store.manifest.get("dataset", "")), "store_manifest_sha256": store.manifest_sha256(),
            "dataset": store.manifest.get("dataset"), "store_config_sha256": store.manifest.get("config_sha256"),
            "submission": {"path": str(self.submission), "method": meta.get("method"), "version": meta.get("version")},
            "counts": {"test_ids": n, "scored_ids": n, "samples_per_prompt": int(proto.samples_per_prompt),
                       "samples": self.counts, "missing_ids": []},
            "complete": True,
            "metrics": {k: metric_entry(k, v, ci.get(k), self.counts, "samples",
                                        **({"clips": over_clips[k]} if k in over_clips else {}))
                        for k, v in metrics.items() if v is not None and k in listed},
            "ground_truth": {k: v for k, v in self.reference.items() if k in listed},
            "undefined_metrics": undefined, "notes": self.notes,
        }



def _multibody_metrics(units: list[dict], jobs: list[tuple], proto, rec) -> tuple[dict, dict, int, dict]:
    """SyncDiff's metrics of the generated samples and of the ground truth, from the per-clip
    units (reduced in id order) and the recognizer; returns (metrics, reference, samples,
    per-clip arrays (:func:`multibody_clip_arrays`))."""
    from ..metrics import multibody as mbm
    from ..metrics.embedding import fid as fid_of
    csr, crr, csiou = mbm.CSR(threshold_m=proto.csr_threshold_m), mbm.CRR(threshold_m=proto.crr_threshold_m), \
        mbm.CSIoU(threshold_m=proto.csr_threshold_m, empty_union=proto.csiou_empty_union)
    gt_csr, gt_crr = mbm.CSR(threshold_m=proto.csr_threshold_m), mbm.CRR(threshold_m=proto.crr_threshold_m)
    iv, idm, gt_iv, gt_id = [], [], [], []
    sd = mbm.SampleDiversity(num_frames=proto.diversity_frames)
    od: dict[str, mbm.OverallDiversity] = {}         # per body layout: wrists compare within one
    gt_od: dict[str, mbm.OverallDiversity] = {}
    gens, gts = [], []
    jobs_by_id = {j[0]: j for j in jobs}
    ordered = sorted(units, key=lambda x: x["id"])
    for u in ordered:
        cid = u["id"]
        _, arrays, sample, _, templates, K = jobs_by_id[cid]
        gt = MultiBodyClip.from_arrays(arrays)
        gt.templates = templates
        gts.append(gt)
        # every generated sample, for the recognizer
        gens += [(gt, clip_from_sample(gt, sample, k, cid)) for k in range(K)]
        g = u["gt"]
        hands = [b.name for b in gt.bodies if b.kind == "hand"]
        humans = [b.name for b in gt.bodies if b.kind == "human"]
        if hands:
            gt_csr.update_frames(cid, [g["contacts"][h] for h in hands])
        if humans:
            gt_crr.update_frames(cid, [g["contacts"][h] for h in humans])
        gt_iv.append(g["iv_cm3"])
        gt_id.append(g["id_mm"])
        sig = gt.signature()
        gt_od.setdefault(sig, mbm.OverallDiversity(num_frames=proto.diversity_frames)).update(cid, g["wrists"])
        for k, s in enumerate(u["samples"]):
            key = f"{cid}#{k}"
            if hands:
                csr.update_frames(key, [s["contacts"][h] for h in hands])
            if humans:
                crr.update_frames(key, [s["contacts"][h] for h in humans])
            skel = hands + humans
            if skel:
                csiou.update_frames(key, [s["contacts"][n] for n in skel], [g["contacts"][n] for n in skel])
            iv.append(s["iv_cm3"])
            idm.append(s["id_mm"])
            od.setdefault(sig, mbm.OverallDiversity(num_frames=proto.diversity_frames)).update(key, s["wrists"])
        if len(u["samples"]) > 1:
            sd.update(cid, np.stack([s["wrists"] for s in u["samples"]]))
    # the recognizer on every generated sample and on the ground truth (one pass each)
    gen_feats, pred = rec.run([c for _, c in gens])
    gt_feats, gt_pred = rec.run(gts)
    ra = mbm.recognition_accuracy(pred, [g.action for g, _ in gens])
    gt_ra = mbm.recognition_accuracy(gt_pred, [g.action for g in gts])

    def computed(m):
        try:
            return float(m.compute())
        except ValueError:
            return None

    def grouped(groups: dict) -> float | None:
        """OD over body layouts: each layout's OD weighted by its trajectories (layouts with
        one trajectory have none)."""
        vals = [(len(m.trajectories), computed(m)) for _, m in sorted(groups.items())]
        vals = [(n, v) for n, v in vals if v is not None]
        return float(sum(n * v for n, v in vals) / sum(n for n, _ in vals)) if vals else None

    metrics = {"csr": computed(csr), "crr": computed(crr), "csiou": computed(csiou),
               "iv_cm3": float(np.mean(iv)), "id_mm": float(np.mean(idm)),
               "sd": computed(sd), "od": grouped(od), "ra": ra,
               "fid": float(fid_of(gt_feats, gen_feats)) if len(gts) > 1 else None}
    reference = {"csr": computed(gt_csr), "crr": computed(gt_crr), "csiou": 1.0, "iv_cm3": float(np.mean(gt_iv)),
                 "id_mm": float(np.mean(gt_id)), "od": grouped(gt_od), "ra": gt_ra, "fid": 0.0}
    correct = [float(p == g.action) for p, (g, _) in zip(pred, gens)]
    per = {"csr": _values(csr), "crr": _values(crr), "csiou": _values(csiou), "iv_cm3": iv, "id_mm": idm,
           "ra": correct}
    # catalogue per-clip functions (the physics tier): one value per sample and per ground truth
    extra = sorted({n for u in ordered for s in u["samples"] for n in s.get("values", {})})
    ext = {n: [s["values"][n] for u in ordered for s in u["samples"]] for n in extra}
    gt_ext = {n: [u["gt"]["values"][n] for u in ordered] for n in extra}
    for n in extra:
        metrics[n] = _nanmean(ext[n])
        reference[n] = _nanmean(gt_ext[n])
        per[n] = [v for v in ext[n] if not np.isnan(v)]
    metrics["ci95"] = {k: half_width_95(v) for k, v in per.items() if half_width_95(v) is not None}
    ids = [u["id"] for u in ordered]
    ks = [len(u["samples"]) for u in ordered]
    keys = [f"{cid}#{k}" for cid, K in zip(ids, ks) for k in range(K)]
    values = {"csr": csr.per_clip(), "crr": crr.per_clip(), "csiou": csiou.per_clip(),
              "iv_cm3": dict(zip(keys, iv)), "id_mm": dict(zip(keys, idm)), "ra": dict(zip(keys, correct)),
              **{n: dict(zip(keys, ext[n])) for n in extra}}
    gt_values = {"csr": gt_csr.per_clip(), "crr": gt_crr.per_clip(), "csiou": dict.fromkeys(ids, 1.0),
                 "iv_cm3": dict(zip(ids, gt_iv)), "id_mm": dict(zip(ids, gt_id)),
                 "ra": {cid: float(p == g.action) for cid, p, g in zip(ids, gt_pred, gts)},
                 **{n: dict(zip(ids, gt_ext[n])) for n in extra}}
    arrays = multibody_clip_arrays(ids, ks, gen_feats, gt_feats, values, gt_values)
    return metrics, reference, len(gens), arrays


def multibody_clip_arrays(ids: list[str], ks: list[int], gen_feats: np.ndarray, gt_feats: np.ndarray,
                          values: dict[str, dict[str, float]], gt_values: dict[str, dict[str, float]],
                          ) -> dict[str, np.ndarray]:
    """A multi-body result's per-clip data (:mod:`hoibench.scoring.clip_data`'s layout, no
    caption embeddings): ``motion`` (K, N, D) the recognizer's features of the first K samples
    of every clip (K the fewest any clip has; ``gen_feats`` holds clip after clip, sample after
    sample), ``real`` (N, D) the ground truth's; ``physical`` (K, N, P) each per-sample metric's
    value (``values[metric]["<id>#<k>"]``; NaN where undefined, e.g. CSR on a clip without
    hands; RA's is the sample's correctness, 0 or 1); ``reference`` (N, P) the ground truth's
    per-clip values of the same metrics (``gt_values[metric][<id>]``: what a metric best
    closest to the ground truth is tested against)."""
    K = min(ks)
    starts = np.cumsum([0] + list(ks))[:-1]
    gen = np.asarray(gen_feats, np.float32)
    motion = np.stack([gen[starts + k] for k in range(K)])
    names = sorted(values)
    phys = np.full((K, len(ids), len(names)), np.nan, np.float64)
    for k in range(K):
        for i, cid in enumerate(ids):
            phys[k, i] = [float(values[n].get(f"{cid}#{k}", np.nan)) for n in names]
    d = motion.shape[-1]
    return {"ids": np.array(ids), "motion": motion, "real": np.asarray(gt_feats, np.float32),
            "text": np.zeros((0, d), np.float32), "text_offsets": np.zeros(len(ids) + 1, np.int64),
            "physical": phys, "physical_samples": np.arange(K, dtype=np.int64), "physical_names": np.array(names),
            "reference": np.array([[float(gt_values[n].get(cid, np.nan)) for n in names] for cid in ids], np.float64)}


def _nanmean(values: list[float]) -> float | None:
    """The mean of the values that are not NaN; None when none is."""
    v = [x for x in values if not np.isnan(x)]
    return float(np.mean(v)) if v else None


def _values(metric) -> list[float]:
    v = [x for x in metric.per_clip().values() if not np.isnan(x)] if metric.clips else []
    return [float(x) for x in v]
