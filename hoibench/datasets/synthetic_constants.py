"""``synthetic_constants``: the vocabulary and fixed constants of the synthetic HOI dataset.

The actions, objects and hands, the object -> action -> hands catalogue, the subjects
(gender, body scale), the BEHAVE camera transform, the physical tolerances and the
motion-model constants shared by the parts of :mod:`hoibench.datasets.synthetic` (whose
docstring describes the motion model, the guarantees and the camera frame).
"""
from __future__ import annotations

import math

import numpy as np

from ..core import geometry as geo


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
