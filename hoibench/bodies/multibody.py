"""Multi-body clips: any number of humans, hands and rigid objects in one scene.

A :class:`MultiBodyClip` is a list of :class:`Body` (SyncDiff's setting, paper 004 section
3.1: articulated skeletons -- SMPL-family humans, MANO-style hands -- and rigid bodies). All
positions are metres in hoibench's world (y-up, right-handed, floor at y = 0 where there
is one), time in frames at ``fps``.

* ``kind="human"``: ``joints`` (T, 22, 3) in SMPL order (joint 0 the pelvis, 20/21 the
  wrists: the "hand roots" SyncDiff's CRR reads).
* ``kind="hand"``: ``joints`` (T, 21, 3): MANO's 16 joints (wrist, index1-3, middle1-3,
  pinky1-3, ring1-3, thumb1-3) then the 5 finger tips (thumb, index, middle, ring, pinky
  -- the order of ``smplx``'s MANO tip vertices); ``side`` is "left" or "right".
* ``kind="object"``: a rigid template (``template``: its name in the store's ``objects/``,
  vertices centred on their mean) posed by ``rot`` (T, 3, 3) and ``trans`` (T, 3):
  ``v = rot[t] @ vertex + trans[t]``.

Humans and hands may carry ``rot`` too (the root's / wrist's global orientation) when the
source has it; SyncDiff's representation does not need it (skeletons are joints).
``owner`` ties a hand to the human it belongs to (a hand of a whole-body capture).

Ground-truth contact is per pair of bodies: ``contacts[(a, b)]`` (T,) bool, ``a`` a human or
hand and ``b`` an object (or two objects), True in the frames they touch.

The single-body HOI clip (one human, one object, :class:`~hoibench.datasets.sequence.HOISequence`
and the clip files every store already holds) is the one-human-one-object case:
:func:`from_hoi_arrays` reads it as a multi-body clip, so every store is a multi-body store.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from ..core.ids import check_id

__all__ = ["KINDS", "HAND_JOINTS", "HUMAN_JOINTS", "LAYOUT", "Body", "MultiBodyClip", "check_clip",
           "from_hoi_arrays", "is_multibody_arrays", "clip_json_fields", "HAND_TIP_ORDER"]

KINDS = ("human", "hand", "object")
HUMAN_JOINTS = 22
HAND_JOINTS = 21
HAND_TIP_ORDER = ("thumb", "index", "middle", "ring", "pinky")
#: the value of a multi-body clip file's ``layout`` array.
LAYOUT = "multibody-1.0"


@dataclass
class Body:
    """One body of a scene (see the module docstring)."""

    name: str
    kind: str
    trans: np.ndarray                          # (T, 3)
    rot: np.ndarray | None = None              # (T, 3, 3)
    joints: np.ndarray | None = None           # (T, J, 3) humans and hands
    template: str | None = None                # objects
    side: str | None = None                    # hands: "left" / "right"
    owner: str | None = None                   # a hand's human

    @property
    def num_frames(self) -> int:
        return int(len(self.trans))

    @property
    def is_rigid(self) -> bool:
        return self.kind == "object"

    def root(self) -> np.ndarray:
        """(T, 3): the object's translation, the human's pelvis or the hand's wrist."""
        return self.trans if self.joints is None else self.joints[:, 0]


@dataclass
class MultiBodyClip:
    name: str
    dataset: str
    subject: str
    fps: float
    bodies: list[Body]
    templates: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)  # name -> (V,3), (F,3)
    contacts: dict[tuple[str, str], np.ndarray] = field(default_factory=dict)
    action: str | None = None
    texts: list[dict[str, Any]] = field(default_factory=list)
    group_id: str | None = None
    provenance: dict[str, Any] = field(default_factory=dict)

    @property
    def num_frames(self) -> int:
        return self.bodies[0].num_frames if self.bodies else 0

    def body(self, name: str) -> Body:
        for b in self.bodies:
            if b.name == name:
                return b
        raise KeyError(f"{self.name}: no body {name!r} (bodies: {', '.join(b.name for b in self.bodies)})")

    def of_kind(self, kind: str) -> list[Body]:
        return [b for b in self.bodies if b.kind == kind]

    def object_vertices(self, name: str, frames: slice | np.ndarray | None = None) -> np.ndarray:
        """Posed vertices (T, V, 3) of object body ``name``."""
        b = self.body(name)
        v, _ = self.templates[b.template]
        sel = slice(None) if frames is None else frames
        return np.einsum("tij,vj->tvi", b.rot[sel], np.asarray(v, np.float64)) + b.trans[sel, None]

    def signature(self) -> str:
        """Kinds and hand sides in body order, e.g. ``hand:left,hand:right,object,object``:
        two clips with one signature have one representation layout."""
        return ",".join(b.kind + (f":{b.side}" if b.side else "") for b in self.bodies)

    # -------------------------------------------------------------- files
    def to_arrays(self) -> dict[str, np.ndarray]:
        """The arrays of a multi-body clip file (``layout`` = :data:`LAYOUT`)."""
        check_clip(self)
        idx = {b.name: i for i, b in enumerate(self.bodies)}
        out: dict[str, np.ndarray] = {
            "layout": np.array(LAYOUT), "name": np.array(self.name), "dataset": np.array(self.dataset),
            "subject": np.array(self.subject), "fps": np.float64(self.fps),
            "body_names": np.array([b.name for b in self.bodies]),
            "body_kinds": np.array([b.kind for b in self.bodies]),
            "body_sides": np.array([b.side or "" for b in self.bodies]),
            "body_templates": np.array([b.template or "" for b in self.bodies]),
            "body_owners": np.array([b.owner or "" for b in self.bodies]),
            "action": np.array(self.action or ""),
        }
        for i, b in enumerate(self.bodies):
            out[f"body{i}_trans"] = np.asarray(b.trans, np.float32)
            if b.rot is not None:
                out[f"body{i}_rot"] = np.asarray(b.rot, np.float32)
            if b.joints is not None:
                out[f"body{i}_joints"] = np.asarray(b.joints, np.float32)
        pairs = sorted(self.contacts)
        out["contact_pairs"] = np.array([[idx[a], idx[b]] for a, b in pairs], dtype=np.int64).reshape(-1, 2)
        out["contact_frames"] = (np.stack([np.asarray(self.contacts[p], bool) for p in pairs]) if pairs
                                 else np.zeros((0, self.num_frames), bool))
        from ..core.io import strict_json_dumps
        if self.texts:
            out["texts"] = np.array([strict_json_dumps(t, sort_keys=True) for t in self.texts])
        out["provenance"] = np.array(strict_json_dumps(self.provenance, sort_keys=True))
        return out

    @classmethod
    def from_arrays(cls, z: dict, template_loader: Callable[[str], tuple[np.ndarray, np.ndarray]] | None = None
                    ) -> "MultiBodyClip":
        """Read a clip file's arrays (:meth:`to_arrays`, or a single-body HOI clip through
        :func:`from_hoi_arrays`); ``template_loader(name)`` gives object templates."""
        if not is_multibody_arrays(z):
            return from_hoi_arrays(z, template_loader)
        names = [str(x) for x in z["body_names"]]
        bodies = []
        for i, n in enumerate(names):
            side, owner, tmpl = (str(z[k][i]) for k in ("body_sides", "body_owners", "body_templates"))
            bodies.append(Body(n, str(z["body_kinds"][i]), np.asarray(z[f"body{i}_trans"], np.float64),
                               np.asarray(z[f"body{i}_rot"], np.float64) if f"body{i}_rot" in z else None,
                               np.asarray(z[f"body{i}_joints"], np.float64) if f"body{i}_joints" in z else None,
                               tmpl or None, side or None, owner or None))
        pairs = np.asarray(z["contact_pairs"]).reshape(-1, 2)
        if pairs.size and (pairs.dtype.kind not in "iu" or pairs.min() < 0 or pairs.max() >= len(names)):
            raise ValueError(f"{z['name']}: contact_pairs: body indices must be whole numbers in 0..{len(names) - 1}, "
                             f"got {pairs.min()}..{pairs.max()}")
        contacts = {(names[a], names[b]): np.asarray(f, bool) for (a, b), f in zip(pairs, z["contact_frames"])}
        templates = {}
        if template_loader is not None:
            for b in bodies:
                if b.template and b.template not in templates:
                    templates[b.template] = template_loader(b.template)
        texts, prov = clip_json_fields(z)
        return cls(str(z["name"]), str(z["dataset"]), str(z["subject"]), float(z["fps"]), bodies, templates,
                   contacts, str(z["action"]) or None, texts, None, prov)


def clip_json_fields(z) -> tuple[list, dict]:
    """The clip's ``texts`` and ``provenance`` JSON strings, parsed strictly (a deep or
    malformed string is a one-line error naming the clip and field)."""
    from ..core.io import load_json_bytes
    name = str(z["name"]) if "name" in z else "clip"
    texts = [load_json_bytes(str(t), f"{name}: texts") for t in z["texts"]] if "texts" in z else []
    prov = load_json_bytes(str(z["provenance"]), f"{name}: provenance") if "provenance" in z else {}
    return texts, prov


def is_multibody_arrays(z) -> bool:
    return "layout" in z and str(np.asarray(z["layout"])).startswith("multibody")


def from_hoi_arrays(z: dict, template_loader: Callable[[str], tuple[np.ndarray, np.ndarray]] | None = None
                    ) -> MultiBodyClip:
    """A single-body HOI clip file (one human, one object; a multi-part object gives one
    object body per part) read as a multi-body clip. The human-object contact frames are
    the frames where any joint is in contact (the clip's ``contacts``)."""
    joints = np.asarray(z["joints"], np.float64)
    human = Body("human", "human", joints[:, 0].copy(), None, joints)
    bodies, templates, contacts = [human], {}, {}
    if "obj_rot" in z and str(z.get("object_name", "")):
        if "object_parts" in z:
            parts = [(str(n), np.asarray(r, np.float64), np.asarray(t, np.float64))
                     for n, r, t in zip(z["object_parts"], z["parts_rot"], z["parts_trans"])]
        else:
            parts = [(str(z["object_name"]), np.asarray(z["obj_rot"], np.float64),
                      np.asarray(z["obj_trans"], np.float64))]
        for name, R, t in parts:
            bodies.append(Body(name, "object", t, R, None, name))
            if template_loader is not None:
                templates[name] = template_loader(name)
        if "contacts" in z:
            contacts[("human", parts[0][0])] = np.asarray(z["contacts"], bool).any(-1)
    texts, prov = clip_json_fields(z)
    return MultiBodyClip(str(z.get("name", "")), str(z.get("dataset", "")), str(z.get("subject", "")),
                         float(z.get("fps", 20.0)), bodies, templates, contacts, None, texts, None, prov)


def check_clip(clip: MultiBodyClip) -> None:
    """Refuse a multi-body clip that is not well formed: id-safe distinct body names, known
    kinds, per-frame arrays over one frame count, finite values, rotation matrices, hands
    with a side, objects with a known template, contact pairs naming its bodies. Errors name
    the clip, the body and the field."""
    from ..core.plausibility import (ImplausibleDataError, check_fps, check_positions, check_rotations, check_speed,
                                     real_array)
    where = check_id(clip.name, "clip name")
    fps = check_fps(clip.fps, "fps", where)
    if not clip.bodies:
        raise ImplausibleDataError(f"{where}: bodies: a clip needs at least one body")
    T = clip.bodies[0].num_frames
    seen = set()
    for b in clip.bodies:
        at = f"{where}: body {b.name!r}"
        check_id(b.name, "body name", where)
        if b.name.casefold() in seen:
            raise ImplausibleDataError(f"{at}: name used twice")
        seen.add(b.name.casefold())
        if b.kind not in KINDS:
            raise ImplausibleDataError(f"{at}: kind {b.kind!r}: expected one of {KINDS}")
        t = real_array(b.trans, "trans", at)
        if t.shape != (T, 3):
            raise ImplausibleDataError(f"{at}: trans: expected ({T}, 3), got {t.shape}")
        check_positions(t, "trans", at)
        check_speed(t, "trans", at, fps=fps)
        if b.rot is not None:
            R = check_rotations(b.rot, "rot", at)
            if len(R) != T:
                raise ImplausibleDataError(f"{at}: rot: {len(R)} frames, expected {T}")
        if b.kind == "object":
            if b.rot is None or not b.template:
                raise ImplausibleDataError(f"{at}: an object needs rot and template")
            check_id(b.template, "template name", at)
            if clip.templates and b.template not in clip.templates:
                raise ImplausibleDataError(f"{at}: template {b.template!r} not among the clip's templates")
        else:
            want = HUMAN_JOINTS if b.kind == "human" else HAND_JOINTS
            J = real_array(b.joints, "joints", at) if b.joints is not None else None
            if J is None or J.shape != (T, want, 3):
                raise ImplausibleDataError(f"{at}: joints: expected ({T}, {want}, 3), got "
                                           f"{None if J is None else J.shape}")
            check_positions(J, "joints", at)
        if b.kind == "hand" and b.side not in ("left", "right"):
            raise ImplausibleDataError(f"{at}: side: expected 'left' or 'right', got {b.side!r}")
    names = {b.name for b in clip.bodies}
    for (a, c), f in clip.contacts.items():
        if a not in names or c not in names:
            raise ImplausibleDataError(f"{where}: contacts ({a}, {c}): not bodies of the clip")
        if np.shape(f) != (T,):
            raise ImplausibleDataError(f"{where}: contacts ({a}, {c}): expected ({T},), got {np.shape(f)}")
