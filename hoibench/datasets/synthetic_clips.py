"""``synthetic_clips``: clip specifications, one clip generated in memory, and the dataset plan.

:class:`ClipSpec` (what to generate, with its BEHAVE-style name), :class:`SyntheticClip` (a
generated clip in the y-up world), :func:`measure_clip` (its physical figures),
:func:`generate_clip` (plan, defects, solve, world placement, measured ``stats``) and
:func:`plan_clips` (the clips of a dataset of ``n``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from ..core import geometry as geo
from ..core import skeleton as sk
from ..bodies.transform import rigid_transform_smpl
from .synthetic_actions import _PLANNERS, _Plan
from .synthetic_body import _Body, subject_betas
from .synthetic_constants import ACTIONS, CATALOGUE, FPS, OBJECTS, SUBJECT_GENDER, SUBJECTS, _WRISTS, _ry
from .synthetic_defects import Defect, _inject_lost_contact, _inject_penetration, _inject_skating
from .synthetic_objects import ObjectModel, build_object
from .synthetic_solve import _solve


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
