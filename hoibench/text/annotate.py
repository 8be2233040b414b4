"""Contact-aware text annotation of a processed store (DESIGN section 6).

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
"""
from __future__ import annotations

import hashlib
import json
import os
import random
import re
import sys
from contextlib import closing
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from ..core import skeleton as sk
from ..bodies.contact import ContactSegment, contact_timeline
from ..core.errors import StrictStop
from ..core.io import atomic_write_json, atomic_write_text, clean_stale_tmp
from ..core.parallel import map_units

__all__ = [
    "SPEC_ENV", "SOURCE", "SpecError", "Token", "AnnotatorSpec", "ActionSpan", "ClipAnnotation",
    "default_spec_dir", "load_spec", "parse_phrase", "resolve_action", "body_part_timeline",
    "scene_action_name", "scene_partner",
    "annotate_clip", "load_action_labels", "humanml3d_line", "parse_humanml3d_line",
    "annotate_store", "preview_table", "main_annotate",
]

SPEC_ENV = "HOIBENCH_ANNOTATORS_DIR"
SPEC_FILE = "spec.yaml"
SOURCE = "annotator"            # `source` of generated texts; human texts keep theirs
ANNOTATIONS = "annotations"
TEXTS = "texts"
INDEX = "index.json"
ERRORS = "errors.jsonl"

UPOS = frozenset("ADJ ADP ADV AUX CCONJ DET INTJ NOUN NUM PART PRON PROPN PUNCT SCONJ SYM VERB X".split())
_PUNCT = frozenset(",.;:!?")
_OBJECT_SLOTS = frozenset({"obj", "np", "it"})
_SENTENCE_SLOTS = frozenset({"person", "verb", "verb_ing", "relation", "relation_ing", "method", "parts"})
_CONTACT_SLOTS = frozenset({"relation", "relation_ing", "method", "parts"})
_REPEAT_SUFFIX = re.compile(r"_\d+$")
_BEHAVE_NAME = re.compile(r"^(Date\d+)_(Sub\d+)_([A-Za-z0-9]+)(?:_(.*))?$")
#: a RICH clip id: ``<Scene>_<sub>[_<sub2>]_<action><take>_<sub>_<first frame:05d>``
_RICH_CLIP = re.compile(r"^(.+)_\d+_\d{5}$")
_TAKE = re.compile(r"\d+$")


class SpecError(ValueError):
    """An annotator spec that cannot be used: names the file and entry."""


# =========================================================================== phrases
@dataclass(frozen=True)
class Token:
    """One word with its lemma and universal POS tag (punctuation: pos PUNCT)."""

    surface: str
    lemma: str
    pos: str

    def hml(self) -> str:
        """HumanML3D's ``word/POS``: the lemma of nouns and verbs (except "left"), else the word."""
        word = self.lemma if self.pos in ("NOUN", "VERB") and self.surface != "left" else self.surface
        return f"{word}/{self.pos}"


@dataclass(frozen=True)
class Slot:
    name: str


Phrase = tuple  # tuple[Token | Slot, ...]


def parse_phrase(text: str, where: str, slots: Iterable[str] = ()) -> Phrase:
    """Parse ``"picks=pick/VERB {it} up/ADP {np}"`` into tokens and slots.

    Tokens are ``word/POS`` or ``word=lemma/POS``; bare punctuation (``,``) is a PUNCT token;
    ``{name}`` is a slot, allowed only when ``name`` is in ``slots``. ``where`` names the spec
    entry in error messages.
    """
    if not isinstance(text, str) or not text.strip():
        raise SpecError(f"{where}: expected a non-empty phrase string, got {text!r}")
    allowed = set(slots)
    out: list = []
    for item in text.split():
        if item.startswith("{") and item.endswith("}"):
            name = item[1:-1]
            if name not in allowed:
                raise SpecError(f"{where}: unknown slot {item} in {text!r} (allowed here: "
                                f"{', '.join('{' + s + '}' for s in sorted(allowed)) or 'none'})")
            out.append(Slot(name))
        elif item in _PUNCT:
            out.append(Token(item, item, "PUNCT"))
        else:
            word, sep, pos = item.rpartition("/")
            if not sep or not word or pos not in UPOS:
                raise SpecError(f"{where}: token {item!r} in {text!r}: expected word/POS or "
                                f"word=lemma/POS with POS one of {' '.join(sorted(UPOS))}")
            surface, _, lemma = word.partition("=")
            if not surface.isalpha() or (lemma and not lemma.isalpha()):
                raise SpecError(f"{where}: token {item!r} in {text!r}: words must be letters only "
                                "(HumanML3D drops other tokens)")
            out.append(Token(surface.lower(), (lemma or surface).lower(), pos))
    return tuple(out)


def _slot_names(phrase: Phrase) -> set[str]:
    return {p.name for p in phrase if isinstance(p, Slot)}


# =========================================================================== the spec
@dataclass
class AnnotatorSpec:
    """A loaded, validated spec folder (plain data: picklable for process executors)."""

    root: str
    name: str
    version: str
    sha256: str
    generation: dict
    person: list
    determiners: list
    pronoun: Phrase
    method: list
    parts_joiner: Phrase
    templates: dict                # "contact" / "no_contact" -> [(id, Phrase)]
    clause: dict                   # "contact" / "no_contact" -> [Phrase]
    joiners: dict                  # "sequential" / "concurrent" -> [(Phrase, form)]
    grouping: dict
    parts: dict                    # key -> {"joints": tuple, "kind": str, "phrases": [Phrase]}
    combinations: dict             # key -> {"parts": tuple, "kind": str, "phrases": [Phrase]}
    min_overlap: float
    relations: dict                # key -> {"s": Phrase, "ing": Phrase}
    relations_by_kind: dict
    relations_default: list
    actions: dict                  # key -> {"verbs": [{"s", "ing"}], "relations": list|None, "exclude": set}
    default_action: str
    aliases: dict
    labels: dict                   # scheme -> {description: key | None}
    objects: dict                  # name -> {"category": str, "nouns": [Phrase]}
    scenes: dict | None = None     # scenes.yaml: {"objects", "actions", "scenes", "default", "name_parts"}

    @property
    def annotator_version(self) -> str:
        return self.version

    def part_joints(self) -> dict[str, tuple[int, ...]]:
        return {k: v["joints"] for k, v in self.parts.items()}

    def object_entry(self, name: str) -> dict:
        if name in self.objects:
            return self.objects[name]
        word = re.sub(r"[^a-z]", "", name.lower()) or "object"
        return {"category": name, "nouns": [(Token(word, word, "NOUN"),)], "unknown": True}

    def partner_entry(self, name: str, scene: bool = False) -> dict:
        """The entry of the clip's contact partner: a scene object of ``scenes.yaml`` when
        ``scene`` (human-only clips), else :meth:`object_entry`."""
        return self.scenes["objects"][name] if scene else self.object_entry(name)


def default_spec_dir() -> Path:
    """``$HOIBENCH_ANNOTATORS_DIR``, else ``annotators/`` next to the package."""
    env = os.environ.get(SPEC_ENV)
    return Path(env) if env else Path(__file__).resolve().parents[2] / "annotators"


def _read_yaml(path: Path) -> Any:
    import yaml
    if not path.exists():
        raise SpecError(f"{path}: missing spec file")
    try:
        return yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        raise SpecError(f"{path}: invalid YAML ({exc})") from None


def _need(d: Any, key: str, where: str, kind=None):
    if not isinstance(d, dict) or key not in d:
        raise SpecError(f"{where}: missing key {key!r}")
    v = d[key]
    if kind is not None and not isinstance(v, kind):
        raise SpecError(f"{where}.{key}: expected {kind.__name__ if isinstance(kind, type) else kind}, got {v!r}")
    return v


def _phrases(items, where: str, slots=()) -> list:
    if isinstance(items, str):
        items = [items]
    if not isinstance(items, list) or not items:
        raise SpecError(f"{where}: expected a non-empty list of phrases")
    return [parse_phrase(x, f"{where}[{i}]", slots) for i, x in enumerate(items)]


def _verb_pair(entry, where: str) -> dict:
    if not isinstance(entry, dict) or set(entry) != {"s", "ing"}:
        raise SpecError(f"{where}: expected {{s: ..., ing: ...}}, got {entry!r}")
    out = {}
    for form in ("s", "ing"):
        ph = parse_phrase(entry[form], f"{where}.{form}", _OBJECT_SLOTS)
        names = [p.name for p in ph if isinstance(p, Slot)]
        if not names:
            ph = ph + (Slot("obj"),)
        elif names.count("obj") > 1 or ("obj" in names and ({"np", "it"} & set(names))) \
                or ({"np", "it"} & set(names) and not {"np", "it"} <= set(names)):
            raise SpecError(f"{where}.{form}: use either one {{obj}} or both {{it}} and {{np}}")
        out[form] = ph
    return out


def _joints(items, where: str) -> tuple[int, ...]:
    if not isinstance(items, list) or not items:
        raise SpecError(f"{where}: expected a non-empty list of joints")
    out = []
    for j in items:
        if isinstance(j, int) and 0 <= j < sk.NUM_JOINTS:
            out.append(j)
        elif isinstance(j, str) and j in sk.JOINT_INDEX:
            out.append(sk.JOINT_INDEX[j])
        else:
            raise SpecError(f"{where}: unknown joint {j!r} (a name of hoibench.core.skeleton.JOINT_NAMES or 0-21)")
    return tuple(out)


def _sha256_files(root: Path, names: Sequence[str]) -> str:
    h = hashlib.sha256()
    for name in sorted(set(names)):
        h.update(name.encode() + b"\0")
        h.update((root / name).read_bytes())
    return h.hexdigest()


def load_spec(spec_dir: str | Path | None = None) -> AnnotatorSpec:
    """Read and validate the spec folder (``spec.yaml`` and the files it names)."""
    root = Path(spec_dir) if spec_dir is not None else default_spec_dir()
    if not (root / SPEC_FILE).exists():
        raise SpecError(f"{root}: no {SPEC_FILE} (annotator spec folder; set {SPEC_ENV} or pass spec_dir)")
    top = _read_yaml(root / SPEC_FILE)
    w = SPEC_FILE
    version = str(_need(top, "version", w))
    files = _need(top, "files", w, dict)
    docs = {}
    for key in ("body_parts", "actions", "relations", "objects"):
        fname = _need(files, key, f"{w}.files", str)
        docs[key] = (fname, _read_yaml(root / fname))
    if files.get("scenes") is not None:          # optional: only human-only clips need it
        fname = _need(files, "scenes", f"{w}.files", str)
        docs["scenes"] = (fname, _read_yaml(root / fname))

    gen = {"paraphrases": 3, "segment_texts": True, "min_frames": 5, "min_part_overlap_s": 0.25,
           "max_parts": 3, "max_actions": 4, "max_attempts": 200, "end": "."}
    gen.update(top.get("generation") or {})
    if int(gen["paraphrases"]) < 1:
        raise SpecError(f"{w}.generation.paraphrases: expected >= 1")

    # templates
    tpl = _need(top, "templates", w, dict)
    templates = {}
    for kind in ("contact", "no_contact"):
        entries = _need(tpl, kind, f"{w}.templates", list)
        if not entries:
            raise SpecError(f"{w}.templates.{kind}: expected at least one template")
        out = []
        for i, e in enumerate(entries):
            where = f"{w}.templates.{kind}[{i}]"
            tid = str(e.get("id", f"{kind}{i}")) if isinstance(e, dict) else f"{kind}{i}"
            text = e.get("text") if isinstance(e, dict) else e
            ph = parse_phrase(text, where, _SENTENCE_SLOTS)
            names = _slot_names(ph)
            if "person" not in names or not ({"verb", "verb_ing"} & names):
                raise SpecError(f"{where}: a sentence template needs {{person}} and {{verb}}")
            if kind == "contact" and "parts" not in names:
                raise SpecError(f"{where}: a contact template must name the body parts ({{parts}})")
            if kind == "no_contact" and names & _CONTACT_SLOTS:
                raise SpecError(f"{where}: a no_contact template may not use contact slots "
                                f"({', '.join(sorted(names & _CONTACT_SLOTS))})")
            out.append((tid, ph))
        templates[kind] = out
    clause_doc = _need(tpl, "clause", f"{w}.templates", dict)
    clause = {}
    for kind in ("contact", "no_contact"):
        phs = _phrases(_need(clause_doc, kind, f"{w}.templates.clause"), f"{w}.templates.clause.{kind}",
                       _SENTENCE_SLOTS - {"person"})
        for i, ph in enumerate(phs):
            names = _slot_names(ph)
            if "verb" not in names:
                raise SpecError(f"{w}.templates.clause.{kind}[{i}]: a clause needs {{verb}}")
            if kind == "contact" and "parts" not in names:
                raise SpecError(f"{w}.templates.clause.contact[{i}]: must name the body parts ({{parts}})")
            if kind == "no_contact" and names & _CONTACT_SLOTS:
                raise SpecError(f"{w}.templates.clause.no_contact[{i}]: may not use contact slots")
        clause[kind] = phs
    jdoc = _need(top, "joiners", w, dict)
    joiners = {}
    for kind in ("sequential", "concurrent"):
        items = _need(jdoc, kind, f"{w}.joiners", list)
        out = []
        for i, e in enumerate(items):
            where = f"{w}.joiners.{kind}[{i}]"
            if not isinstance(e, dict) or e.get("form") not in ("s", "ing"):
                raise SpecError(f"{where}: expected {{text: ..., form: s|ing}}")
            out.append((parse_phrase(e["text"], where), e["form"]))
        if not out:
            raise SpecError(f"{w}.joiners.{kind}: expected at least one joiner")
        joiners[kind] = out

    grouping = {"object": "category", "format": "{object}/{actions}/{parts}", "joiner": "+",
                "no_contact": "nocontact/{clip}"}
    grouping.update(top.get("grouping") or {})
    if grouping["object"] not in ("category", "name"):
        raise SpecError(f"{w}.grouping.object: expected 'category' or 'name'")

    # body parts
    bname, bdoc = docs["body_parts"]
    parts = {}
    seen_joints: dict[int, str] = {}
    for key, e in _need(bdoc, "parts", bname, dict).items():
        where = f"{bname}.parts.{key}"
        joints = _joints(_need(e, "joints", where), f"{where}.joints")
        for j in joints:
            if j in seen_joints:
                raise SpecError(f"{where}: joint {sk.JOINT_NAMES[j]} is already in part {seen_joints[j]} "
                                "(parts must not share joints)")
            seen_joints[j] = key
        parts[key] = {"joints": joints, "kind": str(e.get("kind", key)),
                      "phrases": _phrases(_need(e, "phrases", where), f"{where}.phrases")}
    combos = {}
    for key, e in (bdoc.get("combinations") or {}).items():
        where = f"{bname}.combinations.{key}"
        members = tuple(_need(e, "parts", where, list))
        if len(members) < 2 or any(m not in parts for m in members):
            raise SpecError(f"{where}.parts: expected two or more keys of parts, got {list(members)}")
        combos[key] = {"parts": members, "kind": str(e.get("kind", parts[members[0]]["kind"])),
                       "phrases": _phrases(_need(e, "phrases", where), f"{where}.phrases")}
    min_overlap = float(bdoc.get("min_overlap", 0.5))

    # relations
    rname, rdoc = docs["relations"]
    relations = {k: _verb_pair(v, f"{rname}.relations.{k}")
                 for k, v in _need(rdoc, "relations", rname, dict).items()}

    def _rel_list(items, where):
        if not isinstance(items, list) or not items or any(r not in relations for r in items):
            raise SpecError(f"{where}: expected a non-empty list of keys of {rname} relations, got {items!r}")
        return list(items)

    by_kind = {k: _rel_list(v, f"{rname}.by_kind.{k}") for k, v in (rdoc.get("by_kind") or {}).items()}
    rel_default = _rel_list(rdoc.get("default", ["touch"]), f"{rname}.default")

    # actions
    aname, adoc = docs["actions"]
    known_kinds = {v["kind"] for v in parts.values()}

    def _kinds(items, where):
        if items is None:
            return None
        if not isinstance(items, list) or not items or set(items) - known_kinds:
            raise SpecError(f"{where}: expected a list of body-part kinds of {bname} "
                            f"({', '.join(sorted(known_kinds))}), got {items!r}")
        return list(items)

    all_tids = {tid for kind in templates.values() for tid, _ in kind}
    actions = {}
    for key, e in _need(adoc, "actions", aname, dict).items():
        where = f"{aname}.actions.{key}"
        verbs = _need(e, "verbs", where, list)
        if not verbs:
            raise SpecError(f"{where}.verbs: expected at least one verb")
        excl = set(e.get("exclude_templates") or [])
        if excl - all_tids:
            raise SpecError(f"{where}.exclude_templates: unknown template ids {sorted(excl - all_tids)}")
        mcf = e.get("min_contact_frames")
        if mcf is not None and (not isinstance(mcf, int) or mcf < 1):
            raise SpecError(f"{where}.min_contact_frames: expected a positive integer, got {mcf!r}")
        actions[str(key)] = {
            "verbs": [_verb_pair(v, f"{where}.verbs[{i}]") for i, v in enumerate(verbs)],
            "relations": _rel_list(e["relations"], f"{where}.relations") if e.get("relations") else None,
            "exclude": excl, "min_contact_frames": mcf, "contact": bool(e.get("contact", True)),
            "kinds": _kinds(e.get("kinds"), f"{where}.kinds")}
    default_action = str(adoc.get("default_action", "interact"))
    if default_action not in actions:
        raise SpecError(f"{aname}.default_action: {default_action!r} is not an action")
    aliases = {}
    for k, v in (adoc.get("aliases") or {}).items():
        if v is not None and v not in actions:
            raise SpecError(f"{aname}.aliases.{k}: {v!r} is not an action")
        aliases[str(k).lower()] = v
    labels = {}
    for scheme, table in (adoc.get("labels") or {}).items():
        labels[scheme] = {}
        for k, v in (table or {}).items():
            if v is not None and v not in actions:
                raise SpecError(f"{aname}.labels.{scheme}.{k}: {v!r} is not an action")
            labels[scheme][str(k)] = v

    # objects
    oname, odoc = docs["objects"]
    objects = {}
    for key, e in _need(odoc, "objects", oname, dict).items():
        where = f"{oname}.objects.{key}"
        objects[str(key)] = {"category": str(_need(e, "category", where)),
                             "nouns": _phrases(_need(e, "nouns", where), f"{where}.nouns")}

    scenes = _load_scenes(docs["scenes"]) if "scenes" in docs else None

    sha = _sha256_files(root, [SPEC_FILE] + [f for f, _ in docs.values()])
    return AnnotatorSpec(
        root=str(root), name=str(top.get("name", "hoibench-annotator")), version=version, sha256=sha,
        generation=gen, person=_phrases(_need(top, "person", w), f"{w}.person"),
        determiners=_phrases(_need(top, "object_determiners", w), f"{w}.object_determiners"),
        pronoun=parse_phrase(_need(top, "pronoun", w), f"{w}.pronoun"),
        method=_phrases(_need(top, "method", w), f"{w}.method"),
        parts_joiner=parse_phrase(top.get("parts_joiner", "and/CCONJ"), f"{w}.parts_joiner"),
        templates=templates, clause=clause, joiners=joiners, grouping=grouping,
        parts=parts, combinations=combos, min_overlap=min_overlap,
        relations=relations, relations_by_kind=by_kind, relations_default=rel_default,
        actions=actions, default_action=default_action, aliases=aliases, labels=labels,
        objects=objects, scenes=scenes)


def _load_scenes(doc: tuple) -> dict:
    """Validate ``scenes.yaml``: scene objects (category, nouns, optional determiners), the
    action -> scene object table, per-scene exceptions, the default and ``name_parts``."""
    sname, sdoc = doc
    objects = {}
    for key, e in _need(sdoc, "objects", sname, dict).items():
        where = f"{sname}.objects.{key}"
        entry = {"category": str(_need(e, "category", where)),
                 "nouns": _phrases(_need(e, "nouns", where), f"{where}.nouns")}
        if e.get("determiners") is not None:
            entry["determiners"] = _phrases(e["determiners"], f"{where}.determiners")
        objects[str(key)] = entry
    if not objects:
        raise SpecError(f"{sname}.objects: expected at least one scene object")

    def _table(d, where):
        if d is None:
            return {}
        if not isinstance(d, dict):
            raise SpecError(f"{where}: expected a mapping of action names to scene objects, got {d!r}")
        out = {}
        for k, v in d.items():
            if v not in objects:
                raise SpecError(f"{where}.{k}: {v!r} is not a scene object ({', '.join(sorted(objects))})")
            out[str(k).lower()] = str(v)
        return out

    table = _table(sdoc.get("actions"), f"{sname}.actions")
    per_scene = sdoc.get("scenes") or {}
    if not isinstance(per_scene, dict):
        raise SpecError(f"{sname}.scenes: expected a mapping of scene names to action tables")
    default = sdoc.get("default", "ground")
    if default not in objects:
        raise SpecError(f"{sname}.default: {default!r} is not a scene object")
    name_parts = sdoc.get("name_parts", "action_kinds")
    if name_parts not in ("action_kinds", "all"):
        raise SpecError(f"{sname}.name_parts: expected 'action_kinds' or 'all', got {name_parts!r}")
    return {"file": sname, "objects": objects, "actions": table,
            "scenes": {str(sc): _table(t, f"{sname}.scenes.{sc}") for sc, t in per_scene.items()},
            "default": str(default), "name_parts": name_parts}


# =========================================================================== actions
@dataclass(frozen=True)
class ActionSpan:
    """An action name over ``[start, end)`` seconds from the clip start (None: the whole clip)."""

    name: str
    start: float | None = None
    end: float | None = None
    source: str = "name"


def resolve_action(spec: AnnotatorSpec, raw: str | None, scheme: str | None = None) -> tuple[str | None, bool]:
    """Action key of a raw name (or of a label description of ``scheme``).

    Returns ``(key, known)``: ``key`` None means "not an action" (e.g. action_transition);
    an unknown name gives the spec's default action with ``known`` False.
    """
    if scheme is not None and scheme in spec.labels and raw in spec.labels[scheme]:
        return spec.labels[scheme][raw], True
    s = _REPEAT_SUFFIX.sub("", str(raw or "").strip().lower())
    for cand in (s, s.replace(" ", "_"), s.replace("-", "_")):
        if cand in spec.actions:
            return cand, True
        if cand in spec.aliases:
            return spec.aliases[cand], True
    return spec.default_action, False


def action_from_name(clip_id: str, provenance: Mapping[str, Any] | None = None) -> str:
    """The clip's action name: provenance ``action`` (BEHAVE-layout loaders record it), else
    the ``<action>`` of a ``Date0X_SubYY_<object>_<action>[_<n>]`` name, else ''."""
    if provenance and provenance.get("action") is not None:
        return str(provenance["action"])
    m = _BEHAVE_NAME.match(clip_id)
    return (m.group(4) or "") if m else ""


def scene_action_name(clip_id: str, provenance: Mapping[str, Any] | None = None) -> str:
    """The action of a human-only (RICH) clip: provenance ``action``, else the ``<action>``
    of the RICH sequence name ``<Scene>_<sub>[_<sub2>]_<action><take>`` (provenance
    ``sequence``, else the clip id ``<sequence>_<sub>_<frame:05d>``): the scene, the numeric
    subject ids and the trailing take digits are dropped, so ``Gym_010_pushup1`` gives
    ``pushup`` and ``ParkingLot1_004_005_greetingchattingeating1`` gives
    ``greetingchattingeating``. '' when there is none."""
    if provenance and provenance.get("action") is not None:
        return str(provenance["action"])
    seq = str((provenance or {}).get("sequence") or "")
    if not seq:
        m = _RICH_CLIP.match(clip_id)
        seq = m.group(1) if m else clip_id
    parts = seq.split("_")[1:]                     # drop the scene
    while parts and parts[0].isdigit():            # subject ids
        parts.pop(0)
    return _TAKE.sub("", "_".join(parts)).strip("_").lower()


def scene_partner(spec: AnnotatorSpec, action: str | None, scene: str | None = None) -> tuple[str, str]:
    """The scene object key a human-only clip's action is done on, and the ``scenes.yaml``
    entry that chose it (``"scenes.Gym.sit"``, ``"actions.pushup"``, ``"default"``).

    Looked up by the action name, then by its action key (through the aliases), first among
    the scene's exceptions, then in the action table; else the default."""
    if spec.scenes is None:
        raise ValueError("the annotator spec has no scenes file (spec.yaml files.scenes): human-only "
                         "clips cannot be annotated")
    sc = spec.scenes
    raw = _REPEAT_SUFFIX.sub("", str(action or "").strip().lower())
    key, _ = resolve_action(spec, raw) if raw else (None, False)
    names = [n for n in dict.fromkeys((raw, key)) if n]
    for where, table in ((f"scenes.{scene}", sc["scenes"].get(str(scene), {}) if scene else {}),
                         ("actions", sc["actions"])):
        for n in names:
            if n in table:
                return table[n], f"{where}.{n}"
    return sc["default"], "default"


# =========================================================================== timelines
def body_part_timeline(contacts: np.ndarray, spec: AnnotatorSpec) -> list[ContactSegment]:
    """Contact segments per body part of the spec (``contact_timeline`` with the spec's
    disjoint parts and ``min_frames``)."""
    return contact_timeline(np.asarray(contacts, dtype=bool), spec.part_joints(),
                            min_frames=int(spec.generation["min_frames"]))


@dataclass
class _Action:
    key: str
    name: str
    source: str
    known: bool
    start: float
    end: float
    whole: bool
    parts: list = field(default_factory=list)     # base part keys, spec order
    units: list = field(default_factory=list)     # named units: part or combination keys

    def to_dict(self, spec: AnnotatorSpec) -> dict:
        return {"action": self.key, "name": self.name, "source": self.source, "known": self.known,
                "start": round(self.start, 4), "end": round(self.end, 4), "whole_clip": self.whole,
                "parts": list(self.parts), "named": list(self.units)}


def _normalise_actions(spec: AnnotatorSpec, actions, duration: float, fps: float) -> list[_Action]:
    if actions is None or isinstance(actions, str):
        actions = [ActionSpan(actions or "")]
    out: list[_Action] = []
    for a in actions:
        if not isinstance(a, ActionSpan):
            a = ActionSpan(*a) if isinstance(a, (tuple, list)) else ActionSpan(**a)
        key, known = resolve_action(spec, a.name, a.source if a.source in spec.labels else None)
        if key is None:
            continue
        s = 0.0 if a.start is None else max(0.0, float(a.start))
        e = duration if a.end is None else min(duration, float(a.end))
        if e - s < 0.5 / fps:
            continue
        out.append(_Action(key, a.name, a.source, known, s, e, False))
    out.sort(key=lambda a: (a.start, a.end, a.key))
    merged: list[_Action] = []
    for a in out:   # consecutive spans of one action (split by transitions) read as one
        if merged and merged[-1].key == a.key:
            merged[-1].end = max(merged[-1].end, a.end)
        else:
            merged.append(a)
    merged = merged[: int(spec.generation["max_actions"])]
    if not merged:
        merged = [_Action(spec.default_action, "", "default", False, 0.0, duration, True)]
    for a in merged:
        a.whole = a.start <= 0.5 / fps and a.end >= duration - 0.5 / fps
    return merged


def _candidate_masks(spec: AnnotatorSpec, act: _Action, segs: list[ContactSegment], fps: float,
                     T: int) -> dict[str, np.ndarray]:
    """Part -> frames of the action window in contact, for parts whose described contact
    overlaps the action long enough."""
    if not spec.actions[act.key]["contact"]:
        return {}
    a0, a1 = int(round(act.start * fps)), int(round(act.end * fps))
    a0, a1 = max(0, a0), min(T, max(a1, a0 + 1))
    masks: dict[str, np.ndarray] = {}
    short_ok = spec.actions[act.key]["min_contact_frames"]   # brief contacts this action describes
    for s in segs:
        if s.transition and not (short_ok and s.num_frames >= short_ok):
            continue
        lo, hi = max(s.start, a0), min(s.end, a1)
        if hi > lo:
            m = masks.setdefault(s.part, np.zeros(a1 - a0, dtype=bool))
            m[lo - a0:hi - a0] = True
    need = min(float(spec.generation["min_part_overlap_s"]), 0.5 * (act.end - act.start))
    if short_ok:
        need = min(need, short_ok / fps)
    return {p: m for p, m in masks.items() if m.sum() / fps >= need - 1e-9}


def _resolve_concurrent(spec: AnnotatorSpec, acts: list[_Action], masks: list[dict]) -> None:
    """A part claimed by two overlapping actions stays with the one whose ``kinds`` (actions
    lexicon) include the part's kind: holding a box while sitting on a chair -> the hands
    hold, the hips sit."""
    for i, a in enumerate(acts):
        kinds = spec.actions[a.key]["kinds"]
        if kinds is None:
            continue
        for p in list(masks[i]):
            if spec.parts[p]["kind"] in kinds:
                continue
            for j, b in enumerate(acts):
                if j == i or p not in masks[j] or not (b.start < a.end and a.start < b.end):
                    continue
                bk = spec.actions[b.key]["kinds"]
                if bk is None or spec.parts[p]["kind"] in bk:
                    del masks[i][p]
                    break


def _select_units(spec: AnnotatorSpec, act: _Action, masks: dict[str, np.ndarray], fps: float) -> None:
    """The action's parts (longest contact first, at most max_parts, in spec order) and the
    units that name them, pairs together ("both hands") when their contacts overlap."""
    frames = {p: int(m.sum()) for p, m in masks.items()}
    order = list(spec.parts)
    chosen = sorted(frames, key=lambda p: (-frames[p], order.index(p)))[: int(spec.generation["max_parts"])]
    act.parts = sorted(chosen, key=order.index)
    units, used = [], set()
    for p in act.parts:
        if p in used:
            continue
        for ckey, c in spec.combinations.items():
            members = c["parts"]
            if p in members and all(m in act.parts and m not in used for m in members):
                both = np.logical_and.reduce([masks[m] for m in members]).sum()
                if both >= spec.min_overlap * min(frames[m] for m in members):
                    units.append(ckey)
                    used.update(members)
                    break
        else:
            units.append(p)
            used.add(p)
    act.units = units


def _unit_entry(spec: AnnotatorSpec, unit: str) -> dict:
    return spec.combinations[unit] if unit in spec.combinations else spec.parts[unit]


def group_id(spec: AnnotatorSpec, clip_id: str, object_name: str, actions: list[_Action],
             scene: bool = False) -> str:
    """Semantic group: object category (or name) + action keys + contacting body parts;
    a clip with no described contact forms its own group. ``scene``: ``object_name`` is a
    scene object of ``scenes.yaml`` (human-only clips)."""
    g = spec.grouping
    parts = sorted({p for a in actions for p in a.parts}, key=list(spec.parts).index)
    if not parts:
        return g["no_contact"].format(clip=clip_id, object=object_name)
    obj = spec.partner_entry(object_name, scene)["category"] if g["object"] == "category" else object_name
    keys: list[str] = []
    for a in actions:
        if spec.actions[a.key]["contact"] and (not keys or keys[-1] != a.key):
            keys.append(a.key)
    return g["format"].format(object=obj, actions=g["joiner"].join(keys) or "none",
                              parts=g["joiner"].join(parts))


# =========================================================================== rendering
class _Sentence:
    """Token list under construction; tracks whether the object was mentioned."""

    def __init__(self, np_tokens: list[Token], pronoun: Phrase):
        self.tokens: list[Token] = []
        self.np_tokens = np_tokens
        self.pronoun = list(pronoun)
        self.mentioned = False

    def add(self, phrase: Iterable) -> None:
        for p in phrase:
            if isinstance(p, Token):
                self.tokens.append(p)
            elif p.name in ("obj", "np") and not self.mentioned:
                self.tokens.extend(self.np_tokens)
                self.mentioned = True
            elif p.name in ("obj", "it") and self.mentioned:
                self.tokens.extend(self.pronoun)
            # {np} after the first mention and {it} before it: nothing

    def caption(self, end: str) -> str:
        words: list[str] = []
        for t in self.tokens:
            if t.pos == "PUNCT" and words:
                words[-1] += t.surface
            else:
                words.append(t.surface)
        text = " ".join(words).rstrip(",;: ")
        return text + end if end and not text.endswith(end) else text

    def token_string(self) -> str:
        return " ".join(t.hml() for t in self.tokens if t.pos != "PUNCT")


def _object_np(spec: AnnotatorSpec, rng: random.Random, object_name: str, scene: bool = False) -> list[Token]:
    entry = spec.partner_entry(object_name, scene)
    noun = list(rng.choice(entry["nouns"]))
    det = list(rng.choice(entry.get("determiners") or spec.determiners))
    if det and det[-1].surface == "a" and noun and noun[0].surface[:1] in "aeiou":
        det[-1] = Token("an", "an", det[-1].pos)
    return det + noun


def _relations_for(spec: AnnotatorSpec, act: _Action) -> list[str]:
    rel = spec.actions[act.key]["relations"]
    if rel:
        return rel
    if act.units:
        return spec.relations_by_kind.get(_unit_entry(spec, act.units[0])["kind"], spec.relations_default)
    return spec.relations_default


class _Choices:
    """Per-sentence draws: one verb, relation and part phrases per action."""

    def __init__(self, spec: AnnotatorSpec, rng: random.Random, actions: list[_Action]):
        self.spec, self.rng = spec, rng
        self.method = rng.choice(spec.method)
        self.verbs = [rng.choice(spec.actions[a.key]["verbs"]) for a in actions]
        self.relations = [spec.relations[rng.choice(_relations_for(spec, a))] for a in actions]
        self.parts = [self._parts_phrase(a) for a in actions]

    def _parts_phrase(self, act: _Action) -> list:
        phrases = [list(self.rng.choice(_unit_entry(self.spec, u)["phrases"])) for u in act.units]
        out: list = []
        for i, ph in enumerate(phrases):
            if i and i == len(phrases) - 1:
                out.extend(self.spec.parts_joiner)
            elif i:
                out.append(Token(",", ",", "PUNCT"))
            out.extend(ph)
        return out


def _fill(sent: _Sentence, template: Phrase, ch: _Choices, i: int, person: Phrase | None,
          verb_form: str | None = None) -> None:
    for p in template:
        if isinstance(p, Token):
            sent.tokens.append(p)
        elif p.name == "person":
            sent.add(person or ())
        elif p.name in ("verb", "verb_ing"):
            form = verb_form or ("ing" if p.name == "verb_ing" else "s")
            sent.add(ch.verbs[i][form])
        elif p.name in ("relation", "relation_ing"):
            sent.add(ch.relations[i]["ing" if p.name == "relation_ing" else "s"])
        elif p.name == "method":
            sent.add(ch.method)
        elif p.name == "parts":
            sent.add(ch.parts[i])


def _templates_for(spec: AnnotatorSpec, act: _Action) -> list[tuple[str, Phrase]]:
    kind = "contact" if act.units else "no_contact"
    excl = spec.actions[act.key]["exclude"]
    return [t for t in spec.templates[kind] if t[0] not in excl] or spec.templates[kind]


def _render(spec: AnnotatorSpec, rng: random.Random, object_name: str, actions: list[_Action],
            template: Phrase, scene: bool = False) -> _Sentence:
    ch = _Choices(spec, rng, actions)
    sent = _Sentence(_object_np(spec, rng, object_name, scene), spec.pronoun)
    _fill(sent, template, ch, 0, rng.choice(spec.person))
    for i in range(1, len(actions)):
        concurrent = actions[i].start < actions[i - 1].end - 1e-6
        joiner, form = rng.choice(spec.joiners["concurrent" if concurrent else "sequential"])
        sent.add(joiner)
        clause = rng.choice(spec.clause["contact" if actions[i].units else "no_contact"])
        _fill(sent, clause, ch, i, None, verb_form=form)
    return sent


def _free_text_tokens(caption: str) -> str:
    """HumanML3D tokens of a human-written caption that came without them
    (:func:`hoibench.text.tokens.tokens`: spaCy when installed, else its rule-based fallback)."""
    from . import tokens as text_tokens
    return " ".join(text_tokens.tokens(caption))


def _clip_rng(seed: int, clip_id: str) -> random.Random:
    digest = hashlib.sha256(f"hoibench-annotate\0{int(seed)}\0{clip_id}".encode()).digest()
    return random.Random(int.from_bytes(digest[:8], "big"))


def _fmt_time(x: float) -> str:
    return repr(float(round(float(x), 3)))


def humanml3d_line(text: Mapping[str, Any]) -> str:
    """``caption#tokens#start#end`` (HumanML3D's texts/<id>.txt line)."""
    cap = str(text["caption"]).replace("#", " ").replace("\n", " ").strip()
    tok = str(text.get("tokens") or "").replace("#", " ").replace("\n", " ").strip()
    return f"{cap}#{tok}#{_fmt_time(text.get('start', 0.0))}#{_fmt_time(text.get('end', 0.0))}"


def parse_humanml3d_line(line: str) -> dict:
    """Inverse of :func:`humanml3d_line`: ``{caption, tokens, start, end}``; ValueError on a
    line without exactly four ``#`` fields."""
    fields = line.rstrip("\n").split("#")
    if len(fields) != 4:
        raise ValueError(f"HumanML3D text line: expected caption#tokens#start#end, got {line!r}")
    cap, tok, s, e = fields
    start, end = float(s) if s else 0.0, float(e) if e else 0.0
    return {"caption": cap, "tokens": tok, "start": 0.0 if np.isnan(start) else start,
            "end": 0.0 if np.isnan(end) else end}


# =========================================================================== one clip
@dataclass
class ClipAnnotation:
    clip: str
    object_name: str
    fps: float
    num_frames: int
    group_id: str
    texts: list                 # [{caption, tokens, start, end, source}]
    timeline: list              # [{part, start, end, start_s, end_s, transition}]
    actions: list               # [{action, name, source, start, end, parts, named, ...}]
    annotator_version: str
    spec_sha256: str
    seed: int
    contacts_source: str = "given"
    notes: list = field(default_factory=list)
    # human-only clips: {"object", "category", "scene", "action", "rule"} of the scene object
    # named as the contact partner (object_name is its key); absent for clips with an object
    scene_partner: dict | None = None

    def to_json(self) -> dict:
        d = asdict(self)
        if d["scene_partner"] is None:
            del d["scene_partner"]
        d["annotator"] = "hoibench.text.annotate"
        return d

    def humanml3d_lines(self) -> list[str]:
        return [humanml3d_line(t) for t in self.texts]

    @property
    def generated(self) -> list[dict]:
        return [t for t in self.texts if t["source"] == SOURCE]


def annotate_clip(clip_id: str, contacts: np.ndarray, fps: float, object_name: str,
                  actions: str | Sequence[ActionSpan | tuple] | None = None,
                  spec: AnnotatorSpec | None = None, seed: int = 0,
                  human_texts: Sequence[Mapping[str, Any]] = (), contacts_source: str = "given",
                  scene_partner: Mapping[str, Any] | None = None) -> ClipAnnotation:
    """Annotate one clip from its per-joint contact labels and action labels.

    Args:
        contacts: (T, 22) bool per-joint contact labels.
        actions: one action name for the whole clip ("lift", "putdown_2", ...), or
            :class:`ActionSpan` / ``(name, start_s, end_s[, source])`` items (any order:
            they are described in order of start time). None: the spec's default action.
        human_texts: texts kept before the generated ones (``caption`` or ``text``, optional
            ``tokens``, ``start``, ``end``, ``source`` -- default "human").
        scene_partner: for a human-only clip, ``{"object": key, ...}`` of the scene object
            (``scenes.yaml``; :func:`scene_partner`) it touches: ``object_name`` must be that
            key; with ``name_parts: action_kinds`` only parts of the action's ``kinds`` are
            named (the other contacts are with the rest of the scene).

    Returns the :class:`ClipAnnotation`: ``paraphrases`` different whole-clip texts (start =
    end = 0.0), plus for multi-action clips one text per action with its start/end seconds.
    """
    spec = spec or load_spec()
    contacts = np.asarray(contacts, dtype=bool)
    if contacts.ndim != 2 or contacts.shape[1] != sk.NUM_JOINTS:
        raise ValueError(f"{clip_id}: contacts: expected shape (T, 22), got {contacts.shape}")
    T, fps = int(contacts.shape[0]), float(fps)
    if T < 1 or not fps > 0:
        raise ValueError(f"{clip_id}: empty clip or bad fps {fps}")
    duration = T / fps
    segs = body_part_timeline(contacts, spec)
    acts = _normalise_actions(spec, actions, duration, fps)
    scene = scene_partner is not None
    if scene:
        if spec.scenes is None or object_name not in spec.scenes["objects"]:
            raise ValueError(f"{clip_id}: scene object {object_name!r} is not in the spec's scenes file")
    masks = [_candidate_masks(spec, a, segs, fps, T) for a in acts]
    if scene and spec.scenes["name_parts"] == "action_kinds":
        for a, m in zip(acts, masks):
            kinds = spec.actions[a.key]["kinds"]
            if kinds is not None:
                for p in [p for p in m if spec.parts[p]["kind"] not in kinds]:
                    del m[p]
    _resolve_concurrent(spec, acts, masks)
    for a, m in zip(acts, masks):
        _select_units(spec, a, m, fps)
    gid = group_id(spec, clip_id, object_name, acts, scene)
    rng = _clip_rng(seed, clip_id)
    gen = spec.generation
    notes = [f"unknown action name {a.name!r}: described as {a.key!r}" for a in acts if not a.known and a.name]
    if not scene and spec.object_entry(object_name).get("unknown"):
        notes.append(f"object {object_name!r} not in the objects lexicon: named by its name")

    texts: list[dict] = []
    for t in human_texts:
        cap = str(t.get("caption", t.get("text", ""))).strip()
        texts.append({"caption": cap, "tokens": str(t.get("tokens") or "") or _free_text_tokens(cap),
                      "start": float(t.get("start") or 0.0), "end": float(t.get("end") or 0.0),
                      "source": str(t.get("source") or "human")})
    seen_captions = {t["caption"] for t in texts}
    templates = _templates_for(spec, acts[0])
    order = list(range(len(templates)))
    rng.shuffle(order)
    n_want, made = int(gen["paraphrases"]), 0
    max_attempts = int(gen["max_attempts"])
    for k in range(n_want):
        for attempt in range(max_attempts):
            tpl = templates[order[(k + attempt // 10) % len(order)]][1]
            sent = _render(spec, rng, object_name, acts, tpl, scene)
            cap = sent.caption(gen["end"])
            if cap not in seen_captions:
                seen_captions.add(cap)
                texts.append({"caption": cap, "tokens": sent.token_string(), "start": 0.0, "end": 0.0,
                              "source": SOURCE})
                made += 1
                break
    if made < n_want:
        notes.append(f"only {made} different paraphrases of {n_want} (lexicon too small for this clip)")
    if gen.get("segment_texts", True) and len(acts) > 1:
        for a in acts:
            tid, tpl = rng.choice(_templates_for(spec, a))
            sent = _render(spec, rng, object_name, [a], tpl, scene)
            texts.append({"caption": sent.caption(gen["end"]), "tokens": sent.token_string(),
                          "start": round(a.start, 3), "end": round(a.end, 3), "source": SOURCE})
    timeline = [{"part": s.part, "start": s.start, "end": s.end, "start_s": round(s.start / fps, 4),
                 "end_s": round(s.end / fps, 4), "transition": s.transition} for s in segs]
    return ClipAnnotation(clip=clip_id, object_name=object_name, fps=fps, num_frames=T, group_id=gid,
                          texts=texts, timeline=timeline, actions=[a.to_dict(spec) for a in acts],
                          annotator_version=spec.version, spec_sha256=spec.sha256, seed=int(seed),
                          contacts_source=contacts_source, notes=notes,
                          scene_partner=dict(scene_partner) if scene else None)


# =========================================================================== action label files
def load_action_labels(path: str | Path) -> dict:
    """Read an action label file.

    * HOI-Diff's BEHAVE ``action_label.json`` (``label_description`` + ``action_label`` with
      per-second ``frame`` stamps 't0005.000'): ``{"scheme": "behave", "rate_s": 1.0,
      "clips": {name: [[time_s, description], ...]}}`` (absolute capture times);
    * the generic form ``{"clips": {clip_id: [{"action", "start", "end"}, ...]}}`` (seconds
      from the clip start): returned as ``{"scheme": "generic", "clips": ...}``.
    """
    data = json.loads(Path(path).read_text())
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
                with np.load(path, allow_pickle=False) as z:
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
                d = json.loads(s)
            except json.JSONDecodeError:
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
            prev = json.loads(prev_path.read_text())
            for t in prev.get("texts", []):
                if t.get("source") == SOURCE:
                    ours.add(humanml3d_line(t))
                else:
                    out.append(t)
        except (json.JSONDecodeError, AttributeError):
            pass
    tpath = root / TEXTS / f"{clip_id}.txt"
    if tpath.exists():
        for line in tpath.read_text(encoding="utf-8").splitlines():
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
        prov = json.loads(str(clip["provenance"])) if "provenance" in clip else {}
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
    index = {"annotator": "hoibench.text.annotate", "annotator_version": spec.version, "spec_name": spec.name,
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
