"""Train/test leakage of a store: ``hoibench datasets leak-check STORE [--against STORE2]``.

Compares the clips of one split (``test``) with a reference set: the store's ``train``
split, or with ``--against`` every clip of another store, and reports

* **motion** near-duplicates: MPJPE of the best-aligned overlap (least-squares rotation about
  the vertical and floor translation), over the ``same`` and ``mirror`` variants and every time offset
  (:mod:`hoibench.datasets.leak_motion`, threshold :data:`~hoibench.datasets.leak_motion.THRESHOLD_M`);
* **caption** duplicates: exact, normalised, word 3-gram Jaccard
  (:mod:`hoibench.datasets.leak_text`);
* the **object and subject** sets the two sides share.

:func:`leak_check` returns the report (JSON-ready, deterministic: sorted, rounded to 1e-6);
:func:`write_report` writes ``leak_check.json`` and ``leak_check.md``.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from ..core.io import atomic_write_json, atomic_write_text, read_regular_file
from . import leak_motion, leak_text
from .store import MANIFEST, Store

FORMAT = "hoibench-leak-check-1"
NEAREST_LISTED = 20          # closest pairs listed whether or not they are duplicates


@dataclass
class ClipSet:
    """The clips of one side: ids, joints at ANALYSIS_FPS, captions, objects, subjects."""
    store: str
    split: str
    ids: list[str] = field(default_factory=list)
    joints: list[np.ndarray] = field(default_factory=list)
    captions: list[list[str]] = field(default_factory=list)
    objects: list[str] = field(default_factory=list)
    subjects: list[str] = field(default_factory=list)


def _open(root: str | Path) -> Store:
    root = Path(root)
    if not (root / MANIFEST).is_file():
        raise FileNotFoundError(f"{root / MANIFEST}: missing: {root} is not a hoibench store")
    return Store(root)


def _ids(st: Store, split: str | None) -> list[str]:
    """The store's clip ids of ``split`` (None: all); an absent split is an error naming the field."""
    ids = st.clip_ids(split)
    if split is not None and not ids:
        have = sorted({c["split"] for c in st.manifest["clips"]})
        raise ValueError(f"{st.root / MANIFEST}: clips[].split: no clip in split {split!r} "
                         f"(splits here: {', '.join(have) or 'none'})")
    return ids


def _captions(st: Store, clip_id: str, arrays: dict) -> list[str]:
    """``STORE/texts/<id>.txt`` (the caption before the first ``#`` of each line), else the
    clip's own ``texts`` entries."""
    path = st.root / "texts" / f"{clip_id}.txt"
    if path.is_file():
        raw = read_regular_file(path, 1 << 20, "caption file").decode("utf-8", errors="replace")
        return [line.split("#")[0].strip() for line in raw.splitlines() if line.split("#")[0].strip()]
    out = []
    for t in np.asarray(arrays.get("texts", [])).ravel():
        try:
            text = json.loads(str(t)).get("text", "")   # read-ok: a string of the clip the store read
        except (ValueError, AttributeError):
            raise ValueError(f"{st.root / 'clips' / (clip_id + '.npz')}: texts: not a JSON object per entry") \
                from None
        if isinstance(text, str) and text.strip():
            out.append(text.strip())
    return out


def read_side(root: str | Path, split: str | None, progress=None) -> ClipSet:
    """Joints (resampled to ANALYSIS_FPS), captions, object and subject of every clip of ``split``."""
    st = _open(root)
    ids = _ids(st, split)
    side = ClipSet(str(root), split or "all")
    tick = progress(f"leak-check read {Path(root).name} ({split or 'all'})", len(ids)) if progress else None
    for cid in ids:
        a = st.load(cid, keys=("joints", "fps", "subject", "object_name", "texts"))
        where = st.root / "clips" / f"{cid}.npz"
        j = a.get("joints")
        if j is None or j.ndim != 3 or j.shape[1:] != (22, 3) or len(j) < 2 or not np.isfinite(j).all():
            raise ValueError(f"{where}: joints: expected finite (T >= 2, 22, 3) positions, got "
                             f"{'nothing' if j is None else j.shape}")
        fps = float(a["fps"]) if "fps" in a else float(st.manifest.get("config", {}).get("fps", 0) or 0)
        if not np.isfinite(fps) or fps <= 0:
            raise ValueError(f"{where}: fps: expected a positive frame rate, got {fps}")
        side.ids.append(cid)
        side.joints.append(leak_motion.resample(j, fps))
        side.captions.append(_captions(st, cid, a))
        side.objects.append(str(a["object_name"]) if "object_name" in a else "")
        side.subjects.append(str(a["subject"]) if "subject" in a else "")
        if tick:
            tick(1)
    return side


def _sets(q: Sequence[str], r: Sequence[str]) -> dict:
    qs, rs = {x for x in q if x}, {x for x in r if x}
    return {"shared": sorted(qs & rs), "query_only": sorted(qs - rs), "reference_only": sorted(rs - qs),
            "query_clips_with_shared": sum(1 for x in q if x and x in rs), "query_clips": len(q)}


def _r(x: float) -> float:
    return round(float(x), 6)


def _motion_row(m: leak_motion.Match, q: ClipSet, r: ClipSet, jaccard: float) -> dict:
    fps = leak_motion.ANALYSIS_FPS
    return {"query": q.ids[m.query], "reference": r.ids[m.ref], "variant": m.variant,
            "distance_m": _r(m.distance_m), "offset_s": _r(m.offset / fps), "overlap_s": _r(m.overlap / fps),
            "coverage": _r(m.overlap / min(len(q.joints[m.query]), len(r.joints[m.ref]))),
            "objects": [q.objects[m.query], r.objects[m.ref]], "subjects": [q.subjects[m.query], r.subjects[m.ref]],
            "caption_match": leak_text.pair_kind(q.captions[m.query], r.captions[m.ref], jaccard)}


def leak_check(store: str | Path, against: str | Path | None = None, split: str = "test",
               train_split: str = "train", threshold_m: float = leak_motion.THRESHOLD_M,
               jaccard: float = leak_text.JACCARD_THRESHOLD, progress=None) -> dict:
    """The leak report of ``store``'s ``split`` against its ``train_split`` (or, with
    ``against``, every clip of that store). ``progress(name, total)`` -> a tick function or None."""
    if not (np.isfinite(threshold_m) and threshold_m > 0):
        raise ValueError(f"--threshold: expected a positive distance in metres, got {threshold_m}")
    if not 0 < jaccard <= 1:
        raise ValueError(f"--jaccard: expected a value in (0, 1], got {jaccard}")
    q = read_side(store, split, progress)
    r = read_side(against, None, progress) if against is not None else read_side(store, train_split, progress)
    same = against is not None and Path(against).resolve() == Path(store).resolve()
    at = {c: i for i, c in enumerate(r.ids)}
    exclude = [(i, at[c]) for i, c in enumerate(q.ids) if c in at] if same else []
    motion = leak_motion.match_sets(q.joints, r.joints, exclude=exclude, progress=progress)
    texts = leak_text.match_captions(q.captions, r.captions, jaccard)
    best = {}
    for m in motion:                                   # sorted by (query, distance): first is nearest
        best.setdefault(m.query, m)
    dups = sorted((m for m in motion if m.distance_m <= threshold_m),
                  key=lambda m: (m.distance_m, q.ids[m.query], r.ids[m.ref]))
    nearest = sorted(best.values(), key=lambda m: (m.distance_m, q.ids[m.query]))
    near_d = np.array([m.distance_m for m in nearest])
    text_rows = [{"query": q.ids[t.query], "reference": r.ids[t.ref], "kind": t.kind, "jaccard": t.jaccard,
                  "query_caption": t.query_caption, "reference_caption": t.ref_caption,
                  "reference_clips_with_caption": t.shared_by} for t in texts]
    text_rows.sort(key=lambda t: (leak_text.KINDS.index(t["kind"]), -t["jaccard"], t["query"]))
    flagged_q = {m.query for m in dups}
    motion_rows = [_motion_row(m, q, r, jaccard) for m in dups]
    return {
        "format": FORMAT,
        "query": {"store": str(store), "split": split, "clips": len(q.ids)},
        "reference": {"store": str(against if against is not None else store),
                      "split": "all" if against is not None else train_split, "clips": len(r.ids)},
        "settings": {"distance": "MPJPE (m) of the best-aligned overlap (least-squares rotation about y and xz "
                                 "translation; variants same and mirror; offsets in quarter frames)",
                     "threshold_m": threshold_m, "min_coverage": leak_motion.MIN_COVERAGE,
                     "analysis_fps": leak_motion.ANALYSIS_FPS, "window_frames": leak_motion.WINDOW,
                     "stride_frames": leak_motion.STRIDE, "pca_dims": leak_motion.PCA_DIMS,
                     "window_radius_m": leak_motion.WINDOW_RADIUS_M, "caption_ngram": leak_text.NGRAM,
                     "caption_jaccard": jaccard},
        "summary": {
            "motion_duplicates": len(dups), "query_clips_with_motion_duplicate": len(flagged_q),
            "by_variant": {v: sum(1 for m in dups if m.variant == v) for v in ("same", "mirror")},
            "caption_duplicates": {k: sum(1 for t in texts if t.kind == k) for k in leak_text.KINDS},
            "motion_and_caption": sum(1 for row in motion_rows if row["caption_match"]),
            "nearest_distance_m": ({"min": _r(near_d.min()), "median": _r(np.median(near_d)),
                                    "max": _r(near_d.max())} if len(near_d) else None),
        },
        "motion": {"duplicates": motion_rows,
                   "nearest": [_motion_row(m, q, r, jaccard) for m in nearest[:NEAREST_LISTED]]},
        "text": {"duplicates": text_rows},
        "sets": {"objects": _sets(q.objects, r.objects), "subjects": _sets(q.subjects, r.subjects)},
    }


def _md_pairs(rows: list[dict]) -> list[str]:
    out = ["| query | reference | variant | distance (mm) | offset (s) | coverage | caption |",
           "|---|---|---|---|---|---|---|"]
    out += [f"| {p['query']} | {p['reference']} | {p['variant']} | {1000 * p['distance_m']:.1f} | "
            f"{p['offset_s']:+.2f} | {p['coverage']:.2f} | {p['caption_match'] or '-'} |" for p in rows]
    return out


def markdown(report: dict, rows: int = 10) -> str:
    """A short summary of :func:`leak_check`'s report: counts, the closest pairs, the shared sets."""
    s, st = report["summary"], report["settings"]
    q, r = report["query"], report["reference"]
    cap = s["caption_duplicates"]
    near = s["nearest_distance_m"]
    lines = [f"# Leak check: {q['store']} ({q['split']}, {q['clips']} clips) against {r['store']} "
             f"({r['split']}, {r['clips']} clips)", "",
             f"- motion near-duplicates (MPJPE <= {1000 * st['threshold_m']:.0f} mm, same or mirrored, any offset): "
             f"{s['motion_duplicates']} pairs, {s['query_clips_with_motion_duplicate']} {q['split']} clips "
             f"({s['by_variant']['same']} same, {s['by_variant']['mirror']} mirrored)",
             f"- caption duplicates: {cap['exact']} exact, {cap['normalised']} normalised, {cap['ngram']} word "
             f"{st['caption_ngram']}-gram Jaccard >= {st['caption_jaccard']}; {s['motion_and_caption']} motion "
             f"duplicates also share a caption",
             "- nearest distance per clip: " + (
                 "none found" if near is None else
                 f"min {1000 * near['min']:.1f} mm, median {1000 * near['median']:.1f} mm"),
             ""]
    for what, key in (("objects", "objects"), ("subjects", "subjects")):
        x = report["sets"][key]
        lines.append(f"- {what}: {len(x['shared'])} shared, {len(x['query_only'])} only in {q['split']}; "
                     f"{x['query_clips_with_shared']}/{x['query_clips']} {q['split']} clips have a shared {what[:-1]}")
    lines += ["", "## Closest motion pairs", ""] + _md_pairs(report["motion"]["nearest"][:rows])
    texts = report["text"]["duplicates"][:rows]
    if texts:
        lines += ["", "## Caption duplicates", "", "| query | reference | kind | Jaccard | query caption |",
                  "|---|---|---|---|---|"]
        lines += [f"| {t['query']} | {t['reference']} | {t['kind']} | {t['jaccard']:.2f} | "
                  f"{t['query_caption'].replace('|', '/')} |" for t in texts]
    return "\n".join(lines) + "\n"


def write_report(report: dict, out: str | Path) -> tuple[Path, Path]:
    """``OUT/leak_check.json`` and ``OUT/leak_check.md`` (atomic writes)."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out}: --out: exists and is not a folder")
    j = atomic_write_json(out / "leak_check.json", report)
    m = atomic_write_text(out / "leak_check.md", markdown(report))
    return j, m


__all__ = ["leak_check", "markdown", "write_report", "read_side", "FORMAT"]
