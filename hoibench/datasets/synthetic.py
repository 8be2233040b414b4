"""``synthetic``: a deterministic procedural HOI dataset in the BEHAVE raw layout.

hoibench's embedded default data (DESIGN section 4): clips of a person lifting, carrying,
putting down, pushing, pulling, sitting on, kicking and holding primitive-built objects,
written exactly like BEHAVE's release so that ``hoibench prepare behave`` runs end to end on
it, with the ground truth beside every sequence so that metrics can be checked against
known contacts, known foot skating and known penetration.

Motion model (y-up world, metres, seconds, floor at y = 0, 30 fps)
------------------------------------------------------------------
A clip is planned as per-frame targets -- pelvis position, heading ``psi``, spine bend
``beta``, foot-joint targets and hand targets -- and turned into SMPL joint rotations:

* torso: root ``R_0 = R_y(psi) R_x(0.5 beta)``, spine1/2/3 ``R_x(0.15 beta)`` each, neck and
  head ``R_x(-0.15 beta)`` (looking forward while bending);
* reaching: a per-frame "crouch" ``c`` in [0, 1] -- pelvis drop ``0.52 s c`` (``s`` = body
  scale), back-shift ``0.10 s c``, extra bend ``95 deg * c`` -- the smallest value that puts
  every hand target within 96 % of the arm length while the torso and head joints stay
  3 cm outside the object, smoothed without ever dropping below that requirement;
* legs and arms: analytic two-bone IK (hip-knee-ankle, shoulder-elbow-wrist): with bone
  lengths ``l1, l2`` and root-target distance ``d``, the middle joint is
  ``K = A + l1 (cos(a) u + sin(a) w)``, ``cos(a) = (l1^2 + d^2 - l2^2) / (2 l1 d)``, ``u`` the
  unit root->target direction and ``w`` the pole direction made perpendicular to ``u``;
  each bone's global rotation maps its rest direction and rest hinge axis onto the posed
  ones, so the end joint lands on the target to rounding whenever ``d < l1 + l2``;
* ankles keep the foot flat: ``G_ankle = R_y(foot yaw)``, so the foot joint lies exactly on
  its target and the proxy body's sole on the floor;
* joints = :func:`hoibench.core.skeleton.forward_kinematics` (rotations, rest joints of the
  subject, trans) -- the ground truth is always recomputed from the rotations.

The rest joints are the proxy body's, ``SMPL_REST_JOINTS * (1 + 0.05 beta_0)``
(:func:`hoibench.bodies.proxy.proxy_rest_joints`). A planted foot joint sits at the height
that puts the proxy's sole at y = 0 (about 2.6 cm).

Guarantees (measured per clip into ``stats``; see tests/test_synthetic.py):

* a foot labelled planted does not move (drift ~1e-15 m) -- the pelvis height is softly
  clamped so that the legs never need more than 98.5 % of their length;
* a hand labelled in contact has its wrist joint on the object surface (analytic signed
  distance ~1e-15 m; the written mesh is within a tessellation sagitta, < 1 mm, of it),
  at a fixed object-local point (so a carried object moves rigidly with the hands);
* the object never goes below the floor (objects rest on it with their lowest vertex at
  y = 0, are lifted upwards, slide or roll along it);
* no joint is inside the object by more than ``JOINT_PENETRATION_TOL_M`` (measured: ~1e-15 m,
  the contacting joints on the surface). Sitting puts the hip joints ``SEAT_CLEARANCE_M * s``
  above the seat (the proxy's hip radius, so its body surface rests on the seat; the pelvis
  joint is ~0.18 m above it). Wrists and the kicking foot joint are *on* the surface, so
  the proxy's palm/forearm and toe capsules (2-4 cm radius) overlap the object there:
  body-surface penetration of clean clips is small but not zero near contacts.

Actions (``ACTIONS``): lift, carry, putdown, push, pull, sit, kick, hold, each with the hands
that make sense for the object (``CATALOGUE``): ``both``, ``left``, ``right`` or ``none``.
Contact labels (T, 22): wrists 20/21 while a hand grasps; hips 1/2 while seated; the kicking
foot joint 10/11 while it touches the ball.

Injected defects (:class:`Defect`) for metric tests, recorded with their frames and
measured magnitude in the ground truth:

* ``foot_skating`` (m/s): during the foot's longest planted run (at most 1.5 s), the
  planted-labelled foot joint moves ``speed / fps`` metres every frame along the body's
  forward axis, reversing direction whenever it is 0.10 m from its plant (so the leg stays
  reachable);
* ``penetration`` (m): the contacting hand's wrist is pushed inside along the surface
  normal to signed distance ``-depth`` while in contact (``ValueError`` where the part is
  thinner than that: a signed distance cannot exceed half its thickness); kick: the foot
  joint ``depth`` inside the ball; sitting: the pelvis ``depth`` lower than the clean pose, so
  the body surface sinks ``depth`` into the seat (``depth <= SEAT_CLEARANCE_M * s``);
* ``lost_contact`` (m): over the middle half of the hand's longest contact run (where the
  object moves), the wrist is ``gap`` outside the surface along the normal; contact labels
  stay on (hand actions only).

Full-magnitude defect frames are recorded as ``frames = [start, end)``; ramps of 3-8 frames
lead in and out where the window does not touch the clip ends.

BEHAVE raw layout written by :func:`write_behave_layout`
--------------------------------------------------------
::

    OUT/sequences/<Date0X_SubYY_<object>_<action>[_<n>]>/smpl_fit_all.npz
        poses float32 (T,156) root 3 + body 63 + hands 90 (zeros), betas float32 (T,10),
        trans float32 (T,3), save_name, frame_times ('t0003.033': 't%08.3f', first frame
        at FRAME_TIME_OFFSET_S = 3 s like BEHAVE's captures)
    OUT/sequences/<...>/object_fit_all.npz  angles float64 (T,3), trans float64 (T,3),
        save_name, frame_times
    OUT/sequences/<...>/info.json   BEHAVE's keys: config, intrinsic, cat, gender, empty,
        kinects, beta (paths are null: there are no images)
    OUT/sequences/<...>/hoibench_gt.npz + hoibench_gt.json   ground truth (not BEHAVE)
    OUT/objects/<obj>/<obj>_f1000.ply   binary PLY template, centred on its vertex mean
    OUT/split.json                      {"train": [...], "test": [every Date03 sequence]}
    OUT/body_models/smplh/SMPLH_{MALE,FEMALE,NEUTRAL}.npz   the proxy body
    OUT/hoibench_synthetic.json         the manifest

String arrays are numpy unicode arrays (``np.load(..., allow_pickle=False)`` works); every
file is byte-identical for the same arguments (clips are seeded from ``(seed, clip
index)`` only). Gender: Sub01-05 male, Sub06-08 female.

Camera frame. BEHAVE's world is a Kinect camera (OpenCV axes, y down) with a tilted floor.
The y-up world is mapped to it by the fixed rigid transform ``p_cam = R_c p + c_c`` with
``R_c = R_z(CAMERA_TILT_Z_DEG) R_x(CAMERA_TILT_X_DEG) R_x(180 deg)`` and
``c_c = CAMERA_OFFSET_M`` (the world origin 2.3 m in front of and 0.95 m below the
camera). SMPL parameters are moved with the pelvis-offset rule (:func:`rigid_transform_smpl`):
the posed pelvis is ``J0 + t``, so ``R0' = R R0`` and ``t' = R (J0 + t) + c - J0``.
Objects: ``R' = R_c R``, ``t' = R_c t + c_c``, ``angles`` = axis-angle of ``R'``.
"""
from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ..core import geometry as geo
from ..core import skeleton as sk
from ..bodies.transform import rigid_transform_smpl
from ..core.io import atomic_write_bytes, atomic_write_text, npz_bytes

__all__ = [
    "FPS", "ACTIONS", "OBJECTS", "CATALOGUE", "SUBJECT_GENDER", "SUBJECT_BETA0",
    "CAMERA_R", "CAMERA_C", "FRAME_TIME_OFFSET_S", "JOINT_PENETRATION_TOL_M",
    "ClipSpec", "Defect", "ObjectModel", "SyntheticClip",
    "build_object", "plan_clips", "generate_clip", "write_behave_layout",
    "rigid_transform_smpl", "world_to_camera", "camera_to_world", "subject_betas",
    "rest_joints", "frame_times", "measure_clip", "ply_bytes",
]

GENERATOR_VERSION = "1.1"  # 1.1: sit contact starts when the pelvis has settled within 3 mm
FPS = 30.0
FRAME_TIME_OFFSET_S = 3.0
ACTIONS: tuple[str, ...] = ("lift", "carry", "putdown", "push", "pull", "sit", "kick", "hold")
OBJECTS: tuple[str, ...] = ("boxsmall", "boxlarge", "chairwood", "tablesmall", "stool",
                            "yogaball", "yogamat", "backpack")
HANDS: tuple[str, ...] = ("both", "left", "right", "none")
_B, _1 = ("both",), ("both", "left", "right")

#: object -> action -> hands that make sense.
CATALOGUE: dict[str, dict[str, tuple[str, ...]]] = {
    "boxsmall": {"lift": _B, "carry": _B, "putdown": _B, "hold": _B},
    "boxlarge": {"lift": _B, "carry": _B, "putdown": _B, "hold": _B, "push": _1, "pull": _1,
                 "sit": ("none",)},
    "chairwood": {"lift": _1, "carry": _1, "putdown": _1, "hold": _1, "push": _1, "pull": _1,
                  "sit": ("none",)},
    "tablesmall": {"lift": _B, "carry": _B, "putdown": _B, "push": _1, "pull": _1},
    "stool": {"lift": _B, "carry": _B, "putdown": _B, "hold": _B, "push": _B, "pull": _B,
              "sit": ("none",)},
    "yogaball": {"lift": _B, "carry": _B, "putdown": _B, "hold": _B, "kick": ("none",),
                 "sit": ("none",)},
    "yogamat": {"lift": _1, "carry": _1, "putdown": _1, "hold": _1},
    "backpack": {"lift": _1, "carry": _1, "putdown": _1, "hold": _1},
}

SUBJECTS: tuple[str, ...] = tuple(f"Sub{i:02d}" for i in range(1, 9))
SUBJECT_GENDER: dict[str, str] = {s: ("male" if i < 5 else "female") for i, s in enumerate(SUBJECTS)}
#: beta_0 per subject: the proxy body scales by 1 + 0.05 beta_0 (0.93 .. 1.06).
SUBJECT_BETA0: dict[str, float] = dict(zip(SUBJECTS, (0.8, 0.2, 1.2, -0.3, 0.5, -1.0, -0.5, -1.4)))

CAMERA_TILT_X_DEG = 8.0
CAMERA_TILT_Z_DEG = 2.5
CAMERA_OFFSET_M = (0.10, 0.95, 2.30)


def _rx(a):
    return geo.rotation_about_x(np.asarray(a, dtype=np.float64))


def _ry(a):
    return geo.rotation_about_y(np.asarray(a, dtype=np.float64))


def _rz(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


#: T_cam_from_world: p_cam = CAMERA_R @ p_world + CAMERA_C.
CAMERA_R: np.ndarray = (_rz(math.radians(CAMERA_TILT_Z_DEG)) @ _rx(math.radians(CAMERA_TILT_X_DEG))
                        @ _rx(math.pi))
CAMERA_C: np.ndarray = np.array(CAMERA_OFFSET_M, dtype=np.float64)

#: Largest depth (m) any joint may reach inside the object in a clean clip (measured ~0).
JOINT_PENETRATION_TOL_M = 0.002
#: Hip-joint height above a seat when sitting, times the body scale: the proxy's hip radius.
SEAT_CLEARANCE_M = 0.088
#: hips are labelled seated once the pelvis is this close to its seated position (m)
SIT_CONTACT_TOL_M = 0.003

# motion-model constants (metres at scale 1, radians)
_REACH_FRAC = 0.96        # hand targets within this fraction of the arm length
_LEG_FRAC = 0.985         # legs never stretched beyond this fraction
_CROUCH_DROP = 0.52       # pelvis drop at full crouch
_CROUCH_BACK = 0.10       # pelvis back-shift at full crouch
_CROUCH_BEND = math.radians(95.0)
_PELVIS_SHARE = 0.5       # share of the bend taken by the pelvis (the rest: 3 spine joints)
_LIFT_NEAR = {"yogamat": 0.32, "boxsmall": 0.38}   # floor distance of the near face for lifts
_TORSO_CLEARANCE = 0.03   # torso/head joints stay this far outside the object when crouching
_PREGRASP = 0.08          # approach a grasp from this far along the surface normal
_FREE_HAND = np.array([[0.07, -0.44, 0.05], [-0.07, -0.44, 0.05]])   # wrist - shoulder, body frame
_ARM_POLE = np.array([[0.6, -1.0, -0.4], [-0.6, -1.0, -0.4]])
_LEG_POLE = np.array([[0.2, 0.0, 1.0], [-0.2, 0.0, 1.0]])
_ARM_REST_POLE = np.array([0.0, 0.0, -1.0])
_LEGS = ((1, 4, 7, 10), (2, 5, 8, 11))            # hip, knee, ankle, foot (left, right)
_ARMS = ((13, 16, 18, 20), (14, 17, 19, 21))      # collar, shoulder, elbow, wrist
_WRISTS = (20, 21)
_HAND_INDEX = {"left": 0, "right": 1}


# =========================================================================== objects
@dataclass(frozen=True)
class _Box:
    center: tuple
    half: tuple

    def sdf(self, p: np.ndarray) -> np.ndarray:
        q = np.abs(p - np.asarray(self.center)) - np.asarray(self.half)
        return np.linalg.norm(np.maximum(q, 0.0), axis=-1) + np.minimum(q.max(-1), 0.0)

    def mesh(self) -> tuple[np.ndarray, np.ndarray]:
        c, h = np.asarray(self.center), np.asarray(self.half)
        corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
        faces = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                          [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
        return c + corners * h, faces

    def shifted(self, d):
        return _Box(tuple(np.asarray(self.center) - d), self.half)


@dataclass(frozen=True)
class _Cylinder:
    center: tuple
    axis: int          # 0 x, 1 y, 2 z
    radius: float
    half_length: float
    segments: int = 48

    def sdf(self, p: np.ndarray) -> np.ndarray:
        q = p - np.asarray(self.center)
        a = q[..., self.axis]
        other = [i for i in range(3) if i != self.axis]
        r = np.linalg.norm(q[..., other], axis=-1)
        d = np.stack([r - self.radius, np.abs(a) - self.half_length], -1)
        return np.minimum(d.max(-1), 0.0) + np.linalg.norm(np.maximum(d, 0.0), axis=-1)

    def mesh(self) -> tuple[np.ndarray, np.ndarray]:
        n = self.segments
        ang = 2 * np.pi * np.arange(n) / n
        # local frame: axis along +e2 of (e0, e1, e2) = cyclic permutation keeping handedness
        e2 = self.axis
        e0, e1 = (e2 + 1) % 3, (e2 + 2) % 3
        ring = np.zeros((n, 3))
        ring[:, e0] = self.radius * np.cos(ang)
        ring[:, e1] = self.radius * np.sin(ang)
        lo, hi = ring.copy(), ring.copy()
        lo[:, e2], hi[:, e2] = -self.half_length, self.half_length
        cap_lo, cap_hi = np.zeros(3), np.zeros(3)
        cap_lo[e2], cap_hi[e2] = -self.half_length, self.half_length
        v = np.concatenate([lo, hi, cap_lo[None], cap_hi[None]]) + np.asarray(self.center)
        i = np.arange(n)
        j = (i + 1) % n
        side = np.concatenate([np.stack([i, j, n + j], 1), np.stack([i, n + j, n + i], 1)])
        bottom = np.stack([np.full(n, 2 * n), j, i], 1)
        top = np.stack([np.full(n, 2 * n + 1), n + i, n + j], 1)
        return v, np.concatenate([side, bottom, top])

    def shifted(self, d):
        return _Cylinder(tuple(np.asarray(self.center) - d), self.axis, self.radius,
                         self.half_length, self.segments)


@dataclass(frozen=True)
class _Sphere:
    center: tuple
    radius: float
    n_lon: int = 48
    n_lat: int = 24

    def sdf(self, p: np.ndarray) -> np.ndarray:
        return np.linalg.norm(p - np.asarray(self.center), axis=-1) - self.radius

    def mesh(self) -> tuple[np.ndarray, np.ndarray]:
        nl, nb = self.n_lon, self.n_lat
        theta = np.pi * np.arange(1, nb) / nb                       # polar angle from +y
        phi = 2 * np.pi * np.arange(nl) / nl
        st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
        ring = np.stack([st * np.sin(phi), np.broadcast_to(ct, (nb - 1, nl)), st * np.cos(phi)], -1)
        v = np.concatenate([[[0, 1, 0]], ring.reshape(-1, 3), [[0, -1, 0]]]) * self.radius
        v = v + np.asarray(self.center)
        top, bot = 0, 1 + (nb - 1) * nl
        idx = lambda r, k: 1 + r * nl + (k % nl)  # noqa: E731
        f = []
        for k in range(nl):
            f.append([top, idx(0, k), idx(0, k + 1)])
            f.append([bot, idx(nb - 2, k + 1), idx(nb - 2, k)])
        for r in range(nb - 2):
            for k in range(nl):
                a, b, c, d = idx(r, k), idx(r, k + 1), idx(r + 1, k), idx(r + 1, k + 1)
                f.append([a, c, d])
                f.append([a, d, b])
        return v, np.array(f)

    def shifted(self, d):
        return _Sphere(tuple(np.asarray(self.center) - d), self.radius, self.n_lon, self.n_lat)


@dataclass
class ObjectModel:
    """A primitive-built object in its *centred* local frame (template vertex mean at 0).

    ``vertices`` (V, 3) float64 (exactly float32-representable, as written to the PLY),
    ``faces`` (F, 3) int32; posed vertices ``v = R v_template + t``. Local axes: x to the
    person's left, y up, z away from the person (the person stands on the -z side).
    ``grips[purpose][hands][hand] = (point, outward normal)`` on the surface;
    ``seat = (top y, x, z)`` of a sittable surface; all local, metres.
    """
    name: str
    primitives: tuple
    vertices: np.ndarray
    faces: np.ndarray
    grips: dict
    seat: tuple | None = None
    kind: str = "rigid"

    def sdf_local(self, p: np.ndarray) -> np.ndarray:
        """Signed distance (m) of local points (..., 3): the minimum over the primitives'
        exact signed distances (exact outside the union; negative inside)."""
        p = np.asarray(p, dtype=np.float64)
        return np.min(np.stack([prim.sdf(p) for prim in self.primitives]), axis=0)

    def sdf(self, points: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Signed distance of world points (T, N, 3) to the object posed by ``R`` (T,3,3),
        ``t`` (T,3): evaluated at ``R^T (p - t)``."""
        local = np.einsum("tnj,tjk->tnk", np.asarray(points) - t[:, None], R)
        return self.sdf_local(local)

    @property
    def size(self) -> np.ndarray:
        """Bounding-box extents (x, y, z), metres."""
        return self.vertices.max(0) - self.vertices.min(0)


def _object_spec(name: str):
    """Canonical primitives (base on y = 0, centred in x/z), grips and seat."""
    X, Y, nZ = (1.0, 0, 0), (0, 1.0, 0), (0, 0, -1.0)

    def pair(p, n, mirror_normal=True):
        (x, y, z), m = p, n
        mn = (-m[0], m[1], m[2]) if mirror_normal else m
        return {"left": ((x, y, z), m), "right": ((-x, y, z), mn)}

    def single(p, n):
        (x, y, z) = p
        return {"left": ((x, y, z), n), "right": ((-x, y, z), n)}

    def one_hand(both, single_grips):
        return {"both": both, "left": {"left": single_grips["left"]},
                "right": {"right": single_grips["right"]}}

    grips: dict = {}
    seat = None
    if name == "boxsmall":
        W, H, D = 0.38, 0.28, 0.30
        prims = [_Box((0, H / 2, 0), (W / 2, H / 2, D / 2))]
        grips["lift"] = {"both": pair((W / 2, H - 0.06, -D / 2 + 0.10), X)}
    elif name == "boxlarge":
        W, H, D = 0.56, 0.42, 0.44
        prims = [_Box((0, H / 2, 0), (W / 2, H / 2, D / 2))]
        grips["lift"] = {"both": pair((W / 2, H - 0.07, -D / 2 + 0.10), X)}
        grips["push"] = one_hand(pair((0.16, H - 0.07, -D / 2), nZ, False),
                                 single((0.07, H - 0.07, -D / 2), nZ))
        grips["pull"] = one_hand(pair((0.16, H, -D / 2 + 0.06), Y, False),
                                 single((0.07, H, -D / 2 + 0.06), Y))
        seat = (H, 0.0, 0.0)
    elif name == "chairwood":
        prims = [_Box((0, 0.445, 0), (0.22, 0.015, 0.21))]                        # seat
        prims += [_Box((sx * 0.1925, 0.215, 0.1925), (0.0175, 0.215, 0.0175)) for sx in (1, -1)]
        prims += [_Box((sx * 0.1925, 0.44, -0.1925), (0.0175, 0.44, 0.0175)) for sx in (1, -1)]
        prims += [_Box((0, 0.80, -0.1925), (0.175, 0.06, 0.0125)),                  # top rail
                  _Box((0, 0.60, -0.1925), (0.175, 0.03, 0.0100))]                  # slat
        rail = single((0.04, 0.86, -0.1925), Y)
        grips["lift"] = one_hand(pair((0.10, 0.86, -0.1925), Y, False), rail)
        grips["pull"] = grips["lift"]
        grips["push"] = one_hand(pair((0.10, 0.80, -0.205), nZ, False),
                                 single((0.05, 0.80, -0.205), nZ))
        seat = (0.46, 0.0, 0.0)
    elif name == "tablesmall":
        prims = [_Box((0, 0.535, 0), (0.30, 0.015, 0.25))]
        prims += [_Box((sx * 0.26, 0.26, sz * 0.21), (0.02, 0.26, 0.02))
                  for sx in (1, -1) for sz in (1, -1)]
        grips["lift"] = {"both": pair((0.30, 0.535, -0.12), X)}
        grips["push"] = one_hand(pair((0.15, 0.535, -0.25), nZ, False),
                                 single((0.06, 0.535, -0.25), nZ))
        grips["pull"] = one_hand(pair((0.15, 0.55, -0.19), Y, False),
                                 single((0.06, 0.55, -0.19), Y))
    elif name == "stool":
        prims = [_Cylinder((0, 0.44, 0), 1, 0.17, 0.02)]
        prims += [_Cylinder(c, 1, 0.016, 0.21, 16) for c in
                  ((0.11, 0.21, 0), (-0.11, 0.21, 0), (0, 0.21, 0.11), (0, 0.21, -0.11))]
        grips["lift"] = {"both": pair((0.17, 0.44, 0.0), X)}
        ph = math.radians(40.0)
        grips["push"] = {"both": pair((0.17 * math.sin(ph), 0.44, -0.17 * math.cos(ph)),
                                      (math.sin(ph), 0.0, -math.cos(ph)))}
        grips["pull"] = {"both": pair((0.07, 0.46, -0.10), Y, False)}
        seat = (0.46, 0.0, 0.0)
    elif name == "yogaball":
        r = 0.30
        prims = [_Sphere((0, r, 0), r)]
        th = math.radians(35.0)
        grips["lift"] = {"both": pair((r * math.cos(th), r, -r * math.sin(th)),
                                      (math.cos(th), 0.0, -math.sin(th)))}
        seat = (2 * r, 0.0, 0.0)
    elif name == "yogamat":
        r = 0.075
        prims = [_Cylinder((0, r, 0), 0, r, 0.31)]
        grips["lift"] = one_hand(pair((0.20, 2 * r, 0.0), Y, False), single((0.0, 2 * r, 0.0), Y))
    elif name == "backpack":
        prims = [_Box((0, 0.20, 0), (0.15, 0.20, 0.08)),
                 _Box((0, 0.14, 0.095), (0.12, 0.09, 0.015)),     # front pocket (away side)
                 _Box((0, 0.415, 0), (0.05, 0.015, 0.012))]       # top handle
        grips["lift"] = one_hand(pair((0.15, 0.28, 0.0), X), single((0.0, 0.43, 0.0), Y))
    else:
        raise ValueError(f"object: expected one of {OBJECTS}, got {name!r}")
    return prims, grips, seat


@lru_cache(maxsize=None)
def build_object(name: str) -> ObjectModel:
    """The object ``name`` (one of :data:`OBJECTS`) centred on its template vertex mean."""
    prims, grips, seat = _object_spec(name)
    vs, fs, n = [], [], 0
    for p in prims:
        v, f = p.mesh()
        vs.append(v)
        fs.append(f + n)
        n += len(v)
    v = np.concatenate(vs)
    mean = v.mean(0)
    verts = (v - mean).astype(np.float32).astype(np.float64)
    prims = tuple(p.shifted(mean) for p in prims)
    shift = lambda p: tuple(float(x) for x in np.asarray(p) - mean)  # noqa: E731
    g = {purpose: {hands: {h: (np.asarray(shift(p)), np.asarray(nv, float) / np.linalg.norm(nv))
                           for h, (p, nv) in d.items()} for hands, d in by.items()}
         for purpose, by in grips.items()}
    seat_local = None if seat is None else (seat[0] - mean[1], seat[1] - mean[0], seat[2] - mean[2])
    return ObjectModel(name, prims, verts, np.concatenate(fs).astype(np.int32), g, seat_local,
                       "ball" if name == "yogaball" else "rigid")


def ply_bytes(vertices: np.ndarray, faces: np.ndarray, comment: str = "") -> bytes:
    """Binary little-endian PLY: float32 x, y, z; faces as ``uchar`` count + ``int`` ids."""
    v = np.ascontiguousarray(vertices, dtype="<f4")
    f = np.asarray(faces)
    head = ["ply", "format binary_little_endian 1.0"]
    if comment:
        head.append(f"comment {comment}")
    head += [f"element vertex {len(v)}", "property float x", "property float y",
             "property float z", f"element face {len(f)}",
             "property list uchar int vertex_indices", "end_header"]
    rec = np.zeros(len(f), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    rec["n"] = 3
    rec["i"] = f
    return ("\n".join(head) + "\n").encode("ascii") + v.tobytes() + rec.tobytes()


# =========================================================================== body
def subject_betas(subject: str) -> np.ndarray:
    """(10,) betas of a subject: ``beta_0`` from :data:`SUBJECT_BETA0` (body scale), the rest
    small and fixed per subject (the proxy ignores them)."""
    if subject not in SUBJECT_BETA0:
        raise ValueError(f"subject: expected one of {SUBJECTS}, got {subject!r}")
    rng = np.random.default_rng([int(subject[3:]), 7919])
    b = np.round(rng.normal(0.0, 0.5, 10), 3)
    b[0] = SUBJECT_BETA0[subject]
    return b


def rest_joints(betas: np.ndarray) -> np.ndarray:
    """(22, 3) rest joints of the proxy body for ``betas`` (model frame, metres)."""
    from ..bodies.proxy import proxy_rest_joints
    return np.asarray(proxy_rest_joints(np.asarray(betas, dtype=np.float64)), dtype=np.float64)


@lru_cache(maxsize=None)
def _sole_below_foot_joint() -> tuple[float, float]:
    """Height of the proxy's left/right foot joint above its lowest sole vertex at scale 1
    (foot kept in its rest orientation): a planted foot joint sits this high times scale."""
    from ..bodies.proxy import ProxyBody
    body = ProxyBody()
    v, pj = body.v_template, body.part_joint
    out = []
    for ankle, foot in ((7, 10), (8, 11)):
        sole = v[(pj == ankle) | (pj == foot), 1].min()
        out.append(float(sk.SMPL_REST_JOINTS[foot, 1] - sole))
    return out[0], out[1]


class _Body:
    """Subject-specific skeleton quantities (metres)."""

    def __init__(self, betas: np.ndarray):
        self.betas = np.asarray(betas, dtype=np.float64)
        self.rest = rest_joints(self.betas)
        r = self.rest
        self.s = float(np.linalg.norm(r[20] - r[21]) / np.linalg.norm(
            sk.SMPL_REST_JOINTS[20] - sk.SMPL_REST_JOINTS[21]))
        soles = _sole_below_foot_joint()
        self.foot_y = np.array([soles[0] * self.s, soles[1] * self.s])
        self.leg = [(r[k] - r[h], r[a] - r[k]) for h, k, a, _ in _LEGS]
        self.arm = [(r[e] - r[s_], r[w] - r[e]) for _, s_, e, w in _ARMS]
        self.arm_len = float(np.linalg.norm(self.arm[0][0]) + np.linalg.norm(self.arm[0][1]))
        self.leg_len = [float(np.linalg.norm(a) + np.linalg.norm(b)) for a, b in self.leg]
        self.foot_off = np.stack([r[10] - r[0], r[11] - r[0]])        # foot joints - pelvis
        self.ankle_from_foot = np.stack([r[7] - r[10], r[8] - r[11]])
        # standing pelvis height: planted feet, knees 1.5 cm short of straight
        self.stand_y = float(np.mean(self.foot_y - self.foot_off[:, 1])) - 0.015 * self.s
        self.shoulder_off = np.stack([r[16] - r[0], r[17] - r[0]])

    def stance(self, pelvis_xz, psi: float = 0.0, width: float | None = None,
               dz=(0.0, 0.0)) -> np.ndarray:
        """(2, 3) foot-joint targets of a standing stance under the pelvis."""
        off = self.foot_off.copy()
        if width is not None:
            off[:, 0] = np.array([0.5, -0.5]) * width
        off[:, 2] += np.asarray(dz)
        R = _ry(psi)
        out = off @ R.T
        out[:, 0] += pelvis_xz[0]
        out[:, 2] += pelvis_xz[1]
        out[:, 1] = self.foot_y
        return out


# =========================================================================== kinematics
def _minjerk(u):
    u = np.clip(u, 0.0, 1.0)
    return u * u * u * (10 - 15 * u + 6 * u * u)


def _quintic(p0, v0, p1, v1, dur, u):
    """Quintic Hermite with zero end accelerations: position at ``u`` in [0, 1] of a move
    from ``p0`` (velocity ``v0``) to ``p1`` (velocity ``v1``) lasting ``dur`` seconds."""
    u = np.clip(u, 0.0, 1.0)[..., None]
    h0 = 1 - 10 * u ** 3 + 15 * u ** 4 - 6 * u ** 5
    h1 = u - 6 * u ** 3 + 8 * u ** 4 - 3 * u ** 5
    h4 = -4 * u ** 3 + 7 * u ** 4 - 3 * u ** 5
    h5 = 10 * u ** 3 - 15 * u ** 4 + 6 * u ** 5
    return h0 * p0 + h1 * (np.asarray(v0) * dur) + h4 * (np.asarray(v1) * dur) + h5 * p1


def _normalize(v, axis=-1):
    return v / np.linalg.norm(v, axis=axis, keepdims=True)


def _frame(u, n):
    """Right-handed orthonormal frame (columns u, n_perp, u x n_perp)."""
    n = n - (n * u).sum(-1, keepdims=True) * u
    n = _normalize(n)
    return np.stack([u, n, np.cross(u, n)], -1)


def _two_bone(A, T, pole, b1, b2, n_rest):
    """Analytic two-bone IK. A, T, pole (N, 3); rest bones b1, b2 (3,); rest hinge axis
    n_rest. Returns global rotations of both bones (N,3,3) and the reached end point."""
    l1, l2 = float(np.linalg.norm(b1)), float(np.linalg.norm(b2))
    v = T - A
    d = np.linalg.norm(v, axis=-1)
    dc = np.clip(d, abs(l1 - l2) + 1e-6, (l1 + l2) * (1 - 1e-9))
    u = v / np.maximum(d, 1e-12)[:, None]
    w = pole - (pole * u).sum(-1, keepdims=True) * u
    wn = np.linalg.norm(w, axis=-1, keepdims=True)
    alt = np.cross(u, np.array([1.0, 0.0, 0.0]))
    w = np.where(wn > 1e-6, w / np.maximum(wn, 1e-12), _normalize(alt + 1e-9))
    ca = (l1 * l1 + dc * dc - l2 * l2) / (2 * l1 * dc)
    sa = np.sqrt(np.clip(1 - ca * ca, 0.0, 1.0))
    K = A + l1 * (ca[:, None] * u + sa[:, None] * w)
    E = A + dc[:, None] * u
    n = np.cross(w, u)
    F1r = _frame(b1 / l1, n_rest)
    F2r = _frame(b2 / l2, n_rest)
    G1 = _frame((K - A) / l1, n) @ F1r.T
    G2 = _frame((E - K) / l2, n) @ F2r.T
    return G1, G2, E


def _torso_locals(psi: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """Local rotations (..., 22, 3, 3): heading, spine bend ``beta`` (rad), limbs identity."""
    psi, beta = np.broadcast_arrays(np.asarray(psi, float), np.asarray(beta, float))
    L = np.broadcast_to(np.eye(3), psi.shape + (22, 3, 3)).copy()
    L[..., 0, :, :] = _ry(psi) @ _rx(_PELVIS_SHARE * beta)
    spine = _rx((0.95 - _PELVIS_SHARE) / 3 * beta)
    for j in (3, 6, 9):
        L[..., j, :, :] = spine
    L[..., 12, :, :] = L[..., 15, :, :] = _rx(-0.15 * beta)
    return L


# =========================================================================== plans
class _Plan:
    """Per-frame targets of a clip in the canonical frame (person starts at the origin
    facing +z). Hand targets are object-local points ``p + delta n`` (n outward)."""

    def __init__(self, T: int, body: _Body):
        self.T = T
        self.pelvis = np.zeros((T, 3))
        self.pelvis[:, 1] = body.stand_y
        self.heading = np.zeros(T)
        self.bend = np.zeros(T)
        self.foot = np.repeat(body.stance((0.0, 0.0))[None], T, 0)
        self.foot_yaw = np.zeros((T, 2))
        self.planted = np.ones((T, 2), bool)
        self.hand_w = np.zeros((T, 2))
        self.hand_p = np.full((T, 2, 3), np.nan)
        self.hand_n = np.full((T, 2, 3), np.nan)
        self.hand_delta = np.zeros((T, 2))
        self.obj_R = np.repeat(np.eye(3)[None], T, 0)
        self.obj_t = np.zeros((T, 3))
        self.contacts = np.zeros((T, 22), bool)
        self.segments: list[tuple[str, int, int, str]] = []   # frames [start, end)
        self.crouch = False
        self.hands: tuple[str, ...] = ()
        self.feet: tuple[str, ...] = ()
        self.kick: dict | None = None
        self.seated: np.ndarray | None = None

    def reversed(self) -> "_Plan":
        out = _Plan.__new__(_Plan)
        out.__dict__.update(self.__dict__)
        for k, v in self.__dict__.items():
            if isinstance(v, np.ndarray) and v.ndim >= 1 and v.shape[0] == self.T:
                setattr(out, k, v[::-1].copy())
        out.segments = [(a, self.T - e, self.T - s, h) for a, s, e, h in reversed(self.segments)]
        return out

    def attach(self, hands: str, grips: dict, frames: slice):
        for h, (p, n) in grips[hands].items():
            k = _HAND_INDEX[h]
            self.hand_p[frames, k] = p
            self.hand_n[frames, k] = n

    def hand_targets(self) -> np.ndarray:
        """(T, 2, 3) world targets of the hands attached to the object."""
        loc = self.hand_p + self.hand_delta[..., None] * self.hand_n
        return np.einsum("tij,tkj->tki", self.obj_R, loc) + self.obj_t[:, None]


def _frames(sec: float) -> int:
    return int(round(sec * FPS))


def _floor_y(obj: ObjectModel) -> float:
    return float(-obj.vertices[:, 1].min())


def _approach(plan: _Plan, k: int, i_a: int, i_g: int):
    """Hand ``k`` moves from hanging free to a pre-grasp point _PREGRASP out along the
    normal (first 60 %), then onto the surface at frame ``i_g`` (weights, offsets)."""
    i = np.arange(plan.T)
    u = np.clip((i - i_a) / max(i_g - i_a, 1), 0.0, 1.0)
    plan.hand_w[:, k] = _minjerk(u / 0.6)
    plan.hand_delta[:, k] = _PREGRASP * (1 - _minjerk((u - 0.5) / 0.5))
    plan.hand_w[i_g:, k] = 1.0
    plan.hand_delta[i_g:, k] = 0.0
    plan.contacts[i_g:, _WRISTS[k]] = True


def _hold_pose(obj: ObjectModel, hands: str, body: _Body, walking: bool = False):
    """Object yaw and position (relative to a pelvis at x = z = 0) when held: hanging at the
    side for a one-hand backpack, else in front, chosen on a grid (hand height, near-face
    distance) closest to hands 0.12 s above the standing pelvis and the near face 0.24 m in
    front of it, with the hands within 90 % of the arm length of the standing shoulders and
    the object clear of the knees (near face >= 0.25 m or bottom >= 0.62 m)."""
    s = body.s
    g = obj.grips["lift"][hands]
    if hands != "both" and obj.name == "backpack":
        side = 1.0 if hands == "left" else -1.0
        yaw = math.pi / 2
        R = _ry(yaw)
        (p, _), = g.values()
        wrist = np.array([side * 0.27 * s, body.stand_y + 0.03 * s, 0.03])
        return yaw, wrist - R @ p
    pts = np.stack([p for p, _ in g.values()])
    m = pts.mean(0)
    lateral = 0.0 if hands == "both" else (0.10 if hands == "left" else -0.10) * s
    zmin, ymin = obj.vertices[:, 2].min(), obj.vertices[:, 1].min()
    ys = body.stand_y + np.arange(0.0, 0.40, 0.01) * s
    cs = np.arange(0.14, 0.41, 0.01)
    Y, C = np.meshgrid(ys, cs, indexing="ij")
    t = np.stack([np.full_like(Y, lateral - m[0]), Y - m[1], C - zmin], -1)
    bottom = t[..., 1] + ymin
    sh = np.array([0.0, body.stand_y - (0.025 * s if walking else 0.0), 0.0]) + body.shoulder_off
    ok = (bottom >= 0.05) & ((C >= 0.25) | (bottom >= 0.62))
    for hname, (p, _) in g.items():
        d = np.linalg.norm(t + p - sh[_HAND_INDEX[hname]], axis=-1)
        ok &= d <= 0.90 * body.arm_len
    hand_y = t[..., 1] + m[1]
    cost = np.abs(hand_y - (body.stand_y + 0.12 * s)) + 2 * np.abs(C - 0.24)
    cost = np.where(ok, cost, np.inf)
    idx = np.unravel_index(np.argmin(cost), cost.shape)
    if not np.isfinite(cost[idx]):
        raise RuntimeError(f"synthetic: no reachable hold pose for {obj.name}/{hands}")
    return 0.0, t[idx]


def _floor_pose(obj: ObjectModel, hands: str, body: _Body, rng, near: float):
    """Yaw and position of the object resting on the floor in front of the person."""
    if hands != "both" and obj.name == "backpack":
        yaw = math.pi / 2 + math.radians(rng.uniform(-6, 6))
        lateral = (0.22 if hands == "left" else -0.22) * body.s
    else:
        yaw = math.radians(rng.uniform(-6, 6))
        lateral = 0.0 if hands in ("both", "none") else (0.08 if hands == "left" else -0.08) * body.s
    R = _ry(yaw)
    v = obj.vertices @ R.T
    t = np.array([lateral, _floor_y(obj), near - v[:, 2].min()])
    return yaw, t


def _plan_lift(obj, hands, body, rng) -> _Plan:
    i_a = _frames(rng.uniform(0.2, 0.45))
    i_g = i_a + _frames(rng.uniform(0.8, 0.95))
    i_l = i_g + _frames(rng.uniform(1.1, 1.4))
    T = i_l + _frames(rng.uniform(0.6, 0.9))
    plan = _Plan(T, body)
    plan.crouch = True
    width = 0.30 * body.s if hands == "both" else None
    plan.foot[:] = body.stance((0.0, 0.0), width=width)
    near = _LIFT_NEAR.get(obj.name, 0.40) + rng.uniform(0.0, 0.03)
    yaw0, t0 = _floor_pose(obj, hands, body, rng, near=near)
    yaw1, t1 = _hold_pose(obj, hands, body)
    i = np.arange(T)
    u = np.clip((i - i_g) / (i_l - i_g), 0.0, 1.0)
    uy, uh = _minjerk(u / 0.8), _minjerk((u - 0.15) / 0.85)
    plan.obj_t = np.stack([t0[0] + (t1[0] - t0[0]) * uh, t0[1] + (t1[1] - t0[1]) * uy,
                           t0[2] + (t1[2] - t0[2]) * uh], -1)
    plan.obj_R = _ry(yaw0 + (yaw1 - yaw0) * uh)
    plan.attach(hands, obj.grips["lift"], slice(None))
    for h in obj.grips["lift"][hands]:
        _approach(plan, _HAND_INDEX[h], i_a, i_g)
    plan.hands = tuple(obj.grips["lift"][hands])
    plan.segments = [("lift", i_g, i_l, hands), ("hold", i_l, T, hands)]
    return plan


def _plan_putdown(obj, hands, body, rng) -> _Plan:
    return _plan_lift(obj, hands, body, rng).reversed()


def _plan_hold(obj, hands, body, rng) -> _Plan:
    T = _frames(rng.uniform(3.0, 3.6))
    plan = _Plan(T, body)
    plan.crouch = True
    yaw, t = _hold_pose(obj, hands, body)
    time = np.arange(T) / FPS
    f = rng.uniform(0.3, 0.6, 4)
    ph = rng.uniform(0, 2 * np.pi, 4)
    ramp = _minjerk(time / 0.5)
    sway = np.stack([0.025 * np.sin(2 * np.pi * f[0] * time + ph[0]),
                     0.020 * np.sin(2 * np.pi * f[1] * time + ph[1]),
                     0.015 * np.sin(2 * np.pi * f[2] * time + ph[2])], -1) * ramp[:, None]
    plan.obj_t = t + sway
    plan.obj_R = _ry(yaw + math.radians(4.0) * np.sin(2 * np.pi * f[3] * time + ph[3]) * ramp)
    plan.pelvis[:, 0] = 0.015 * np.sin(2 * np.pi * 0.4 * time + ph[0]) * ramp
    _grip_whole_clip(plan, obj, hands)
    plan.segments = [("hold", 0, T, hands)]
    return plan


def _grip_whole_clip(plan: _Plan, obj: ObjectModel, hands: str) -> None:
    """The hands hold the object (its lift grips) on every frame of the clip."""
    plan.attach(hands, obj.grips["lift"], slice(None))
    for h in obj.grips["lift"][hands]:
        k = _HAND_INDEX[h]
        plan.hand_w[:, k] = 1.0
        plan.contacts[:, _WRISTS[k]] = True
    plan.hands = tuple(obj.grips["lift"][hands])


def _gait(plan: _Plan, body: _Body, i0: int, n_swings: int, step: float, swing: int, ds: int,
          direction: float, first: int, lift: float = 0.06) -> int:
    """Alternating steps along the heading (+z, or -z for ``direction`` -1). Each swing moves
    one foot (min-jerk horizontally, ``16 u^2 (1-u)^2 * lift`` vertically) to ``step``
    beyond the other foot (the last swing brings the feet together) while the other stays
    planted; the pelvis follows the mean of the feet. Returns the frame the walk ends."""
    T = plan.T
    cur = plan.foot[i0].copy()
    side, i = first, i0
    for k in range(n_swings):
        other = 1 - side
        new = cur[side].copy()
        new[2] = cur[other, 2] + (direction * step if k < n_swings - 1 else 0.0)
        a, b = i, min(i + swing, T - 1)
        idx = np.arange(a, b + 1)
        u = (idx - a) / (b - a)
        m = _minjerk(u)
        plan.foot[a:b + 1, side] = cur[side] + (new - cur[side]) * m[:, None]
        plan.foot[a:b + 1, side, 1] = cur[side, 1] + 16 * u * u * (1 - u) ** 2 * lift
        plan.foot[b:, side] = new
        plan.planted[a + 1:b, side] = False
        cur[side] = new
        side, i = other, b + ds
    mean0 = plan.foot[i0, :, 2].mean()
    plan.pelvis[i0:, 2] += plan.foot[i0:, :, 2].mean(1) - mean0
    return min(i - ds, T)


def _plan_carry(obj, hands, body, rng) -> _Plan:
    n_sw = int(rng.integers(4, 6))
    swing, ds = _frames(rng.uniform(0.42, 0.5)), _frames(0.12)
    i0 = _frames(rng.uniform(0.25, 0.4))
    T = i0 + n_sw * (swing + ds) + _frames(rng.uniform(0.4, 0.6))
    plan = _Plan(T, body)
    plan.crouch = True
    plan.pelvis[:, 1] = body.stand_y - 0.025 * body.s
    _gait(plan, body, i0, n_sw, rng.uniform(0.26, 0.32) * body.s, swing, ds, 1.0,
          int(rng.integers(0, 2)))
    yaw, t = _hold_pose(obj, hands, body, walking=True)
    plan.obj_R[:] = _ry(yaw)
    plan.obj_t = t + np.stack([plan.pelvis[:, 0], np.zeros(T), plan.pelvis[:, 2]], -1)
    _grip_whole_clip(plan, obj, hands)
    plan.segments = [("carry", 0, T, hands)]
    return plan


def _plan_push_pull(obj, hands, body, rng, action: str) -> _Plan:
    direction = 1.0 if action == "push" else -1.0
    grips = obj.grips[action]
    i_a = _frames(rng.uniform(0.2, 0.4))
    i_g = i_a + _frames(rng.uniform(0.7, 0.85))
    i_w = i_g + _frames(rng.uniform(0.15, 0.3))
    n_sw = int(rng.integers(3, 5))
    swing, ds = _frames(rng.uniform(0.45, 0.52)), _frames(0.12)
    T = i_w + n_sw * (swing + ds) + _frames(rng.uniform(0.3, 0.5))
    plan = _Plan(T, body)
    plan.crouch = True
    plan.pelvis[:, 1] = body.stand_y - 0.02 * body.s
    yaw0, t0 = _floor_pose(obj, "both", body, rng, near=0.40 + rng.uniform(0.0, 0.04))
    i_end = _gait(plan, body, i_w, n_sw, rng.uniform(0.22, 0.28) * body.s, swing, ds, direction,
                  int(rng.integers(0, 2)))
    plan.obj_R[:] = _ry(yaw0)
    plan.obj_t = t0 + np.stack([plan.pelvis[:, 0], np.zeros(T), plan.pelvis[:, 2]], -1)
    plan.attach(hands, grips, slice(None))
    for h in grips[hands]:
        _approach(plan, _HAND_INDEX[h], i_a, i_g)
    plan.hands = tuple(grips[hands])
    plan.segments = [(action, i_g, i_end, hands)]
    return plan


def _plan_sit(obj, hands, body, rng) -> _Plan:
    s = body.s
    i0 = _frames(rng.uniform(0.3, 0.6))
    i1 = i0 + _frames(rng.uniform(1.2, 1.5))
    T = i1 + _frames(rng.uniform(1.2, 1.6))
    plan = _Plan(T, body)
    top, sx, sz = obj.seat
    front = obj.vertices[:, 2].max()
    ball = obj.kind == "ball"
    t = np.array([-sx, _floor_y(obj), -(0.16 if ball else 0.14) * s - front])
    plan.obj_t[:] = t
    hip_drop = float(np.mean(body.rest[0, 1] - body.rest[[1, 2], 1]))
    fwd = 0.08 if ball else 0.03           # sit a little forward of the seat centre
    if ball:                               # the sphere's surface is lower there
        r = obj.primitives[0].radius
        top -= r - math.sqrt(r * r - fwd * fwd)
    end = np.array([0.0, t[1] + top + SEAT_CLEARANCE_M * s + hip_drop, t[2] + sz + fwd])
    i = np.arange(T)
    u = np.clip((i - i0) / (i1 - i0), 0.0, 1.0)
    start = plan.pelvis[0].copy()
    plan.pelvis[:, 2] = start[2] + (end[2] - start[2]) * _minjerk(u / 0.85)
    plan.pelvis[:, 1] = start[1] + (end[1] - start[1]) * _minjerk((u - 0.1) / 0.9)
    plan.bend = math.radians(35.0) * np.sin(np.pi * u)
    # hips are labelled from the first frame the settling pelvis is within SIT_CONTACT_TOL_M
    # of its seated position (the min-jerk approach spends several frames within millimetres)
    near = np.hypot(plan.pelvis[:, 1] - end[1], plan.pelvis[:, 2] - end[2]) < SIT_CONTACT_TOL_M
    first = int(np.argmax(near & (i >= i0))) if (near & (i >= i0)).any() else i1
    plan.contacts[min(first, i1):, [1, 2]] = True
    plan.seated = i >= i1
    plan.segments = [("sit", i0, T, "none")]
    return plan


def _plan_kick(obj, hands, body, rng) -> _Plan:
    s = body.s
    k = int(rng.integers(0, 2))                      # kicking foot: 0 left, 1 right
    i_s = _frames(rng.uniform(0.3, 0.5))
    i_c = i_s + _frames(0.5)
    n_c = 3
    i_r = i_c + n_c
    i_p = i_r + _frames(0.55)
    T = i_p + _frames(rng.uniform(1.0, 1.3))
    plan = _Plan(T, body)
    plan.foot[:] = body.stance((0.0, 0.0), dz=(-0.05, 0.0) if k == 0 else (0.0, -0.05))
    f0 = plan.foot[0, k].copy()
    r = obj.primitives[0].radius
    h_c = 0.11
    v_c = rng.uniform(1.1, 1.4)
    z_c = f0[2] + 0.32 * s
    e = math.sqrt(r * r - (r - h_c) ** 2)
    c0 = np.array([f0[0], r, z_c + e])
    plan.obj_t[:] = c0 - np.array([0.0, 0.0, 0.0])
    plan.obj_t[:, 1] = _floor_y(obj)
    i = np.arange(T)
    foot = plan.foot[:, k]
    a = (i > i_s) & (i <= i_c)
    u = (i[a] - i_s) / (i_c - i_s)
    dur = (i_c - i_s) / FPS
    foot[a, 2] = _quintic(np.array([f0[2]]), [0.0], np.array([z_c]), [v_c], dur, u)[:, 0]
    foot[a, 1] = f0[1] + (h_c - f0[1]) * _minjerk(u)
    c = (i > i_c) & (i <= i_r)
    foot[c, 2] = z_c + v_c * (i[c] - i_c) / FPS
    foot[c, 1] = h_c
    z_r = z_c + v_c * n_c / FPS
    b = i > i_r
    u = (i[b] - i_r) / (i_p - i_r)
    z_end = plan.foot[0, 1 - k, 2] + 0.03
    foot[b, 2] = _quintic(np.array([z_r]), [v_c], np.array([z_end]), [0.0], (i_p - i_r) / FPS, u)[:, 0]
    foot[b, 1] = h_c + (f0[1] - h_c) * _minjerk(u)
    plan.planted[i_s + 1:i_p, k] = False
    # ball: still, then pushed by the foot, then rolling with exponential slowdown
    tau = 0.8
    zc = np.full(T, c0[2])
    zc[c] = c0[2] + foot[c, 2] - z_c
    zb = z_r + e             # the kick leaves the light ball 1.6 times faster than the foot
    zc[b] = zb + 1.6 * v_c * tau * (1 - np.exp(-(i[b] - i_r) / FPS / tau))
    plan.obj_t[:, 2] = zc
    plan.obj_R = _rx((zc - c0[2]) / r)            # rolling without slipping along +z
    # weight on the support foot, pelvis a little forward and lower during the kick
    bump = np.sin(np.pi * np.clip((i - i_s + 6) / (i_p - i_s + 12), 0, 1)) ** 2
    plan.pelvis[:, 0] += (0.04 if k == 1 else -0.04) * bump
    plan.pelvis[:, 1] -= 0.03 * s * bump
    plan.pelvis[:, 2] += 0.06 * bump
    plan.contacts[i_c:i_r + 1, 10 + k] = True
    plan.feet = ("left", "right")[k:k + 1]
    plan.kick = {"foot": k, "contact": (i_c, i_r + 1)}
    plan.segments = [("kick", i_s, i_r + 1, "none")]
    return plan


_PLANNERS = {"lift": _plan_lift, "putdown": _plan_putdown, "hold": _plan_hold,
             "carry": _plan_carry, "sit": _plan_sit, "kick": _plan_kick,
             "push": lambda o, h, b, r: _plan_push_pull(o, h, b, r, "push"),
             "pull": lambda o, h, b, r: _plan_push_pull(o, h, b, r, "pull")}


# =========================================================================== solving
def _crouch(plan: _Plan, body: _Body, obj: ObjectModel, A: np.ndarray,
            need: np.ndarray) -> tuple[np.ndarray, int, int]:
    """Per-frame crouch ``c`` in [0, 1]: pelvis drop ``_CROUCH_DROP s c``, back-shift
    ``_CROUCH_BACK s c``, spine bend ``_CROUCH_BEND c``. Per frame, the smallest value on a
    41-point grid that puts every needed hand target within ``_REACH_FRAC`` of the arm
    length while the torso and head joints stay ``_TORSO_CLEARANCE`` outside the object;
    then ``c = gauss(max_filter(c_req))`` (sigma 1.5 frames, support 4 = filter half-width,
    so it never drops below ``c_req``); frames where the smoothed value breaks a constraint
    fall back to ``c_req``. Returns (c, fallback frames, frames with no feasible value)."""
    from scipy.ndimage import gaussian_filter1d, maximum_filter1d
    frames = np.where(need.any(1))[0]
    cs = np.linspace(0.0, 1.0, 41)
    torso = [0, 3, 6, 9, 12, 13, 14, 15, 16, 17]

    def evaluate(c_sel, fr):
        shape = c_sel.shape
        psi = np.broadcast_to(plan.heading[fr], shape)
        beta = plan.bend[fr] + _CROUCH_BEND * c_sel
        L = _torso_locals(psi, beta)
        off = np.stack([0 * c_sel, -_CROUCH_DROP * body.s * c_sel, -_CROUCH_BACK * body.s * c_sel], -1)
        P = plan.pelvis[fr] + np.einsum("...ij,...j->...i", _ry(psi), off)
        J, _ = sk.forward_kinematics(L, body.rest, P - body.rest[0])
        d = np.linalg.norm(A[fr] - J[..., [16, 17], :], axis=-1)
        reach = ((d <= _REACH_FRAC * body.arm_len) | ~need[fr]).all(-1)
        pts = J[..., torso, :].reshape(-1, len(fr), len(torso), 3)
        sd = np.stack([obj.sdf(p, plan.obj_R[fr], plan.obj_t[fr]) for p in pts]).reshape(
            shape + (len(torso),))
        clear = sd.min(-1) >= _TORSO_CLEARANCE
        return reach, clear, np.where(need[fr], d, 0.0).max(-1)

    reach, clear, dmax = evaluate(np.broadcast_to(cs[:, None], (len(cs), len(frames))), frames)
    feas = reach & clear
    first = np.where(feas.any(0), feas.argmax(0),
                     np.where(reach.any(0), reach.argmax(0), dmax.argmin(0)))
    infeasible = int((~feas.any(0)).sum())
    req = np.zeros(plan.T)
    req[frames] = cs[first]
    c = gaussian_filter1d(maximum_filter1d(req, 9, mode="nearest"), 1.5, truncate=2.67,
                          mode="nearest")
    c = np.clip(c, req, 1.0)
    r2, c2, _ = evaluate(c[frames], frames)
    ok_req = feas[first, np.arange(len(frames))] | ~feas.any(0)
    bad = frames[~(r2 & c2) & ok_req & (c[frames] != req[frames])]
    c[bad] = req[bad]
    return c, int(len(bad)), infeasible


def _softclamp(y, ymax, k=0.01):
    """Smooth ``min(y, ymax)`` that stays strictly below ``ymax``."""
    return ymax - k * np.logaddexp(0.0, (ymax - y) / k)


def _solve(plan: _Plan, body: _Body, obj: ObjectModel) -> dict:
    """Targets -> local rotations (T,22,3,3), trans, joints and residuals."""
    T, s, rest = plan.T, body.s, body.rest
    psi = plan.heading
    Rpsi = _ry(psi)
    A = plan.hand_targets()
    need = plan.hand_w > 0
    c, fallback, infeasible = (_crouch(plan, body, obj, A, need) if plan.crouch and need.any()
                               else (np.zeros(T), 0, 0))
    P = plan.pelvis + np.einsum("tij,tj->ti", Rpsi, np.stack(
        [0 * c, -_CROUCH_DROP * s * c, -_CROUCH_BACK * s * c], -1))
    L = _torso_locals(psi, plan.bend + _CROUCH_BEND * c)
    G0 = L[:, 0]
    Ryf = _ry(plan.foot_yaw)                                            # (T, 2, 3, 3)
    ankles = plan.foot + np.einsum("tkij,kj->tki", Ryf, body.ankle_from_foot)
    for k, (hip, _, _, _) in enumerate(_LEGS):
        off = G0 @ (rest[hip] - rest[0])
        dxz = np.hypot(P[:, 0] + off[:, 0] - ankles[:, k, 0], P[:, 2] + off[:, 2] - ankles[:, k, 2])
        R = _LEG_FRAC * body.leg_len[k]
        ymax = ankles[:, k, 1] - off[:, 1] + np.sqrt(np.maximum(R * R - dxz * dxz, 0.0))
        P[:, 1] = _softclamp(P[:, 1], ymax)
    trans = P - rest[0]
    J, G = sk.forward_kinematics(L, rest, trans)
    for k, (hip, knee, ankle, _) in enumerate(_LEGS):
        pole = np.einsum("tij,j->ti", Ryf[:, k], _LEG_POLE[k])
        b1, b2 = body.leg[k]
        n_rest = np.cross(_LEG_POLE[k], _normalize(b1))
        G1, G2, _ = _two_bone(J[:, hip], ankles[:, k], pole, b1, b2, n_rest)
        L[:, hip] = G0.transpose(0, 2, 1) @ G1
        L[:, knee] = G1.transpose(0, 2, 1) @ G2
        L[:, ankle] = G2.transpose(0, 2, 1) @ Ryf[:, k]
    targets = np.empty((T, 2, 3))
    for k, (collar, sh, elbow, _) in enumerate(_ARMS):
        S = J[:, sh]
        free = S + np.einsum("tij,j->ti", Rpsi, _FREE_HAND[k] * s)
        w = plan.hand_w[:, k, None]
        tgt = np.where(w > 0, (1 - w) * free + w * np.nan_to_num(A[:, k]), free)
        targets[:, k] = tgt
        pole = np.einsum("tij,j->ti", Rpsi, _ARM_POLE[k])
        b1, b2 = body.arm[k]
        n_rest = np.cross(_ARM_REST_POLE, _normalize(b1))
        G1, G2, _ = _two_bone(S, tgt, pole, b1, b2, n_rest)
        L[:, sh] = G[:, collar].transpose(0, 2, 1) @ G1
        L[:, elbow] = G1.transpose(0, 2, 1) @ G2
    joints, _ = sk.forward_kinematics(L, rest, trans)
    return {"L": L, "trans": trans, "joints": joints, "hand_targets": targets, "ankles": ankles,
            "crouch": c, "crouch_fallback_frames": fallback, "crouch_infeasible_frames": infeasible}


# =========================================================================== defects
@dataclass(frozen=True)
class Defect:
    """A known defect to inject. ``kind``: ``foot_skating`` (``magnitude`` = speed, m/s),
    ``penetration`` (depth, m) or ``lost_contact`` (gap, m). ``side``: 'left'/'right' hand
    or foot, None = automatic (the foot with the longest planted run; the first hand)."""
    kind: str
    magnitude: float
    side: str | None = None

    def __post_init__(self):
        if self.kind not in ("foot_skating", "penetration", "lost_contact"):
            raise ValueError(f"Defect.kind: expected foot_skating, penetration or lost_contact, "
                             f"got {self.kind!r}")
        if not (self.magnitude > 0 and math.isfinite(self.magnitude)):
            raise ValueError(f"Defect.magnitude: expected a positive number, got {self.magnitude!r}")
        if self.side not in (None, "left", "right"):
            raise ValueError(f"Defect.side: expected None, 'left' or 'right', got {self.side!r}")

    @property
    def units(self) -> str:
        return "m/s" if self.kind == "foot_skating" else "m"


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) runs of True."""
    m = np.concatenate([[False], np.asarray(mask, bool), [False]])
    d = np.diff(m.astype(np.int8))
    return list(zip(np.where(d == 1)[0], np.where(d == -1)[0]))


def _inject_skating(plan: _Plan, d: Defect) -> dict:
    runs = {k: max(_runs(plan.planted[:, k]), key=lambda r: r[1] - r[0]) for k in (0, 1)}
    k = _HAND_INDEX[d.side] if d.side else max((0, 1), key=lambda j: runs[j][1] - runs[j][0])
    a, b = runs[k]
    n = min(b - a, _frames(1.5))
    step = d.magnitude / FPS
    K = max(1, int(math.floor(0.10 / step + 1e-9)))
    j = np.arange(n)
    tri = K - np.abs(j % (2 * K) - K)
    fwd = _ry(plan.heading[a]) @ np.array([0.0, 0.0, 1.0])
    off = np.zeros((plan.T, 3))
    off[a:a + n] = tri[:, None] * step * fwd
    end = off[a + n - 1].copy()
    i = a + n
    while i < plan.T and plan.planted[i, k]:
        off[i] = end
        i += 1
    swing = [r for r in _runs(~plan.planted[:, k]) if r[0] >= i - 1]
    if swing:
        s0, s1 = swing[0]
        u = (np.arange(s0, s1 + 1) - (s0 - 1)) / (s1 - s0 + 1)
        off[s0:s1 + 1] = end * (1 - _minjerk(u))[:, None]
    plan.foot[:, k] += off
    return {"kind": "foot_skating", "magnitude": d.magnitude, "units": "m/s",
            "side": ("left", "right")[k], "joints": [7 + k, 10 + k], "frames": [int(a), int(a + n)],
            "note": "foot joint moves speed/fps every frame in frames[0]..frames[1]-1 while "
                    "labelled planted, reversing at 0.10 m from its plant"}


def _hand_contact_side(plan: _Plan, d: Defect) -> int:
    if d.side:
        k = _HAND_INDEX[d.side]
        if not plan.contacts[:, _WRISTS[k]].any():
            raise ValueError(f"defect {d.kind}: the {d.side} hand never touches the object")
        return k
    for k in (0, 1):
        if plan.contacts[:, _WRISTS[k]].any():
            return k
    raise ValueError(f"defect {d.kind}: no hand contact in this clip")


def _offset_window(plan: _Plan, k: int, a: int, b: int, value: float, ramp: int) -> tuple[int, int]:
    """Add ``value`` to hand k's normal offset on [a, b) with min-jerk ramps of ``ramp``
    frames inside the window where it does not touch the clip ends; returns the full-value
    frames."""
    i = np.arange(plan.T)
    up = 1.0 if a == 0 else _minjerk((i - a) / ramp)
    down = 1.0 if b == plan.T else _minjerk((b - 1 - i) / ramp)
    prof = np.where((i >= a) & (i < b), np.minimum(up, down), 0.0)
    plan.hand_delta[:, k] += value * prof
    full = np.where(prof >= 1.0 - 1e-12)[0]
    return int(full[0]), int(full[-1] + 1)


def _inject_penetration(plan: _Plan, d: Defect, obj: ObjectModel, body: _Body) -> dict:
    if plan.seated is not None:
        if d.magnitude > SEAT_CLEARANCE_M * body.s:
            raise ValueError(f"defect penetration: sitting depth must be <= the seat clearance "
                             f"{SEAT_CLEARANCE_M * body.s:.3f} m, got {d.magnitude}")
        a, b = _runs(plan.seated)[0]
        i = np.arange(plan.T)
        plan.pelvis[:, 1] -= d.magnitude * np.where(i >= a, _minjerk((i - a + 1) / 8), 0.0)
        return {"kind": "penetration", "magnitude": d.magnitude, "units": "m", "side": None,
                "joints": [1, 2], "frames": [int(a + 7), int(b)],
                "note": "pelvis lowered by magnitude from the clean seated pose: the body "
                        "surface (which rests on the seat) sinks magnitude into it; the hip "
                        "joints' signed distance drops by magnitude"}
    if plan.kick is not None:
        k = plan.kick["foot"]
        a, b = plan.kick["contact"]
        fwd = np.array([0.0, 0.0, 1.0])
        n = _normalize(plan.obj_t[a] - plan.foot[a, k] + 0 * fwd)   # inward normal
        plan.foot[a:b, k] += d.magnitude * n
        return {"kind": "penetration", "magnitude": d.magnitude, "units": "m",
                "side": ("left", "right")[k], "joints": [10 + k], "frames": [int(a), int(b)],
                "note": "kicking foot joint pushed magnitude inside the ball while touching it"}
    k = _hand_contact_side(plan, d)
    a, b = _runs(plan.contacts[:, _WRISTS[k]])[0]
    p, n = plan.hand_p[a, k], plan.hand_n[a, k]
    steps = np.arange(1, 2001) * 2.5e-4                   # up to 0.5 m inward, 0.25 mm steps
    depth = -obj.sdf_local(p[None] - steps[:, None] * n[None])
    if depth.max() < d.magnitude:
        raise ValueError(f"defect penetration: {obj.name} is at most {depth.max():.4f} m thick "
                         f"under this grip, cannot push {d.magnitude} m inside")
    j = int(np.argmax(depth >= d.magnitude))
    lo, hi = (steps[j - 1] if j else 0.0), steps[j]
    for _ in range(50):                                   # bisection: sdf(p - delta n) = -depth
        mid = 0.5 * (lo + hi)
        if -obj.sdf_local(p - mid * n) < d.magnitude:
            lo = mid
        else:
            hi = mid
    fa, fb = _offset_window(plan, k, a, b, -0.5 * (lo + hi), 4)
    return {"kind": "penetration", "magnitude": d.magnitude, "units": "m",
            "side": ("left", "right")[k], "joints": [_WRISTS[k]], "frames": [fa, fb],
            "note": "wrist pushed inside along the surface normal to signed distance -magnitude "
                    "while in contact"}


def _inject_lost_contact(plan: _Plan, d: Defect) -> dict:
    if plan.seated is not None or plan.kick is not None:
        raise ValueError("defect lost_contact: needs a hand action (lift, carry, putdown, push, "
                         "pull, hold)")
    k = _hand_contact_side(plan, d)
    a, b = max(_runs(plan.contacts[:, _WRISTS[k]]), key=lambda r: r[1] - r[0])
    n = b - a
    a, b = a + n // 4, b - n // 4
    if np.linalg.norm(plan.obj_t[a:b] - plan.obj_t[a], axis=-1).max() < 0.01:
        raise ValueError("defect lost_contact: the object does not move while the hand holds it")
    fa, fb = _offset_window(plan, k, a, b, d.magnitude, 3)
    return {"kind": "lost_contact", "magnitude": d.magnitude, "units": "m",
            "side": ("left", "right")[k], "joints": [_WRISTS[k]], "frames": [fa, fb],
            "note": "wrist magnitude outside the surface along the normal while the object "
                    "moves; contact labels stay on"}


# =========================================================================== clips
@dataclass(frozen=True)
class ClipSpec:
    """What to generate: BEHAVE-style names ``Date0X_SubYY_<object>_<action>[_<index>]``
    (the suffix only for ``index`` > 1)."""
    date: str
    subject: str
    object: str
    action: str
    hands: str = "both"
    index: int = 1

    def __post_init__(self):
        if self.object not in CATALOGUE:
            raise ValueError(f"ClipSpec.object: expected one of {OBJECTS}, got {self.object!r}")
        if self.action not in CATALOGUE[self.object]:
            raise ValueError(f"ClipSpec.action: {self.object} supports "
                             f"{sorted(CATALOGUE[self.object])}, got {self.action!r}")
        if self.hands not in CATALOGUE[self.object][self.action]:
            raise ValueError(f"ClipSpec.hands: {self.object}/{self.action} supports "
                             f"{CATALOGUE[self.object][self.action]}, got {self.hands!r}")
        if self.subject not in SUBJECT_GENDER:
            raise ValueError(f"ClipSpec.subject: expected one of {SUBJECTS}, got {self.subject!r}")
        if not (len(self.date) == 6 and self.date.startswith("Date") and self.date[4:].isdigit()):
            raise ValueError(f"ClipSpec.date: expected 'Date0X', got {self.date!r}")

    @property
    def name(self) -> str:
        base = f"{self.date}_{self.subject}_{self.object}_{self.action}"
        return base if self.index <= 1 else f"{base}_{self.index}"

    @property
    def gender(self) -> str:
        return SUBJECT_GENDER[self.subject]


@dataclass
class SyntheticClip:
    """A generated clip in the y-up world (metres, 30 fps).

    ``rotations`` (T,22,3) parent-relative axis-angle (joint 0 = root orientation),
    ``trans`` (T,3) SMPL ``transl`` (posed pelvis = ``rest_joints[0] + trans``),
    ``joints`` (T,22,3) = FK(rotations, rest_joints, trans); ``obj_rot`` (T,3,3),
    ``obj_trans`` (T,3) with ``v = R v_template + t``; ``contacts`` (T,22) joints meant to
    touch the object; ``foot_planted`` (T,2) feet meant to be still (left, right);
    ``hand_contact_local`` (T,2,3) object-local wrist contact points (NaN when not in
    contact); ``segments`` [(action, start_s, end_s, hands)] relative to the first frame.
    """
    spec: ClipSpec
    seed: tuple
    betas: np.ndarray
    rest_joints: np.ndarray
    rotations: np.ndarray
    trans: np.ndarray
    joints: np.ndarray
    object: ObjectModel
    obj_rot: np.ndarray
    obj_trans: np.ndarray
    contacts: np.ndarray
    foot_planted: np.ndarray
    hand_contact_local: np.ndarray
    hand_contact_normal: np.ndarray
    segments: list
    hands: tuple
    feet: tuple
    defects: list
    world_yaw: float
    world_offset: np.ndarray
    stats: dict = field(default_factory=dict)
    fps: float = FPS

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def num_frames(self) -> int:
        return int(self.joints.shape[0])

    def object_vertices(self, frames=slice(None)) -> np.ndarray:
        """Posed object vertices (T, V, 3)."""
        return (np.einsum("tij,vj->tvi", self.obj_rot[frames], self.object.vertices)
                + self.obj_trans[frames, None])

    def object_sdf(self, points: np.ndarray, frames=slice(None)) -> np.ndarray:
        """Analytic signed distance (T, N) of per-frame world points (T, N, 3) (``frames``
        selects the object poses when ``points`` covers only some frames)."""
        return self.object.sdf(points, self.obj_rot[frames], self.obj_trans[frames])


def world_to_camera(root_orient, trans, rest_pelvis, obj_rot, obj_trans):
    """y-up world -> BEHAVE camera frame (``CAMERA_R``, ``CAMERA_C``): returns
    ``(root_orient', trans', obj_rot', obj_trans')``."""
    r, t = rigid_transform_smpl(root_orient, trans, rest_pelvis, CAMERA_R, CAMERA_C)
    return r, t, CAMERA_R @ obj_rot, np.asarray(obj_trans) @ CAMERA_R.T + CAMERA_C


def camera_to_world(root_orient, trans, rest_pelvis, obj_rot=None, obj_trans=None):
    """Inverse of :func:`world_to_camera` (``R = CAMERA_R^T``, ``c = -CAMERA_R^T CAMERA_C``)."""
    Ri = CAMERA_R.T
    ci = -Ri @ CAMERA_C
    r, t = rigid_transform_smpl(root_orient, trans, rest_pelvis, Ri, ci)
    if obj_rot is None:
        return r, t
    return r, t, Ri @ obj_rot, np.asarray(obj_trans) @ Ri.T + ci


def frame_times(n: int, offset_s: float = FRAME_TIME_OFFSET_S, fps: float = FPS) -> np.ndarray:
    """BEHAVE frame stamps ``'t%08.3f' % (offset + i / fps)`` ('t0003.033'), unicode array."""
    return np.array([f"t{offset_s + i / fps:08.3f}" for i in range(n)])


def measure_clip(clip: SyntheticClip) -> dict:
    """The physical figures of a clip (metres): planted-foot drift, hand-surface distance
    and hand-to-object-local drift during contact, lowest object point, deepest joint inside
    the object, lowest joint, and the worst distance of a labelled contact joint."""
    J = clip.joints
    out: dict[str, Any] = {}
    drift = 0.0
    for k in (0, 1):
        both = clip.foot_planted[1:, k] & clip.foot_planted[:-1, k]
        for j in (7 + k, 10 + k):
            dxz = np.linalg.norm(np.diff(J[:, j][:, [0, 2]], axis=0), axis=-1)
            if both.any():
                drift = max(drift, float(dxz[both].max()))
    out["planted_foot_drift_max_m"] = drift
    sdf = clip.object_sdf(J)                                                   # (T, 22)
    hand_d, local_drift = 0.0, 0.0
    for k, w in enumerate(_WRISTS):
        m = clip.contacts[:, w]
        if m.any():
            hand_d = max(hand_d, float(np.abs(sdf[m, w]).max()))
            loc = np.einsum("tji,tj->ti", clip.obj_rot[m], J[m, w] - clip.obj_trans[m])
            local_drift = max(local_drift, float(np.linalg.norm(loc - clip.hand_contact_local[m, k],
                                                                axis=-1).max()))
    out["hand_surface_max_m"] = hand_d
    out["hand_object_local_drift_max_m"] = local_drift
    lab = clip.contacts
    out["contact_joint_distance_max_m"] = float(np.abs(sdf[lab]).max()) if lab.any() else 0.0
    out["object_min_y_m"] = float(clip.object_vertices()[..., 1].min())
    out["joint_penetration_max_m"] = float(max(0.0, -sdf.min()))
    out["joint_min_y_m"] = float(J[..., 1].min())
    return out


def _plan_for(spec: ClipSpec, body: _Body, rng) -> tuple[_Plan, ObjectModel]:
    obj = build_object(spec.object)
    plan = _PLANNERS[spec.action](obj, spec.hands, body, rng)
    return plan, obj


def generate_clip(spec: ClipSpec, seed: int | Sequence[int] = 0,
                  defects: Sequence[Defect] | Defect | None = None) -> SyntheticClip:
    """Generate one clip, in memory, in the y-up world. Deterministic in ``(spec, seed)``;
    ``seed`` may be an int or a sequence of ints (``write_behave_layout`` uses
    ``(seed, clip index)``). ``defects`` are injected into the plan before solving."""
    seed_t = tuple(int(x) for x in (seed if isinstance(seed, (tuple, list)) else (seed,)))
    rng = np.random.default_rng(list(seed_t))
    betas = subject_betas(spec.subject)
    body = _Body(betas)
    plan, obj = _plan_for(spec, body, rng)
    world_yaw = float(np.deg2rad(rng.uniform(-30.0, 30.0)))
    world_off = np.array([rng.uniform(-0.3, 0.3), 0.0, rng.uniform(-0.3, 0.3)])
    if isinstance(defects, Defect):
        defects = [defects]
    records = []
    for d in defects or ():
        if d.kind == "foot_skating":
            records.append(_inject_skating(plan, d))
        elif d.kind == "penetration":
            records.append(_inject_penetration(plan, d, obj, body))
        else:
            records.append(_inject_lost_contact(plan, d))
    sol = _solve(plan, body, obj)
    # to the world: random yaw about y and floor offset (pelvis-offset rule)
    Rw = _ry(world_yaw)
    aa = geo.matrix_to_axis_angle(sol["L"])
    root, trans = rigid_transform_smpl(aa[:, 0], sol["trans"], body.rest[0], Rw, world_off)
    aa[:, 0] = root
    L = sol["L"].copy()
    L[:, 0] = geo.axis_angle_to_matrix(root)
    joints, _ = sk.forward_kinematics(geo.axis_angle_to_matrix(aa), body.rest, trans)
    obj_R = Rw @ plan.obj_R
    obj_t = plan.obj_t @ Rw.T + world_off
    hand_local = np.where(plan.contacts[:, list(_WRISTS), None], plan.hand_p, np.nan)
    hand_normal = np.where(plan.contacts[:, list(_WRISTS), None], plan.hand_n, np.nan)
    segs = [(a, round(s / FPS, 6), round(e / FPS, 6), h) for a, s, e, h in plan.segments]
    clip = SyntheticClip(spec, seed_t, betas, body.rest, aa, trans, joints, obj,
                         obj_R, obj_t, plan.contacts.copy(), plan.planted.copy(),
                         hand_local, hand_normal, segs, plan.hands, plan.feet, records,
                         world_yaw, world_off)
    st = measure_clip(clip)
    res = np.linalg.norm(sol["joints"][:, list(_WRISTS)] - sol["hand_targets"], axis=-1)
    res_f = np.linalg.norm(sol["joints"][:, [7, 8]] - sol["ankles"], axis=-1)
    st["ik_residual_max_m"] = float(max(res.max(), res_f.max()))
    st["crouch_fallback_frames"] = sol["crouch_fallback_frames"]
    st["crouch_infeasible_frames"] = sol["crouch_infeasible_frames"]
    st["crouch_max"] = float(sol["crouch"].max())
    for rec in records:
        a, b = rec["frames"]
        if rec["kind"] == "foot_skating":
            j = rec["joints"][1]
            step = np.linalg.norm(np.diff(joints[a:b, j][:, [0, 2]], axis=0), axis=-1)
            rec["measured_speed_mps"] = float(step.mean() * FPS)
        elif rec["kind"] == "penetration" and rec["joints"] == [1, 2]:
            clean = generate_clip(spec, seed_t, [x for x in (defects or ()) if x.kind != "penetration"])
            sd0 = clean.object_sdf(clean.joints[a:b, 1:3], slice(a, b))
            sd1 = clip.object_sdf(joints[a:b, 1:3], slice(a, b))
            rec["measured_depth_m"] = float((sd0 - sd1).mean())
        else:
            sd = clip.object_sdf(joints[a:b], slice(a, b))[:, rec["joints"]].min(-1)
            key = "measured_depth_m" if rec["kind"] == "penetration" else "measured_gap_m"
            rec[key] = float(-sd.mean() if rec["kind"] == "penetration" else sd.mean())
    clip.stats = st
    return clip


# =========================================================================== planning
def plan_clips(n_clips: int, seed: int = 0) -> list[ClipSpec]:
    """The clips of a dataset of ``n_clips``: rounds of the 8 actions (order shuffled per
    round); within an action the objects that support it take turns (order shuffled once
    per action) and cycle through their hand options; subjects Sub01-08 in turn
    (``(3 i + seed) % 8``); dates: clips with ``i % 7 in (2, 5)`` are Date03 (2/7 = 29 %, so
    the test split is non-empty from 3 clips on), the others alternate Date01 / Date02.
    Repeated (date, subject, object, action) get the suffix ``_2``, ``_3``, ..."""
    if n_clips < 0:
        raise ValueError(f"n_clips: expected >= 0, got {n_clips}")
    rng = np.random.default_rng([int(seed), 20240601])
    objs = {a: [o for o in OBJECTS if a in CATALOGUE[o]] for a in ACTIONS}
    perms = {a: [objs[a][j] for j in rng.permutation(len(objs[a]))] for a in ACTIONS}
    rounds = -(-n_clips // len(ACTIONS))
    orders = [rng.permutation(len(ACTIONS)) for _ in range(rounds)]
    specs, seen, other = [], {}, 0
    for i in range(n_clips):
        r, pos = divmod(i, len(ACTIONS))
        action = ACTIONS[orders[r][pos]]
        cyc, k = divmod(r, len(perms[action]))
        obj = perms[action][k]
        options = CATALOGUE[obj][action]
        hands = options[(cyc + k) % len(options)]
        if i % 7 in (2, 5):
            date = "Date03"
        else:
            date = ("Date01", "Date02")[other % 2]
            other += 1
        subject = SUBJECTS[(3 * i + int(seed)) % 8]
        base = (date, subject, obj, action)
        seen[base] = seen.get(base, 0) + 1
        specs.append(ClipSpec(date, subject, obj, action, hands, seen[base]))
    return specs


# =========================================================================== writing
def _behave_files(clip: SyntheticClip) -> dict[str, bytes]:
    T = clip.num_frames
    times = frame_times(T)
    J0 = clip.rest_joints[0]
    root_c, trans_c, objR_c, objt_c = world_to_camera(clip.rotations[:, 0], clip.trans, J0,
                                                      clip.obj_rot, clip.obj_trans)
    poses = np.zeros((T, 156))
    poses[:, :3] = root_c
    poses[:, 3:66] = clip.rotations[:, 1:].reshape(T, 63)
    smpl = {"poses": poses.astype(np.float32),
            "betas": np.tile(clip.betas, (T, 1)).astype(np.float32),
            "trans": trans_c.astype(np.float32),
            "save_name": np.array("fit03"), "frame_times": times}
    objf = {"angles": geo.matrix_to_axis_angle(objR_c).astype(np.float64),
            "trans": objt_c.astype(np.float64),
            "save_name": np.array("fit01"), "frame_times": times}
    info = {"config": None, "intrinsic": None, "cat": clip.spec.object, "gender": clip.spec.gender,
            "empty": None, "kinects": [0, 1, 2, 3], "beta": None}
    gt = {"joints": clip.joints, "contacts": clip.contacts, "foot_planted": clip.foot_planted,
          "obj_rot": clip.obj_rot, "obj_trans": clip.obj_trans,
          "obj_rotvec": geo.matrix_to_axis_angle(clip.obj_rot),
          "root_orient": clip.rotations[:, 0], "body_pose": clip.rotations[:, 1:].reshape(T, 63),
          "trans": clip.trans, "betas": clip.betas, "rest_joints": clip.rest_joints,
          "hand_contact_local": clip.hand_contact_local,
          "hand_contact_normal": clip.hand_contact_normal,
          "cam_R": CAMERA_R, "cam_c": CAMERA_C, "fps": np.array(FPS)}
    meta = {"name": clip.name, "generator": f"hoibench.synthetic {GENERATOR_VERSION}",
            "spec": asdict(clip.spec), "seed": list(clip.seed), "gender": clip.spec.gender,
            "object": clip.spec.object, "fps": FPS, "num_frames": T,
            "frame_time_offset_s": FRAME_TIME_OFFSET_S,
            "segments": [list(s) for s in clip.segments], "hands": list(clip.hands),
            "feet": list(clip.feet), "defects": clip.defects,
            "world": "y-up, metres, floor y=0; BEHAVE files: p_cam = cam_R p + cam_c",
            "cam_R": CAMERA_R.tolist(), "cam_c": CAMERA_C.tolist(),
            "world_yaw_rad": clip.world_yaw, "world_offset_m": clip.world_offset.tolist(),
            "contact_joints": {"hands": list(_WRISTS), "sit": [1, 2], "kick": [10, 11]},
            "stats": clip.stats}
    return {"smpl_fit_all.npz": npz_bytes(smpl), "object_fit_all.npz": npz_bytes(objf),
            "info.json": (json.dumps(info, indent=2) + "\n").encode(),
            "hoibench_gt.npz": npz_bytes(gt),
            "hoibench_gt.json": (json.dumps(meta, indent=2, sort_keys=True) + "\n").encode()}


def _write_clip(args) -> dict:
    """Pure unit of work: generate clip ``index`` of the plan and write its folder."""
    out_dir, spec, seed, index, defects = args
    clip = generate_clip(spec, (seed, index), defects)
    folder = Path(out_dir) / "sequences" / clip.name
    for fname, data in _behave_files(clip).items():
        atomic_write_bytes(folder / fname, data)
    return {"name": clip.name, "index": index, "spec": asdict(spec), "num_frames": clip.num_frames,
            "split": "test" if spec.date == "Date03" else "train",
            "segments": [list(s) for s in clip.segments], "defects": clip.defects,
            "stats": clip.stats}


def _defects_for(defects, i: int, name: str) -> list[Defect]:
    if not defects:
        return []
    d = defects.get(i, defects.get(name))
    if d is None:
        return []
    return [d] if isinstance(d, Defect) else list(d)


def write_behave_layout(out_dir: str | Path, n_clips: int, seed: int = 0,
                        defects: Mapping[int | str, Defect | Sequence[Defect]] | None = None,
                        progress: bool = True, executor: str = "serial",
                        body_model: bool = True) -> dict:
    """Generate ``n_clips`` clips (:func:`plan_clips`) and write them in the BEHAVE raw layout
    under ``out_dir`` (see the module docstring), with ``split.json``, the object templates,
    the proxy body (``body_model``) and the manifest ``hoibench_synthetic.json``.

    ``defects`` maps a clip index or name to the defect(s) injected into it. Deterministic:
    the same arguments give byte-identical files whatever ``executor``
    (:mod:`hoibench.core.parallel`: serial, processes[:N], dask://...). Returns the manifest.
    """
    out = Path(out_dir)
    specs = plan_clips(n_clips, seed)
    units = [(str(out), spec, int(seed), i, _defects_for(defects, i, spec.name))
             for i, spec in enumerate(specs)]
    for obj in sorted({s.object for s in specs}):
        m = build_object(obj)
        atomic_write_bytes(out / "objects" / obj / f"{obj}_f1000.ply",
                           ply_bytes(m.vertices, m.faces, f"hoibench synthetic {obj}"))
    from ..core.parallel import map_units
    entries = list(map_units(_write_clip, units, executor, progress="synthetic" if progress else None))
    split = {"train": sorted(e["name"] for e in entries if e["split"] == "train"),
             "test": sorted(e["name"] for e in entries if e["split"] == "test")}
    atomic_write_text(out / "split.json", json.dumps(split, indent=2) + "\n")
    if body_model:
        from ..bodies.proxy import write_proxy_model
        write_proxy_model(out / "body_models")
    manifest = {"dataset": "synthetic", "generator": f"hoibench.synthetic {GENERATOR_VERSION}",
                "layout": "behave", "seed": int(seed), "n_clips": int(n_clips), "fps": FPS,
                "cam_R": CAMERA_R.tolist(), "cam_c": CAMERA_C.tolist(),
                "objects": sorted({s.object for s in specs}),
                "split": {k: len(v) for k, v in split.items()}, "clips": entries}
    atomic_write_text(out / "hoibench_synthetic.json", json.dumps(manifest, indent=2, sort_keys=True) + "\n")
    return manifest
