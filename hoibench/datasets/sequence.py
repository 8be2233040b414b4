"""``HOISequence``: the canonical in-memory clip every loader produces.

Conventions (docs/representations.md, docs/datasets.md): metres, seconds, y-up right-handed world with the floor at
y = 0, SMPL joint order. Object vertices are ``v = R v_template + t`` with the template
centred on its vertex mean.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass
class BodyParams:
    """Parameters that rebuild the body mesh with ``model_type`` files (y-up world).

    ``poses`` (T, P) axis-angle (SMPL-H: root 3 + body 63 + hands 90; SMPL-X: root 3 +
    body 63 + jaw/eyes 9 + hands 90), ``betas`` (B,) or (T, B), ``trans`` (T, 3) as SMPL's
    ``transl`` (the posed pelvis is rest pelvis + trans).

    ``flat_hand_mean`` is the hand convention the poses are in: True, zero hand pose is the
    flat hand (BEHAVE, OMOMO); False, the model's mean hand is added to the stored pose
    (RICH, whose toolkit builds SMPL-X with ``flat_hand_mean=False``). ``expression`` (T, E)
    holds SMPL-X expression coefficients when the source had them (RICH), else None (zero
    expression). Both are stored with the clip and read by
    :func:`hoibench.bodies.clip_body_forward`, so the stored parameters rebuild the mesh
    the source drew.
    """

    model_type: str
    gender: str
    betas: np.ndarray
    poses: np.ndarray
    trans: np.ndarray
    flat_hand_mean: bool = True
    expression: np.ndarray | None = None


@dataclass
class ObjectPart:
    """One rigid part of an object with several parts (OMOMO's vacuum and mop: a top and a
    bottom): template ``vertices`` (V, 3) centred on their mean, ``faces`` (F, 3) and the
    part's own pose, ``v = rot[t] @ vertex + trans[t]`` (y-up metres)."""

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    rot: np.ndarray                            # (T, 3, 3)
    trans: np.ndarray                          # (T, 3)

    def vertices_at(self, frames: slice | np.ndarray | None = None) -> np.ndarray:
        sel = slice(None) if frames is None else frames
        return np.einsum("tij,vj->tvi", self.rot[sel], self.vertices) + self.trans[sel, None]


@dataclass
class HOISequence:
    name: str
    dataset: str
    subject: str
    fps: float
    joints: np.ndarray                       # (T, 22, 3) float32
    object_name: str | None = None
    object_vertices: np.ndarray | None = None  # (V, 3) template, centred
    object_faces: np.ndarray | None = None     # (F, 3)
    obj_rot: np.ndarray | None = None          # (T, 3, 3)
    obj_trans: np.ndarray | None = None        # (T, 3)
    body: BodyParams | None = None
    contacts: np.ndarray | None = None         # (T, 22) bool
    texts: list[dict[str, Any]] = field(default_factory=list)  # {"text", "start", "end", "source"}
    group_id: str | None = None
    provenance: dict[str, Any] = field(default_factory=dict)
    #: every part of a multi-part object, the first being the primary part that
    #: ``object_name`` / ``object_vertices`` / ``obj_rot`` / ``obj_trans`` describe (the one
    #: the representations and metrics use); empty for a one-part object.
    parts: list[ObjectPart] = field(default_factory=list)
    #: further per-clip arrays a source provides, written into the clip file as they are
    #: (InterAct: ``markers`` (T, 77, 3), ``object_sample_points`` (P, 3) in the template frame)
    extra_arrays: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def num_frames(self) -> int:
        return int(self.joints.shape[0])

    def object_vertices_at(self, frames: slice | np.ndarray | None = None) -> np.ndarray:
        """Posed object vertices (T, V, 3): ``R v + t``."""
        if self.object_vertices is None:
            raise ValueError(f"{self.name}: no object")
        sel = slice(None) if frames is None else frames
        return np.einsum("tij,vj->tvi", self.obj_rot[sel], self.object_vertices) + self.obj_trans[sel, None]
