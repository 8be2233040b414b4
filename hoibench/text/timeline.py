"""Turning a clip's contact timeline and action labels into the described actions.

Action names (clip names, RICH sequence names, label descriptions) resolve to action keys
of the spec (:func:`resolve_action`); human-only clips get the scene object their action is
done on (:func:`scene_partner`). Per-joint contact labels become segments per body part
(:func:`body_part_timeline`), and each action gets the body parts (and the units that name
them, e.g. "both hands") whose contacts overlap it; :func:`group_id` names the clip's
semantic group from the result.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from ..bodies.contact import ContactSegment, contact_timeline
from .spec import AnnotatorSpec

_REPEAT_SUFFIX = re.compile(r"_\d+$")
_BEHAVE_NAME = re.compile(r"^(Date\d+)_(Sub\d+)_([A-Za-z0-9]+)(?:_(.*))?$")
#: a RICH clip id: ``<Scene>_<sub>[_<sub2>]_<action><take>_<sub>_<first frame:05d>``
_RICH_CLIP = re.compile(r"^(.+)_\d+_\d{5}$")
_TAKE = re.compile(r"\d+$")


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

