"""MuJoCo scenes of one clip for the physics metrics (:mod:`hoibench.metrics.physics`).

A scene (MJCF built as a string, y-up: gravity ``(0, -g, 0)``) holds

* the floor: a plane at y = 0 (its normal, MuJoCo's local z, turned onto +y);
* the object: one free rigid body whose collision geometry is the convex hull of its template
  mesh (MuJoCo collides meshes through their hulls), its mass ``density * volume`` (the
  template's volume when the mesh is watertight, else its hull's) and its inertia MuJoCo's
  for that hull at that mass. The body frame is the template frame, so the free joint's
  position and quaternion are the clip's ``obj_trans`` and ``obj_rot``
  (``v = R v_template + t``); the object centre is its centre of mass;
* the human: one capsule per bone of :func:`hoibench.bodies.capsules.segments` (``human``:
  pelvis-hips, spine, neck, head, collars, upper arms, forearms, 9 cm hands past the wrists,
  thighs, shins, feet; radii 3.3-10 cm), each a body whose pose follows the joints. Capsule
  lengths are the clip's median bone lengths. ``kinematic="free"``: heavy free bodies
  (1000 x the object's mass, gravity compensated) whose position *and velocity* are set
  before every step, so friction sees the true hand-object relative velocity (a mocap body
  has zero velocity for the solver); ``"mocap"``: a frozen body (settling). A multi-body
  clip's hands (``hand``: palm and finger bones, radii 9-12 mm) join the same list;
* other objects (multi-body clips): each a kinematic body (``other<j>``, its template's hull)
  that follows its generated pose like the capsules and collides with the free object only.

Contacts: object-floor, object-body and object-other only (body parts and other objects do
not touch each other or the floor); one sliding friction coefficient on every geom (MuJoCo takes the pair's maximum),
``condim`` 3, MuJoCo's soft contact ``solref = (timeconst, dampratio)`` and default
``solimp``.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Sequence

import numpy as np

from ..bodies.capsules import segments
from ..core.geometry import matrix_to_quaternion, quaternion_between, quaternion_to_matrix

#: the floor's quaternion: MuJoCo's plane normal (local z) turned onto +y (-90 deg about x)
FLOOR_QUAT = (np.sqrt(0.5), -np.sqrt(0.5), 0.0, 0.0)
#: mass of each kinematic body part, as a multiple of the object's mass
BODY_MASS_RATIO = 1000.0
#: hull volume / mesh volume above which the hull is said to close a handle or cavity
HULL_CLOSES_RATIO = 1.5
_Z = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class ObjectGeometry:
    """What the scene needs of a template: hull vertices/faces, mass volume (m^3), the mesh's
    own volume (None when not watertight), and ``hull_ratio`` = hull volume / mesh volume
    (> :data:`HULL_CLOSES_RATIO`: the hull fills a handle, seat gap or cavity)."""

    hull_vertices: np.ndarray
    hull_faces: np.ndarray
    volume_m3: float
    mesh_volume_m3: float | None
    hull_ratio: float

    @property
    def hull_closes_cavity(self) -> bool:
        return self.hull_ratio > HULL_CLOSES_RATIO


def object_geometry(vertices: np.ndarray, faces: np.ndarray) -> ObjectGeometry:
    """The template's convex hull and volume (cached per template)."""
    v = np.ascontiguousarray(vertices, np.float64)
    f = np.ascontiguousarray(faces, np.int64)
    return _object_geometry(v.tobytes(), f.tobytes(), v.shape, f.shape)


@lru_cache(maxsize=64)
def _object_geometry(vb: bytes, fb: bytes, vshape: tuple, fshape: tuple) -> ObjectGeometry:
    import trimesh
    v = np.frombuffer(vb, np.float64).reshape(vshape)
    f = np.frombuffer(fb, np.int64).reshape(fshape)
    mesh = trimesh.Trimesh(v, f, process=True)
    hull = mesh.convex_hull
    hv = float(abs(hull.volume))
    mv = float(abs(mesh.volume)) if mesh.is_watertight else None
    if not hv > 0:
        raise ValueError(f"object template: its convex hull has no volume ({len(v)} vertices)")
    vol = mv if mv and mv > 0 else hv
    return ObjectGeometry(np.asarray(hull.vertices, np.float64), np.asarray(hull.faces, np.int64), vol, mv,
                          hv / vol)


def _floats(a) -> str:
    return " ".join(f"{x:.9g}" for x in np.asarray(a, np.float64).ravel())


def _mesh_asset(name: str, geom: ObjectGeometry) -> str:
    return f'<mesh name="{name}" vertex="{_floats(geom.hull_vertices)}" face="{" ".join(map(str, geom.hull_faces.ravel()))}"/>'


def scene_xml(geom: ObjectGeometry, radii: np.ndarray, lengths: np.ndarray, *, density: float, friction: float,
              timestep: float, solref: tuple[float, float], kinematic: str = "free",
              others: Sequence[ObjectGeometry] = ()) -> str:
    """The MJCF of a scene (see the module): object body ``object`` first, then one body per
    capsule ``part<i>``, then one per other object ``other<j>`` (``kinematic``: ``free`` or
    ``mocap``); every kinematic body weighs :data:`BODY_MASS_RATIO` x the object."""
    mass = density * geom.volume_m3
    common = f'friction="{friction:.9g} 0.005 0.0001" condim="3" solref="{solref[0]:.9g} {solref[1]:.9g}"'
    heavy = f'contype="2" conaffinity="0" mass="{BODY_MASS_RATIO * mass:.9g}" {common}'
    shapes = [(f"part{i}", f'<geom type="capsule" size="{float(r):.9g} {max(float(length) / 2.0, 1e-4):.9g}" {heavy}/>')
              for i, (r, length) in enumerate(zip(radii, lengths))]
    shapes += [(f"other{j}", f'<geom type="mesh" mesh="other{j}" {heavy}/>') for j in range(len(others))]
    if kinematic == "mocap":
        parts = [f'<body name="{name}" mocap="true">{g}</body>' for name, g in shapes]
    else:
        parts = [f'<body name="{name}" gravcomp="1"><freejoint/>{g}</body>' for name, g in shapes]
    assets = [_mesh_asset("object", geom)] + [_mesh_asset(f"other{j}", g) for j, g in enumerate(others)]
    return f"""<mujoco model="hoibench-physics">
  <option timestep="{timestep:.9g}" gravity="0 -9.81 0"/>
  <asset>{' '.join(assets)}</asset>
  <worldbody>
    <geom name="floor" type="plane" size="0 0 1" quat="{_floats(FLOOR_QUAT)}" contype="1" conaffinity="1" {common}/>
    <body name="object"><freejoint/>
      <geom name="object" type="mesh" mesh="object" mass="{mass:.9g}" contype="1" conaffinity="3" {common}/>
    </body>
    {' '.join(parts)}
  </worldbody>
</mujoco>"""


# ----------------------------------------------------------------- body kinematics
@dataclass(frozen=True)
class BodyTrack:
    """The capsules of a clip's frames: centres (T, S, 3), unit axes (T, S, 3), radii (S,),
    lengths (S,) (median over frames)."""

    centres: np.ndarray
    axes: np.ndarray
    radii: np.ndarray
    lengths: np.ndarray


def body_track(joints: np.ndarray, kind: str = "human") -> BodyTrack:
    """Capsules of :func:`hoibench.bodies.capsules.segments` (``human`` or ``hand``) per frame."""
    a, b, r = segments(np.asarray(joints, np.float64), kind)
    d = b - a
    n = np.linalg.norm(d, axis=-1, keepdims=True)
    axes = np.where(n > 1e-9, d / np.maximum(n, 1e-12), _Z)
    return BodyTrack(0.5 * (a + b), axes, np.asarray(r, np.float64), np.median(n[..., 0], axis=0))


def joined_tracks(tracks: Sequence[BodyTrack], frames: int) -> BodyTrack:
    """The capsules of several skeletons of one clip as one track (``frames`` frames; no
    skeleton: zero capsules)."""
    if not tracks:
        return BodyTrack(np.zeros((frames, 0, 3)), np.zeros((frames, 0, 3)), np.zeros(0), np.zeros(0))
    return BodyTrack(*(np.concatenate([getattr(t, f) for t in tracks], axis)
                       for f, axis in (("centres", 1), ("axes", 1), ("radii", 0), ("lengths", 0))))


def body_states(track: BodyTrack, frames: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Free-joint ``qpos`` (N, S, 7) and ``qvel`` (N, S, 6) of the capsules at fractional
    ``frames`` (N,): centres linearly interpolated, axes normalised-lerped; velocities those
    of the linear interpolation (``(c[k+1] - c[k]) fps``; angular ``u x du/dt``, no spin about
    the axis), angular part in the capsule's frame as MuJoCo's free joint wants it."""
    T = len(track.centres)
    f = np.clip(np.asarray(frames, np.float64), 0.0, T - 1)
    k = np.minimum(np.floor(f).astype(int), max(T - 2, 0))
    k1 = np.minimum(k + 1, T - 1)
    w = (f - k)[:, None, None]
    c0, c1 = track.centres[k], track.centres[k1]
    u0, u1 = track.axes[k], track.axes[k1]
    pos = c0 + w * (c1 - c0)
    u = u0 + w * (u1 - u0)
    u /= np.maximum(np.linalg.norm(u, axis=-1, keepdims=True), 1e-12)
    quat = quaternion_between(np.broadcast_to(_Z, u.shape), u)
    moving = (k1 > k)[:, None, None] * fps
    vel = (c1 - c0) * moving
    omega = np.cross(u, (u1 - u0) * moving)
    local = np.einsum("nsji,nsj->nsi", quaternion_to_matrix(quat), omega)
    return np.concatenate([pos, quat], -1), np.concatenate([vel, local], -1)


def rigid_states(R: np.ndarray, t: np.ndarray, frames: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Free-joint ``qpos`` (N, 7) and ``qvel`` (N, 6) of a rigid trajectory (poses ``v = R v + t``)
    at fractional ``frames`` (N,): origin linearly interpolated, rotation along the geodesic
    ``R_k exp(w log(R_k^T R_k+1))``; velocities those of that interpolation (linear: world;
    angular: ``log(R_k^T R_k+1) fps``, body frame)."""
    from ..core.geometry import axis_angle_to_matrix, matrix_to_axis_angle
    R = np.asarray(R, np.float64)
    t = np.asarray(t, np.float64)
    T = len(t)
    f = np.clip(np.asarray(frames, np.float64), 0.0, T - 1)
    k = np.minimum(np.floor(f).astype(int), max(T - 2, 0))
    k1 = np.minimum(k + 1, T - 1)
    w = (f - k)[:, None]
    step = matrix_to_axis_angle(np.einsum("nji,njk->nik", R[k], R[k1]))       # log(R_k^T R_k1), body frame
    rot = np.einsum("nij,njk->nik", R[k], axis_angle_to_matrix(w * step))
    moving = (k1 > k)[:, None] * fps
    pos = t[k] + w * (t[k1] - t[k])
    return (np.concatenate([pos, matrix_to_quaternion(rot)], -1),
            np.concatenate([(t[k1] - t[k]) * moving, step * moving], -1))


def object_qpos(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Free-joint ``qpos`` (..., 7) of poses ``v = R v_template + t``."""
    return np.concatenate([np.asarray(t, np.float64), matrix_to_quaternion(np.asarray(R, np.float64))], -1)


def object_qvel(R: np.ndarray, t: np.ndarray, k: int, fps: float) -> np.ndarray:
    """Free-joint ``qvel`` (6,) at frame ``k`` by finite differences of the trajectory
    (central where both neighbours exist, else one-sided): linear velocity of the body
    origin (world), angular velocity ``log(R_a^T R_b) / dt`` (body frame)."""
    T = len(t)
    a, b = max(k - 1, 0), min(k + 1, T - 1)
    if b == a:
        return np.zeros(6)
    dt = (b - a) / fps
    from ..core.geometry import matrix_to_axis_angle
    omega = matrix_to_axis_angle(np.asarray(R[a], np.float64).T @ np.asarray(R[b], np.float64)) / dt
    return np.concatenate([(np.asarray(t[b], np.float64) - t[a]) / dt, omega])


__all__ = ["ObjectGeometry", "object_geometry", "scene_xml", "BodyTrack", "body_track", "joined_tracks",
           "body_states", "rigid_states",
           "object_qpos", "object_qvel", "FLOOR_QUAT", "BODY_MASS_RATIO", "HULL_CLOSES_RATIO"]
