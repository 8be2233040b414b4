"""InterAct (Xu et al., CVPR 2025) processed release -> :class:`HOISequence` clips.

InterAct converts BEHAVE, GRAB, InterCap, OMOMO, NeuralDome, IMHD and CHAIRS into one
per-sequence format. ``ROOT`` is InterAct's ``data/`` folder::

    ROOT/<source>/sequences_canonical/<name>/human.npz    poses (T, P), betas (B,) | vtemp (10475, 3) (GRAB),
                                                           trans (T, 3), gender (str)
    ROOT/<source>/sequences_canonical/<name>/object.npz   angles (T, 3) axis-angle, trans (T, 3), name (str)
    ROOT/<source>/sequences_canonical/<name>/text.txt     one "caption#tokens#from#to" line per text
    ROOT/<source>/sequences_canonical/<name>/markers.npy  (T, 77, 3) body markers (optional)
    ROOT/<source>/objects/<object>/<object>.obj            object mesh; sample_points.npy beside it
    ROOT/test.txt, ROOT/test_seq.txt                       object split / sequence split (test ids)

(``joints.npy`` and ``motion.npy`` are InterAct's derived arrays; hoibench recomputes the
joints with the user's body models and does not read them.)

Facts and where they come from (GitHub ``wzyabcas/InterAct``, commit ``daa7945``):

* Keys: ``data_demo.ipynb`` and ``process/canonicalize_human.py`` read ``human.npz``
  ``poses``, ``betas``, ``trans``, ``gender`` (GRAB: ``vtemp`` instead of ``betas``) and
  ``object.npz`` ``angles``, ``trans``, ``name``; the text loader
  (``text2interaction/data_loaders/behave/data/dataset.py``) splits each ``text.txt`` line
  at ``#``: caption, then tokens.
* Bodies (``canonicalize_human.py`` ``visualize_smpl`` / ``visualize_grab``, mirrored in
  ``process/motion_representation.py``): BEHAVE SMPL-H, 10 betas, ``smplx.create`` with
  axis-angle hands (``flat_hand_mean`` False: smplx's default); NeuralDome and IMHD SMPL-H,
  16 betas, human_body_prior ``BodyModel`` (no hand mean: flat); CHAIRS SMPL-X, 10 betas,
  axis-angle hands (not flat), jaw/eyes at pose columns 156..164 when present; InterCap
  SMPL-X, 10 betas, 12 PCA hand components per hand with ``flat_hand_mean=True``; OMOMO
  SMPL-X, 16 betas, ``BodyModel`` (flat); GRAB SMPL-X with the subject template ``vtemp``
  as ``v_template``, 24 PCA hand components, not flat, no betas. PCA coefficients are turned
  into axis-angle with the user's model's hand components (``coeffs @ components[:k]``), which
  poses the same mesh.
* World: the canonical sequences are y-up metres (the canonicalisation rotates about y and
  lifts the floor with ``trans[..., 1] -= min y``; the representation's ground marker sets
  ``y = 0``), at 30 fps (``eval_marker_representation.py``: ``fps = 30``). hoibench keeps this
  frame (no further floor shift), so markers and object poses stay in InterAct's frame.
* Objects: ``object vertices = R(angles) @ mesh vertex + trans`` with the ``.obj`` read by
  ``trimesh.load`` (default processing); hoibench centres the template on its vertex mean
  and moves the mean into the translation. ``sample_points.npy`` (the evaluator's object
  points) is kept per clip in the same centred frame.
* Splits: ``dataset.py`` takes a sequence as test when its object name is in ``test.txt``
  (object split, ``--obj_split``) or its folder name is in ``test_seq.txt`` (sequence split:
  the default, and what ``text2interaction/scripts/eval.sh`` evaluates on).

Clip ids are ``<source>-<sequence>``; object names ``<source>-<object>`` (the same name,
e.g. ``chair``, is a different object in different sources). Each clip records its source
dataset in the provenance (``source_dataset``). ARCTIC and ParaHome (articulated,
several object files per sequence) are not read.
"""
from __future__ import annotations

import io
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..bodies.markers import markers_from_vertices
from ..core import geometry as geo
from ..core.ids import check_id
from ..core.io import load_raw_npz, read_regular_file
from .behave import SequenceError, _lerp, _slerp_resample, read_mesh, resample_rigid, resample_times
from .sequence import BodyParams, HOISequence

SOURCE_FPS = 30.0
SEQUENCES = "sequences_canonical"
SPLIT_FILES = {"object": "test.txt", "sequence": "test_seq.txt"}


@dataclass(frozen=True)
class SourceSpec:
    """How InterAct poses one source's bodies: model type, betas (or ``vtemp``), hand
    convention (``pca``: components per hand, 0 = axis-angle) and ``flat_hand_mean``."""

    model_type: str
    num_betas: int
    pca: int
    flat_hand_mean: bool
    vtemp: bool = False


SOURCES: dict[str, SourceSpec] = {
    "behave": SourceSpec("smplh", 10, 0, False),
    "neuraldome": SourceSpec("smplh", 16, 0, True),
    "imhd": SourceSpec("smplh", 16, 0, True),
    "chairs": SourceSpec("smplx", 10, 0, False),
    "intercap": SourceSpec("smplx", 10, 12, True),
    "omomo": SourceSpec("smplx", 16, 0, True),
    "grab": SourceSpec("smplx", 10, 24, False, vtemp=True),
}


def _npz(path: Path, name: str) -> dict:
    if not path.is_file():
        raise SequenceError(f"{name}: missing file {path.name}")
    try:
        return load_raw_npz(path, what=path.name)
    except Exception as exc:
        raise SequenceError(f"{name}: {path.name}: unreadable ({type(exc).__name__}: {exc})") from None


def _float(d: dict, key: str, shape: tuple, name: str, file: str) -> np.ndarray:
    """``d[key]`` as float64 with ``shape`` (None = any length), real and finite."""
    if key not in d:
        raise SequenceError(f"{name}: {file}: missing key {key!r}")
    a = np.asarray(d[key])
    if a.dtype.kind not in "fi" or a.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, a.shape)):
        want = "(" + ", ".join("T" if s is None else str(s) for s in shape) + ")"
        raise SequenceError(f"{name}: {file}: {key}: expected real numbers of shape {want}, got {a.dtype} {a.shape}")
    a = a.astype(np.float64)
    if not np.all(np.isfinite(a)):
        raise SequenceError(f"{name}: {file}: {key}: non-finite value at index {tuple(np.argwhere(~np.isfinite(a))[0])}")
    return a


def _string(d: dict, key: str, name: str, file: str) -> str:
    if key not in d or np.asarray(d[key]).dtype.kind not in "US" or np.asarray(d[key]).size != 1:
        raise SequenceError(f"{name}: {file}: {key}: expected a string")
    return str(np.asarray(d[key]).reshape(-1)[0])


def read_texts(path: Path, name: str) -> list[dict]:
    """``text.txt``: one entry per non-empty line; ``text`` is the caption (the line's part
    before the first ``#``, surrounding whitespace removed as InterAct's loader does) and
    ``tokens`` the part after it, both verbatim."""
    if not path.is_file():
        return []
    raw = read_regular_file(path, 4 << 20, "text.txt").decode("utf-8")
    out = []
    for line in raw.splitlines():
        parts = line.strip().split("#")
        if parts[0]:
            out.append({"text": parts[0], "tokens": parts[1] if len(parts) > 1 else "", "start": None, "end": None,
                        "source": "interact", "line": line.strip()})
    return out


@lru_cache(maxsize=16)
def _model(model_dir: str, model_type: str, gender: str, num_betas: int, flat: bool):
    from ..bodies.smpl import load_body_model
    return load_body_model(model_dir, model_type, gender, num_betas=num_betas, flat_hand_mean=flat)


@lru_cache(maxsize=16)
def _hand_components(model_dir: str, model_type: str, gender: str, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The first ``k`` PCA hand components (left, right), each (k, 45), of the user's model."""
    from ..bodies.smpl import load_body_model
    m = load_body_model(model_dir, model_type, gender, use_pca=True, num_pca_comps=k)
    return (m.left_hand_components.detach().cpu().numpy().astype(np.float64),
            m.right_hand_components.detach().cpu().numpy().astype(np.float64))


def hoibench_poses(poses: np.ndarray, spec: SourceSpec, comps: tuple | None, name: str) -> np.ndarray:
    """InterAct's pose rows -> hoibench's axis-angle layout (SMPL-H / SMPL-X 156, SMPL-X 165
    when jaw and eyes are given)."""
    k = spec.pca
    if k:
        need = 66 + 2 * k
        if poses.shape[1] < need:
            raise SequenceError(f"{name}: human.npz: poses: {poses.shape[1]} columns, {need} expected "
                                f"(root, body, {k} PCA components per hand)")
        left = poses[:, 66:66 + k] @ comps[0]
        right = poses[:, 66 + k:66 + 2 * k] @ comps[1]
        return np.concatenate([poses[:, :66], left, right], 1)
    if poses.shape[1] < 156:
        raise SequenceError(f"{name}: human.npz: poses: {poses.shape[1]} columns, at least 156 expected")
    if spec.model_type == "smplx" and spec.num_betas == 10 and poses.shape[1] >= 165:
        return np.concatenate([poses[:, :66], poses[:, 156:165], poses[:, 66:156]], 1)
    return poses[:, :156]


def _resample(T: int, fps: float):
    src = np.arange(T) / SOURCE_FPS
    return src, resample_times(src, fps)


def load_sequence(seq_dir: str, objects_root: str, body_models: str, source: str, fps: float = SOURCE_FPS
                  ) -> HOISequence:
    """One InterAct sequence folder -> :class:`HOISequence` at ``fps`` (SequenceError naming
    the sequence, file and field for bad input)."""
    from ..bodies.smpl import body_forward, load_body_model, model_path
    seq_dir = Path(seq_dir)
    name = seq_dir.name
    spec = SOURCES[source]
    h = _npz(seq_dir / "human.npz", name)
    o = _npz(seq_dir / "object.npz", name)
    poses = _float(h, "poses", (None, None), name, "human.npz")
    T = len(poses)
    trans = _float(h, "trans", (T, 3), name, "human.npz")
    gender = _string(h, "gender", name, "human.npz").lower()
    angles = _float(o, "angles", (T, 3), name, "object.npz")
    o_trans = _float(o, "trans", (T, 3), name, "object.npz")
    obj = check_id(_string(o, "name", name, "object.npz"), "object name", f"{name}: object.npz")
    comps = _hand_components(body_models, spec.model_type, gender, spec.pca) if spec.pca else None
    aa = hoibench_poses(poses, spec, comps, name)
    src_t, dst_t = _resample(T, fps)
    P = aa.shape[1] // 3
    aa = _slerp_resample(src_t, dst_t, aa.reshape(T, P, 3)).reshape(len(dst_t), -1)
    trans = _lerp(src_t, dst_t, trans)
    if spec.vtemp:
        vtemp = _float(h, "vtemp", (10475, 3), name, "human.npz")
        model = load_body_model(body_models, "smplx", gender, flat_hand_mean=spec.flat_hand_mean,
                                v_template=vtemp.astype(np.float32))
        betas = None
    else:
        betas = _float(h, "betas", (None,), name, "human.npz")[:spec.num_betas]
        try:
            model = _model(body_models, spec.model_type, gender, spec.num_betas, spec.flat_hand_mean)
        except ValueError as exc:                       # a model file with fewer shape components
            raise SequenceError(f"{name}: {exc}") from None
    joints, verts = body_forward(model, aa, betas, trans)
    markers_src = "computed from the posed body"
    markers = markers_from_vertices(verts).astype(np.float64)
    mpath = seq_dir / "markers.npy"
    if mpath.is_file():
        m = np.load(io.BytesIO(read_regular_file(mpath, 256 << 20, "markers.npy")), allow_pickle=False)
        if m.shape != (T, 77, 3) or m.dtype.kind != "f" or not np.all(np.isfinite(m)):
            raise SequenceError(f"{name}: markers.npy: expected finite floats of shape ({T}, 77, 3), got "
                                f"{m.dtype} {m.shape}")
        markers = _lerp(src_t, dst_t, m.reshape(T, -1).astype(np.float64)).reshape(-1, 77, 3)
        markers_src = "markers.npy"
    R, t = resample_rigid(src_t, dst_t, geo.axis_angle_to_matrix(angles), o_trans)
    mesh_path = Path(objects_root) / obj / f"{obj}.obj"
    if not mesh_path.is_file():
        raise SequenceError(f"{name}: object {obj!r}: mesh {mesh_path} not found")
    v, f = read_mesh(mesh_path, f"{name}: object {obj!r}", process=True)
    mean = v.mean(0)
    arrays = {"markers": markers.astype(np.float32), "object_origin": (-mean).astype(np.float64)}
    spath = Path(objects_root) / obj / "sample_points.npy"
    if spath.is_file():
        p = np.load(io.BytesIO(read_regular_file(spath, 64 << 20, "sample_points.npy")), allow_pickle=False)
        if p.ndim != 2 or p.shape[1] != 3 or p.dtype.kind != "f":
            raise SequenceError(f"{name}: {spath.name}: expected (P, 3) floats, got {p.dtype} {p.shape}")
        arrays["object_sample_points"] = (p - mean).astype(np.float32)
    prov = {"source": "interact", "source_dataset": source, "sequence": name, "source_fps": SOURCE_FPS,
            "resampled_to_fps": float(fps), "source_frames": T, "template": f"{obj}.obj",
            "template_mean_subtracted": mean.tolist(), "markers": markers_src,
            "object_origin": "InterAct's object frame origin in the centred template (-mean): its BPS anchor",
            "body_model_file": str(model_path(body_models, "smplx" if spec.vtemp else spec.model_type, gender)),
            "body_model_betas": int(model.num_betas),
            "body": (f"{spec.model_type}, subject template vtemp (body parameters not stored)" if spec.vtemp else
                     f"{spec.model_type}, {spec.num_betas} betas, flat_hand_mean={spec.flat_hand_mean}"
                     + (f", {spec.pca} PCA hand components converted to axis-angle" if spec.pca else "")),
            "raw_source": f"{source}/{SEQUENCES}/{name}/ (human.npz, object.npz, text.txt), "
                          f"{source}/objects/{obj}/{obj}.obj"}
    body = None if spec.vtemp else BodyParams(spec.model_type, gender, betas.astype(np.float32), aa.astype(np.float32),
                                              trans.astype(np.float32), flat_hand_mean=spec.flat_hand_mean)
    seq = HOISequence(
        name=f"{source}-{name}", dataset="interact", subject=name.split("_")[0], fps=float(fps),
        joints=joints[:, :22].astype(np.float32), object_name=f"{source}-{obj}", object_vertices=v - mean,
        object_faces=f, obj_rot=R, obj_trans=t + R @ mean, body=body,
        texts=read_texts(seq_dir / "text.txt", name), provenance=prov, extra_arrays=arrays)
    return seq


def write_texts(out: str | Path, manifest: dict) -> int:
    """``DATA/texts/<clip>.txt`` of every prepared clip from its InterAct texts, one
    ``caption#tokens#0.0#0.0`` line each (whole-clip captions: InterAct's loader ignores the
    line's time tags and uses every caption for the whole sequence). Returns the files written."""
    import json
    from ..core.io import atomic_write_text
    from .store import Store
    st, n = Store(out), 0
    for c in manifest.get("clips", []):
        clip = st.load(c["id"], keys=("texts",))
        texts = [json.loads(str(t)) for t in np.asarray(clip.get("texts", [])).ravel()]  # read-ok: strings of a clip read through the store
        lines = [f"{t['text']}#{t.get('tokens', '')}#0.0#0.0" for t in texts if t.get("source") == "interact"]
        if lines:
            atomic_write_text(Path(out) / "texts" / f"{c['id']}.txt", "\n".join(lines) + "\n")
            n += 1
    return n


def read_test_ids(root: Path, split: str) -> set[str]:
    """The test ids of ``split`` (``object``: object names from ``test.txt``; ``sequence``:
    sequence names from ``test_seq.txt``)."""
    if split not in SPLIT_FILES:
        raise ValueError(f"--split: expected object or sequence, got {split!r}")
    path = Path(root) / SPLIT_FILES[split]
    if not path.is_file():
        raise FileNotFoundError(f"--root: no {SPLIT_FILES[split]} in {root} (InterAct's {split} split; its "
                                f"repository ships it in data/)")
    return {line.strip() for line in read_regular_file(path, 16 << 20, path.name).decode().splitlines()
            if line.strip()}


def prepare_jobs(root: str | Path, body_models: str | Path, out: str | Path, config, split_file=None,
                 sources: str | None = None, split: str = "sequence") -> list[tuple]:
    """One :func:`hoibench.datasets.store.run_unit` job per sequence of the chosen sources
    (default: every supported source folder present under ``root``)."""
    from .store import fail_unit, file_sha256, refuse_duplicates, refused_id_job
    if split_file is not None:
        raise ValueError("prepare interact: --split-file is not used; choose --split object|sequence")
    root = Path(root)
    wanted = [s.strip() for s in sources.split(",")] if sources else [s for s in SOURCES if (root / s).is_dir()]
    unknown = [s for s in wanted if s not in SOURCES]
    if unknown:
        raise ValueError(f"--sources: {unknown[0]!r} is not an InterAct source hoibench reads "
                         f"(known: {', '.join(SOURCES)})")
    if not wanted:
        raise FileNotFoundError(f"--root: none of {', '.join(SOURCES)} under {root} (expected InterAct's data/ folder)")
    test = read_test_ids(root, split)
    jobs, where = [], []
    for src in wanted:
        seqs = root / src / SEQUENCES
        if not seqs.is_dir():
            raise FileNotFoundError(f"--root: no {src}/{SEQUENCES} in {root}")
        for seq in sorted(p for p in seqs.iterdir() if p.is_dir()):
            clip = f"{src}-{seq.name}"
            refused = refused_id_job(clip, "sequence folder", seqs, out, config.mode)
            if refused:
                jobs.append(refused)
                where.append(str(seq))
                continue
            try:
                from ..core.io import load_raw_npz
                obj = str(load_raw_npz(seq / "object.npz", what="InterAct object.npz", keys=("name",))["name"])
            except Exception:        # the unit reports it when it loads
                obj = ""
            is_test = (obj in test) if split == "object" else (seq.name in test)
            loader, args = load_sequence, (str(seq), str(root / src / "objects"), str(body_models), src, config.fps)
            if not obj:
                loader, args = fail_unit, (f"{clip}: object.npz: unreadable or without 'name'",)
            files = [seq / n for n in ("human.npz", "object.npz", "text.txt", "markers.npy")]
            files += [root / src / "objects" / obj / f"{obj}.obj", root / src / "objects" / obj / "sample_points.npy"]
            jobs.append((clip, "test" if is_test else "train", file_sha256(files, extra=config.sha256() + split),
                         str(out), loader, args, config.mode))
            where.append(str(seq))
    return refuse_duplicates(jobs, where)


__all__ = ["SOURCES", "SourceSpec", "SOURCE_FPS", "load_sequence", "prepare_jobs", "read_texts", "read_test_ids",
           "write_texts",
           "hoibench_poses"]
