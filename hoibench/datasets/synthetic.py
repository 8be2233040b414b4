"""``synthetic``: a deterministic procedural HOI dataset in the BEHAVE raw layout.

hoibench's embedded default data (docs/datasets.md, "synthetic (embedded default)"): clips of a person lifting, carrying,
putting down, pushing, pulling, sitting on, kicking and holding primitive-built objects,
written exactly like BEHAVE's release so that ``hoibench prepare behave`` runs end to end on
it, with the ground truth beside every sequence so that metrics can be checked against
known contacts, known foot skating and known penetration.

This module writes the BEHAVE layout and is the one the package imports from; the generator
lives in its parts, re-exported here: :mod:`~hoibench.datasets.synthetic_constants` (names,
catalogue, camera, tolerances), :mod:`~hoibench.datasets.synthetic_objects` (object shapes
and meshes), :mod:`~hoibench.datasets.synthetic_body` (subject bodies, IK primitives),
:mod:`~hoibench.datasets.synthetic_actions` (per-action motion plans),
:mod:`~hoibench.datasets.synthetic_solve` (plan -> joint rotations),
:mod:`~hoibench.datasets.synthetic_defects` (defect injection) and
:mod:`~hoibench.datasets.synthetic_clips` (clip specs, clip generation, dataset plan).

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
from dataclasses import asdict
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from ..core import geometry as geo
from ..bodies.transform import rigid_transform_smpl
from ..core.io import atomic_write_bytes, atomic_write_text, npz_bytes
# the generator's parts, re-exported: this module is the one the package imports from
from .synthetic_body import rest_joints, subject_betas
from .synthetic_clips import ClipSpec, SyntheticClip, generate_clip, measure_clip, plan_clips
from .synthetic_constants import (ACTIONS, CAMERA_C, CAMERA_OFFSET_M, CAMERA_R, CAMERA_TILT_X_DEG,
                                  CAMERA_TILT_Z_DEG, CATALOGUE, FPS, FRAME_TIME_OFFSET_S, GENERATOR_VERSION,
                                  HANDS, JOINT_PENETRATION_TOL_M, OBJECTS, SEAT_CLEARANCE_M, SIT_CONTACT_TOL_M,
                                  SUBJECT_BETA0, SUBJECT_GENDER, SUBJECTS, _WRISTS)
from .synthetic_defects import Defect
from .synthetic_objects import ObjectModel, build_object, ply_bytes

__all__ = [
    "FPS", "ACTIONS", "OBJECTS", "CATALOGUE", "SUBJECT_GENDER", "SUBJECT_BETA0",
    "CAMERA_R", "CAMERA_C", "FRAME_TIME_OFFSET_S", "JOINT_PENETRATION_TOL_M",
    "ClipSpec", "Defect", "ObjectModel", "SyntheticClip",
    "build_object", "plan_clips", "generate_clip", "write_behave_layout",
    "rigid_transform_smpl", "world_to_camera", "subject_betas",
    "rest_joints", "frame_times", "measure_clip", "ply_bytes",
]


# =========================================================================== camera frame
def world_to_camera(root_orient, trans, rest_pelvis, obj_rot, obj_trans):
    """y-up world -> BEHAVE camera frame (``CAMERA_R``, ``CAMERA_C``): returns
    ``(root_orient', trans', obj_rot', obj_trans')``."""
    r, t = rigid_transform_smpl(root_orient, trans, rest_pelvis, CAMERA_R, CAMERA_C)
    return r, t, CAMERA_R @ obj_rot, np.asarray(obj_trans) @ CAMERA_R.T + CAMERA_C


def frame_times(n: int, offset_s: float = FRAME_TIME_OFFSET_S, fps: float = FPS) -> np.ndarray:
    """BEHAVE frame stamps ``'t%08.3f' % (offset + i / fps)`` ('t0003.033'), unicode array."""
    return np.array([f"t{offset_s + i / fps:08.3f}" for i in range(n)])


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
