"""One clip's captions: sentences rendered from its described actions, and its annotation.

Sentences fill the spec's templates with the drawn verb, relation, object noun phrase and
body-part phrases (every token tagged with its lemma and universal POS, written in
HumanML3D's ``word/POS`` form); :func:`annotate_clip` assembles a clip's texts (human texts
first, then the generated paraphrases and per-action texts), timeline, actions and group
into a :class:`ClipAnnotation`. Paraphrase choices are drawn from a ``random.Random``
seeded by sha256 of (seed, clip id).
"""
from __future__ import annotations

import hashlib
import random
from dataclasses import asdict, dataclass, field
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

from ..core import skeleton as sk
from .spec import AnnotatorSpec, Phrase, Token, load_spec
from .timeline import (ActionSpan, _Action, _candidate_masks, _normalise_actions, _resolve_concurrent,
                       _select_units, _unit_entry, body_part_timeline, group_id)

SOURCE = "annotator"            # `source` of generated texts; human texts keep theirs
#: the annotator's name as annotation files record it (a stable id, not a module path: it
#: enters the texts' hashes, so it did not change when the module moved to hoibench.text)
ANNOTATOR_ID = "hoibench.annotate"


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
        d["annotator"] = ANNOTATOR_ID
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

