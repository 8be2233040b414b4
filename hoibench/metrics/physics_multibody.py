"""The physics tier of a multi-body clip (:class:`hoibench.bodies.multibody.MultiBodyClip`):
the four metrics of :mod:`hoibench.metrics.physics` with every object of the scene simulated
in turn.

For each object ``o`` one scene (:class:`hoibench.metrics.physics.ClipScene`) holds ``o`` as
the free body, the floor, the capsules of every skeleton (humans: the proxy body's bones;
hands: the palm and finger bones of :func:`hoibench.bodies.capsules.bones`) and every other
object (its template's hull) as kinematic colliders following their generated motion. Support
windows and releases are those of the single-body tier; a release frame is one where no
skeleton's capsule surface is within ``contact_m`` of ``o`` (another object touching ``o``
does not hold it: a tool resting on a plate is released and stays). A clip's values pool
the windows and releases of all its objects (each window and each release counts once);
a clip without objects has NaN ("not applicable").
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from ..bodies.multibody import MultiBodyClip
from .physics import (NAMES, ClipScene, capsule_contact_frames, clip_values, resolve_settings, settle_values,
                      support_errors)
from .physics_scene import body_track, joined_tracks

__all__ = ["multibody_physics_values", "object_values"]


def object_values(clip: MultiBodyClip, index: int, settings: Mapping | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Object ``clip.bodies[index]``'s support errors per window (m) and its releases'
    displacements (m) and turns (deg), the rest of the scene kinematic (see the module)."""
    s = resolve_settings(settings)
    obj = clip.bodies[index]
    if not obj.is_rigid:
        raise ValueError(f"{clip.name}: body {obj.name!r} is a {obj.kind}, not an object")
    skeletons = [(b.joints, b.kind) for b in clip.bodies if b.kind in ("human", "hand")]
    track = joined_tracks([body_track(j, kind) for j, kind in skeletons], clip.num_frames)
    others = [(*clip.templates[b.template], b.rot, b.trans)
              for i, b in enumerate(clip.bodies) if b.is_rigid and i != index]
    v, f = clip.templates[obj.template]
    scene = ClipScene(v, f, track, s, others)
    err = support_errors(scene, obj.rot, obj.trans, float(clip.fps))
    touching = capsule_contact_frames(skeletons, v, f, obj.rot, obj.trans, float(s["contact_m"]))
    disp, turn = settle_values(scene, touching, obj.rot, obj.trans)
    return err, disp, turn


def multibody_physics_values(clip: MultiBodyClip, settings: Mapping | None = None) -> dict[str, float]:
    """The four physics metrics of a multi-body clip: windows and releases of every object
    pooled (module docstring); NaN without objects."""
    s = resolve_settings(settings)
    rigid = [i for i, b in enumerate(clip.bodies) if b.is_rigid]
    if not rigid:
        return {n: float("nan") for n in NAMES}
    parts = [object_values(clip, i, s) for i in rigid]
    err, disp, turn = (np.concatenate([p[k] for p in parts]) for k in range(3))
    return clip_values(err, disp, turn, s)
