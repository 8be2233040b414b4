"""Physics metrics: is the generated object supported by the body and the floor, and does it
rest where it is left? Simulated in MuJoCo (the ``mujoco`` package: ``pip install
hoibench[physics]``) on the scenes of :mod:`hoibench.metrics.physics_scene`.

Per clip (:func:`physics_clip_values`, the catalogue's ``clip_fn`` of every entry below;
settings: the protocol's ``physics:`` mapping, :data:`DEFAULTS`):

``phys_support_err_m`` (m, lower)
    Windows of ``window_s`` (h) start every ``stride_s`` at a frame ``k0`` with the generated
    object pose and its finite-difference velocity; the object is simulated with the floor
    and the body (capsules following the joints, interpolated in time) as colliders; the
    window scores ``|c_sim(k0 + h) - c_gen(k0 + h)|``, c the object's centre of mass. Clip
    value: mean over windows (NaN when the clip is shorter than h). A carried or resting
    object scores ~0, one floating in mid-air ``0.5 g h^2`` (1.23 m at h = 0.5 s).
``phys_unsupported_ratio`` (fraction, lower)
    Windows whose error exceeds ``unsupported_m``.
``phys_settle_m`` (m, lower; HUMOTO's test)
    The object is released with zero velocity at the clip's last frame and at every frame
    without human-object contact (no capsule surface within ``contact_m`` of the object
    mesh), the body frozen in that frame's pose; the release scores the displacement of the
    centre after ``settle_frames`` frames at ``settle_fps``. Clip value: mean over releases.
``phys_balance_ratio`` (fraction, higher)
    Releases after which the object moved less than ``unsupported_m`` and turned less than
    ``balance_turn_deg`` (it was left in a stable rest, not on an edge).

Everything is single-threaded MuJoCo with fixed settings: reruns give identical numbers.
"""
from __future__ import annotations

import math
from typing import Any, Mapping, Sequence

import numpy as np

from .physics_scene import (BodyTrack, body_states, body_track, object_geometry, object_qpos, object_qvel,
                            rigid_states, scene_xml)

from .catalog import METRICS

#: the metrics this module computes: the catalogue's entries read from the ``physics:`` key
NAMES = tuple(n for n, i in METRICS.items() if i.settings_key == "physics")
#: the protocol's ``physics:`` keys and their defaults (docs/metrics.md, "Physics")
DEFAULTS: dict[str, Any] = {
    "window_s": 0.5,              # h: length of a support window
    "stride_s": 0.25,             # between window starts
    "density_kg_m3": 500.0,       # object mass = density * mesh volume
    "friction": 0.5,              # sliding friction of every geom (object-floor, object-body)
    "timestep_s": 0.002,          # MuJoCo's solver timestep
    "contact_timeconst_s": 0.02,  # MuJoCo solref: contact time constant
    "contact_dampratio": 1.0,     # MuJoCo solref: damping ratio
    "contact_m": 0.02,            # human-object contact: a capsule surface this near the mesh
    "unsupported_m": 0.05,        # a window (or release) moving more than this fails
    "settle_frames": 35,          # a release is simulated this many frames ...
    "settle_fps": 30.0,           # ... at this frame rate (HUMOTO: 35 frames at 30 fps)
    "balance_turn_deg": 10.0,     # a release turning more than this did not rest
}
_INT_KEYS = ("settle_frames",)
#: axis-point spacing (m) of the capsule-to-mesh contact test
_AXIS_SPACING_M = 0.02


def resolve_settings(settings: Mapping | None) -> dict:
    """:data:`DEFAULTS` updated with the protocol's ``physics:`` mapping."""
    return {**DEFAULTS, **dict(settings or {})}


def check_settings(mapping: Mapping, where: str) -> None:
    """Validate a protocol's ``physics:`` mapping: known keys, numbers, positive values
    (``friction`` >= 0), an integer ``settle_frames`` and a timestep at most a tenth of the
    window; ValueError naming ``where`` and the field."""
    unknown = sorted(set(mapping) - set(DEFAULTS))
    if unknown:
        raise ValueError(f"{where}: unknown field(s) {unknown}; known: {sorted(DEFAULTS)}")
    for key, v in mapping.items():
        if key in _INT_KEYS:
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"{where}: field {key!r} must be a positive integer, got {v!r}")
            continue
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise ValueError(f"{where}: field {key!r} must be a number, got {v!r}")
        if v < 0 or (v == 0 and key != "friction"):
            raise ValueError(f"{where}: field {key!r} must be {'>= 0' if key == 'friction' else 'positive'}, "
                             f"got {v!r}")
    s = resolve_settings(mapping)
    if s["timestep_s"] > s["window_s"] / 10:
        raise ValueError(f"{where}: field 'timestep_s' must be at most window_s / 10, got {s['timestep_s']!r}")


# ----------------------------------------------------------------- scenes
class ClipScene:
    """The MuJoCo models of one clip (object + floor + the capsules of ``track`` + the kinematic
    ``others``: ``(vertices, faces, R (T, 3, 3), t (T, 3))`` of a multi-body clip's other
    objects), built once: ``free`` (moving body, support windows) and ``mocap`` (frozen body,
    releases)."""

    def __init__(self, vertices, faces, track: BodyTrack, s: Mapping, others: Sequence[tuple] = ()):
        import mujoco
        self.mj = mujoco
        self.geom = object_geometry(vertices, faces)
        self.track = track
        self.others = [(np.asarray(R, np.float64), np.asarray(t, np.float64)) for _, _, R, t in others]
        self.kinematic = len(track.radii) + len(self.others)
        self.s = s
        self.models = {}
        other_geoms = [object_geometry(v, f) for v, f, _, _ in others]
        for kind in ("free", "mocap"):
            xml = scene_xml(self.geom, self.track.radii, self.track.lengths, density=float(s["density_kg_m3"]),
                            friction=float(s["friction"]), timestep=float(s["timestep_s"]),
                            solref=(float(s["contact_timeconst_s"]), float(s["contact_dampratio"])), kinematic=kind,
                            others=other_geoms)
            m = mujoco.MjModel.from_xml_string(xml)
            self.models[kind] = (m, mujoco.MjData(m))
        m = self.models["free"][0]
        self.obj = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "object")
        self.com_local = np.array(m.body_ipos[self.obj], np.float64)   # centre of mass, template frame
        self.dt = float(m.opt.timestep)

    def centres(self, R: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Object centres of mass (T, 3) of poses ``v = R v_template + t``."""
        return np.einsum("tij,j->ti", np.asarray(R, np.float64), self.com_local) + np.asarray(t, np.float64)

    def states(self, frames: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
        """``qpos`` (N, P, 7) and ``qvel`` (N, P, 6) of the P kinematic bodies (capsules, then the
        other objects) at fractional ``frames`` (:func:`body_states`, :func:`rigid_states`)."""
        q, v = body_states(self.track, frames, fps)
        if not self.others:
            return q, v
        rigid = [rigid_states(R, t, frames, fps) for R, t in self.others]
        return (np.concatenate([q] + [r[0][:, None] for r in rigid], 1),
                np.concatenate([v] + [r[1][:, None] for r in rigid], 1))

    def simulate(self, q0: np.ndarray, v0: np.ndarray, steps: int, body_q: np.ndarray | None = None,
                 body_v: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Free-body run: object from ``(q0, v0)``, the kinematic bodies set to ``body_q[i],
        body_v[i]`` (N, P, 7), (N, P, 6) (:meth:`states`) before step i (parked below the floor
        when None). Returns the object's final centre (3,) and quaternion (4,)."""
        m, d = self.models["free"]
        self.mj.mj_resetData(m, d)
        d.qpos[:7], d.qvel[:6] = q0, v0
        if body_q is None:
            d.qpos[7:] = np.tile([0.0, -100.0, 0.0, 1.0, 0.0, 0.0, 0.0], self.kinematic)
            self.mj.mj_step(m, d, nstep=steps)
        else:
            for i in range(steps):
                d.qpos[7:] = body_q[i].ravel()
                d.qvel[6:] = body_v[i].ravel()
                self.mj.mj_step(m, d)
        return np.array(d.xipos[self.obj]), np.array(d.xquat[self.obj])

    def release(self, q0: np.ndarray, frame: int, steps: int) -> tuple[np.ndarray, np.ndarray]:
        """Mocap run: object from rest at ``q0``, the kinematic bodies frozen in ``frame``'s pose."""
        m, d = self.models["mocap"]
        self.mj.mj_resetData(m, d)
        q, _ = self.states(np.array([float(frame)]), 1.0)
        d.mocap_pos[:], d.mocap_quat[:] = q[0, :, :3], q[0, :, 3:]
        d.qpos[:7] = q0
        self.mj.mj_step(m, d, nstep=steps)
        return np.array(d.xipos[self.obj]), np.array(d.xquat[self.obj])


# ----------------------------------------------------------------- metrics
def window_starts(T: int, fps: float, s: Mapping) -> list[int]:
    """Start frames of the support windows: every ``round(stride_s fps)`` frames while the
    window ``[k0, k0 + window_s fps]`` lies within the clip."""
    span = float(s["window_s"]) * fps
    step = max(1, int(round(float(s["stride_s"]) * fps)))
    return [k for k in range(0, T, step) if k + span <= T - 1 + 1e-9]


def support_errors(scene: ClipScene, R: np.ndarray, t: np.ndarray, fps: float) -> np.ndarray:
    """Per-window support errors (m), :func:`window_starts` order (see the module)."""
    s = scene.s
    h = float(s["window_s"])
    steps = max(1, int(round(h / scene.dt)))
    gen = scene.centres(R, t)
    qpos = object_qpos(R, t)
    out = []
    for k0 in window_starts(len(t), fps, s):
        frames = k0 + np.arange(steps) * scene.dt * fps
        bq, bv = scene.states(frames, fps)
        end, _ = scene.simulate(qpos[k0], object_qvel(R, t, k0, fps), steps, bq, bv)
        fe = k0 + h * fps
        k = min(int(math.floor(fe)), len(t) - 1)
        k1 = min(k + 1, len(t) - 1)
        want = gen[k] + (fe - k) * (gen[k1] - gen[k])
        out.append(float(np.linalg.norm(end - want)))
    return np.asarray(out)


def contact_frames(inp, contact_m: float = DEFAULTS["contact_m"]) -> np.ndarray:
    """(T,) bool: some body capsule's surface within ``contact_m`` of the object mesh
    (:func:`capsule_contact_frames` of the clip's human)."""
    return capsule_contact_frames([(inp.joints, "human")], inp.template_vertices, inp.template_faces,
                                  inp.obj_rot, inp.obj_trans, contact_m)


def capsule_contact_frames(skeletons: Sequence[tuple[np.ndarray, str]], vertices, faces, R, t,
                           contact_m: float = DEFAULTS["contact_m"]) -> np.ndarray:
    """(T,) bool: some capsule of the ``(joints (T, J, 3), kind)`` skeletons has its surface
    within ``contact_m`` of the object mesh posed by ``R, t`` (signed distance of axis points
    every <= 2 cm minus the radius; :class:`hoibench.bodies.capsules.ObjectField`)."""
    from ..bodies.capsules import ObjectField, segments
    if not skeletons:
        return np.zeros(len(t), bool)
    parts = [segments(np.asarray(j, np.float64), kind) for j, kind in skeletons]
    a, b = (np.concatenate([x[i] for x in parts], 1) for i in (0, 1))
    r = np.concatenate([x[2] for x in parts])
    longest = np.linalg.norm(b - a, axis=-1).max(0)
    seg, frac = [], []
    for i, length in enumerate(longest):
        n = int(math.ceil(float(length) / _AXIS_SPACING_M)) + 1
        seg += [i] * n
        frac += list(np.linspace(0.0, 1.0, n))
    seg, frac = np.asarray(seg), np.asarray(frac)[None, :, None]
    pts = a[:, seg] + frac * (b[:, seg] - a[:, seg])
    field = ObjectField(vertices, faces)
    d = field.signed(pts, R, t) - r[seg][None]
    return d.min(1) < contact_m


def settle_values(scene: ClipScene, touching: np.ndarray, R: np.ndarray, t: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Per release (the last frame and the frames where ``touching`` (T,) is False, in order):
    displacement (m) and turn (deg) after settling."""
    s = scene.s
    steps = max(1, int(round(int(s["settle_frames"]) / float(s["settle_fps"]) / scene.dt)))
    frames = sorted(set(np.flatnonzero(~touching).tolist()) | {len(t) - 1})
    gen = scene.centres(R, t)
    qpos = object_qpos(R, t)
    disp, turn = [], []
    for k in frames:
        end, quat = scene.release(qpos[k], k, steps)
        disp.append(float(np.linalg.norm(end - gen[k])))
        dot = min(1.0, abs(float(np.dot(quat, qpos[k, 3:]))))
        turn.append(math.degrees(2.0 * math.acos(dot)))
    return np.asarray(disp), np.asarray(turn)


def physics_clip_values(inp, settings: Mapping | None = None) -> dict[str, float]:
    """The four physics metrics of one clip (:class:`hoibench.metrics.physical.ClipInput`);
    NaN for a human-only clip (and the support metrics of a clip shorter than a window)."""
    nan = {n: float("nan") for n in NAMES}
    if inp.obj_rot is None or inp.obj_trans is None or inp.template_vertices is None:
        return nan
    s = resolve_settings(settings)
    R = np.asarray(inp.obj_rot, np.float64)
    t = np.asarray(inp.obj_trans, np.float64)
    scene = ClipScene(inp.template_vertices, inp.template_faces, body_track(inp.joints), s)
    err = support_errors(scene, R, t, float(inp.fps))
    disp, turn = settle_values(scene, contact_frames(inp, float(s["contact_m"])), R, t)
    return clip_values(err, disp, turn, s)


def clip_values(err: np.ndarray, disp: np.ndarray, turn: np.ndarray, s: Mapping) -> dict[str, float]:
    """The four metrics of a clip from its windows' support errors and its releases'
    displacements and turns (NaN where a clip has none)."""
    out = {n: float("nan") for n in NAMES}
    if len(err):
        out["phys_support_err_m"] = float(np.mean(err))
        out["phys_unsupported_ratio"] = float((np.asarray(err) > float(s["unsupported_m"])).mean())
    if len(disp):
        out["phys_settle_m"] = float(np.mean(disp))
        out["phys_balance_ratio"] = float(((np.asarray(disp) < float(s["unsupported_m"]))
                                           & (np.asarray(turn) < float(s["balance_turn_deg"]))).mean())
    return out


__all__ = ["NAMES", "DEFAULTS", "resolve_settings", "check_settings", "ClipScene", "window_starts", "support_errors",
           "contact_frames", "capsule_contact_frames", "settle_values", "clip_values", "physics_clip_values"]
