"""Synthetic multi-body interactions with known contacts (license-free proxies).

Three families, three actions each (the action is the clip's label; the recognizer learns
it), every clip seeded from ``(seed, index)``:

* ``hands`` (TACO-like: two hands, a tool and a target): the left hand holds a plate at its
  rim, the right hand holds a brush standing on the plate; the brush moves relative to the
  plate periodically -- ``brush`` (back and forth), ``stir`` (circles), ``tap`` (up and
  down, touching at the bottom of each beat) -- while the plate drifts slowly.
* ``grasp`` (GRAB-like: one hand, one object): the right hand reaches an object standing
  still, touches it and moves it -- ``lift``, ``pass`` (lift and move sideways), ``shake``
  (lift and shake).
* ``carry`` (CORE4D-like: two people, one box): two people face each other holding a box
  between their hands -- ``carry`` (side-step along the box), ``turn`` (the group turns
  about the box), ``shuffle`` (the group moves towards one person).

Hands are the proxy MANO hand (:class:`hoibench.bodies.proxy_hand.ProxyHand`, 16 joints +
5 tips); people are the 22-joint SMPL skeleton posed by forward kinematics. A body rests on
what it holds: it is placed so its capsule surface (:mod:`hoibench.bodies.capsules`, the
model the metrics use) is :data:`GAP_M` from the object's surface. Ground-truth contacts
are computed from the clip with the metrics' own rules (:func:`contact_frames`), so the
ground truth scores what the metrics define.

:func:`inject` makes defective copies: ``desync`` (one body delayed), ``lost_contact`` (the
held object pulled away for the second half), ``interpenetration`` (a hand pushed into the
object it holds).
"""
from __future__ import annotations

import dataclasses
from functools import lru_cache

import numpy as np

from ..core import geometry as geo
from ..core.skeleton import NUM_JOINTS, SMPL_REST_JOINTS, forward_kinematics
from ..bodies.multibody import Body, MultiBodyClip
from ..bodies.capsules import (ObjectField, hand_root_points, object_fields, pair_contact_frames, skeleton_object_distance)

__all__ = ["FAMILIES", "ACTIONS", "FPS", "GENERATOR_VERSION", "GAP_M", "CSR_THRESHOLD_M", "CRR_THRESHOLD_M",
           "templates", "plan", "generate", "contact_frames", "inject", "DEFECTS", "caption"]

GENERATOR_VERSION = "multibody-synthetic-1.0"
FAMILIES = {"hands": ("brush", "stir", "tap"), "grasp": ("lift", "pass", "shake"),
            "carry": ("carry", "turn", "shuffle")}
ACTIONS = tuple(a for acts in FAMILIES.values() for a in acts)
FPS = 20.0
#: distance a holding body's surface is placed from the object's surface, metres
GAP_M = 0.001
CSR_THRESHOLD_M = 0.005
CRR_THRESHOLD_M = 0.05
DEFECTS = ("desync", "lost_contact", "interpenetration")
_GRASP_OBJECTS = ("cube", "can", "ball")


# --------------------------------------------------------------------------- templates
@lru_cache(maxsize=1)
def templates() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Closed template meshes (vertices centred on their mean, metres, y-up) by name."""
    import trimesh

    def centred(m):
        v = np.asarray(m.vertices, np.float64)
        return v - v.mean(0), np.asarray(m.faces, np.int64)

    def upright(m):          # trimesh's cylinders run along z: stand them along y
        m = m.copy()
        m.apply_transform(trimesh.transformations.rotation_matrix(-np.pi / 2, [1, 0, 0]))
        return m

    return {
        "plate": centred(upright(trimesh.creation.cylinder(radius=0.09, height=0.015, sections=32))),
        "brush": centred(trimesh.creation.box(extents=(0.025, 0.14, 0.03))),
        "cube": centred(trimesh.creation.box(extents=(0.06, 0.06, 0.06))),
        "can": centred(upright(trimesh.creation.cylinder(radius=0.033, height=0.11, sections=24))),
        "ball": centred(trimesh.creation.icosphere(subdivisions=2, radius=0.04)),
        "carrybox": centred(trimesh.creation.box(extents=(0.5, 0.3, 0.4))),
    }


def _half_height(name: str) -> float:
    return float(templates()[name][0][:, 1].max())


# --------------------------------------------------------------------------- plan
def plan(n_clips: int, seed: int = 0) -> list[tuple[int, str, str]]:
    """``(index, family, action)`` of ``n_clips`` clips, cycling through the 9 actions."""
    return [(i, fam, act) for i, (fam, act) in zip(range(n_clips), _cycle())]


def _cycle():
    pairs = [(f, a) for f, acts in FAMILIES.items() for a in acts]
    while True:
        yield from pairs


def caption(action: str, rng: np.random.Generator | None = None) -> str:
    texts = {
        "brush": "a person brushes a plate with a brush, holding the plate in the left hand",
        "stir": "someone moves a brush in circles on a plate held in the other hand",
        "tap": "a person taps a brush up and down on a plate",
        "lift": "a right hand picks up the {o} and lifts it",
        "pass": "a hand lifts the {o} and moves it to the side",
        "shake": "a person lifts the {o} and shakes it",
        "carry": "two people carry a box together, stepping sideways",
        "turn": "two people holding a box turn around together",
        "shuffle": "two people move a box towards one of them",
    }
    return texts[action]


# --------------------------------------------------------------------------- helpers
def _smoothstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def _yaw(theta) -> np.ndarray:
    theta = np.asarray(theta, np.float64)
    c, s = np.cos(theta), np.sin(theta)
    R = np.zeros(theta.shape + (3, 3))
    R[..., 0, 0], R[..., 0, 2], R[..., 1, 1], R[..., 2, 0], R[..., 2, 2] = c, s, 1.0, -s, c
    return R


def _hand_local(side: str, flex: float) -> np.ndarray:
    """(21, 3) joints of a proxy hand with its wrist at the origin, identity orientation,
    fingers flexed by ``flex`` rad at every finger joint (about the hand's lateral axis)."""
    from ..bodies.proxy_hand import ProxyHand
    hand = ProxyHand(side)
    pose = np.zeros(45)
    axis = np.array([0.0, 0.0, 1.0 if side == "right" else -1.0])
    for j in range(15):
        if j // 3 == 4:           # thumb: a little only
            pose[3 * j:3 * j + 3] = 0.3 * flex * axis
        else:
            pose[3 * j:3 * j + 3] = flex * axis
    _, J = hand.forward(np.zeros(3), pose, tips=True)
    return J[0] - J[0, 0]


def _rigid_body(name: str, template: str, R: np.ndarray, t: np.ndarray) -> Body:
    return Body(name, "object", np.asarray(t, np.float64), np.asarray(R, np.float64), None, template)


def _hand_on(obj: Body, local_joints: np.ndarray, anchor_local: np.ndarray, name: str, side: str,
             frame: int = 0) -> Body:
    """A hand rigidly attached to ``obj`` in the object's frame: its joints ``local_joints``
    (wrist at the origin) are moved so joint ``anchor`` sits above ``anchor_local`` (object
    frame), then lowered until its surface is :data:`GAP_M` from the object's surface."""
    v, f = templates()[obj.template]
    field = ObjectField(v, f)
    J = local_joints + anchor_local
    ident = Body("probe", "object", np.zeros((1, 3)), np.eye(3)[None], None, obj.template)
    for _ in range(3):                  # settle onto the surface (vertical moves)
        probe = Body(name, "hand", J[None, 0], None, J[None], None, side)
        d = float(skeleton_object_distance(probe, field, ident)[0])
        J = J - np.array([0.0, d - GAP_M, 0.0])
    world = np.einsum("tij,kj->tki", obj.rot, J) + obj.trans[:, None]
    return Body(name, "hand", world[:, 0].copy(), obj.rot.copy(), world, None, side)


# --------------------------------------------------------------------------- families
def _hands(action: str, rng: np.random.Generator, T: int) -> tuple[list[Body], dict]:
    t = np.arange(T) / FPS
    plate_h, brush_h = _half_height("plate"), _half_height("brush")
    yaw0 = rng.uniform(-0.6, 0.6)
    drift = rng.uniform(0.01, 0.03)
    phase = rng.uniform(0, 2 * np.pi)
    R_p = _yaw(yaw0 + 0.1 * np.sin(2 * np.pi * 0.2 * t))
    t_p = np.stack([drift * np.sin(2 * np.pi * 0.25 * t + phase), np.full(T, 0.95 + rng.uniform(-0.05, 0.05)),
                    0.35 + drift * np.cos(2 * np.pi * 0.25 * t + phase)], -1)
    plate = _rigid_body("plate", "plate", R_p, t_p)
    f = rng.uniform(1.2, 2.0)
    A = rng.uniform(0.025, 0.04)
    w = 2 * np.pi * f * t
    rel = np.zeros((T, 3))
    rel[:, 1] = plate_h + brush_h + GAP_M
    if action == "brush":
        rel[:, 0] = A * np.sin(w)
    elif action == "stir":
        rel[:, 0], rel[:, 2] = A * np.cos(w), A * np.sin(w)
    else:                                                  # tap
        rel[:, 1] += 0.04 * (1 - np.cos(w)) / 2
    brush = _rigid_body("brush", "brush", R_p, np.einsum("tij,tj->ti", R_p, rel) + t_p)
    left_local = _hand_local("left", rng.uniform(0.05, 0.2))
    # the middle finger's tip 2 cm inside the rim: the palm and the fingers' roots off the plate
    left = _hand_on(plate, left_local, np.array([-0.072 - left_local[18, 0], 0.05, -left_local[18, 2]]),
                    "left_hand", "left")
    right_local = _hand_local("right", rng.uniform(0.1, 0.3))
    right_local = right_local - right_local[4] * np.array([1, 0, 1])   # the middle finger's base over the brush
    right = _hand_on(brush, right_local, np.array([0.0, 0.12, 0.0]), "right_hand", "right")
    return [left, right, plate, brush], {"frequency_hz": f, "amplitude_m": A}


def _grasp(action: str, rng: np.random.Generator, T: int, obj_name: str) -> tuple[list[Body], dict]:
    t = np.arange(T) / FPS
    h = _half_height(obj_name)
    base = np.array([rng.uniform(-0.1, 0.1), 0.8 + h, rng.uniform(0.3, 0.45)])
    yaw = rng.uniform(-0.8, 0.8)
    t1 = int(rng.integers(T // 5, T // 3))
    s = _smoothstep((np.arange(T) - t1) / max(1, (T - t1) * 0.6))
    move = np.zeros((T, 3))
    if action == "lift":
        move[:, 1] = rng.uniform(0.15, 0.3) * s
    elif action == "pass":
        move[:, 1] = 0.1 * s
        move[:, 0] = rng.choice([-1, 1]) * rng.uniform(0.2, 0.35) * s
    else:                                                    # shake
        move[:, 1] = 0.15 * s
        move[:, 1] += 0.04 * np.sin(2 * np.pi * rng.uniform(1.5, 2.5) * t) * s
    R = _yaw(np.full(T, yaw))
    obj = _rigid_body("object", obj_name, R, base + move)
    local = _hand_local("right", rng.uniform(0.05, 0.3))
    local = local - local[4] * np.array([1, 0, 1])
    held = _hand_on(obj, local, np.array([0.0, h + 0.05, 0.0]), "right_hand", "right")
    # before t1 the hand approaches from above and aside
    approach = (1 - _smoothstep(np.arange(T) / max(1, t1)))[:, None] * np.array([0.15, 0.12, -0.1])
    J = held.joints + approach[:, None]
    hand = Body("right_hand", "hand", J[:, 0].copy(), held.rot, J, None, "right")
    return [hand, obj], {"grasp_frame": t1}


def _rot_z(theta: float) -> np.ndarray:
    return np.asarray(geo.axis_angle_to_matrix(np.array([0.0, 0.0, float(theta)])))


def _carry_pose(T: int, stride: np.ndarray, arm_drop: float) -> np.ndarray:
    """(T, 22, 3, 3) local rotations: both arms forward (+z) and ``arm_drop`` rad down,
    holding; hips swing by ``stride`` rad and knees bend with them."""
    R = np.repeat(np.eye(3)[None, None], T, 0).repeat(NUM_JOINTS, 1)
    R[:, 16] = _yaw(-np.pi / 2) @ _rot_z(-arm_drop)         # left arm: +x -> forward, down
    R[:, 17] = _yaw(np.pi / 2) @ _rot_z(arm_drop)           # right arm: -x -> forward, down
    R[:, 1] = geo.rotation_about_x(stride)
    R[:, 2] = geo.rotation_about_x(-stride)
    R[:, 4] = geo.rotation_about_x(np.abs(stride) * 1.2)
    R[:, 5] = geo.rotation_about_x(np.abs(stride) * 1.2)
    return R


def _carry(action: str, rng: np.random.Generator, T: int) -> tuple[list[Body], dict]:
    t = np.arange(T) / FPS
    rest = np.asarray(SMPL_REST_JOINTS, np.float64)
    s = _smoothstep(t / t[-1])
    speed_hz = rng.uniform(1.2, 1.8)
    moving = np.gradient(s) > 1e-4
    stride = 0.25 * np.sin(2 * np.pi * speed_hz * t) * moving
    local = _carry_pose(T, stride, rng.uniform(0.2, 0.4))
    foot = rest[:, 1].min()
    # pose one person at the origin facing +z to find the hands' reach
    probe, _ = forward_kinematics(local[:1], rest, np.array([[0.0, -foot + 0.04, 0.0]]))
    hand_pts = hand_root_points(Body("p", "human", probe[:, 0], None, probe))[0]
    reach = float(hand_pts[:, 2].mean())
    height = float(hand_pts[:, 1].mean())
    half = 0.25
    d = reach + half + 0.02           # hand capsule end 2 cm from the box face (capsule radius 3 cm)
    yaw0 = rng.uniform(0, 2 * np.pi)
    centre0 = np.array([rng.uniform(-0.3, 0.3), height, rng.uniform(-0.3, 0.3)])
    if action == "carry":
        group_yaw = np.full(T, yaw0)
        centre = centre0 + s[:, None] * (_yaw(yaw0) @ np.array([0.0, 0.0, rng.uniform(0.8, 1.4)]))
    elif action == "turn":
        group_yaw = yaw0 + s * rng.choice([-1, 1]) * rng.uniform(1.2, 1.8)
        centre = np.repeat(centre0[None], T, 0)
    else:                                                                  # shuffle
        group_yaw = np.full(T, yaw0)
        centre = centre0 + s[:, None] * (_yaw(yaw0) @ np.array([rng.uniform(0.5, 0.9), 0.0, 0.0]))
    G = _yaw(group_yaw)
    box = _rigid_body("box", "carrybox", G, centre)
    bodies = []
    for name, sign in (("person1", -1.0), ("person2", 1.0)):
        face = _yaw(group_yaw + (np.pi / 2 if sign < 0 else -np.pi / 2))   # facing the box
        rots = local.copy()
        rots[:, 0] = face
        root_world = centre + np.einsum("tij,j->ti", G, np.array([sign * d, 0.0, 0.0]))
        # FK puts the pelvis at rest[0] + trans: choose trans so the pelvis lands below root_world
        pelvis = root_world.copy()
        pelvis[:, 1] = rest[0, 1] - foot + 0.04
        J, _ = forward_kinematics(rots, rest, pelvis - rest[0])
        bodies.append(Body(name, "human", J[:, 0].copy(), face, J))
    return bodies + [box], {"reach_m": reach, "stride_hz": speed_hz}


# --------------------------------------------------------------------------- clips
def generate(index: int, family: str, action: str, seed: int = 0) -> MultiBodyClip:
    """One clip (deterministic in ``(seed, index)``)."""
    if family not in FAMILIES or action not in FAMILIES[family]:
        raise ValueError(f"generate: unknown family/action {family!r}/{action!r}")
    rng = np.random.default_rng([int(seed), int(index), 7711])
    T = int(rng.integers(60, 90))
    obj_name = None
    if family == "hands":
        bodies, params = _hands(action, rng, T)
    elif family == "grasp":
        obj_name = _GRASP_OBJECTS[int(rng.integers(0, len(_GRASP_OBJECTS)))]
        bodies, params = _grasp(action, rng, T, obj_name)
    else:
        bodies, params = _carry(action, rng, T)
    used = {b.template for b in bodies if b.template}
    name = f"mb{index:04d}_{family}_{action}"
    clip = MultiBodyClip(name, "multibody-synthetic", f"S{index % 6:02d}", FPS, bodies,
                         {k: templates()[k] for k in sorted(used)}, {}, action,
                         [{"text": caption(action).format(o=obj_name or "object"), "start": None, "end": None,
                           "source": "template"}],
                         None, {"generator": GENERATOR_VERSION, "seed": [int(seed), int(index)], "family": family,
                                "params": {k: float(v) for k, v in params.items()}})
    clip.contacts = contact_frames(clip)
    return clip


def contact_frames(clip: MultiBodyClip, fields: dict[str, ObjectField] | None = None) -> dict[tuple[str, str], np.ndarray]:
    """Per (skeleton, object) pair, the frames in contact by the metrics' rules at the
    track's thresholds (:data:`CSR_THRESHOLD_M`, :data:`CRR_THRESHOLD_M`;
    :func:`hoibench.bodies.capsules.pair_contact_frames`)."""
    return pair_contact_frames(clip, fields or object_fields(clip), CSR_THRESHOLD_M, CRR_THRESHOLD_M)


def inject(clip: MultiBodyClip, defect: str, frames: int = 6) -> MultiBodyClip:
    """A defective copy of ``clip`` (see the module docstring); contacts recomputed."""
    if defect not in DEFECTS:
        raise ValueError(f"inject: defect {defect!r}: expected one of {DEFECTS}")
    bodies = [dataclasses.replace(b) for b in clip.bodies]
    T = clip.num_frames
    holder = next(b for b in bodies if not b.is_rigid)
    held = next(b for b in bodies if b.is_rigid)
    if defect == "desync":
        idx = np.clip(np.arange(T) - frames, 0, T - 1)             # the first skeleton lags
        holder.trans = holder.trans[idx]
        holder.joints = holder.joints[idx]
        holder.rot = None if holder.rot is None else holder.rot[idx]
    elif defect == "lost_contact":
        away = np.zeros((T, 3))
        away[T // 2:, 1] = -0.08                                   # the object drops 8 cm
        held.trans = held.trans + away
    else:                                                          # interpenetration
        if holder.kind == "human":                                 # every joint 6 cm towards the box
            push = held.trans[:, None] - holder.joints
            push = 0.06 * push / np.linalg.norm(push, axis=-1, keepdims=True)
        else:                                                      # the hand 2 cm down into its object
            push = np.array([0.0, -0.02, 0.0])
        holder.joints = holder.joints + push
        holder.trans = holder.joints[:, 0].copy()
    out = dataclasses.replace(clip, bodies=bodies, contacts={}, provenance={**clip.provenance, "defect": defect})
    out.contacts = contact_frames(out)
    return out
