"""hoibench's multi-body exchange layout -> multi-body store.

A folder any multi-body data can be written into (hoibench's synthetic multi-body data is,
with :func:`write_synthetic_layout`; a user's own capture can be)::

    ROOT/sequences/<id>.npz     one MultiBodyClip's arrays (hoibench.bodies.multibody,
                                MultiBodyClip.to_arrays: layout "multibody-1.0", body_names,
                                body_kinds, body_sides, body_templates, body_owners,
                                body<i>_trans / _rot / _joints, contact_pairs,
                                contact_frames, action, texts, provenance), y-up metres
    ROOT/objects/<template>.obj the object templates the sequences name (any mesh trimesh
                                reads; centred on their vertex mean when prepared, the
                                poses moved so posed vertices are unchanged)
    ROOT/split.json             {"train": [ids], "test": [ids], ...} (optional: all "train")
    ROOT/hoibench_synthetic.json  present when the data is hoibench's synthetic set

Files are read with ``allow_pickle=False``. Clips are resampled by time to the store's fps
when their own differs (slerp for rotations, linear for positions; contact frames take the
nearest source frame).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..core.ids import InvalidIdError, check_id
from ..bodies.multibody import MultiBodyClip, check_clip, is_multibody_arrays
from .behave import SequenceError, _lerp, load_split_file, read_mesh, resample_rigid, resample_times

__all__ = ["SequenceError", "load_sequence", "prepare_jobs", "write_synthetic_layout", "dataset_name"]

MARKER = "hoibench_synthetic.json"


def dataset_name(root: str | Path) -> str:
    return "multibody-synthetic" if (Path(root) / MARKER).exists() else "multibody"


def _template(path: Path, name: str, seq: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(centred vertices, faces, the subtracted mean) of ``objects/<name>.obj``."""
    from ..core import plausibility as pl
    if not path.is_file():
        raise SequenceError(f"{seq}: body template {name!r}: missing {path.parent.name}/{path.name}")
    try:
        v, f = pl.check_template(*read_mesh(path, f"{seq}: template {name!r}"), f"{seq}: template {path.name}")
    except ValueError as exc:
        raise SequenceError(str(exc)) from None
    mean = v.mean(0)
    return v - mean, f, mean


def load_sequence(path: str | Path, objects: str | Path, fps: float, clip_id: str, dataset: str) -> MultiBodyClip:
    """One ``sequences/<id>.npz`` -> MultiBodyClip at ``fps`` (see the module docstring);
    SequenceError naming the file and field."""
    from ..core.io import load_raw_npz
    path = Path(path)
    try:
        z = load_raw_npz(path, what="multi-body sequence")
    except Exception as exc:
        raise SequenceError(f"{clip_id}: {path.name}: unreadable ({type(exc).__name__}: {exc})") from None
    if not is_multibody_arrays(z):
        raise SequenceError(f"{clip_id}: {path.name}: 'layout' missing or not a multi-body layout")
    try:
        clip = MultiBodyClip.from_arrays(z)
    except KeyError as exc:
        raise SequenceError(f"{clip_id}: {path.name}: missing key {exc}") from None
    except (ValueError, TypeError, IndexError) as exc:
        raise SequenceError(f"{clip_id}: {path.name}: {exc}") from None
    src_fps = float(clip.fps)
    if not np.isfinite(src_fps) or src_fps <= 0:
        raise SequenceError(f"{clip_id}: {path.name}: fps: expected a positive number, got {src_fps}")
    templates = {}
    for b in clip.bodies:
        if b.kind == "object":
            if not b.template:
                raise SequenceError(f"{clip_id}: {path.name}: body {b.name!r}: an object needs a template name")
            try:
                check_id(b.template, "template name", path.name)
            except InvalidIdError as exc:
                raise SequenceError(f"{clip_id}: {exc}") from None
            v, f, mean = _template(Path(objects) / f"{b.template}.obj", b.template, clip_id)
            templates[b.template] = (v, f)
            if b.rot is not None:           # keep posed vertices: t' = t + R mean
                b.trans = b.trans + np.einsum("tij,j->ti", b.rot, mean)
    clip.templates = templates
    clip.name, clip.dataset = clip_id, dataset
    T = clip.num_frames
    if T < 2:
        raise SequenceError(f"{clip_id}: {path.name}: {T} frame(s); a clip needs at least 2")
    if abs(src_fps - fps) > 1e-9:
        src_t = np.arange(T) / src_fps
        dst = resample_times(src_t, fps)
        for b in clip.bodies:
            if b.rot is not None:
                b.rot, b.trans = resample_rigid(src_t, dst, b.rot, b.trans)
            else:
                b.trans = _lerp(src_t, dst, b.trans)
            if b.joints is not None:
                b.joints = _lerp(src_t, dst, b.joints.reshape(T, -1)).reshape(len(dst), -1, 3)
        nearest = np.clip(np.searchsorted(src_t, dst - 0.5 / src_fps), 0, T - 1)
        clip.contacts = {k: v[nearest] for k, v in clip.contacts.items()}
        clip.fps = float(fps)
    clip.provenance = {**clip.provenance, "source": "hoibench multi-body layout", "source_file": path.name,
                       "source_fps": src_fps, "resampled_to_fps": float(fps)}
    try:
        check_clip(clip)
    except ValueError as exc:
        raise SequenceError(f"{clip_id}: {path.name}: {exc}") from None
    return clip


def prepare_jobs(root: str | Path, body_models, out: str | Path, config, split_file: str | Path | None = None
                 ) -> list[tuple]:
    """One job per ``ROOT/sequences/<id>.npz`` (``body_models`` is not used: the layout
    holds joints). The split is ``split_file``, else ``ROOT/split.json``, else "train"."""
    from .store import fail_unit, file_sha256, refuse_duplicates, refused_id_job
    root = Path(root)
    seq_dir = root / "sequences"
    if not seq_dir.is_dir():
        raise FileNotFoundError(f"--root: no 'sequences' folder in {root} (expected hoibench's multi-body layout)")
    split_path = Path(split_file) if split_file else (root / "split.json" if (root / "split.json").exists() else None)
    splits = load_split_file(split_path) if split_path else None
    dataset = dataset_name(root)
    objs = sorted((root / "objects").glob("*.obj")) if (root / "objects").is_dir() else []
    jobs, sources = [], []
    for p in sorted(seq_dir.glob("*.npz")):
        cid = p.stem
        refused = refused_id_job(cid, "sequence file name", seq_dir, out, config.mode)
        if refused:
            jobs.append(refused)
            sources.append(str(p))
            continue
        split = splits.get(cid, "unknown") if splits is not None else "train"
        sha = file_sha256([p, *objs], extra=f"{cid}|{dataset}|" + config.sha256())
        loader, args = load_sequence, (str(p), str(root / "objects"), float(config.fps), cid, dataset)
        if split == "unknown":
            loader, args = fail_unit, (f"{cid}: not listed in split file {split_path}",)
        jobs.append((cid, split, sha, str(out), loader, args, config.mode))
        sources.append(str(p))
    return refuse_duplicates(jobs, sources)


def write_synthetic_layout(out: str | Path, n_clips: int, seed: int = 0) -> dict:
    """hoibench's synthetic multi-body clips (:mod:`hoibench.datasets.synthetic_multibody`) in the
    layout above; every fourth clip is test. Byte-identical for the same arguments."""
    from ..core.io import atomic_write_bytes, atomic_write_text, npz_bytes
    from . import synthetic_multibody as syn
    if int(n_clips) < 1:
        raise ValueError(f"--clips: expected at least 1, got {n_clips}")
    out = Path(out)
    split: dict[str, list[str]] = {"train": [], "test": []}
    entries = []
    used = set()
    for i, fam, act in syn.plan(n_clips, seed):
        clip = syn.generate(i, fam, act, seed)
        atomic_write_bytes(out / "sequences" / f"{clip.name}.npz", npz_bytes(clip.to_arrays()))
        split["test" if i % 4 == 3 else "train"].append(clip.name)
        used |= set(clip.templates)
        entries.append({"id": clip.name, "family": fam, "action": act, "frames": clip.num_frames,
                        "bodies": clip.signature()})
    for name in sorted(used):
        v, f = syn.templates()[name]
        lines = [f"v {a:.9f} {b:.9f} {c:.9f}" for a, b, c in v] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f]
        atomic_write_text(out / "objects" / f"{name}.obj", "\n".join(lines) + "\n")
    atomic_write_text(out / "split.json", json.dumps(split, indent=1) + "\n")
    manifest = {"dataset": "multibody-synthetic", "generator": syn.GENERATOR_VERSION, "seed": int(seed),
                "n_clips": int(n_clips), "fps": syn.FPS, "sequences": entries}
    atomic_write_text(out / MARKER, json.dumps(manifest, indent=2, sort_keys=True) + "\n")
    return manifest
