"""hoibench's synthetic clips written in the OMOMO and RICH raw layouts, with ground truth.

The clips are :mod:`hoibench.datasets.synthetic`'s (the same plan, motion model and proxy
body: :func:`~hoibench.datasets.synthetic.plan_clips` and
:func:`~hoibench.datasets.synthetic.generate_clip`, seeded from ``(seed, clip index)``), so
``hoibench.datasets.omomo`` and ``hoibench.datasets.rich`` run end to end without licensed
files and their output can be checked against known joints, object vertices and contacts.
Every file is byte-identical for the same arguments.

OMOMO layout (:func:`write_omomo_layout`)::

    OUT/train_diffusion_manip_seq_joints24.p, OUT/test_diffusion_manip_seq_joints24.p
        joblib pickles {int: sequence dict} with OMOMO's keys: seq_name
        'sub<N>_<object>_<take:03d>', gender, betas (1, 16), trans / root_orient (T, 3),
        pose_body (T, 63), rest_offsets (24, 3), trans2joint (3,) (= trans - pelvis =
        -rest pelvis), obj_trans (T, 3, 1), obj_rot (T, 3, 3), obj_scale (T,), obj_com_pos
        (T, 3) (vertex mean of the posed object); float32 like the release; z-up world
        (the generator's y-up world rotated by +90 degrees about x), floor at z = 0
    OUT/captured_objects/<object>_cleaned_simplified.obj   not centred (the base's centre
        at the origin plus an offset) and divided by the object's scale
        (:data:`OMOMO_OBJECT_SCALE`), so ``s R v + t`` gives the generator's vertices
    OUT/omomo_text_anno_json_data/<seq_name>.json   {seq_name: sentence} (every sixth clip
        has none, as OMOMO's annotations cover about 84 % of the sequences)
    OUT/hoibench_gt/<seq_name>.npz + .json   ground truth in the y-up world (not OMOMO)
    OUT/body_models/smplx/SMPLX_{MALE,FEMALE,NEUTRAL}.npz   the proxy body (SMPL-X structure)
    OUT/hoibench_synthetic.json   the manifest

Subjects: the generator's Sub01-08 become OMOMO subjects :data:`OMOMO_SUBJECT` (Sub03 and
Sub07 are 16 and 17: the test split).

RICH layout (:func:`write_rich_layout`)::

    OUT/bodies/<split>/<seq>/<frame:05d>/<sub:03d>.pkl    pickled dict of (1, D) float32:
        betas (10), global_orient, body_pose (63), left/right_hand_pose (12-D PCA),
        jaw_pose, leye_pose, reye_pose, expression (10), transl -- in camera 0's frame
    OUT/human_scene_contact/<split>/<seq>/<frame:05d>/<sub:03d>.pkl   {'contact': (6890,)}
    OUT/multicam2world/<Scene>[_chair]_multicam2world.json   {"R", "t", "c"}: camera 0 ->
        z-up world as ``c * X @ R + t`` (ParkingLot1 has c != 1)
    OUT/resource/gender.json, OUT/resource/meta/{train,val,test}.txt   as rich_toolkit's
    OUT/hoibench_gt/<seq>_<sub>.npz + .json   ground truth: frame ids, y-up joints, contacts
    OUT/body_models/smplx/ (the proxy, SMPL-X) and OUT/body_models/smplh/ (the proxy in
        SMPL topology: skinning weights for the contact labels)
    OUT/hoibench_synthetic.json

A RICH sequence ``<Scene>_<sub:03d>_<action><k>`` is one generated clip, or (every third
one) two takes of its action by the same subject (two clips generated from their own seeds)
with a gap of 2-4 frame ids between them (the gap hides the change of take; the loader must
split there). Frame ids start at 3-18. The scene is
static, so the object is dropped; contact labels mark every third SMPL-topology vertex of
each joint in contact -- the generator's contact joints plus the planted feet (ankle and
foot joints) -- so the per-joint ground truth is exactly those joints. The camera-frame
body is the world body scaled by ``1/c`` (the proxy's ``beta_0`` scales it uniformly), so
``c * X @ R + t`` maps it back exactly.
"""
from __future__ import annotations

import dataclasses
import io
import json
import os
import pickle
import tempfile
from pathlib import Path

import numpy as np

from ..core import geometry as geo
from ..bodies.proxy import PROXY_SCALE_PER_BETA, ProxyBody, write_proxy_model
from ..bodies.transform import rigid_transform_smpl
from ..core.io import atomic_write_bytes, atomic_write_text, npz_bytes
from .omomo import PICKLES, ZUP_TO_YUP
from .rich_contacts import SMPL_NUM_VERTICES, vertex_joint_map
from .synthetic import FPS, GENERATOR_VERSION, OBJECTS, SyntheticClip, build_object, generate_clip, plan_clips

__all__ = ["OMOMO_SUBJECT", "OMOMO_OBJECT_SCALE", "RICH_SCENES", "write_omomo_layout", "write_rich_layout"]

#: y-up -> z-up (the inverse of the loaders' z-up -> y-up): +90 degrees about x.
YUP_TO_ZUP = ZUP_TO_YUP.T
#: generator subject -> OMOMO subject number (16 and 17 are OMOMO's test subjects).
OMOMO_SUBJECT = {"Sub01": 1, "Sub02": 4, "Sub03": 16, "Sub04": 7, "Sub05": 10, "Sub06": 12,
                 "Sub07": 17, "Sub08": 14}
#: per-object scale of the OMOMO templates (``v = s R v_obj + t``).
OMOMO_OBJECT_SCALE = {o: round(0.8 + 0.1 * (k % 5), 2) for k, o in enumerate(OBJECTS)}
#: (scene, scan name, json name, scale c) of the synthetic RICH captures.
RICH_SCENES = (("BBQ", "scan_camcoord", "BBQ_multicam2world.json", 1.0),
               ("Gym", "scan_camcoord", "Gym_multicam2world.json", 1.0),
               ("ParkingLot1", "scan_camcoord", "ParkingLot1_multicam2world.json", 0.97),
               ("LectureHall", "scan_chair_scene_camcoord", "LectureHall_chair_multicam2world.json", 1.0))
_VERBS = {"lift": "lifts", "carry": "carries", "putdown": "puts down", "push": "pushes", "pull": "pulls",
          "sit": "sits on", "kick": "kicks", "hold": "holds"}
_HANDS = {"both": " with both hands", "left": " with the left hand", "right": " with the right hand", "none": ""}
_FEET = ((7, 10), (8, 11))


def _write_frame_file(path: Path, data: bytes) -> None:
    """Write a per-frame file atomically (temporary file + rename) but without ``fsync``:
    a RICH layout has thousands of tiny files and the data can be regenerated at will."""
    path.parent.mkdir(parents=True, exist_ok=True)
    from ..core.io import TMP_PREFIX, current_umask
    fd, tmp = tempfile.mkstemp(prefix=f"{TMP_PREFIX}{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        os.fchmod(fd, 0o666 & ~current_umask())
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _sentence(clip: SyntheticClip) -> str:
    s = clip.spec
    return f"A person {_VERBS[s.action]} the {s.object}{_HANDS[s.hands]}."


def _joblib_bytes(obj) -> bytes:
    try:
        import joblib
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("writing OMOMO's pickles needs the 'joblib' package: pip install joblib") from exc
    buf = io.BytesIO()
    joblib.dump(obj, buf)
    return buf.getvalue()


def _obj_text(vertices: np.ndarray, faces: np.ndarray, comment: str) -> str:
    lines = [f"# {comment}"]
    lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in vertices.tolist()]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces.tolist()]
    return "\n".join(lines) + "\n"


def _world_params(clip: SyntheticClip):
    """Root orientation (T, 3), trans (T, 3) of the clip's body and its rest pelvis."""
    return clip.rotations[:, 0], clip.trans, clip.rest_joints[0]


# =========================================================================== OMOMO
def _omomo_object(obj: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(file vertices, faces, offset o, scale s): ``s v_file = v_centred + o``."""
    m = build_object(obj)
    s = OMOMO_OBJECT_SCALE[obj]
    o = np.array([0.0, -m.vertices[:, 1].min(), 0.0]) + np.array([0.05, 0.0, -0.03])
    return (m.vertices + o) / s, m.faces, o, s


def _omomo_sequence(clip: SyntheticClip, seq_name: str) -> tuple[dict, dict]:
    T = clip.num_frames
    root_w, trans_w, j0 = _world_params(clip)
    Z = YUP_TO_ZUP
    root_z, trans_z = rigid_transform_smpl(root_w, trans_w, j0, Z, np.zeros(3))
    _, _, o, s = _omomo_object(clip.spec.object)
    R = Z @ clip.obj_rot                                   # z-up object rotation
    t = clip.obj_trans @ Z.T - R @ o                       # so that s R v_file + t = Z (R_g v_c + t_g)
    posed = np.einsum("tij,vj->tvi", R, clip.object.vertices + o) + t[:, None]
    body = ProxyBody("smplx")
    J = body.rest_joints * (1.0 + PROXY_SCALE_PER_BETA * clip.betas[0])
    parents24 = list(body.parents[:22]) + [20, 21]
    J24 = np.concatenate([J[:22], J[[25, 40]]])
    offsets = np.concatenate([J24[:1], np.stack([J24[k] - J24[parents24[k]] for k in range(1, 24)])])
    betas = np.zeros((1, 16))
    betas[0, :len(clip.betas)] = clip.betas
    f32 = lambda x: np.asarray(x, dtype=np.float32)  # noqa: E731
    seq = {"seq_name": seq_name, "gender": clip.spec.gender, "betas": f32(betas),
           "trans": f32(trans_z), "root_orient": f32(root_z),
           "pose_body": f32(clip.rotations[:, 1:].reshape(T, 63)),
           "rest_offsets": f32(offsets), "trans2joint": f32(-J[0]),
           "obj_trans": f32(t[:, :, None]), "obj_rot": f32(R), "obj_scale": np.full(T, s, dtype=np.float32),
           "obj_com_pos": f32(posed.mean(1))}
    gt = {"joints": clip.joints, "contacts": clip.contacts, "foot_planted": clip.foot_planted,
          "obj_rot": clip.obj_rot, "obj_trans": clip.obj_trans, "object_vertices": clip.object.vertices,
          "object_faces": clip.object.faces, "object_scale": np.float64(s), "template_offset": o,
          "betas": clip.betas, "rest_joints": clip.rest_joints, "fps": np.float64(FPS)}
    return seq, gt


def write_omomo_layout(out_dir: str | Path, n_clips: int, seed: int = 0, body_model: bool = True) -> dict:
    """Write ``n_clips`` synthetic clips in OMOMO's processed-release layout under ``out_dir``
    (see the module docstring) with ground truth beside them. Deterministic in
    ``(n_clips, seed)``. Returns the manifest (also written as ``hoibench_synthetic.json``)."""
    out = Path(out_dir)
    specs = plan_clips(n_clips, seed)
    data = {"train": {}, "test": {}}
    entries, takes = [], {}
    for i, spec in enumerate(specs):
        clip = generate_clip(spec, (int(seed), i))
        sub = OMOMO_SUBJECT[spec.subject]
        key = (sub, spec.object)
        takes[key] = takes.get(key, -1) + 1
        name = f"sub{sub}_{spec.object}_{takes[key]:03d}"
        seq, gt = _omomo_sequence(clip, name)
        split = "test" if sub in (16, 17) else "train"
        data[split][len(data[split])] = seq
        has_text = i % 6 != 5
        if has_text:
            atomic_write_text(out / "omomo_text_anno_json_data" / f"{name}.json",
                              json.dumps({name: _sentence(clip)}) + "\n")
        atomic_write_bytes(out / "hoibench_gt" / f"{name}.npz", npz_bytes(gt))
        meta = {"name": name, "source_clip": clip.name, "spec": dataclasses.asdict(spec), "seed": list(clip.seed),
                "split": split, "num_frames": clip.num_frames, "fps": FPS, "text": has_text,
                "object_scale": OMOMO_OBJECT_SCALE[spec.object],
                "world": "ground truth in the generator's y-up world (floor y = 0); files: z-up, p_zup = "
                         "Rx(+90 deg) p_yup", "stats": clip.stats}
        atomic_write_text(out / "hoibench_gt" / f"{name}.json", json.dumps(meta, indent=2, sort_keys=True) + "\n")
        entries.append(meta)
    for split, fname in PICKLES.items():
        atomic_write_bytes(out / fname, _joblib_bytes(data[split]))
    for obj in sorted({s.object for s in specs}):
        v, f, _, s = _omomo_object(obj)
        atomic_write_text(out / "captured_objects" / f"{obj}_cleaned_simplified.obj",
                          _obj_text(v, f, f"hoibench synthetic {obj}, OMOMO layout: v = {s} R v_file + t"))
    if body_model:
        write_proxy_model(out / "body_models", "smplx")
    manifest = {"dataset": "synthetic", "layout": "omomo", "generator": f"hoibench.synthetic {GENERATOR_VERSION}",
                "seed": int(seed), "n_clips": int(n_clips), "fps": FPS,
                "split": {k: len(v) for k, v in data.items()},
                "objects": {o: OMOMO_OBJECT_SCALE[o] for o in sorted({s.object for s in specs})},
                "clips": entries}
    atomic_write_text(out / "hoibench_synthetic.json", json.dumps(manifest, indent=2, sort_keys=True) + "\n")
    return manifest


# =========================================================================== RICH
def _rich_transform(k: int, seed: int) -> tuple[np.ndarray, np.ndarray, float]:
    scene, _, _, c = RICH_SCENES[k]
    rng = np.random.default_rng([int(seed), 7411, k])
    axis = rng.normal(size=3)
    R = geo.axis_angle_to_matrix(axis / np.linalg.norm(axis) * rng.uniform(0.6, 2.5))
    t = rng.uniform(-3.0, 3.0, 3)
    return R, t, c


def _camera_frames(clip: SyntheticClip, R: np.ndarray, t: np.ndarray, c: float, rng) -> list[dict]:
    """Per-frame RICH body dicts: the y-up world body in camera 0's frame, scaled by 1/c."""
    T = clip.num_frames
    root_w, trans_w, j0 = _world_params(clip)
    M = R @ YUP_TO_ZUP                                     # y-up world -> camera rotation
    s_w = 1.0 + PROXY_SCALE_PER_BETA * clip.betas[0]
    b0 = (s_w / c - 1.0) / PROXY_SCALE_PER_BETA
    root_c = geo.matrix_to_axis_angle(M @ geo.axis_angle_to_matrix(root_w))
    pelvis_c = ((j0 + trans_w) @ YUP_TO_ZUP.T - t) @ R.T / c
    transl_c = pelvis_c - j0 / c
    betas = np.array(clip.betas, dtype=np.float64)
    betas[0] = b0
    f32 = lambda x: np.asarray(x, dtype=np.float32)[None]  # noqa: E731
    frames = []
    for i in range(T):
        frames.append({"betas": f32(betas), "global_orient": f32(root_c[i]),
                       "body_pose": f32(clip.rotations[i, 1:].reshape(63)),
                       "left_hand_pose": f32(rng.normal(0.0, 0.3, 12)),
                       "right_hand_pose": f32(rng.normal(0.0, 0.3, 12)),
                       "jaw_pose": f32(rng.normal(0.0, 0.05, 3)), "leye_pose": f32(rng.normal(0.0, 0.05, 3)),
                       "reye_pose": f32(rng.normal(0.0, 0.05, 3)), "expression": f32(rng.normal(0.0, 0.5, 10)),
                       "transl": f32(transl_c[i])})
    return frames


def _joint_contact_truth(clip: SyntheticClip) -> np.ndarray:
    c = clip.contacts.copy()
    for k, (ankle, foot) in enumerate(_FEET):
        c[:, ankle] |= clip.foot_planted[:, k]
        c[:, foot] |= clip.foot_planted[:, k]
    return c


def _vertex_labels(joint_contacts: np.ndarray, vmap: np.ndarray) -> np.ndarray:
    """(T, 6890) labels: every third vertex of each joint in contact."""
    members = [np.flatnonzero(vmap == j)[::3] for j in range(joint_contacts.shape[1])]
    out = np.zeros((len(joint_contacts), len(vmap)), dtype=np.float32)
    for t, row in enumerate(joint_contacts):
        for j in np.flatnonzero(row):
            out[t, members[j]] = 1.0
    return out


def _rich_split(i: int) -> str:
    return "test" if i % 7 in (2, 5) else ("val" if i % 7 == 4 else "train")


def write_rich_layout(out_dir: str | Path, n_clips: int, seed: int = 0, body_model: bool = True) -> dict:
    """Write ``n_clips`` synthetic RICH sequences (each one or two generated clips, see the
    module docstring) in RICH's release layout under ``out_dir``, with ground truth.
    Deterministic in ``(n_clips, seed)``. Returns the manifest."""
    out = Path(out_dir)
    specs = plan_clips(n_clips, seed)
    vmap = vertex_joint_map(ProxyBody("smplh").weights)
    assert len(vmap) == SMPL_NUM_VERTICES
    transforms = [_rich_transform(k, seed) for k in range(len(RICH_SCENES))]
    for k, (_, _, jname, _) in enumerate(RICH_SCENES):
        R, t, c = transforms[k]
        atomic_write_text(out / "multicam2world" / jname,
                          json.dumps({"R": R.tolist(), "t": t.tolist(), "c": c}, indent=1) + "\n")
    genders, meta_lines, entries, names = {}, {"train": [], "val": [], "test": []}, [], {}
    for i, spec in enumerate(specs):
        k = i % len(RICH_SCENES)
        scene, scan, jname, _ = RICH_SCENES[k]
        R, t, c = transforms[k]
        sub = f"{int(spec.subject[3:]):03d}"
        key = (scene, sub, spec.action)
        names[key] = names.get(key, 0) + 1
        seq = f"{scene}_{sub}_{spec.action}{names[key]}"
        split = _rich_split(i)
        clips = [generate_clip(spec, (int(seed), i))]
        if i % 3 == 1:
            # a second take of the same action (a RICH sequence is one action; the annotator
            # reads it from the sequence name), generated from its own seed
            partner = dataclasses.replace(spec, index=spec.index + 1)
            clips.append(generate_clip(partner, (int(seed), i, 1)))
        rng = np.random.default_rng([int(seed), 9173, i])
        start = 3 + 5 * (i % 4)
        gap = 2 + i % 3
        ids, joints, contacts, runs = [], [], [], []
        for n, clip in enumerate(clips):
            first = start if n == 0 else ids[-1] + 1 + gap
            fid = list(range(first, first + clip.num_frames))
            runs.append([fid[0], fid[-1]])
            jc = _joint_contact_truth(clip)
            labels = _vertex_labels(jc, vmap)
            for f, body in zip(fid, _camera_frames(clip, R, t, c, rng)):
                _write_frame_file(out / "bodies" / split / seq / f"{f:05d}" / f"{sub}.pkl",
                                  pickle.dumps(body, protocol=4))
            for f, lab in zip(fid, labels):
                _write_frame_file(out / "human_scene_contact" / split / seq / f"{f:05d}" / f"{sub}.pkl",
                                  pickle.dumps({"contact": lab}, protocol=4))
            ids += fid
            joints.append(clip.joints)
            contacts.append(jc)
        genders[str(int(sub))] = spec.gender
        meta_lines[split].append("\t".join([seq, scene, scan, sub, "X", spec.gender, "V", "V", "X"]))
        gt = {"frame_ids": np.array(ids, dtype=np.int64), "joints": np.concatenate(joints),
              "contacts": np.concatenate(contacts), "fps": np.float64(FPS)}
        atomic_write_bytes(out / "hoibench_gt" / f"{seq}_{sub}.npz", npz_bytes(gt))
        meta = {"sequence": seq, "subject": sub, "split": split, "scene": scene, "multicam2world": jname,
                "c": c, "runs": runs, "gender": spec.gender, "source_clips": [cl.name for cl in clips],
                "seeds": [list(cl.seed) for cl in clips], "fps": FPS,
                "world": "ground truth in the generator's y-up world (floor y = 0); files: camera 0, "
                         "X_world_zup = c * X @ R + t, p_zup = Rx(+90 deg) p_yup"}
        atomic_write_text(out / "hoibench_gt" / f"{seq}_{sub}.json", json.dumps(meta, indent=2, sort_keys=True) + "\n")
        entries.append(meta)
    atomic_write_text(out / "resource" / "gender.json", json.dumps(dict(sorted(genders.items()))) + "\n")
    for split, lines in meta_lines.items():
        atomic_write_text(out / "resource" / "meta" / f"{split}.txt", "\n".join(lines) + ("\n" if lines else ""))
    if body_model:
        write_proxy_model(out / "body_models", "smplx")
        write_proxy_model(out / "body_models", "smplh")
    manifest = {"dataset": "synthetic", "layout": "rich", "generator": f"hoibench.synthetic {GENERATOR_VERSION}",
                "seed": int(seed), "n_clips": int(n_clips), "fps": FPS,
                "scenes": [{"scene": s, "scan": sc, "multicam2world": j, "c": c} for s, sc, j, c in RICH_SCENES],
                "sequences": entries}
    atomic_write_text(out / "hoibench_synthetic.json", json.dumps(manifest, indent=2, sort_keys=True) + "\n")
    return manifest

