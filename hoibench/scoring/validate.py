"""Validating a submission against a store: every problem at once, as a
:class:`ValidationReport` (:func:`validation_report`, :func:`validate`), and the
``hoibench validate`` entry point.

Checks ``submission.json``, the ids against the store's split, and per file the arrays'
presence, shapes, dtypes, K and lengths (here) and their values
(:mod:`hoibench.scoring.validate_arrays`). A broken or partial submission never raises and
is never scored as complete.
"""
from __future__ import annotations

import json
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable


from ..core.ids import ID_RULE, is_valid_id
from .submission_read import (DEFAULT_MAX_SAMPLES_PER_PROMPT, KNOWN_ARRAYS, SAMPLES_DIR, SUBMISSION_JSON,
                              Problem, Submission, SubmissionError, SubmissionLimits, limits_for, max_frames)
from .validate_arrays import ClipContext, EncodeBatcher, check_arrays, expect_shape

REQUIRED_FIELDS = {"method": str, "version": str, "representation": str, "fps": (int, float)}
FLAG_FIELDS = {"uses_gt_length": bool, "samples_per_prompt": int, "checkpoint_selection": str, "human_only": bool}


# ====================================================================== validation
@dataclass
class ValidationReport:
    """Outcome of :func:`validation_report`: every problem, and what can be scored.
    ``complete`` is True only when there is no error at all; ``valid_ids`` are the test ids
    whose file has no error; ``missing_ids`` the test ids without a valid file;
    ``submitted_ids`` the ids the submission holds; ``lead`` the line printed first when most
    of them belong to no test split of the store (:func:`foreign_ids_line`)."""

    problems: list
    test_ids: list
    valid_ids: list
    samples_per_prompt: int | None
    submitted_ids: list = field(default_factory=list)
    lead: str | None = None
    complete: bool = field(init=False)

    def __post_init__(self):
        self.complete = not any(p.severity == "error" for p in self.problems)

    @property
    def missing_ids(self) -> list:
        ok = set(self.valid_ids)
        return [i for i in self.test_ids if i not in ok]

    @property
    def errors(self) -> list:
        return [p for p in self.problems if p.severity == "error"]

    @property
    def warnings(self) -> list:
        return [p for p in self.problems if p.severity == "warning"]

    def to_dict(self) -> dict:
        return {"complete": self.complete, "test_ids": len(self.test_ids), "valid_ids": len(self.valid_ids),
                "missing_ids": self.missing_ids, "samples_per_prompt": self.samples_per_prompt,
                "problems": [p.to_dict() for p in self.problems]}


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def accepted_representations(manifest: dict) -> set[str]:
    """``representation`` values a submission for this store may declare: the store's own
    representation versions, or ``joints`` (joint positions only); ``""`` too when the store
    records none."""
    reps = {str(v) for v in (manifest.get("representations") or {}).values()}
    return reps | {"joints"} if reps else {"", "joints"}


def _check_meta(meta: dict | None, store_fps: float, protocol, accepted: set[str] | None = None) -> list[Problem]:
    if meta is None:
        return []
    out = []
    rep = meta.get("representation")
    if accepted is not None and isinstance(rep, str) and rep not in accepted:
        out.append(Problem("*", SUBMISSION_JSON, f"field 'representation' is {rep[:60]!r}, which does not match the "
                                                 f"store (one of {sorted(accepted)})"))
    for key, kind in REQUIRED_FIELDS.items():
        if key not in meta:
            out.append(Problem("*", SUBMISSION_JSON, f"missing field {key!r}"))
        elif not isinstance(meta[key], kind) or isinstance(meta[key], bool):
            want = "a number" if key == "fps" else "a string"
            out.append(Problem("*", SUBMISSION_JSON, f"field {key!r} must be {want}, got {meta[key]!r}"))
    if "url" in meta and not isinstance(meta["url"], str):
        out.append(Problem("*", SUBMISSION_JSON, f"field 'url' must be a string, got {meta['url']!r}"))
    flags = meta.get("flags", {})
    if not isinstance(flags, dict):
        out.append(Problem("*", SUBMISSION_JSON, f"field 'flags' must be an object, got {flags!r}"))
    else:
        for key, kind in FLAG_FIELDS.items():
            if key in flags and (not isinstance(flags[key], kind) or (kind is int and isinstance(flags[key], bool))):
                out.append(Problem("*", SUBMISSION_JSON, f"flags.{key} must be {kind.__name__}, got {flags[key]!r}"))
        if isinstance(flags.get("samples_per_prompt"), int) and flags["samples_per_prompt"] < 1:
            out.append(Problem("*", SUBMISSION_JSON, "flags.samples_per_prompt must be >= 1"))
    fps = meta.get("fps")
    if _is_number(fps) and not (math.isfinite(fps) and fps > 0):
        out.append(Problem("*", SUBMISSION_JSON, f"field 'fps' must be a positive finite number, got {fps!r}"))
    elif _is_number(fps) and abs(float(fps) - store_fps) > 1e-6:
        out.append(Problem("*", SUBMISSION_JSON, f"fps {fps} but the store is evaluated at {store_fps:g} fps: "
                                                 "resample by time (not by dropping every n-th frame) first"))
    if protocol is not None and abs(protocol.fps - store_fps) > 1e-6:
        out.append(Problem("*", "protocol", f"protocol {protocol.ref} evaluates at {protocol.fps:g} fps but the "
                                            f"store holds {store_fps:g} fps clips"))
    return out


def _check_clip(sub: Submission, sid: str, ctx: ClipContext,
                keep=None) -> tuple[list[Problem], int | None, str | None]:
    """Problems of one sample file, its K (None when unknown) and the up axis its joints
    suggest (None when y-up or undecided); ``keep`` receives the arrays of a file without errors."""
    try:
        headers = sub.headers(sid)
    except SubmissionError as e:
        return [Problem(sid, "file", str(e))], None, None
    probs: list[Problem] = []
    for k in headers:
        if k not in KNOWN_ARRAYS:
            probs.append(Problem(sid, k, f"unexpected array {k!r} (ignored); known: {', '.join(KNOWN_ARRAYS)}",
                                 "warning"))
    if "joints" not in headers:
        probs.append(Problem(sid, "joints", "missing: every sample file needs joints (K, T, 22, 3)"))
    for k in ctx.required:
        if k not in headers:
            probs.append(Problem(sid, k, f"missing: this track's evaluator reads {k} "
                                         + ("(K, T, 77, 3): InterAct's body-surface markers, metres, the joints' "
                                            "frame (hoibench.bodies.markers.markers_from_vertices of the posed "
                                            "SMPL-H/SMPL-X vertices)" if k == "markers" else "")))
    if ctx.has_object and ctx.human_only:      # a human-only method on an HOI store: joints only
        for k in ("obj_rot", "obj_rotvec", "obj_trans"):
            if k in headers:
                probs.append(Problem(sid, k, "flags.human_only is set in submission.json but this file has object "
                                             "arrays: drop them, or the flag to have them scored"))
    elif ctx.has_object:
        hint = (" (a human-only method: set flags.human_only in submission.json -- hoibench import mdm|joints does "
                "-- and the object metrics are reported as not applicable)")
        if "obj_trans" not in headers:
            probs.append(Problem(sid, "obj_trans", "missing: the object's translation (K, T, 3) is required" + hint))
        if "obj_rot" not in headers and "obj_rotvec" not in headers:
            probs.append(Problem(sid, "obj_rot", "missing: give obj_rot (K, T, 3, 3) or obj_rotvec (K, T, 3)" + hint))
        if "obj_rot" in headers and "obj_rotvec" in headers:
            probs.append(Problem(sid, "obj_rot", "both obj_rot and obj_rotvec given: give exactly one"))
    else:       # human-only clip (RICH): joints only; object arrays are checked but measure nothing
        for k in ("obj_rot", "obj_rotvec", "obj_trans"):
            if k in headers:
                probs.append(Problem(sid, k, "the ground-truth clip has no object (human-only store): this "
                                             "array is not used by any metric", "warning"))
    shape_probs = (expect_shape(headers.get("joints"), (22, 3), "joints", sid, dtype="float32")
                   + expect_shape(headers.get("obj_rot"), (3, 3), "obj_rot", sid)
                   + expect_shape(headers.get("obj_rotvec"), (3,), "obj_rotvec", sid)
                   + expect_shape(headers.get("obj_trans"), (3,), "obj_trans", sid)
                   + expect_shape(headers.get("hml263"), (263,), "hml263", sid)
                   + expect_shape(headers.get("markers"), (77, 3), "markers", sid))
    probs += shape_probs
    bad = {p.field for p in shape_probs}
    present = [k for k in KNOWN_ARRAYS if k in headers and k not in bad]
    K = T = None
    if "joints" in present:
        K, T = headers["joints"].shape[:2]
    for k in present:
        if k == "joints" or K is None:
            continue
        kk, tt = headers[k].shape[:2]
        if kk != K:
            probs.append(Problem(sid, k, f"{kk} samples but joints has {K}"))
            bad.add(k)
        if k == "hml263":
            if tt not in (T - 1, T):
                probs.append(Problem(sid, k, f"{tt} frames; expected T - 1 = {T - 1} or T = {T} (joints has T = {T})"))
                bad.add(k)
        elif tt != T:
            probs.append(Problem(sid, k, f"{tt} frames but joints has {T}"))
            bad.add(k)
    gt, fps = ctx.gt_frames, ctx.fps
    if K is not None:
        if K > ctx.max_samples:
            probs.append(Problem(sid, "joints", f"K = {K} samples per prompt, over the protocol's cap of "
                                                f"{ctx.max_samples} (no metric uses more): not loaded"))
            return probs, K, None
        if T < 2:
            probs.append(Problem(sid, "joints", f"{T} frame(s): at least 2 are needed"))
        elif ctx.uses_gt_length and T != gt:
            probs.append(Problem(sid, "joints", f"{T} frames, but submission.json says uses_gt_length and the "
                                                f"ground truth has {gt}"))
        elif T > max_frames(gt, fps):
            probs.append(Problem(sid, "joints", f"{T} frames, more than max(4x, +10 s) the ground truth's {gt} at "
                                                f"{fps:g} fps: wrong frame rate?"))
        elif not (gt / 2 <= T <= 2 * gt):
            probs.append(Problem(sid, "joints", f"{T} frames vs {gt} in the ground truth (outside 0.5x-2x)",
                                 "warning"))
    ok = [k for k in present if k not in bad]
    if not ok or K is None or any(p.severity == "error" and p.field == "joints" for p in probs):
        return probs, K, None
    try:
        arrays = sub.load(sid, ok)
    except SubmissionError as e:
        return probs + [Problem(sid, "file", str(e))], K, None
    value_probs, up = check_arrays(sid, arrays, ctx)
    if keep is not None and not any(p.severity == "error" for p in probs + value_probs):
        keep.keep_arrays(sid, arrays)
    return probs + value_probs, K, up


def submission_context(st, protocol, split: str = "test") -> tuple[dict, float, int, str]:
    """(test rows by id, store fps, K cap, hoi269 mode) for a store and an optional protocol."""
    rows = {c["id"]: c for c in st.manifest["clips"] if c["split"] == split}
    fps = float(st.manifest["config"]["fps"])
    if protocol is None:        # the store's default protocol fixes the K cap when it exists
        from ..tracks.protocol import default_protocol
        protocol = default_protocol(st.manifest)
    cap = protocol.max_samples_per_prompt if protocol is not None and protocol.kind in ("hoi", "interact-task") \
        else DEFAULT_MAX_SAMPLES_PER_PROMPT           # a multi-body protocol reads every sample
    mode = "legacy" if str(st.manifest["config"].get("mode", "clean")).startswith("legacy") else "clean"
    return rows, fps, int(cap), mode


def required_arrays(protocol) -> tuple[str, ...]:
    """Sample arrays beyond joints and object poses that ``protocol``'s track needs (its
    ``submission_arrays`` extra: the interact track's evaluator reads ``markers``)."""
    track = getattr(protocol, "track", "") if protocol is not None else ""
    if not track:
        return ()
    from ..tracks.registry import get_track
    try:
        return tuple(get_track(track).extras.get("submission_arrays", ()))
    except (KeyError, ValueError):
        return ()


#: a submission-wide up-axis error needs at least this many clips agreeing, and a majority
UP_AXIS_MIN_CLIPS = 3
#: how to convert, by the up axis the files look like
UP_FIX = {"z": ", e.g. `hoibench import joints JOINTS_DIR --data DATA --out SUB --up z` (z-up joints -> y-up)"}


def foreign_ids_line(submission: str | Path, data: str | Path, submitted: Iterable[str],
                     test_ids: Iterable[str]) -> str | None:
    """The one line that leads ``validate``/``evaluate`` when most ``submitted`` ids belong to
    no test split of the store (a submission made for another store); None otherwise."""
    submitted, tests = sorted(set(submitted)), set(test_ids)
    foreign = [i for i in submitted if i not in tests]
    if not submitted or 2 * len(foreign) <= len(submitted):
        return None
    return (f"{submission}: these ids belong to no test split of this store ({len(foreign)} of {len(submitted)}, "
            f"e.g. {foreign[0]!r}): is --data {data} the right store?")


def validation_report(sub, store, split: str = "test", protocol=None,
                      max_array_bytes: int | None = None, keep=None) -> ValidationReport:
    """Validate ``sub`` (path or :class:`Submission`) against ``store`` (path or
    :class:`hoibench.datasets.store.Store`); never raises on a broken submission. See :func:`validate`.
    ``keep``: a :class:`hoibench.scoring.read_cache.ReadCache` that receives the arrays and
    encoded features of the files that validate (scoring then reads each file once)."""
    from .read_cache import feature_sink
    from ..datasets.store import Store

    st = store if isinstance(store, Store) else Store(store)
    if protocol is not None and not hasattr(protocol, "fps"):
        from ..tracks.protocol import get_protocol
        protocol = get_protocol(protocol)
    if _is_multibody(st):
        return multibody_report(sub, st, split, protocol)
    rows, fps, cap, mode = submission_context(st, protocol, split)
    required = required_arrays(protocol)
    task = protocol.task if protocol is not None and protocol.kind == "interact-task" else None
    limits = limits_for(rows, fps, cap)
    if max_array_bytes is not None:
        limits = SubmissionLimits({k: min(v, max_array_bytes) for k, v in limits.per_id_bytes.items()},
                                  min(limits.total_bytes, max_array_bytes * max(1, len(rows))), cap, limits.max_files)
    own = not isinstance(sub, Submission)
    s = Submission(sub, limits=limits) if own else sub
    if not own and s.limits is None:
        s.limits = limits
    try:
        problems = list(s.problems)
        problems += _check_meta(s.meta, fps, protocol, accepted_representations(st.manifest))
        flags = (s.meta or {}).get("flags", {}) if isinstance((s.meta or {}).get("flags", {}), dict) else {}
        test_ids = sorted(rows)
        found = set(s.ids)
        for sid in test_ids:
            if sid not in found and not s.unreadable and not any(p.id == sid for p in problems):
                problems.append(Problem(sid, SAMPLES_DIR, f"missing: no {SAMPLES_DIR}/{sid}.npz"))
        for sid in sorted(found - set(rows)):
            why = f"not a valid id ({ID_RULE})" if not is_valid_id(sid) else \
                f"not in the {split!r} split of dataset {st.manifest.get('dataset', '?')!r}"
            problems.append(Problem(sid, SAMPLES_DIR, f"extra file: {why} (not read)"))
        refused = {p.id for p in problems if p.severity == "error" and p.id != "*"}
        valid, ks, ups = [], {}, {}
        sink = feature_sink(keep)
        batcher = EncodeBatcher(mode, fps, sink)
        for sid in test_ids:
            if sid not in found or sid in refused:
                continue
            if task:            # InterAct's o2h/h2o tracks: markers or object poses only
                from .interact_task_files import file_problems
                (probs, K), up = file_problems(s, sid, task, int(rows[sid]["frames"]), cap), None
            else:
                ctx = ClipContext(int(rows[sid]["frames"]), bool(rows[sid].get("object")), fps,
                                  bool(flags.get("uses_gt_length", False)) is True, cap, mode, required,
                                  human_only=flags.get("human_only") is True, encoded=sink, batcher=batcher)
                probs, K, up = _check_clip(s, sid, ctx, keep)
            problems += probs
            if K is not None:
                ks[sid] = K
            if up is not None:
                ups[sid] = up
            if not any(p.severity == "error" for p in probs):
                valid.append(sid)
        late = batcher.finish()             # the samples' encodings, checked in batches
        if late:
            problems += late.values()
            valid = [sid for sid in valid if sid not in late]
            if keep is not None:
                for sid in late:
                    keep.drop(sid)               # kept before its encoding failed
        kvals = sorted(set(ks.values()))
        spp = flags.get("samples_per_prompt")
        if len(kvals) > 1:
            problems.append(Problem("*", SAMPLES_DIR, f"samples per prompt differ between files: K in {kvals}"))
        elif kvals and isinstance(spp, int) and not isinstance(spp, bool) and spp != kvals[0]:
            problems.append(Problem("*", SUBMISSION_JSON, f"flags.samples_per_prompt is {spp} but the files hold "
                                                          f"K = {kvals[0]}"))
        if ups:
            axis, n = max(((a, sum(1 for u in ups.values() if u == a)) for a in set(ups.values())), key=lambda x: x[1])
            if n >= min(UP_AXIS_MIN_CLIPS, len(ks)) and n > len(ks) / 2:
                problems.append(Problem("*", "joints", f"{n} of {len(ks)} sample files look {axis}-up (their feet "
                                                       f"are the lowest joints along {axis}, not y): hoibench is y-up; "
                                                       "rotate the motions (and objects) into y-up first"
                                                       + UP_FIX.get(axis, "")))
        if protocol is not None and protocol.kind == "hoi" and kvals and kvals[0] <= protocol.mm_pairs:
            problems.append(Problem("*", SAMPLES_DIR, f"K = {kvals[0]} sample(s) per prompt: MultiModality needs "
                                                      f"{protocol.mm_samples} and will not be computed", "warning"))
        problems.sort(key=lambda p: (p.id != "*", p.id, p.field, p.message))
        return ValidationReport(problems, test_ids, valid, kvals[0] if len(kvals) == 1 else None, sorted(found),
                                foreign_ids_line(s.path, st.root, found, test_ids))
    finally:
        if own:
            s.close()


def _is_multibody(st) -> bool:
    """Whether the store holds multi-body clips; False when its first clip file cannot be read
    (validation then needs only the manifest, as before)."""
    try:
        return bool(st.is_multibody)
    except (OSError, ValueError):
        return False


def multibody_report(sub, st, split: str = "test", protocol=None) -> ValidationReport:
    """:func:`validation_report` for a multi-body store: the container and ``submission.json``
    as for single-body stores, each file within its budget
    (:func:`hoibench.scoring.multibody.multibody_limits`), and every sample read as the
    scorer reads it (one array per body of the clip, its shape, finite values within 1 km,
    at most 50 m/s, rotation matrices)."""
    from ..bodies.multibody import MultiBodyClip
    from .multibody_samples import clip_from_sample, multibody_limits
    if protocol is None:
        from ..tracks.protocol import default_protocol
        protocol = default_protocol(st.manifest)
    # the protocol's K is what it scores; SD needs K >= 2, so files may hold up to the default cap
    cap = max(int(getattr(protocol, "samples_per_prompt", None) or 1), DEFAULT_MAX_SAMPLES_PER_PROMPT)
    rows = {c["id"]: c for c in st.manifest["clips"] if c["split"] == split}
    test_ids, fps = sorted(rows), float(st.manifest["config"]["fps"])
    own = not isinstance(sub, Submission)
    s = Submission(sub, limits=multibody_limits(st, test_ids, cap)) if own else sub
    try:
        accepted = accepted_representations(st.manifest) | {"multibody-joints"}
        problems = list(s.problems) + _check_meta(s.meta, fps, None, accepted)
        found, valid, ks = set(s.ids), [], set()
        problems += [Problem(sid, SAMPLES_DIR, f"missing: no {SAMPLES_DIR}/{sid}.npz") for sid in test_ids
                     if sid not in found and not s.unreadable]
        problems += [Problem(sid, SAMPLES_DIR, f"extra file: not in the {split!r} split (not read)")
                     for sid in sorted(found - set(rows))]
        for sid in (i for i in test_ids if i in found):
            try:
                arrays = s.load(sid, keys=None)
                K = len(next(iter(arrays.values()))) if arrays else 0
                if not 1 <= K <= cap:
                    raise ValueError(f"{sid}: samples: K = {K} samples per prompt, expected 1..{cap}")
                gt = MultiBodyClip.from_arrays(st.load(sid))
                for k in range(K):
                    clip_from_sample(gt, arrays, k, sid)
            except ValueError as e:
                parts = str(e).split(": ")
                field_ = parts[1] if len(parts) > 2 and parts[0] == sid else "file"
                problems.append(Problem(sid, field_, ": ".join(parts[2:]) if field_ != "file" else str(e)))
                continue
            ks.add(K)
            valid.append(sid)
        if len(ks) > 1:
            problems.append(Problem("*", SAMPLES_DIR, f"samples per prompt differ between files: K in {sorted(ks)}"))
        problems.sort(key=lambda p: (p.id != "*", p.id, p.field, p.message))
        return ValidationReport(problems, test_ids, valid, min(ks) if len(ks) == 1 else None, sorted(found),
                                foreign_ids_line(s.path, st.root, found, test_ids))
    finally:
        if own:
            s.close()


def validate(sub, store, split: str = "test", protocol=None,
             max_array_bytes: int | None = None) -> list[Problem]:
    """Every problem of a submission at once (errors and warnings), sorted by id and field.

    Checks: the container (zip member paths, links, repeated members, special files),
    ``submission.json`` fields and types (strict JSON: no NaN), fps against the store, ids
    against the store's ``split`` (missing, extra, the id rule), per file: readable safely
    within its byte budget (no pickles, no oversized, negative or empty dimensions, no
    repeated arrays), required arrays, shapes, dtypes (joints float32; others float32 or
    float64), K within the protocol's cap, consistent K and T, finite values, plausibility
    bounds (|coordinate| <= 1 km, pelvis and object <= 50 m/s, object <= 100 m from the
    pelvis in every frame), plausible units (body height 0.5-3 m per sample and no frame
    outside 0.25-6 m; object within 20 m of the pelvis, median per sample), y-up (an error
    when most files look x- or z-up), lengths (>= 2 frames; equal to the ground truth's
    when ``uses_gt_length``; at most max(4x, +10 s); a warning outside 0.5x-2x), object
    rotation matrices (orthonormal within 1e-3, det > 0), and every sample encodes to finite
    features. A submission is complete only when no problem is an error.
    """
    return validation_report(sub, store, split, protocol, max_array_bytes).problems


# ====================================================================== CLI entry points
def main_validate(sub: str | Path, data: str | Path, protocol: str | None = None, split: str = "test",
                  as_json: bool = False) -> int:
    """``hoibench validate SUB --data DATA``: print every problem; exit status 0 when the
    submission is complete (warnings allowed), 1 when it has errors, 2 when the store or
    protocol cannot be read."""
    p = Path(sub)
    if not (p.is_dir() or p.is_file()):
        what = "does not exist" if not p.exists() else "is neither a folder nor a regular file"
        print(f"hoibench validate: error: {sub}: {what} (expected a submission folder or .zip)", file=sys.stderr)
        return 2
    try:
        rep = validation_report(sub, data, split, protocol)
    except (FileNotFoundError, KeyError, ValueError) as e:
        print(f"hoibench validate: error: {e.args[0] if isinstance(e, KeyError) else e}", file=sys.stderr)
        return 2
    if as_json:
        print(json.dumps(rep.to_dict(), indent=2, sort_keys=True))
    else:
        if rep.lead:
            print(rep.lead)
        for p in rep.problems:
            print(p)
        state = "complete" if rep.complete else "INCOMPLETE (will not be scored as complete)"
        whole = [p for p in rep.errors if p.id == "*"]
        if not rep.complete and whole and len(rep.valid_ids) == len(rep.test_ids):
            state = (f"INCOMPLETE: every sample file is valid, but {len(whole)} error(s) of the whole submission "
                     f"({whole[0].field}) keep it from being scored as complete")
        print(f"{sub}: {len(rep.errors)} error(s), {len(rep.warnings)} warning(s); "
              f"{len(rep.valid_ids)} of {len(rep.test_ids)} test ids valid; {state}")
        misfit = _protocol_misfit(protocol, data)
        if misfit:
            print(f"note: --protocol {protocol} does not fit the store ({misfit}): hoibench evaluate refuses it "
                  f"without --allow-protocol-mismatch")
    return 0 if rep.complete else 1


def _protocol_misfit(protocol: str | None, data: str | Path) -> str:
    """Why a named protocol does not fit the store (``protocol_mismatches``), or ''."""
    if protocol is None:
        return ""
    from ..datasets.store import Store
    from ..tracks.protocol import get_protocol, protocol_mismatches
    try:
        return "; ".join(protocol_mismatches(get_protocol(protocol), Store(data).manifest))
    except (AttributeError, KeyError, TypeError, ValueError):
        return ""
