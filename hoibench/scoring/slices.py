"""Per-slice tables: where on the test split a method is good or bad, and where two methods
differ most.

Each scored test clip gets one label per slice, read from the store (never from the
submission):

- ``object``: the clip's object template name (``none`` for a human-only clip);
- ``verb``: the first action of the clip's annotation (``annotations/<id>.json``), else the
  main verb of its first caption (the first word tagged VERB that is not an auxiliary);
- ``contact``: which body parts touch the object in the ground truth's contact labels
  (``hands`` = wrists 20, 21 and elbows 18, 19; ``feet`` = ankles and toes 7, 8, 10, 11;
  ``sitting/lying`` = pelvis, hips, spine, neck, head 0-3, 6, 9, 12, 15), joined by ``+``;
  ``none`` without contact;
- ``source``: the capture dataset (``provenance.source_dataset`` of a merged store, else the
  clip's ``dataset``);
- ``text_length``: words of the first caption, in :data:`TEXT_BINS`;
- ``motion_length``: seconds, in :data:`MOTION_BINS`.

A multi-body clip (``layout`` ``multibody-*``) is labelled from its own arrays: ``object``
its object templates joined by ``+``; ``verb`` its action label; ``contact`` the kinds of
skeleton in contact in its contact labels (``hands``, ``people``, ``hands+people``, ``none``);
``source``, ``text_length`` and ``motion_length`` as above (its first ``texts`` line).

A slice table holds, for each label, the number of clips and the mean of every per-clip
metric over them (R-precision top-k and MM-Dist in :func:`~hoibench.scoring.paired.
per_clip_draws`'s per-clip form, the physical metrics' per-clip values; sample 0). Set-level
metrics (FID, Diversity) are not sliced: a slice of a few clips has no meaningful covariance.
"""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

SLICES = ("object", "verb", "contact", "source", "text_length", "motion_length")
#: upper bounds (inclusive) of the text-length bins, words
TEXT_BINS = ((8, "<= 8 words"), (15, "9-15 words"), (10 ** 9, ">= 16 words"))
#: upper bounds (exclusive) of the motion-length bins, seconds
MOTION_BINS = ((3.0, "< 3 s"), (6.0, "3-6 s"), (float("inf"), ">= 6 s"))
_PARTS = (("hands", (18, 19, 20, 21)), ("feet", (7, 8, 10, 11)), ("sitting/lying", (0, 1, 2, 3, 6, 9, 12, 15)))
#: the fewest shared clips a slice label needs to be named by compare
MIN_SLICE_CLIPS = 3


def _bin(value: float, bins) -> str:
    return next(label for bound, label in bins if value <= bound) if bins is TEXT_BINS else \
        next(label for bound, label in bins if value < bound)


def contact_label(contacts: np.ndarray | None) -> str:
    """The ``contact`` label of a (T, J) boolean contact map (module docstring)."""
    if contacts is None or np.asarray(contacts).size == 0:
        return "none"
    touched = np.asarray(contacts, bool).any(0)
    parts = [name for name, joints in _PARTS if any(j < len(touched) and touched[j] for j in joints)]
    return "+".join(parts) or "none"


def first_verb(caption) -> str:
    """The main verb lemma of a caption (:func:`hoibench.evaluator.text.main_verb`; ``?`` when
    it has none)."""
    from ..evaluator.text import main_verb
    return main_verb(caption) or "?"


def _annotation_actions(path) -> list:
    """The ``actions`` list of an annotation file (empty when absent or unreadable)."""
    import json
    from ..core.io import read_text_file
    if not path.is_file():
        return []
    try:
        got = json.loads(read_text_file(path, what="annotation file")).get("actions", [])  # read-ok: guarded read
    except (ValueError, AttributeError):
        return []
    return got if isinstance(got, list) else []


#: the clip arrays the labels read (single-body, then multi-body clips)
_LABEL_KEYS = ("object_name", "contacts", "provenance", "dataset", "fps", "joints",
               "layout", "name", "action", "body_kinds", "body_templates", "contact_pairs", "contact_frames", "texts")
#: a multi-body skeleton kind's ``contact`` label
_MULTIBODY_PARTS = (("hand", "hands"), ("human", "people"))


def _multibody_labels(z) -> dict[str, str]:
    """The slice labels of one multi-body clip's arrays ``z`` (module docstring)."""
    from ..bodies.multibody import clip_json_fields
    kinds = [str(k) for k in z["body_kinds"]]
    templates = sorted(str(t) for t in z["body_templates"] if str(t))
    touching = {kinds[int(a)] for (a, _), frames in zip(z["contact_pairs"], z["contact_frames"]) if np.any(frames)} \
        if "contact_pairs" in z and len(z["contact_pairs"]) else set()
    lines, prov = clip_json_fields(z)
    texts = [str(t.get("text", "")) for t in lines if isinstance(t, dict)]
    frames = int(np.shape(z["contact_frames"])[1]) if "contact_frames" in z and np.ndim(z["contact_frames"]) == 2 else 0
    return {"object": "+".join(templates) or "none", "verb": str(z["action"]) if "action" in z else "?",
            "contact": "+".join(label for kind, label in _MULTIBODY_PARTS if kind in touching) or "none",
            "source": str(prov.get("source_dataset") or (z["dataset"] if "dataset" in z else "?")),
            "text_length": _bin(len(texts[0].split()), TEXT_BINS) if texts else "no text",
            "motion_length": _bin(frames / float(z["fps"]), MOTION_BINS) if frames else "?"}


def clip_labels(store, ids: Sequence[str]) -> dict[str, dict[str, str]]:
    """``{slice: {clip id: label}}`` for the test ids ``ids`` of ``store`` (module docstring)."""
    import json
    from ..bodies.multibody import is_multibody_arrays
    from ..evaluator.text import read_captions
    out: dict[str, dict[str, str]] = {s: {} for s in SLICES}
    for cid in ids:
        z = store.load(cid, keys=_LABEL_KEYS)
        if is_multibody_arrays(z):
            for name, label in _multibody_labels(z).items():
                out[name][cid] = label
            continue
        caps = read_captions(store.root, cid) or []
        prov = json.loads(str(z["provenance"])) if "provenance" in z else {}  # read-ok: the clip the store read
        actions = _annotation_actions(store.root / "annotations" / f"{cid}.json")
        verb = next((str(a.get("action")) for a in actions if isinstance(a, dict) and a.get("action")), None)
        frames = len(z["joints"]) if "joints" in z else 0
        out["object"][cid] = str(z["object_name"]) if "object_name" in z and str(z["object_name"]) else "none"
        out["verb"][cid] = verb or (first_verb(caps[0]) if caps else "?")
        out["contact"][cid] = contact_label(z["contacts"] if "contacts" in z else None)
        out["source"][cid] = str(prov.get("source_dataset") or (z["dataset"] if "dataset" in z else "?"))
        out["text_length"][cid] = _bin(len(caps[0].text.split()), TEXT_BINS) if caps else "no text"
        out["motion_length"][cid] = _bin(frames / float(z["fps"]), MOTION_BINS) if frames else "?"
    return out


def _groups(by_clip: Mapping[str, str], ids: Sequence[str], keep=None) -> dict[str, list[int]]:
    """``{label: [index in ids, ...]}`` (a clip without a label is ``?``; ``keep``: a boolean
    mask of the clips to count)."""
    groups: dict[str, list[int]] = {}
    for i, cid in enumerate(ids):
        if keep is None or keep[i]:
            groups.setdefault(by_clip.get(cid, "?"), []).append(i)
    return groups


def slice_tables(labels: Mapping[str, Mapping[str, str]], ids: Sequence[str],
                 per_clip: Mapping[str, np.ndarray]) -> dict[str, dict[str, dict[str, float]]]:
    """``{slice: {label: {"n": clips, metric: mean, ...}}}`` of the per-clip metric arrays
    ``per_clip`` (aligned with ``ids``; NaN clips left out of a metric's mean)."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    for s, by_clip in labels.items():
        groups = _groups(by_clip, ids)
        table = {}
        for label in sorted(groups):
            idx = np.array(groups[label])
            row: dict[str, float] = {"n": int(len(idx))}
            for m, v in per_clip.items():
                vals = np.asarray(v, float)[idx]
                vals = vals[np.isfinite(vals)]
                if len(vals):
                    row[m] = float(vals.mean())
            table[label] = row
        out[s] = table
    return out


def test_clip_labels(root: str) -> dict[str, dict[str, str]]:
    """:func:`clip_labels` of every test clip of the store at ``root``."""
    from ..datasets.store import Store
    store = Store(root)
    return clip_labels(store, store.clip_ids("test"))


def result_slices(store, arrays: Mapping[str, np.ndarray], proto,
                  labels: Mapping[str, Mapping[str, str]] | None = None) -> dict:
    """The ``slices`` block of a result: ``{"labels": {slice: {id: label}}, "tables": {slice:
    {label: {"n", metric: mean}}}, "over", "metrics"}`` from its per-clip arrays
    (:mod:`hoibench.scoring.clip_data`). ``labels``: :func:`clip_labels` of a superset of
    the result's clips, when already read (e.g. :func:`test_clip_labels`)."""
    from .paired import clip_values
    ids = [str(x) for x in arrays["ids"]]
    labels = clip_labels(store, ids) if labels is None else \
        {s: {cid: by_clip[cid] for cid in ids} for s, by_clip in labels.items()}
    values = clip_values(dict(arrays), proto)
    return {"labels": labels, "tables": slice_tables(labels, ids, values), "over": "test clips, sample 0",
            "metrics": sorted(values)}


def slice_differences(a_labels: Mapping[str, Mapping[str, str]], ids: Sequence[str],
                      a_vals: Mapping[str, np.ndarray], b_vals: Mapping[str, np.ndarray],
                      metrics: Sequence[str], top: int = 5) -> list[dict]:
    """The slice labels where B and A differ most on ``metrics`` (per-clip values aligned with
    ``ids``, the shared clips): for each (slice, label, metric) with at least
    :data:`MIN_SLICE_CLIPS` clips, ``diff`` = mean(B - A) over the label's clips and ``z`` =
    diff / (sd of the per-clip differences over all shared clips / sqrt(n)); the ``top``
    largest ``|z|``, largest first (ties by name)."""
    from ..metrics.catalog import METRICS
    rows = []
    for m in metrics:
        if m not in a_vals or m not in b_vals:
            continue
        d = np.asarray(b_vals[m], float) - np.asarray(a_vals[m], float)
        ok = np.isfinite(d)
        sd = float(d[ok].std(ddof=1)) if ok.sum() > 1 else 0.0
        for s, by_clip in a_labels.items():
            groups = _groups(by_clip, ids, ok)
            for label, idx in sorted(groups.items()):
                if len(idx) < MIN_SLICE_CLIPS or len(groups) < 2:
                    continue
                diff = float(d[idx].mean())
                z = diff / (sd / np.sqrt(len(idx))) if sd > 0 else 0.0
                rows.append({"slice": s, "label": label, "metric": m, "n": len(idx), "diff": diff, "z": float(z),
                             "a": float(np.nanmean(np.asarray(a_vals[m], float)[idx])),
                             "b": float(np.nanmean(np.asarray(b_vals[m], float)[idx])),
                             "direction": METRICS[m].direction if m in METRICS else None})
    rows.sort(key=lambda r: (-abs(r["z"]), r["slice"], r["label"], r["metric"]))
    return rows[:top]


def slice_gaps(a: dict, a_arrays: dict, b: dict, b_arrays: dict, proto) -> dict[str, list[dict]]:
    """``{"slices": [...]}``: the slices where B and A differ most (:func:`slice_differences`
    on the shared clips, every per-clip metric; empty when A carries no slice labels)."""
    from .paired import clip_values
    labels = (a.get("slices") or {}).get("labels")
    if not isinstance(labels, dict):
        return {"slices": []}
    va, vb = clip_values(a_arrays, proto), clip_values(b_arrays, proto)
    ia = {str(c): i for i, c in enumerate(a_arrays["ids"])}
    ib = {str(c): i for i, c in enumerate(b_arrays["ids"])}
    shared = sorted(set(ia) & set(ib))
    sa = {m: np.asarray(v)[[ia[c] for c in shared]] for m, v in va.items()}
    sb = {m: np.asarray(v)[[ib[c] for c in shared]] for m, v in vb.items()}
    return {"slices": slice_differences(labels, shared, sa, sb, sorted(set(sa) & set(sb)))}


__all__ = ["SLICES", "slice_gaps", "clip_labels", "contact_label", "result_slices", "slice_differences", "slice_tables"]
