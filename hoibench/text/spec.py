"""The annotator spec: loading and validating the versioned spec folder (``annotators/``).

``spec.yaml`` names the lexicon files (body parts, actions, relations, objects, optionally
scenes) and holds the sentence templates, joiners, person words and the grouping rule;
:func:`load_spec` reads them all into one :class:`AnnotatorSpec`, checking every entry and
naming the file and entry of any error (:class:`SpecError`). The phrases of the spec are
written as ``word/POS`` tokens and ``{slot}`` placeholders (:func:`parse_phrase`).
"""
from __future__ import annotations

import hashlib
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Sequence

from ..core import skeleton as sk
from ..core.io import read_text_file, sha256_regular_file

SPEC_ENV = "HOIBENCH_ANNOTATORS_DIR"
SPEC_FILE = "spec.yaml"

UPOS = frozenset("ADJ ADP ADV AUX CCONJ DET INTJ NOUN NUM PART PRON PROPN PUNCT SCONJ SYM VERB X".split())
_PUNCT = frozenset(",.;:!?")
_OBJECT_SLOTS = frozenset({"obj", "np", "it"})
_SENTENCE_SLOTS = frozenset({"person", "verb", "verb_ing", "relation", "relation_ing", "method", "parts"})
_CONTACT_SLOTS = frozenset({"relation", "relation_ing", "method", "parts"})


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
        return yaml.safe_load(read_text_file(path, what="annotator spec"))  # read-ok: text read by read_text_file
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
        sha256_regular_file(root / name, h, "annotator spec")
    return h.hexdigest()


def _read_spec_files(root: Path) -> tuple[dict, str, dict]:
    """``spec.yaml`` and the files it names: ``(top, version, {key: (file name, parsed)})``."""
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
    return top, version, docs


def _load_generation(top: dict, w: str) -> dict:
    """``generation`` of spec.yaml over its defaults."""
    gen = {"paraphrases": 3, "segment_texts": True, "min_frames": 5, "min_part_overlap_s": 0.25,
           "max_parts": 3, "max_actions": 4, "max_attempts": 200, "end": "."}
    gen.update(top.get("generation") or {})
    if int(gen["paraphrases"]) < 1:
        raise SpecError(f"{w}.generation.paraphrases: expected >= 1")
    return gen


def _load_templates(top: dict, w: str) -> tuple[dict, dict]:
    """Sentence templates and clauses of spec.yaml: ``(templates, clause)``."""
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
    return templates, clause


def _load_joiners(top: dict, w: str) -> dict:
    """``joiners`` of spec.yaml: kind -> [(Phrase, form)]."""
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
    return joiners


def _load_grouping(top: dict, w: str) -> dict:
    """``grouping`` of spec.yaml over its defaults."""
    grouping = {"object": "category", "format": "{object}/{actions}/{parts}", "joiner": "+",
                "no_contact": "nocontact/{clip}"}
    grouping.update(top.get("grouping") or {})
    if grouping["object"] not in ("category", "name"):
        raise SpecError(f"{w}.grouping.object: expected 'category' or 'name'")
    return grouping


def _load_parts(doc: tuple) -> tuple[dict, dict, float]:
    """The body-parts file: ``(parts, combinations, min_overlap)``."""
    bname, bdoc = doc
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
    return parts, combos, min_overlap


def _rel_list(items, where: str, relations: dict, rname: str) -> list:
    """A non-empty list of keys of ``relations`` (of the relations file ``rname``)."""
    if not isinstance(items, list) or not items or any(r not in relations for r in items):
        raise SpecError(f"{where}: expected a non-empty list of keys of {rname} relations, got {items!r}")
    return list(items)


def _load_relations(doc: tuple) -> tuple[dict, dict, list]:
    """The relations file: ``(relations, by_kind, default)``."""
    rname, rdoc = doc
    relations = {k: _verb_pair(v, f"{rname}.relations.{k}")
                 for k, v in _need(rdoc, "relations", rname, dict).items()}
    by_kind = {k: _rel_list(v, f"{rname}.by_kind.{k}", relations, rname)
               for k, v in (rdoc.get("by_kind") or {}).items()}
    rel_default = _rel_list(rdoc.get("default", ["touch"]), f"{rname}.default", relations, rname)
    return relations, by_kind, rel_default


def _kinds(items, where: str, known_kinds: set, bname: str):
    """None, or a non-empty list of body-part kinds of the body-parts file ``bname``."""
    if items is None:
        return None
    if not isinstance(items, list) or not items or set(items) - known_kinds:
        raise SpecError(f"{where}: expected a list of body-part kinds of {bname} "
                        f"({', '.join(sorted(known_kinds))}), got {items!r}")
    return list(items)


def _load_actions(doc: tuple, bname: str, parts: dict, templates: dict, relations: dict,
                  rname: str) -> tuple[dict, str, dict, dict]:
    """The actions file: ``(actions, default_action, aliases, labels)``."""
    aname, adoc = doc
    known_kinds = {v["kind"] for v in parts.values()}
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
            "relations": _rel_list(e["relations"], f"{where}.relations", relations, rname)
            if e.get("relations") else None,
            "exclude": excl, "min_contact_frames": mcf, "contact": bool(e.get("contact", True)),
            "kinds": _kinds(e.get("kinds"), f"{where}.kinds", known_kinds, bname)}
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
    return actions, default_action, aliases, labels


def _load_objects(doc: tuple) -> dict:
    """The objects file: name -> {"category", "nouns"}."""
    oname, odoc = doc
    objects = {}
    for key, e in _need(odoc, "objects", oname, dict).items():
        where = f"{oname}.objects.{key}"
        objects[str(key)] = {"category": str(_need(e, "category", where)),
                             "nouns": _phrases(_need(e, "nouns", where), f"{where}.nouns")}
    return objects


def load_spec(spec_dir: str | Path | None = None) -> AnnotatorSpec:
    """Read and validate the spec folder (``spec.yaml`` and the files it names)."""
    root = Path(spec_dir) if spec_dir is not None else default_spec_dir()
    top, version, docs = _read_spec_files(root)
    w = SPEC_FILE
    gen = _load_generation(top, w)
    templates, clause = _load_templates(top, w)
    joiners = _load_joiners(top, w)
    grouping = _load_grouping(top, w)
    parts, combos, min_overlap = _load_parts(docs["body_parts"])
    relations, by_kind, rel_default = _load_relations(docs["relations"])
    actions, default_action, aliases, labels = _load_actions(
        docs["actions"], docs["body_parts"][0], parts, templates, relations, docs["relations"][0])
    objects = _load_objects(docs["objects"])

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

