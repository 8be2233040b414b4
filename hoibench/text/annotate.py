"""Contact-aware text annotation of a processed store (docs/annotator.md).

For every clip the annotator turns the contact timeline (per-joint labels -> segments per
body part, :func:`hoibench.bodies.contact.contact_timeline`) and the clip's action labels into
RICH-CAT-style sentences, "<person> <action> <contact relation> <object> <method> <body
parts>", several paraphrases per clip, in HumanML3D's text format, and a semantic group id
(object category + actions + contacting body parts).

Everything the text is made of -- body-part vocabulary, action lexicon, contact relations,
object nouns, sentence templates, joiners, person words, the grouping rule -- lives in the
versioned spec folder ``annotators/`` (``$HOIBENCH_ANNOTATORS_DIR`` when set, else the
``annotators/`` folder next to the package); this module only runs it. Editing a lexicon
file changes the output without code changes. See docs/annotator.md.

Human-only clips (RICH: static scenes, no ``object_name``) are described against the scene
object their action is done on -- the floor, a chair, a fence -- which ``scenes.yaml`` picks
from the action (parsed from the RICH sequence name ``<Scene>_<sub>[_<sub2>]_<action><take>``)
and the scene; the annotation records it (``object_name`` = the scene object key,
``scene_partner``) and the group id uses its category.

Action labels come from (a) the clip name / provenance (synthetic and BEHAVE-layout names
``Date0X_SubYY_<object>_<action>[_<n>]``: one action for the whole clip); (b) per-second
labels the user passes (HOI-Diff's BEHAVE ``action_label.json``); or (c) a generic label
file ``{"clips": {clip_id: [{"action", "start", "end"}]}}`` (seconds from the clip start,
e.g. RICH-CAT's action names, mapped through the lexicon's aliases).

Output, written into the store (atomically)::

    DATA/annotations/<clip_id>.json   {clip, annotator_version, spec_sha256, group_id, texts:
                                      [{caption, tokens, start, end, source}], timeline,
                                      actions, ...}
    DATA/texts/<clip_id>.txt          HumanML3D lines ``caption#tokens#start#end``
    DATA/annotations/index.json       annotator version, spec sha256, seed, group -> clip ids
    DATA/annotations/errors.jsonl     one line per clip that could not be annotated

Determinism: paraphrase choices are drawn from a ``random.Random`` seeded by sha256 of
(seed, clip id) -- never Python's salted ``hash()`` nor the global random state -- so the
output is identical whatever the executor and order of clips.

Layout: :mod:`hoibench.text.spec` loads and validates the spec, :mod:`hoibench.text.timeline`
turns contact timelines and action labels into the described actions, and
:mod:`hoibench.text.captions` renders the sentences of one clip (:func:`annotate_clip`); this
module reads the action label files and runs the annotator over a store, and re-exports the
names of those modules.
"""
from __future__ import annotations

import json
import sys
from contextlib import closing
from pathlib import Path
from typing import Sequence

import numpy as np

from ..core.errors import StrictStop
from ..core.io import (MAX_SMALL_JSON_BYTES, atomic_write_json, atomic_write_text, clean_stale_tmp, load_json_bytes,
                       load_raw_npz, read_json_file, read_text_file)
from ..core.parallel import map_units
from .captions import ANNOTATOR_ID, SOURCE, ClipAnnotation, annotate_clip, humanml3d_line, parse_humanml3d_line
from .spec import SPEC_ENV, AnnotatorSpec, SpecError, Token, default_spec_dir, load_spec, parse_phrase
from .timeline import (_REPEAT_SUFFIX, ActionSpan, action_from_name, body_part_timeline, resolve_action,
                       scene_action_name, scene_partner)

__all__ = [
    "SPEC_ENV", "SOURCE", "SpecError", "Token", "AnnotatorSpec", "ActionSpan", "ClipAnnotation",
    "default_spec_dir", "load_spec", "parse_phrase", "resolve_action", "body_part_timeline",
    "scene_action_name", "scene_partner",
    "annotate_clip", "load_action_labels", "humanml3d_line", "parse_humanml3d_line",
    "annotate_store", "preview_table", "main_annotate",
]

ANNOTATIONS = "annotations"
TEXTS = "texts"
INDEX = "index.json"
ERRORS = "errors.jsonl"


# =========================================================================== action label files
def load_action_labels(path: str | Path) -> dict:
    """Read an action label file.

    * HOI-Diff's BEHAVE ``action_label.json`` (``label_description`` + ``action_label`` with
      per-second ``frame`` stamps 't0005.000'): ``{"scheme": "behave", "rate_s": 1.0,
      "clips": {name: [[time_s, description], ...]}}`` (absolute capture times);
    * the generic form ``{"clips": {clip_id: [{"action", "start", "end"}, ...]}}`` (seconds
      from the clip start): returned as ``{"scheme": "generic", "clips": ...}``.
    """
    data = read_json_file(path, what="action label file")
    if isinstance(data, dict) and "action_label" in data:
        desc = {str(d["id"]): str(d["description"]) for d in data.get("label_description", [])}
        clips: dict[str, list] = {}
        for e in data["action_label"]:
            t = float(str(e["frame"]).lstrip("t"))
            lab = str(e["label"])
            clips.setdefault(str(e["name"]), []).append([t, desc.get(lab, lab)])
        for v in clips.values():
            v.sort(key=lambda x: x[0])
        return {"scheme": "behave", "rate_s": 1.0, "clips": clips, "path": str(path)}
    if isinstance(data, dict) and isinstance(data.get("clips"), dict):
        return {"scheme": "generic", "clips": data["clips"], "path": str(path)}
    raise ValueError(f"{path}: not an action label file (expected HOI-Diff's action_label.json "
                     "or {\"clips\": {clip_id: [{\"action\", \"start\", \"end\"}]}})")


def _labels_for(labels: dict | None, clip_id: str):
    if not labels:
        return None
    clips = labels["clips"]
    for cand in (clip_id, _REPEAT_SUFFIX.sub("", clip_id)):
        if cand in clips:
            return {"scheme": labels["scheme"], "rate_s": labels.get("rate_s", 1.0), "entries": clips[cand]}
    return None


def _spans_from_labels(lab: dict, origin: float) -> list[ActionSpan]:
    """Per-second labels -> spans: each stamp covers [t, t + rate); equal labels at
    consecutive stamps (gaps up to one missing stamp) merge."""
    if lab["scheme"] == "generic":
        return [ActionSpan(str(e["action"]), e.get("start"), e.get("end"), "generic") for e in lab["entries"]]
    rate = float(lab["rate_s"])
    spans: list[list] = []
    for t, desc in lab["entries"]:
        s = float(t) - origin
        if spans and spans[-1][0] == desc and s - spans[-1][2] <= rate + 1e-6:
            spans[-1][2] = s + rate
        else:
            spans.append([desc, s, s + rate])
    return [ActionSpan(d, s, e, lab["scheme"]) for d, s, e in spans]


def _label_origin(root: Path, manifest: dict, clip_id: str, prov: dict) -> tuple[float | None, str]:
    """Capture time of the clip's first frame (per-second BEHAVE labels are absolute)."""
    for key in ("source_start_s", "first_frame_time_s", "start_time_s"):
        if prov.get(key) is not None:
            return float(prov[key]), f"provenance {key}"
    src = (manifest.get("source") or {}).get("root")
    if src:
        path = Path(src) / "sequences" / clip_id / "smpl_fit_all.npz"
        if path.exists():
            try:
                z = load_raw_npz(path, what="BEHAVE smpl_fit_all.npz", keys=("frame_times",))
                return float(str(z["frame_times"][0]).lstrip("t")), "raw frame_times[0]"
            except Exception:   # unreadable raw file: fall back below
                pass
    return None, "first label"


# =========================================================================== the store
def _human_texts(root: Path, clip_id: str, clip: dict) -> list[dict]:
    """Texts not written by the annotator: the clip's ``texts`` array, lines of an existing
    DATA/texts/<id>.txt that a previous annotation did not write, and the non-annotator texts
    a previous annotation recorded."""
    out: list[dict] = []
    if "texts" in clip:
        for item in np.asarray(clip["texts"]).ravel():
            s = str(item).strip()
            if not s:
                continue
            try:
                d = load_json_bytes(s, f"{clip_id}: texts")
            except ValueError:
                d = None
            if isinstance(d, dict):
                out.append(d)
            elif s.count("#") == 3:
                out.append(parse_humanml3d_line(s))
            else:
                out.append({"caption": s})
    prev_path = root / ANNOTATIONS / f"{clip_id}.json"
    ours: set[str] = set()
    if prev_path.exists():
        try:
            prev = read_json_file(prev_path, MAX_SMALL_JSON_BYTES, "annotation file")
            for t in prev.get("texts", []):
                if t.get("source") == SOURCE:
                    ours.add(humanml3d_line(t))
                else:
                    out.append(t)
        except (ValueError, AttributeError):
            pass
    tpath = root / TEXTS / f"{clip_id}.txt"
    if tpath.exists():
        for line in read_text_file(tpath, what="caption file").splitlines():
            if line.strip() and line not in ours:
                try:
                    d = parse_humanml3d_line(line)
                except ValueError:
                    d = {"caption": line.strip()}
                d["source"] = "human"
                out.append(d)
    uniq, keys = [], set()
    for t in out:
        cap = str(t.get("caption", t.get("text", ""))).strip()
        k = (cap, float(t.get("start") or 0.0), float(t.get("end") or 0.0))
        if cap and k not in keys:
            keys.add(k)
            uniq.append({**t, "caption": cap})
    return uniq


def _compute_contacts(store, clip: dict) -> np.ndarray | None:
    from ..bodies import contact as contact_mod
    fn = getattr(contact_mod, "joint_contact_labels", None)
    if fn is None or "obj_rot" not in clip:
        return None
    name = str(clip["object_name"])
    verts, faces = store.object_template(name)
    return np.asarray(fn(clip["joints"], verts, faces, clip["obj_rot"], clip["obj_trans"], name), dtype=bool)


def _annotate_unit(job: tuple) -> dict:
    """Annotate one store clip (pure: depends on the job only); writes its files when asked."""
    root, clip_id, spec, seed, lab, write = job     # lab: this clip's labels (_labels_for) or None
    root = Path(root)
    try:
        from ..datasets.store import Store
        store = Store(root)
        clip = store.load(clip_id)
        prov = load_json_bytes(str(clip["provenance"]), f"{clip_id}: provenance") if "provenance" in clip else {}
        partner = None
        if "object_name" in clip and str(clip["object_name"]):
            object_name = str(clip["object_name"])
        else:       # human-only (RICH: static scene): the scene object its action is done on
            action = scene_action_name(clip_id, prov)
            scene = prov.get("scene")
            object_name, rule = scene_partner(spec, action, scene)
            partner = {"object": object_name, "category": spec.scenes["objects"][object_name]["category"],
                       "scene": scene, "action": action, "rule": f"{spec.scenes['file']}: {rule}"}
        fps = float(clip["fps"])
        if "contacts" in clip:
            contacts, csrc = clip["contacts"].astype(bool), "store"
        else:
            contacts = _compute_contacts(store, clip)
            if contacts is None and partner is not None:
                raise ValueError(f"{clip_id}: no contact labels ('contacts') in the human-only clip (no "
                                 "object to compute them from)")
            if contacts is None:
                raise ValueError(f"{clip_id}: no contact labels ('contacts') in the clip, and "
                                 "hoibench.bodies.contact.joint_contact_labels is not available to compute them")
            csrc = "computed (hoibench.bodies.contact.joint_contact_labels)"
        notes = []
        actions = None
        if lab is not None:
            origin, how = (0.0, "clip start") if lab["scheme"] == "generic" else \
                _label_origin(root, store.manifest, clip_id, prov)
            if origin is None:
                origin = float(np.floor(lab["entries"][0][0])) if lab["entries"] else 0.0
                notes.append("per-second labels aligned to the first label: the clip's first capture "
                             "time is unknown (no provenance source_start_s, no raw frame_times)")
            spans = _spans_from_labels(lab, origin)
            if spans:
                actions = spans
                notes.append(f"actions from {lab['scheme']} labels (time origin: {how}, {origin:.3f} s)")
        if actions is None:
            actions = action_from_name(clip_id, prov) if partner is None else partner["action"]
        ann = annotate_clip(clip_id, contacts, fps, object_name, actions, spec, seed,
                            human_texts=_human_texts(root, clip_id, clip), contacts_source=csrc,
                            scene_partner=partner)
        if partner is not None and partner["rule"].endswith(": default"):
            ann.notes.append(f"no scene object listed for action {partner['action']!r} (scene "
                             f"{partner['scene']!r}): named the default, {object_name!r}")
        if lab is not None and all(a["source"] in ("name", "default") for a in ann.actions):
            notes.append(f"{lab['scheme']} labels gave no action: used the clip name")
        ann.notes = notes + ann.notes
        out = ann.to_json()
        if write:
            atomic_write_json(root / ANNOTATIONS / f"{clip_id}.json", out)
            atomic_write_text(root / TEXTS / f"{clip_id}.txt", "".join(l + "\n" for l in ann.humanml3d_lines()))
        return {"clip": clip_id, "status": "ok", "group_id": ann.group_id, "annotation": out}
    except Exception as exc:
        msg = str(exc) if isinstance(exc, ValueError) else f"{type(exc).__name__}: {exc}"
        if not msg.startswith(clip_id):
            msg = f"{clip_id}: {msg}"
        return {"clip": clip_id, "status": "failed", "error": msg}


def annotate_store(data: str | Path, spec_dir: str | Path | None = None, seed: int = 0,
                   labels: str | Path | dict | None = None, executor: str = "serial", strict: bool = False,
                   clip_ids: Sequence[str] | None = None, write: bool = True) -> dict:
    """Annotate every clip of the store ``data`` (or ``clip_ids``).

    Writes DATA/annotations/<id>.json, DATA/texts/<id>.txt, DATA/annotations/index.json and
    DATA/annotations/errors.jsonl (unless ``write`` is False). With ``strict`` the first
    failing clip stops the run at once (``StrictStop``, after recording it). Returns the index, with the
    per-clip annotations under ``"annotations"`` (not written into index.json).
    """
    from ..datasets.store import Store
    root = Path(data)
    store = Store(root)
    spec = load_spec(spec_dir)
    if labels is not None and not isinstance(labels, dict):
        labels = load_action_labels(labels)
    ids = list(clip_ids) if clip_ids is not None else store.clip_ids()
    jobs = [(str(root), cid, spec, int(seed), _labels_for(labels, cid), write) for cid in ids]
    if write:
        clean_stale_tmp(root / ANNOTATIONS, root / TEXTS)
    annotations, errors = _run_annotate_jobs(jobs, root, executor, strict, write)
    groups: dict[str, list[str]] = {}
    for cid in sorted(annotations):
        groups.setdefault(annotations[cid]["group_id"], []).append(cid)
    index = {"annotator": ANNOTATOR_ID, "annotator_version": spec.version, "spec_name": spec.name,
             "spec_sha256": spec.sha256, "seed": int(seed),
             "labels": None if not labels else {"scheme": labels["scheme"], "file": Path(labels.get("path", "")).name},
             "counts": {"clips": len(ids), "annotated": len(annotations), "failed": len(errors),
                        "groups": len(groups),
                        "texts": sum(len(a["texts"]) for a in annotations.values()),
                        "generated_texts": sum(sum(t["source"] == SOURCE for t in a["texts"])
                                               for a in annotations.values())},
             "clips": sorted(annotations), "groups": dict(sorted(groups.items()))}
    if write:
        _write_errors(root, errors)
        atomic_write_json(root / ANNOTATIONS / INDEX, index)
    return {**index, "errors": errors, "annotations": annotations}


def _run_annotate_jobs(jobs: list[tuple], root: Path, executor: str, strict: bool,
                       write: bool) -> tuple[dict[str, dict], list[dict]]:
    """Run :func:`_annotate_unit` over ``jobs``: (annotations by clip, errors). Under
    ``strict`` the first failure (in job order) is recorded and raises ``StrictStop`` at once;
    leaving the loop closes :func:`map_units`, which cancels the units not started."""
    annotations: dict[str, dict] = {}
    errors: list[dict] = []
    with closing(map_units(_annotate_unit, jobs, executor, progress="annotate")) as units:
        for done, res in enumerate(units, 1):
            if res["status"] == "ok":
                annotations[res["clip"]] = res["annotation"]
                continue
            errors.append({"clip": res["clip"], "error": res["error"]})
            if strict:
                if write:
                    _write_errors(root, errors)
                where = f"; recorded in {root / ANNOTATIONS / ERRORS}" if write else ""
                raise StrictStop(f"--strict: {res['error']} (stopped after {done} of {len(jobs)} clips{where})")
            print(f"[annotate] skipped {res['error']}", file=sys.stderr)
    return annotations, errors


def _write_errors(root: Path, errors: list[dict]) -> None:
    text = "".join(json.dumps(e, sort_keys=True) + "\n" for e in sorted(errors, key=lambda e: e["clip"]))
    atomic_write_text(root / ANNOTATIONS / ERRORS, text)


# =========================================================================== preview / CLI
def _timeline_text(ann: dict) -> str:
    segs = ann["timeline"]
    if not segs:
        return "no contact"
    return ", ".join(f"{s['part']} {s['start_s']:.1f}-{s['end_s']:.1f}s" + (" (short)" if s["transition"] else "")
                     for s in segs)


def preview_table(data: str | Path, n: int = 5, spec_dir: str | Path | None = None, seed: int = 0,
                  labels: str | Path | dict | None = None, executor: str = "serial",
                  texts: int = 2) -> str:
    """A readable table of the annotation of the first ``n`` clips (computed from the current
    spec, nothing written): clip id, object, contact timeline, group id, first ``texts`` texts."""
    from ..datasets.store import Store
    ids = Store(data).clip_ids()[: max(0, int(n))]
    res = annotate_store(data, spec_dir, seed, labels, executor, clip_ids=ids, write=False)
    rows = []
    for cid in ids:
        if cid in res["annotations"]:
            a = res["annotations"][cid]
            rows.append((cid, a["object_name"], a["group_id"], _timeline_text(a),
                         [t for t in a["texts"]][:texts], None))
        else:
            err = next(e["error"] for e in res["errors"] if e["clip"] == cid)
            rows.append((cid, "-", "-", "-", [], err))
    wc = max([len("clip")] + [len(r[0]) for r in rows])
    wo = max([len("object")] + [len(r[1]) for r in rows])
    wg = max([len("group")] + [len(r[2]) for r in rows])
    lines = [f"annotator {res['annotator_version']} (spec sha256 {res['spec_sha256'][:12]}), seed {seed}",
             f"{'clip':{wc}s}  {'object':{wo}s}  {'group':{wg}s}  contact timeline",
             f"{'-' * wc}  {'-' * wo}  {'-' * wg}  {'-' * 16}"]
    for cid, obj, gid, tl, txts, err in rows:
        lines.append(f"{cid:{wc}s}  {obj:{wo}s}  {gid:{wg}s}  {tl}")
        if err:
            lines.append(f"    error: {err}")
        for i, t in enumerate(txts, 1):
            span = "" if not (t["start"] or t["end"]) else f" [{t['start']:.1f}-{t['end']:.1f}s]"
            lines.append(f"    {i}. {t['caption']}{span}  ({t['source']})")
    return "\n".join(lines)


def main_annotate(data: str | Path, preview: int | None = None, executor: str = "serial",
                  strict: bool = False, seed: int = 0, spec_dir: str | Path | None = None,
                  labels: str | Path | None = None) -> int:
    """``hoibench annotate DATA``: annotate the store and print a summary.

    ``preview=N``: print :func:`preview_table` for the first N clips and write nothing (a dry
    run, e.g. while editing the lexicons). ``labels``: an action label file
    (:func:`load_action_labels`). ``spec_dir``: the spec folder (default: ``annotators/``).
    Returns 0, or 1 when clips failed under ``strict`` (the error is also raised).
    """
    if preview:
        print(preview_table(data, preview, spec_dir, seed, labels, executor))
        return 0
    index = annotate_store(data, spec_dir, seed, labels, executor, strict)
    c = index["counts"]
    print(f"annotated {c['annotated']}/{c['clips']} clips of {data} with annotator {index['annotator_version']} "
          f"(spec sha256 {index['spec_sha256'][:12]}, seed {seed}): {c['generated_texts']} generated texts, "
          f"{c['texts'] - c['generated_texts']} kept, {c['groups']} semantic groups, {c['failed']} failed")
    if c["failed"]:
        print(f"  errors: {Path(data) / ANNOTATIONS / ERRORS}")
    return 1 if (strict and c["failed"]) else 0
