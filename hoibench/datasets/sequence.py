"""``HOISequence``: the canonical in-memory clip every loader produces.

Conventions (DESIGN section 3): metres, seconds, y-up right-handed world with the floor at
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

    ``poses`` (T, P) axis-angle (SMPL-H: root 3 + body 63 + hands 90), ``betas`` (B,) or
    (T, B), ``trans`` (T, 3) as SMPL's ``transl`` (the posed pelvis is rest pelvis + trans).
    """

    model_type: str
    gender: str
    betas: np.ndarray
    poses: np.ndarray
    trans: np.ndarray
    flat_hand_mean: bool = True


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

    @property
    def num_frames(self) -> int:
        return int(self.joints.shape[0])

    def object_vertices_at(self, frames: slice | np.ndarray | None = None) -> np.ndarray:
        """Posed object vertices (T, V, 3): ``R v + t``."""
        if self.object_vertices is None:
            raise ValueError(f"{self.name}: no object")
        sel = slice(None) if frames is None else frames
        return np.einsum("tij,vj->tvi", self.obj_rot[sel], self.object_vertices) + self.obj_trans[sel, None]
