"""Leaderboard entries (docs/leaderboards.md): one strict-JSON file per method and track.

``leaderboards/<track>/entries/<slug>.json`` holds what a reader needs to compare a row:
method, source (``reproduced`` by hoibench from a submission it scored, or ``reported`` in
a paper), metrics with 95% CIs, evaluator id, protocol id and version, representation and
toolkit versions, sample counts and missing ids, flags, whether the result was complete,
which metrics were undefined, and where the submission came from (for a baseline: its
checkpoint id and config). Rendering the tables (``hoibench leaderboard build``) reads these.
"""
from __future__ import annotations

import re
from pathlib import Path

from ..core.io import atomic_write_json
from ..metrics.catalog import METRICS
from ..tracks.catalog import HOI_COLUMNS

ENTRY_FORMAT = "hoibench-entry-2"
#: entry formats :func:`read_entry` reads (older ones through :func:`upgrade_entry`)
ENTRY_FORMATS = ("hoibench-entry-1", ENTRY_FORMAT)
#: a track's own evaluator folder, shipped with a track whose rows hoibench reproduces
TRACK_EVALUATOR = "evaluator"
SOURCES = ("reproduced", "reported")


def slug(method: str) -> str:
    """File name of an entry: lower-case letters, digits and '-' (``"ChainHOI (tiny)"`` ->
    ``chainhoi-tiny``)."""
    s = re.sub(r"[^a-z0-9]+", "-", method.lower()).strip("-")
    if not s:
        raise ValueError(f"method {method!r}: no letters or digits to name its entry")
    return s[:100]


def training_of(entry: dict) -> dict:
    """The training budget a reproduced row's submission recorded (``submission_source.training``:
    steps, parameters, wall_seconds, hardware, text_encoder), or {}."""
    t = (entry.get("submission_source") or {}).get("training")
    return t if isinstance(t, dict) else {}


def shares_evaluator_text_encoder(entry: dict) -> bool:
    """Whether the row's generator was conditioned on the very text-encoder weights the
    evaluator reads captions with (sha256 equal): its R-precision and MM-Dist may be inflated."""
    mine = (training_of(entry).get("text_encoder") or {}).get("weights_sha256")
    theirs = (entry.get("evaluator_text_encoder") or {}).get("weights_sha256")
    return bool(mine) and mine == theirs


def entry_from_result(result: dict, *, method: str, track: str, source: str = "reproduced",
                      submission_meta: dict | None = None, notes: str = "") -> dict:
    """An entry for a result of ``hoibench evaluate`` (``submission_meta``: the submission's
    ``submission.json``, for its ``source`` block)."""
    from ..scoring.results import upgrade_result
    if source not in SOURCES:
        raise ValueError(f"source: expected one of {SOURCES}, got {source!r}")
    result = upgrade_result(result)
    counts = result.get("counts", {})
    metrics = {k: {f: v[f] for f in ENTRY_METRIC_FIELDS if f in v} for k, v in sorted(result.get("metrics", {}).items())}
    return {
        "format": ENTRY_FORMAT, "track": track, "method": method, "source": source,
        "metrics": metrics, "undefined_metrics": result.get("undefined_metrics", {}),
        "evaluator_id": result.get("evaluator_id"),
        "evaluator_text_encoder": result.get("evaluator_text_encoder") or {},
        "evaluator_backend": result.get("evaluator_backend"),
        "protocol": result.get("protocol"),
        "protocol_version": result.get("protocol_version"), "representation": result.get("representation"),
        "toolkit_version": result.get("toolkit_version"), "replications": result.get("replications"),
        "samples_per_prompt": counts.get("samples_per_prompt"), "scored_ids": counts.get("scored_ids"),
        "test_ids": counts.get("test_ids"), "missing_ids": counts.get("missing_ids", []),
        "flags": result.get("submission", {}).get("flags", {}), "complete": bool(result.get("complete")),
        "overrides": result.get("overrides", []),
        "submission_source": (submission_meta or {}).get("source", {}), "notes": notes,
    }


#: the fields of an entry's metric block
ENTRY_METRIC_FIELDS = ("mean", "ci95", "n", "unit", "direction", "interval", "clips")


def upgrade_entry(entry: dict) -> dict:
    """An entry in :data:`ENTRY_FORMAT` (a new dict; numbers unchanged). ``hoibench-entry-1``
    blocks gain the catalogue's unit and direction and what their interval is over: the
    protocol's replications, or the scored samples for a multi-body row (its metrics are of
    the catalogue's ``multibody`` kind, whose intervals were over samples)."""
    if entry.get("format") != "hoibench-entry-1":
        return entry
    kinds = {METRICS[k].kind for k in entry.get("metrics", {}) if k in METRICS}
    over = "samples" if "multibody" in kinds else "replications"
    out = dict(entry, format=ENTRY_FORMAT)
    out["metrics"] = {k: ({**m, "unit": METRICS[k].unit if k in METRICS else None,
                           "direction": METRICS[k].direction if k in METRICS else None,
                           "interval": over if m.get("ci95") is not None else "none"} if isinstance(m, dict) else m)
                      for k, m in entry.get("metrics", {}).items()}
    return out


def write_entry(entry: dict, entries_dir: str | Path) -> Path:
    """Write ``entries_dir/<slug(method)>.json`` atomically (strict JSON, sorted keys)."""
    return atomic_write_json(Path(entries_dir) / f"{slug(entry['method'])}.json", entry)


# =========================================================================== tracks
ROLES = ("ground-truth", "reference", "baseline", "method")
def table_columns(track: str) -> tuple[str, ...]:
    """The leaderboard columns of ``track`` (its registry entry's ``columns``; the
    single-body columns for a track the registry does not know)."""
    from ..tracks.registry import get_track
    try:
        return get_track(track).columns
    except KeyError:
        return HOI_COLUMNS


def title(name: str) -> str:
    """A metric's column title (the catalogue's ``short``; the name for an unknown metric)."""
    return METRICS[name].title if name in METRICS else name


_REQUIRED = (("format", str), ("track", str), ("method", str), ("source", str), ("metrics", dict))


class LeaderboardError(ValueError):
    """A leaderboard entry or result that cannot be read, added or rendered (names file and field)."""


def read_entry(path: str | Path) -> dict:
    """One entry file, checked: strict JSON, format, required fields, metric blocks."""
    from ..core.io import load_json_bytes, read_regular_file
    path = Path(path)
    try:
        e = load_json_bytes(read_regular_file(path, 8 << 20, "leaderboard entry"), path)
    except ValueError as exc:
        raise LeaderboardError(str(exc)) from None
    if not isinstance(e, dict):
        raise LeaderboardError(f"{path}: expected a JSON object")
    for key, t in _REQUIRED:
        if not isinstance(e.get(key), t):
            raise LeaderboardError(f"{path}: field {key}: expected a {t.__name__}, got {type(e.get(key)).__name__}")
    if e["format"] not in ENTRY_FORMATS:
        raise LeaderboardError(f"{path}: field format: {e['format']!r} is not one of {', '.join(ENTRY_FORMATS)}")
    e = upgrade_entry(e)
    if e["source"] not in SOURCES:
        raise LeaderboardError(f"{path}: field source: expected one of {SOURCES}, got {e['source']!r}")
    from ..scoring.results import counts_problem, metrics_problem
    problem = metrics_problem(e["metrics"]) or counts_problem(e, "entry")
    if problem:
        raise LeaderboardError(f"{path}: {problem.replace('field entry.', 'field ')}")
    for key in ("method", "notes", "citation", "url"):
        v = e.get(key)
        if v is not None and not isinstance(v, str):
            raise LeaderboardError(f"{path}: field {key}: expected a string, got {type(v).__name__}")
        if isinstance(v, str) and not _utf8(v):
            raise LeaderboardError(f"{path}: field {key}: not valid Unicode text (a lone surrogate escape)")
    if e["source"] == "reported" and not e.get("citation"):
        raise LeaderboardError(f"{path}: field citation: a reported row needs the paper it is copied from")
    want = e.get("comparable_with")
    if want is not None and not (isinstance(want, dict) and all(isinstance(want.get(k), str) and want.get(k)
                                                                for k in ("protocol", "evaluator_backend"))
                                 and isinstance(want.get("evaluator_id", ""), str)):
        raise LeaderboardError(f"{path}: field comparable_with: expected {{\"protocol\": id, "
                               f"\"evaluator_backend\": name}} (and optionally \"evaluator_id\": id)")
    e["role"] = role_of(e)
    e["_file"] = path.name
    return e


def _utf8(text: str) -> bool:
    try:
        text.encode("utf-8")
        return True
    except UnicodeEncodeError:
        return False


def comparable(entry: dict, reported: dict) -> bool:
    """Whether ``entry`` (scored by hoibench) can stand beside the paper row ``reported``: the
    paper row names the protocol and evaluator backend that reproduce its paper's evaluation
    (``comparable_with: {protocol, evaluator_backend}``: the paper's legacy protocol and its
    published evaluator), and ``entry`` was scored under exactly those. When one backend loads
    several published weight sets (``t2m``: HumanML3D's evaluator, or one retrained in the
    same layout for another dataset), the paper row also names the ``evaluator_id`` its
    weights import to, and ``entry`` must have that id. A paper row without
    ``comparable_with`` is comparable with nothing."""
    want = reported.get("comparable_with")
    return (isinstance(want, dict) and reported.get("source") == "reported" and entry.get("source") != "reported"
            and bool(want.get("protocol")) and entry.get("protocol") == want.get("protocol")
            and entry.get("evaluator_backend") == want.get("evaluator_backend")
            and (not want.get("evaluator_id") or entry.get("evaluator_id") == want.get("evaluator_id")))


def comparable_citations(entry: dict, entries: list[dict]) -> list[str]:
    """The citations of the paper rows ``entry`` is comparable with (:func:`comparable`)."""
    return sorted({str(r.get("citation")) for r in entries if comparable(entry, r)})


def role_of(entry: dict) -> str:
    """The entry's role (``role`` field; older entries: ``GT ...`` is the ground truth)."""
    r = entry.get("role")
    if r in ROLES:
        return r
    return "ground-truth" if str(entry.get("method", "")).startswith("GT") else "method"


def is_track(folder: str | Path) -> bool:
    """Whether ``folder`` is a leaderboard track (it holds an ``entries/`` folder)."""
    return (Path(folder) / "entries").is_dir()


def track_dirs(root: str | Path) -> list[Path]:
    """The track folders under ``root`` (sorted by name; none when ``root`` is not a folder)."""
    root = Path(root)
    return sorted(p for p in root.iterdir() if is_track(p)) if root.is_dir() else []


def find_root(start: str | Path | None = None) -> Path | None:
    """The nearest ``leaderboards/`` folder holding track folders, looking in ``start`` (default:
    the current folder) and each folder above it; None when there is none."""
    here = Path.cwd() if start is None else Path(start)
    here = here.resolve()
    for folder in (here, *here.parents):
        if track_dirs(folder / "leaderboards"):
            return folder / "leaderboards"
    return None


def track_folder(root: str | Path, track: str, new_track: bool = False) -> Path:
    """``root/track`` after checking ``track`` against the id rule and that the track exists
    (a new one only with ``new_track``: it starts without a ground-truth row)."""
    from ..core.ids import check_id
    check_id(track, "--track", f"leaderboard root {root}")
    folder = Path(root) / track
    if not is_track(folder) and not new_track:
        known = ", ".join(p.name for p in track_dirs(root)) or "none"
        raise LeaderboardError(f"--track {track!r}: {root} has no such track (tracks: {known}); pass --new-track to "
                               f"start one (it has no ground-truth row until you add one with --role ground-truth)")
    return folder


def load_track(track_dir: str | Path) -> list[dict]:
    """Every entry of ``track_dir/entries`` (sorted by file name)."""
    folder = Path(track_dir) / "entries"
    if not folder.is_dir():
        raise LeaderboardError(f"{track_dir}: no entries/ folder (not a leaderboard track)")
    return [read_entry(p) for p in sorted(folder.glob("*.json"))]


def _mean(e: dict, name: str) -> float | None:
    m = e["metrics"].get(name)
    return None if m is None else float(m["mean"])


#: the bands of a rendered track, in display order: (band, heading)
BANDS = (("ground-truth", "ground truth (the test clips themselves)"),
         ("ranked", "methods and baselines, ranked by FID"),
         ("reference", "reference rows (not ranked: they calibrate each metric's scale)"),
         ("reported", "reported in papers (not ranked: another evaluator, protocol and splits)"))


def band(e: dict) -> str:
    """The band of a row: ``ground-truth`` (hoibench's own ground truth), ``ranked`` (methods
    and baselines scored by hoibench), ``reference`` (reference rows: noise, static, mean
    pose, untrained models) or ``reported`` (rows copied from papers, their ground truth too)."""
    if e["source"] == "reported":
        return "reported"
    if e["role"] == "ground-truth":
        return "ground-truth"
    return "reference" if e["role"] == "reference" else "ranked"


def order(entries: list[dict], key: str = "fid") -> list[dict]:
    """Display order: the bands of :data:`BANDS`; inside one, rows by ``key`` (best first, rows
    without it last) -- in the reported band a paper's own ground-truth row first."""
    higher = METRICS[key].higher_is_better if key in METRICS else False
    bands = [b for b, _ in BANDS]

    def k(e):
        v = _mean(e, key)
        first = e["source"] == "reported" and e["role"] == "ground-truth"
        return (bands.index(band(e)), not first, v is None, (-v if higher else v) if v is not None else 0.0,
                e["method"])
    return sorted(entries, key=k)


def ranks(entries: list[dict]) -> list[int | None]:
    """Rank of each row of ``entries`` (in :func:`order`'s order): 1, 2, ... for the ranked
    band (methods and baselines), None for every other row."""
    out, n = [], 0
    for e in entries:
        if band(e) == "ranked":
            n += 1
            out.append(n)
        else:
            out.append(None)
    return out


def read_result(path: str | Path) -> dict:
    """A result of ``hoibench evaluate`` (:func:`hoibench.scoring.results.read_result`), or
    :class:`LeaderboardError` naming the file and field."""
    from ..scoring.results import ResultError, read_result as read
    try:
        return read(path)
    except ResultError as exc:
        raise LeaderboardError(str(exc)) from None


def _existing_method(path: Path, entries: list[dict]) -> str:
    """The method name of the entry already at ``path`` (its file name when unreadable)."""
    return next((str(e["method"]) for e in entries if e.get("_file") == path.name), path.stem)


def add_result(result_path: str | Path, track_dir: str | Path, *, method: str, role: str = "method",
               allow_incomplete: bool = False, replace: bool = False, notes: str = "",
               submission_meta: dict | None = None) -> Path:
    """Add a ``hoibench evaluate`` result to a track as a reproduced entry. Refused: another
    evaluator id or protocol than the track's reproduced rows, an existing entry of the same
    name (unless ``replace``), a result with another test-split size (``counts.test_ids``: another store),
    an incomplete result (unless ``allow_incomplete``: marked)."""
    if role not in ROLES:
        raise LeaderboardError(f"--role: expected one of {ROLES}, got {role!r}")
    for flag, text in (("--method", method), ("--notes", notes)):
        if not _utf8(text):
            raise LeaderboardError(f"{flag}: not valid Unicode text (a byte the command line could not decode, "
                                   f"kept as a lone surrogate): give the name in UTF-8")
    result_path, track_dir = Path(result_path), Path(track_dir)
    result = read_result(result_path)
    if result.get("evaluator_id") is None:
        raise LeaderboardError(f"{result_path}: field evaluator_id: missing: not a result of `hoibench evaluate`")
    track = track_dir.name
    existing = load_track(track_dir) if (track_dir / "entries").is_dir() else []
    ours = [e for e in existing if e["source"] == "reproduced"]
    ids = sorted({str(e.get("evaluator_id")) for e in ours})
    if ids and str(result.get("evaluator_id")) not in ids:
        shipped = track_dir / TRACK_EVALUATOR
        how = (f"rescore with the track's evaluator (hoibench evaluate SUB --data DATA --evaluator {shipped})"
               if (shipped / "card.json").is_file() else "rescore with that evaluator")
        raise LeaderboardError(f"{result_path}: field evaluator_id: {str(result.get('evaluator_id'))[:12]} is not the "
                               f"evaluator of track {track!r} ({', '.join(i[:12] for i in ids)}): {how}, or "
                               f"rescore every row with this one")
    protos = sorted({f"{e.get('protocol')}@{e.get('protocol_version')}" for e in ours})
    mine = f"{result.get('protocol')}@{result.get('protocol_version')}"
    if protos and mine not in protos:
        raise LeaderboardError(f"{result_path}: field protocol: {mine} is not the protocol of track {track!r} "
                               f"({', '.join(protos)})")
    sizes = sorted({e.get("test_ids") for e in ours} - {None})       # whole numbers (counts_problem)
    theirs = (result.get("counts") or {}).get("test_ids")
    if sizes and theirs is not None and theirs not in sizes:
        raise LeaderboardError(f"{result_path}: field counts.test_ids: {theirs} test clips, not the "
                               f"{' or '.join(map(str, sizes))} of track {track!r}: a result of another store or "
                               f"split; score the track's store")
    if not result.get("complete") and not allow_incomplete:
        why = "; ".join(str(o.get("override")) for o in result.get("overrides", [])) or \
            f"{len(result.get('counts', {}).get('missing_ids', []))} missing id(s)"
        raise LeaderboardError(f"{result_path}: field complete: false ({why}); pass --allow-incomplete to add it "
                               f"marked as incomplete")
    path = track_dir / "entries" / f"{slug(method)}.json"
    if path.exists() and not replace:
        raise LeaderboardError(f"{path}: field method: an entry named {_existing_method(path, existing)!r} exists "
                               f"already (--method {method!r} has the same file name); choose another --method or "
                               f"pass --replace")
    pcd = result.get("per_clip_data")
    digest = pcd.get("sha256") if isinstance(pcd, dict) else None
    twin = next((e for e in existing if digest and e.get("_file") != path.name
                 and (e.get("per_clip_data") or {}).get("samples") == "all"
                 and (e.get("per_clip_data") or {}).get("sha256") == digest), None)
    if twin is not None:
        raise LeaderboardError(f"{result_path}: field per_clip_data.sha256: the same per-clip data as the entry "
                               f"{twin['method']!r} ({twin['_file']}): this result is on the track already")
    if submission_meta is None:
        submission_meta = submission_meta_of(result, result_path)
    entry = entry_from_result(result, method=method, track=track, submission_meta=submission_meta, notes=notes)
    entry["role"] = role
    attach_clip_data(entry, result, result_path, track_dir / "entries")
    return write_entry(entry, track_dir / "entries")


#: the largest per-clip file an entry keeps (1 MiB)
ENTRY_CLIP_BYTES = 1 << 20


def _first_sample(arrays: dict) -> dict:
    """``arrays`` with the embeddings and physical values of sample 0 only."""
    import numpy as np
    out = dict(arrays)
    out["motion"] = arrays["motion"][:1]
    keep = np.flatnonzero(np.asarray(arrays["physical_samples"]) == 0)[:1]
    out["physical"] = arrays["physical"][keep]
    out["physical_samples"] = np.asarray(arrays["physical_samples"])[keep]
    return out


def attach_clip_data(entry: dict, result: dict, result_path: str | Path, entries_dir: str | Path,
                     max_bytes: int = ENTRY_CLIP_BYTES) -> Path | None:
    """Copy the per-clip data of ``result`` (read beside ``result_path``, checked by sha256)
    to ``entries_dir/<slug>.clips.npz`` and record it in ``entry["per_clip_data"]`` (``file``,
    ``sha256``, ``bytes``, ``samples``: ``all`` or ``sample 0``). None, and nothing recorded,
    when the result kept none; :class:`LeaderboardError` when even sample 0 exceeds ``max_bytes``."""
    import hashlib
    from ..core.io import atomic_write_bytes, npz_bytes
    from ..scoring.clip_data import read_clip_data
    if not isinstance(result.get("per_clip_data"), dict):
        return None
    try:
        arrays = read_clip_data(result, result_path)
    except ValueError as exc:
        raise LeaderboardError(str(exc)) from None
    samples, data = "all", npz_bytes(arrays)
    if len(data) > max_bytes:
        samples, data = "sample 0", npz_bytes(_first_sample(arrays))
    if len(data) > max_bytes:
        raise LeaderboardError(f"{result_path}: field per_clip_data: {len(data):,} bytes for sample 0 alone, over "
                               f"the {max_bytes:,} an entry keeps")
    path = atomic_write_bytes(Path(entries_dir) / f"{slug(entry['method'])}.clips.npz", data)
    entry["per_clip_data"] = {"file": path.name, "sha256": hashlib.sha256(data).hexdigest(), "bytes": len(data),
                              "samples": samples}
    return path


def submission_meta_of(result: dict, result_path: str | Path) -> dict | None:
    """The ``submission.json`` of the submission a result scored (its ``submission.path``, a
    folder or a ``.zip``, relative to the current folder or to the result file's), for the
    entry's ``source`` block (a baseline's training budget, its conditioner); None when that
    submission is not here or its file is unreadable (the entry then says "not stated")."""
    from ..scoring.submission import Submission
    sub = (result.get("submission") or {}).get("path")
    if not isinstance(sub, str) or not sub:
        return None
    for base in (Path.cwd(), Path(result_path).resolve().parent):
        if (base / sub).exists():
            with Submission(base / sub) as found:
                return found.meta if isinstance(found.meta, dict) else None
    return None
