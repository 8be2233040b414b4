"""The processed-dataset store: what ``hoibench prepare`` writes and everything else reads.

Layout::

    DATA/manifest.json       toolkit version, dataset, config, source checksums, counts,
                             representation versions, clips (id, split, frames), errors,
                             incomplete (raw files the dataset needs that were missing or
                             unreadable: the store is not the whole dataset)
    DATA/clips/<id>.npz      one clip, no pickles: joints (T,22,3), fps, object name and pose,
                             body parameters, contacts (when known), hml263, hoi269,
                             joint_level (clean mode, T-1 rows), source_sha256, split
    DATA/objects/<obj>.npz   centred object templates (vertices, faces)
    DATA/stats/<repr>.npz    normalisation statistics from the train split
    DATA/errors.jsonl        one JSON line per sequence that failed, with the reason

Writes are atomic. A rerun skips every clip whose stored ``source_sha256`` (raw files +
object template + config) matches and redoes the rest, so an interrupted run resumes and
ends byte-identical to an uninterrupted one. A failing sequence is logged and skipped, or
stops the run under ``strict``. Every clip id passes :func:`hoibench.core.ids.check_id` and is
unique in the store, and every clip passes :func:`hoibench.core.plausibility.check_sequence`,
before anything is written.
"""
from __future__ import annotations

import io
import hashlib
import json
import sys
import zipfile
from contextlib import closing
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from .. import __version__
from ..core.errors import StrictStop
from ..core.ids import InvalidIdError, check_id
from ..core.io import (MAX_CLIP_BYTES, atomic_save_npz, atomic_write_bytes, atomic_write_json, atomic_write_text,
                       clean_stale_tmp, is_atomic_tmp, load_raw_npz, npz_bytes, read_json_file, read_regular_file, sha256_regular_file,
                       strict_json_dumps)
from ..core.plausibility import check_fps, check_sequence
from ..core.parallel import map_units
from ..representations import hml263, hoi269, joint_level, normalization

MANIFEST = "manifest.json"
ERRORS = "errors.jsonl"
#: what a store folder may hold (prepare writes the first five, annotate the last two): an
#: existing --out holding anything else is not a store and is never written into
STORE_ENTRIES = frozenset({"clips", "objects", "stats", MANIFEST, ERRORS, "texts", "annotations"})


@dataclass(frozen=True)
class PrepareConfig:
    dataset: str
    fps: float = 20.0
    mode: str = "clean"            # representation mode stored in the clips
    body_model_type: str = "smplh"

    def __post_init__(self) -> None:
        check_fps(self.fps, "--fps", f"prepare {self.dataset}")

    def sha256(self) -> str:
        return hashlib.sha256(json.dumps(asdict(self), sort_keys=True).encode()).hexdigest()


def file_sha256(paths: Sequence[Path], extra: str = "") -> str:
    """sha256 over the bytes of ``paths`` (in order, each prefixed by its name) and ``extra``."""
    h = hashlib.sha256()
    for p in paths:
        p = Path(p)
        h.update(p.name.encode() + b"\0")
        if not p.exists():
            h.update(b"<missing>")
        elif not p.is_file():            # FIFO, device, socket: never read (the unit reports it)
            h.update(b"<not a regular file>")
        else:
            try:
                sha256_regular_file(p, h)
            except ValueError:           # swapped for a special file since the check
                h.update(b"<not a regular file>")
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
    if len(seq.parts) > 1:           # a multi-part object: every part's name and pose
        out.update(object_parts=np.array([p.name for p in seq.parts]),
                   parts_rot=np.stack([p.rot for p in seq.parts]).astype(np.float32),
                   parts_trans=np.stack([p.trans for p in seq.parts]).astype(np.float32))
    if seq.body is not None:
        out.update(body_model_type=np.array(seq.body.model_type), gender=np.array(seq.body.gender),
                   betas=seq.body.betas, poses=seq.body.poses, trans=seq.body.trans,
                   flat_hand_mean=np.array(bool(seq.body.flat_hand_mean)))
        if seq.body.expression is not None:
            out["expression"] = np.asarray(seq.body.expression, dtype=np.float32)
    if seq.contacts is not None:
        out["contacts"] = seq.contacts.astype(bool)
    if seq.texts:   # dataset texts (e.g. OMOMO's annotations), one JSON object per entry
        out["texts"] = np.array([strict_json_dumps(t, sort_keys=True) for t in seq.texts])
    for k, v in getattr(seq, "extra_arrays", {}).items():
        if k in out:
            raise ValueError(f"{seq.name}: extra array {k!r} would replace a clip field")
        out[k] = np.asarray(v)
    out["provenance"] = np.array(strict_json_dumps(seq.provenance, sort_keys=True))
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
    scope: str = "sequence"         # "source": a whole raw file failed (see fail_source)


class Store:
    """Read access to a prepared store."""

    def __init__(self, root: str | Path):
        self.root = Path(root)
        mpath = self.root / MANIFEST
        if not mpath.exists():
            raise FileNotFoundError(f"{self.root}: not a hoibench store (no {MANIFEST})")
        manifest = read_json_file(mpath, what=MANIFEST)
        if not isinstance(manifest, dict) or not isinstance(manifest.get("clips"), list) \
                or not isinstance(manifest.get("config", {}), dict):
            raise ValueError(f"{mpath}: not a hoibench manifest (expected an object with a 'clips' list)")
        for i, row in enumerate(manifest["clips"]):
            if not isinstance(row, dict) or not isinstance(row.get("id"), str) or not isinstance(row.get("split"), str):
                raise ValueError(f"{mpath}: clips[{i}]: expected an object with string 'id' and 'split'")
        self.manifest = manifest

    def clip_ids(self, split: str | None = None) -> list[str]:
        return [c["id"] for c in self.manifest["clips"] if split is None or c["split"] == split]

    @property
    def is_multibody(self) -> bool:
        """Whether the store holds multi-body clips (its first present clip's ``layout`` says so;
        a hosted challenge's hidden store holds the test split's files only)."""
        from ..bodies.multibody import is_multibody_arrays
        ids = self.clip_ids()
        present = next((c for c in ids if (self.root / "clips" / f"{c}.npz").is_file()), ids[0] if ids else None)
        return present is not None and is_multibody_arrays(self.load(present, keys=("layout",)))

    def load(self, clip_id: str, keys: Sequence[str] | None = None) -> dict[str, np.ndarray]:
        """The clip's arrays (``keys``: only those of them the file holds; None: all)."""
        check_id(clip_id, "clip id", self.root / MANIFEST)
        path = self.root / "clips" / f"{clip_id}.npz"
        try:
            if not path.exists():
                raise FileNotFoundError(path)
            return load_raw_npz(path, MAX_CLIP_BYTES, "clip file", keys=keys)
        except FileNotFoundError:
            if clip_id not in self.clip_ids():
                raise FileNotFoundError(f"{self.root / MANIFEST}: no clip {clip_id!r} (not an id of this store's "
                                        f"manifest)") from None
            raise FileNotFoundError(f"{path}: missing: clip {clip_id} is in the manifest but its file is not "
                                    f"(incomplete copy? rerun `hoibench prepare`)") from None
        except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
            why = "not an .npz archive of arrays" if "pickle" in str(exc) else \
                f"{type(exc).__name__}: {' '.join(str(exc).split())[:120]}"
            raise ValueError(f"{path}: not a readable clip file ({why}); rerun `hoibench prepare` to rebuild it") \
                from None

    def object_template(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        check_id(name, "object name", self.root / MANIFEST)
        z = load_raw_npz(self.root / "objects" / f"{name}.npz", MAX_CLIP_BYTES, "object template")
        return z["vertices"], z["faces"]

    def stats(self, name: str) -> normalization.NormStats:
        return normalization.NormStats.from_npz(self.root / "stats" / f"{name}.npz")

    def stats_sha256(self, name: str) -> str:
        """sha256 of the ``name`` normalisation statistics; ``""`` when the store has none."""
        return self.stats(name).sha256() if (self.root / "stats" / f"{name}.npz").exists() else ""

    def manifest_sha256(self) -> str:
        return manifest_sha256(self.manifest)


def content_manifest(manifest: dict) -> dict:
    """The manifest without what says where and by which toolkit version a store was made:
    ``toolkit_version`` and ``source.root`` are dropped, and the raw root inside the
    ``incomplete`` and ``warnings`` lines is replaced by ``<raw>``. The same data, config
    and raw files prepared into other folders (or by a toolkit whose output bytes are the
    same) give the same content manifest."""
    out = {k: v for k, v in manifest.items() if k != "toolkit_version"}
    source = dict(out.get("source") or {})
    root = source.pop("root", None)
    if "source" in out:
        out["source"] = source
    if isinstance(root, str) and root:
        for key in ("incomplete", "warnings"):
            if isinstance(out.get(key), list):
                out[key] = [line.replace(root, "<raw>") if isinstance(line, str) else line for line in out[key]]
    return out


def legacy_manifest_sha256(manifest: dict) -> str:
    """sha256 of the whole manifest, paths and toolkit version included: the store identity
    that cards written before 0.7.0 record (a folder trained then is still this store's)."""
    return hashlib.sha256(json.dumps(manifest, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def manifest_sha256(manifest: dict) -> str:
    """sha256 of the canonical JSON of :func:`content_manifest`: the store identity evaluator
    and baseline cards record (so their ids depend on the data, never on a path)."""
    return hashlib.sha256(json.dumps(content_manifest(manifest), sort_keys=True,
                                     separators=(",", ":")).encode()).hexdigest()


def _stored_result(path: Path, clip_id: str, split: str, sha: str) -> UnitResult | None:
    """The already-prepared clip at ``path`` when its ``source_sha256`` equals ``sha`` (one
    read of the file); None when it is missing, unreadable or stale."""
    try:
        with np.load(io.BytesIO(read_regular_file(path, MAX_CLIP_BYTES, "clip file")), allow_pickle=False) as z:
            if "source_sha256" not in z.files or str(z["source_sha256"]) != sha:
                return None
            if "layout" in z.files:          # a multi-body clip
                contacts = int(z["contact_frames"].any(0).sum()) if len(z["contact_frames"]) else 0
                objects = ",".join(str(t) for t in z["body_templates"] if str(t))
                return UnitResult(clip_id, "skipped", split, int(len(z["body0_trans"])), sha, objects, contacts)
            contacts = int(z["contacts"].any(-1).sum()) if "contacts" in z.files else 0
            return UnitResult(clip_id, "skipped", split, int(len(z["joints"])), sha,
                              str(z["object_name"]) if "object_name" in z.files else "", contacts)
    except Exception:   # missing or truncated file: prepare it again
        return None


def run_unit(job: tuple) -> UnitResult:
    """Prepare one sequence (pure: output depends on the job only). ``job`` =
    (clip_id, split, source_sha256, out_dir, loader, loader_args, mode).

    The clip id passes :func:`hoibench.core.ids.check_id` before any path is made from it, and
    the loaded clip :func:`hoibench.core.plausibility.check_sequence` before it is written."""
    clip_id, split, sha, out_dir, loader, loader_args, mode = job
    if loader is fail_unit or loader is fail_source:   # nothing to read or write
        return _failed(clip_id, split, loader, loader_args)
    try:
        check_id(clip_id, "clip id", f"the {getattr(loader, '__module__', '?')} job list")
    except InvalidIdError as exc:
        return UnitResult(clip_id, "failed", split, error=str(exc))
    path = Path(out_dir) / "clips" / f"{clip_id}.npz"
    done = _stored_result(path, clip_id, split, sha) if path.exists() else None
    if done is not None:
        return done
    try:
        seq = loader(*loader_args)
        from ..bodies.multibody import MultiBodyClip
        if isinstance(seq, MultiBodyClip):
            return _write_multibody(seq, path, Path(out_dir), clip_id, split, sha)
        prov = seq.provenance if isinstance(seq.provenance, dict) else {}
        check_sequence(seq, str(prov.get("raw_source") or prov.get("source_file") or ""))
        arrays = clip_arrays(seq, mode, split, sha)
        atomic_save_npz(path, **arrays)
        if seq.object_vertices is not None:
            _write_object(Path(out_dir), seq.object_name, seq.object_vertices, seq.object_faces)
        for part in seq.parts[1:]:
            _write_object(Path(out_dir), part.name, part.vertices, part.faces)
        contacts = int(seq.contacts.any(-1).sum()) if seq.contacts is not None else 0
        return UnitResult(clip_id, "written", split, seq.num_frames, sha, seq.object_name or "", contacts)
    except Exception as exc:
        return UnitResult(clip_id, "failed", split, error=_message(clip_id, exc))


def _write_multibody(clip, path: Path, out_dir: Path, clip_id: str, split: str, sha: str) -> UnitResult:
    """Write a :class:`~hoibench.bodies.multibody.MultiBodyClip` (checked by its
    ``to_arrays``) and its object templates."""
    if clip.name != clip_id:
        raise ValueError(f"{clip_id}: the loader returned clip {clip.name!r}")
    arrays = clip.to_arrays()
    arrays.update(split=np.array(split), source_sha256=np.array(sha))
    atomic_save_npz(path, **arrays)
    for b in clip.bodies:
        if b.template:
            v, f = clip.templates[b.template]
            _write_object(out_dir, b.template, np.asarray(v), np.asarray(f))
    objects = ",".join(b.template for b in clip.bodies if b.template)
    contact = (np.stack(list(clip.contacts.values())).any(0).sum() if clip.contacts else 0)
    return UnitResult(clip_id, "written", split, clip.num_frames, sha, objects, int(contact))


def _message(clip_id: str, exc: BaseException) -> str:
    """The error text of a failed unit, prefixed by the clip id."""
    msg = str(exc) if isinstance(exc, ValueError) else f"{type(exc).__name__}: {exc}"
    return msg if msg.startswith(str(clip_id)) else f"{clip_id}: {msg}"


def _failed(clip_id: str, split: str, loader, loader_args) -> UnitResult:
    """The result of a job whose loader is :func:`fail_unit` or :func:`fail_source`."""
    try:
        loader(*loader_args)
        raise ValueError("a failing job did not fail")
    except Exception as exc:
        scope = "source" if loader is fail_source else "sequence"
        return UnitResult(clip_id, "failed", split, error=_message(clip_id, exc), scope=scope)


def _write_object(out_dir: Path, name: str, vertices: np.ndarray, faces: np.ndarray) -> None:
    """``objects/<name>.npz``, rewritten when its bytes differ (a stale template of an
    earlier run is replaced, never kept)."""
    opath = out_dir / "objects" / f"{check_id(name, 'object name')}.npz"
    data = npz_bytes({"vertices": vertices.astype(np.float32), "faces": faces.astype(np.int32)})
    if not opath.exists() or read_regular_file(opath, len(data) + 1, "object template") != data:
        atomic_write_bytes(opath, data)


def fail_unit(message: str):
    """A job "loader" for a sequence that cannot be prepared: the unit records ``message``."""
    raise ValueError(message)


class SourceError(ValueError):
    """A whole raw source (a missing or unreadable file) that a dataset needs."""


def fail_source(message: str):
    """A job "loader" for a raw source file that is missing or unreadable (e.g. OMOMO's test
    pickle): the unit records ``message`` and the manifest lists it under ``incomplete``."""
    raise SourceError(message)


def source_failure_job(source_id: str, message: str, out, mode: str) -> tuple:
    """A failing job standing for a whole raw file; ``source_id`` (the file name) is the
    ``sequence`` of its errors.jsonl line."""
    return (source_id, "unknown", "", str(out), fail_source, (message,), mode)


def invalid_id_job(raw_id: object, message: str, out, mode: str) -> tuple:
    """A failing job for an id refused by :func:`check_id`. Its own id is a safe stand-in,
    ``invalid-id-<sha256(repr(id))[:12]>``; ``message`` names the refused id and its source."""
    stand_in = "invalid-id-" + hashlib.sha256(repr(raw_id).encode()).hexdigest()[:12]
    return (stand_in, "unknown", "", str(out), fail_unit, (f"{stand_in}: {message}",), mode)


def refused_id_job(raw_id: str, what: str, where, out, mode: str) -> tuple | None:
    """The :func:`invalid_id_job` of ``raw_id`` when :func:`check_id` refuses it (``what``
    and ``where`` name the id's source in the message); None for an id it accepts."""
    try:
        check_id(raw_id, what, where)
    except InvalidIdError as exc:
        return invalid_id_job(raw_id, str(exc), out, mode)
    return None


def refuse_duplicates(jobs: list[tuple], sources: Sequence[str] | None = None) -> list[tuple]:
    """Fail every copy of a clip id that more than one job produces (compared case-folded:
    ``A.npz`` and ``a.npz`` are one file on some file systems), naming all their sources
    (``sources[i]`` describes ``jobs[i]``): a store never holds one id twice, overwritten
    or in two splits. Jobs that already fail keep their own message."""
    sources = list(sources) if sources is not None else [f"job {i}" for i in range(len(jobs))]
    groups: dict[str, list[int]] = {}
    for i, job in enumerate(jobs):
        groups.setdefault(str(job[0]).casefold(), []).append(i)
    out = list(jobs)
    for idx in groups.values():
        live = [i for i in idx if jobs[i][4] not in (fail_unit, fail_source)]
        if len(idx) < 2 or not live:
            continue
        where = "; ".join(f"{jobs[i][0]} (split {jobs[i][1]}) from {sources[i]}" for i in idx)
        for i in live:
            cid, split, _, out_dir, _, _, mode = jobs[i]
            out[i] = (cid, split, "", out_dir, fail_unit,
                      (f"{cid}: duplicate clip id, every copy refused: {where}",), mode)
    return out


def check_jobs(jobs: list[tuple]) -> list[tuple]:
    """Before running: every job id passes :func:`check_id` (else an :func:`invalid_id_job`)
    and no id comes twice (:func:`refuse_duplicates`). Loaders do both with their sources
    named; this is the store's own guard for any job list."""
    out = []
    for job in jobs:
        try:
            check_id(job[0], "clip id", f"the {getattr(job[4], '__module__', '?')} job list")
            out.append(job)
        except InvalidIdError as exc:
            out.append(invalid_id_job(job[0], str(exc), job[3], job[6]))
    return refuse_duplicates(out)


def incomplete_sources(results: Sequence[UnitResult]) -> list[str]:
    """The errors of :func:`fail_source` units: raw files a dataset needs that were
    missing or unreadable (the manifest's ``incomplete``; the CLI exits non-zero)."""
    return sorted(r.error for r in results if r.status == "failed" and r.scope == "source")


def unlisted_split_jobs(jobs: list[tuple], splits: dict[str, str], split_file, out, mode: str,
                        where: str) -> list[tuple]:
    """Failing jobs for ids a split file lists but ``jobs`` lack (``where``: what was searched)."""
    present = {j[0] for j in jobs}
    return [(name, splits[name], "", str(out), fail_unit,
             (f"{name}: listed in split file {split_file} but {where}",), mode)
            for name in sorted(set(splits) - present)]


def prepare(jobs: list[tuple], out: str | Path, config: PrepareConfig, executor: str = "serial",
            strict: bool = False, source: dict[str, Any] | None = None,
            warnings: Sequence[str] = ()) -> dict:
    """Run ``jobs`` (see :func:`run_unit`) and write the manifest, stats and errors.

    Returns the manifest. With ``strict`` the first failing sequence (in job order) stops the
    run at once (:class:`~hoibench.core.errors.StrictStop`, after recording it in errors.jsonl).
    An interrupt (``KeyboardInterrupt``) stops it too; a rerun resumes.

    Before running, :func:`check_jobs` fails jobs with an unsafe or duplicate id. A raw file
    the dataset needs that was missing or unreadable (a :func:`fail_source` job) is listed
    under the manifest's ``incomplete``: such a store is not the whole dataset.
    ``warnings`` (dataset-level, e.g. RICH clips prepared without contacts) are printed and
    kept in the manifest's ``warnings``.
    """
    out = Path(out)
    for line in warnings:
        print(f"[prepare] WARNING: {line}", file=sys.stderr)
    _refuse_foreign_store(out, config, source or {})
    (out / "clips").mkdir(parents=True, exist_ok=True)
    clean_stale_tmp(out, out / "clips", out / "objects", out / "stats")
    jobs = check_jobs(jobs)
    results, errors = _run_jobs(jobs, out, executor, strict, f"prepare {config.dataset}")
    incomplete = _report_incomplete(results)
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
        "incomplete": incomplete,
    }
    if warnings:
        manifest["warnings"] = list(warnings)
    atomic_write_json(out / MANIFEST, manifest)
    return manifest


def _refuse_foreign_store(out: Path, config: PrepareConfig, source: dict) -> None:
    """``out`` may be new, or a store of the same dataset, config and raw root (a resume);
    preparing other data into an existing store would mix two stores silently."""
    mpath = out / MANIFEST
    if out.exists() and not out.is_dir():
        raise FileExistsError(f"--out {out}: exists and is not a folder; choose a new folder")
    if not mpath.exists():
        foreign = sorted(p.name for p in out.iterdir() if p.name not in STORE_ENTRIES
                         and not is_atomic_tmp(p.name)) if out.is_dir() else []
        if foreign:
            raise FileExistsError(f"--out {out}: not empty and not a store (holds {', '.join(foreign[:3])}"
                                  f"{'...' if len(foreign) > 3 else ''}); choose a new or empty folder")
        return
    try:
        old = read_json_file(mpath, what=MANIFEST)
    except ValueError:
        old = {}
    same = (isinstance(old, dict) and old.get("config_sha256") == config.sha256()
            and (old.get("source") or {}).get("root") == source.get("root"))
    if not same:
        raise FileExistsError(f"--out {out}: already holds a store of other data or settings (dataset "
                              f"{(old or {}).get('dataset', '?')!r}, root {((old or {}).get('source') or {}).get('root')!r}); "
                              "choose a new folder, or rerun the same command to resume")


def _run_jobs(jobs: list[tuple], out: Path, executor: str, strict: bool,
              progress: str) -> tuple[list[UnitResult], list[dict]]:
    """Run :func:`run_unit` over ``jobs``: (results, errors). Under ``strict`` the first
    failure is written to errors.jsonl and raises ``StrictStop``; leaving the loop closes
    :func:`map_units`, which cancels the units not started and stops the pool."""
    results: list[UnitResult] = []
    errors: list[dict] = []
    with closing(map_units(run_unit, jobs, executor, progress=progress)) as units:
        for res in units:
            results.append(res)
            if res.status != "failed":
                continue
            errors.append({"sequence": res.clip_id, "error": res.error})
            if strict:
                _write_errors(out, errors)
                raise StrictStop(f"--strict: {res.error} (stopped after {len(results)} of {len(jobs)} "
                                 f"sequences; recorded in {out / ERRORS})")
            print(f"[prepare] skipped {res.error}", file=sys.stderr)
    return results, errors


def _report_incomplete(results: list[UnitResult]) -> list[str]:
    """:func:`incomplete_sources`, printed; and a guard that no clip id was prepared twice."""
    ids = [r.clip_id.casefold() for r in results if r.status != "failed"]
    if len(ids) != len(set(ids)):           # check_jobs makes this impossible
        raise RuntimeError("prepare: a clip id was prepared twice; the store is not consistent")
    incomplete = incomplete_sources(results)
    for line in incomplete:
        print(f"[prepare] INCOMPLETE: {line}", file=sys.stderr)
    return incomplete


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
            z = load_raw_npz(out / "clips" / f"{cid}.npz", MAX_CLIP_BYTES, "clip file", keys=(key,))
            if key in z:
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
