"""The processed-dataset store: what ``hoibench prepare`` writes and everything else reads.

Layout::

    DATA/manifest.json       toolkit version, dataset, config, source checksums, counts,
                             representation versions, clips (id, split, frames), errors
    DATA/clips/<id>.npz      one clip, no pickles: joints (T,22,3), fps, object name and pose,
                             body parameters, contacts (when known), hml263, hoi269,
                             joint_level (clean mode, T-1 rows), source_sha256, split
    DATA/objects/<obj>.npz   centred object templates (vertices, faces)
    DATA/stats/<repr>.npz    normalisation statistics from the train split
    DATA/errors.jsonl        one JSON line per sequence that failed, with the reason

Writes are atomic. A rerun skips every clip whose stored ``source_sha256`` (raw files +
object template + config) matches and redoes the rest, so an interrupted run resumes and
ends byte-identical to an uninterrupted one. A failing sequence is logged and skipped, or
stops the run under ``strict``.
"""
from __future__ import annotations

import hashlib
import json
import sys
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from . import __version__
from .io import atomic_save_npz, atomic_write_bytes, atomic_write_json, atomic_write_text
from .parallel import map_units
from .representations import hml263, hoi269, joint_level, normalization

MANIFEST = "manifest.json"
ERRORS = "errors.jsonl"


@dataclass(frozen=True)
class PrepareConfig:
    dataset: str
    fps: float = 20.0
    mode: str = "clean"            # representation mode stored in the clips
    body_model_type: str = "smplh"

    def sha256(self) -> str:
        return hashlib.sha256(json.dumps(asdict(self), sort_keys=True).encode()).hexdigest()


def file_sha256(paths: Sequence[Path], extra: str = "") -> str:
    """sha256 over the bytes of ``paths`` (in order, each prefixed by its name) and ``extra``."""
    h = hashlib.sha256()
    for p in paths:
        p = Path(p)
        h.update(p.name.encode() + b"\0")
        h.update(p.read_bytes() if p.exists() else b"<missing>")
    h.update(extra.encode())
    return h.hexdigest()


def clip_arrays(seq, mode: str, split: str, source_sha256: str) -> dict[str, np.ndarray]:
    """Everything a clip file holds, from a canonical HOISequence."""
    feats = hml263.encode(seq.joints, mode=mode, fps=seq.fps)
    hoi_mode = "legacy" if mode.startswith("legacy") else "clean"
    out: dict[str, np.ndarray] = {
        "name": np.array(seq.name), "dataset": np.array(seq.dataset), "subject": np.array(seq.subject),
        "split": np.array(split), "fps": np.float64(seq.fps), "joints": seq.joints.astype(np.float32),
        "hml263": feats, "source_sha256": np.array(source_sha256),
    }
    if seq.obj_rot is not None:
        hoi = hoi269.encode(seq.joints, seq.obj_rot, seq.obj_trans, mode=hoi_mode, fps=seq.fps)
        out.update(object_name=np.array(seq.object_name), obj_rot=seq.obj_rot.astype(np.float32),
                   obj_trans=seq.obj_trans.astype(np.float32), hoi269=hoi,
                   joint_level=joint_level.from_hoi269(hoi))
    else:
        out["joint_level"] = joint_level.from_hoi269(feats)
    if seq.body is not None:
        out.update(body_model_type=np.array(seq.body.model_type), gender=np.array(seq.body.gender),
                   betas=seq.body.betas, poses=seq.body.poses, trans=seq.body.trans)
    if seq.contacts is not None:
        out["contacts"] = seq.contacts.astype(bool)
    if seq.texts:   # dataset texts (e.g. OMOMO's annotations), one JSON object per entry
        out["texts"] = np.array([json.dumps(t, sort_keys=True) for t in seq.texts])
    out["provenance"] = np.array(json.dumps(seq.provenance, sort_keys=True))
    return out


@dataclass
class UnitResult:
    clip_id: str
    status: str                     # "written" | "skipped" | "failed"
    split: str = ""
    frames: int = 0
    source_sha256: str = ""
    object_name: str = ""
    contact_frames: int = 0
    error: str = ""


class Store:
    """Read access to a prepared store."""

    def __init__(self, root: str | Path):
        self.root = Path(root)
        mpath = self.root / MANIFEST
        if not mpath.exists():
            raise FileNotFoundError(f"{self.root}: not a hoibench store (no {MANIFEST})")
        self.manifest = json.loads(mpath.read_text())

    def clip_ids(self, split: str | None = None) -> list[str]:
        return [c["id"] for c in self.manifest["clips"] if split is None or c["split"] == split]

    def load(self, clip_id: str) -> dict[str, np.ndarray]:
        with np.load(self.root / "clips" / f"{clip_id}.npz", allow_pickle=False) as z:
            return {k: z[k] for k in z.files}

    def object_template(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        with np.load(self.root / "objects" / f"{name}.npz", allow_pickle=False) as z:
            return z["vertices"], z["faces"]

    def stats(self, name: str) -> normalization.NormStats:
        return normalization.NormStats.from_npz(self.root / "stats" / f"{name}.npz")


def _stored_result(path: Path, clip_id: str, split: str, sha: str) -> UnitResult | None:
    """The already-prepared clip at ``path`` when its ``source_sha256`` equals ``sha`` (one
    read of the file); None when it is missing, unreadable or stale."""
    try:
        with np.load(path, allow_pickle=False) as z:
            if "source_sha256" not in z.files or str(z["source_sha256"]) != sha:
                return None
            contacts = int(z["contacts"].any(-1).sum()) if "contacts" in z.files else 0
            return UnitResult(clip_id, "skipped", split, int(len(z["joints"])), sha,
                              str(z["object_name"]) if "object_name" in z.files else "", contacts)
    except Exception:   # missing or truncated file: prepare it again
        return None


def run_unit(job: tuple) -> UnitResult:
    """Prepare one sequence (pure: output depends on the job only). ``job`` =
    (clip_id, split, source_sha256, out_dir, loader, loader_args, mode)."""
    clip_id, split, sha, out_dir, loader, loader_args, mode = job
    path = Path(out_dir) / "clips" / f"{clip_id}.npz"
    done = _stored_result(path, clip_id, split, sha) if path.exists() else None
    if done is not None:
        return done
    try:
        seq = loader(*loader_args)
        arrays = clip_arrays(seq, mode, split, sha)
        atomic_save_npz(path, **arrays)
        if seq.object_vertices is not None:
            opath = Path(out_dir) / "objects" / f"{seq.object_name}.npz"
            if not opath.exists():
                atomic_save_npz(opath, vertices=seq.object_vertices.astype(np.float32),
                                faces=seq.object_faces.astype(np.int32))
        contacts = int(seq.contacts.any(-1).sum()) if seq.contacts is not None else 0
        return UnitResult(clip_id, "written", split, seq.num_frames, sha, seq.object_name or "", contacts)
    except Exception as exc:
        msg = str(exc) if isinstance(exc, ValueError) else f"{type(exc).__name__}: {exc}"
        if not msg.startswith(clip_id):
            msg = f"{clip_id}: {msg}"
        return UnitResult(clip_id, "failed", split, error=msg)


def fail_unit(message: str):
    """A job "loader" for a sequence that cannot be prepared: the unit records ``message``."""
    raise ValueError(message)


def unlisted_split_jobs(jobs: list[tuple], splits: dict[str, str], split_file, out, mode: str,
                        where: str) -> list[tuple]:
    """Failing jobs for ids a split file lists but ``jobs`` lack (``where``: what was searched)."""
    present = {j[0] for j in jobs}
    return [(name, splits[name], "", str(out), fail_unit,
             (f"{name}: listed in split file {split_file} but {where}",), mode)
            for name in sorted(set(splits) - present)]


def prepare(jobs: list[tuple], out: str | Path, config: PrepareConfig, executor: str = "serial",
            strict: bool = False, source: dict[str, Any] | None = None) -> dict:
    """Run ``jobs`` (see :func:`run_unit`) and write the manifest, stats and errors.

    Returns the manifest. With ``strict`` the first failure raises ``RuntimeError`` (after
    recording it in errors.jsonl).
    """
    out = Path(out)
    (out / "clips").mkdir(parents=True, exist_ok=True)
    results: list[UnitResult] = []
    errors: list[dict] = []
    for res in map_units(run_unit, jobs, executor, progress=f"prepare {config.dataset}"):
        results.append(res)
        if res.status == "failed":
            errors.append({"sequence": res.clip_id, "error": res.error})
            print(f"[prepare] skipped {res.error}", file=sys.stderr)
            if strict:
                _write_errors(out, errors)
                raise RuntimeError(f"--strict: {res.error}")
    _write_errors(out, errors)
    ok = sorted((r for r in results if r.status != "failed"), key=lambda r: r.clip_id)
    stats = _write_stats(out, [r.clip_id for r in ok if r.split == "train"], config)
    manifest = {
        "toolkit": "hoibench", "toolkit_version": __version__, "dataset": config.dataset,
        "config": asdict(config), "config_sha256": config.sha256(),
        "representations": {"hml263": hml263.VERSION[config.mode],
                            "hoi269": hoi269.VERSION["legacy" if config.mode.startswith("legacy") else "clean"],
                            "joint_level": "joint_level-1.0"},
        "source": source or {},
        "source_checksums": {r.clip_id: r.source_sha256 for r in ok},
        "counts": {"clips": len(ok), "failed": len(errors),
                   "frames": int(sum(r.frames for r in ok)),
                   "by_split": {s: sum(1 for r in ok if r.split == s) for s in sorted({r.split for r in ok})},
                   "contact_frames": int(sum(r.contact_frames for r in ok))},
        "clips": [{"id": r.clip_id, "split": r.split, "frames": r.frames, "object": r.object_name,
                   "contact_frames": r.contact_frames} for r in ok],
        "stats": stats,
    }
    atomic_write_json(out / MANIFEST, manifest)
    return manifest


def _write_errors(out: Path, errors: list[dict]) -> None:
    text = "".join(json.dumps(e, sort_keys=True) + "\n" for e in sorted(errors, key=lambda e: e["sequence"]))
    atomic_write_text(out / ERRORS, text)


def _write_stats(out: Path, train_ids: list[str], config: PrepareConfig) -> dict:
    if not train_ids:
        return {}
    written = {}
    stat_mode = "legacy" if config.mode.startswith("legacy") else "clean"
    for key in ("hml263", "hoi269"):
        clips = []
        for cid in train_ids:
            with np.load(out / "clips" / f"{cid}.npz", allow_pickle=False) as z:
                if key in z.files:
                    clips.append(z[key])
        if clips:
            st = normalization.compute_stats(clips, mode=stat_mode)
            atomic_write_bytes(out / "stats" / f"{key}.npz", st.to_npz_bytes())
            written[key] = {"sha256": st.sha256(), "frames": st.count, "split": "train"}
    return written


def summary_table(manifest: dict) -> str:
    """Plain-text summary: clips, frames, per-split counts, contact frames."""
    c = manifest["counts"]
    lines = [f"dataset {manifest['dataset']}  (fps {manifest['config']['fps']}, mode {manifest['config']['mode']})",
             f"{'split':8s} {'clips':>6s} {'frames':>8s} {'contact frames':>15s}"]
    for split in sorted(c["by_split"]):
        rows = [r for r in manifest["clips"] if r["split"] == split]
        lines.append(f"{split:8s} {len(rows):6d} {sum(r['frames'] for r in rows):8d} "
                     f"{sum(r['contact_frames'] for r in rows):15d}")
    lines.append(f"{'total':8s} {c['clips']:6d} {c['frames']:8d} {c['contact_frames']:15d}   failed: {c['failed']}")
    return "\n".join(lines)
