"""``hoibench evaluate``: score a submission under a versioned protocol, for every track.

:func:`evaluate` is the one evaluation function: the store names its track
(:func:`hoibench.tracks.registry.track_for`: a given protocol may name another track of the
store's dataset), the track its protocol kind, evaluator
kind and scorer; the scorer runs the stages of :mod:`hoibench.scoring.pipeline`
(prepare -> validate -> stream per-clip units on the executor -> replications -> summary).
What each stage does for single-body tracks is in :mod:`hoibench.scoring.hoi`, for
multi-body tracks in :mod:`hoibench.scoring.multibody`.
"""
from __future__ import annotations

import time
from pathlib import Path

from ..core.io import atomic_write_json
from ..datasets.store import Store
from .pipeline import EvaluationRefused
from .report import format_result


def evaluate(submission: str | Path, data: str | Path, evaluator: str | Path | None, protocol=None,
             executor: str = "serial", allow_failed_gate: bool = False, allow_protocol_mismatch: bool = False,
             allow_evaluator_mismatch: bool = False, lead=None, clip_data: dict | None = None) -> dict:
    """Score ``submission`` against the store ``data`` with the evaluator folder ``evaluator``.

    The track is the store's (:func:`hoibench.tracks.registry.track_for`), or the one a given
    protocol names among the tracks of the store's dataset (``interact-o2h-clean`` on an
    interact store: the ``interact-o2h`` track). ``evaluator`` may be None for a track that
    reads none (InterAct's o2h and h2o tracks).

    Returns the result dictionary (also what ``--out`` writes). Raises
    :class:`EvaluationRefused` when the protocol or evaluator does not fit the store (unless
    allowed), when the evaluator fails its sanity gate on this store (unless
    ``allow_failed_gate``), or when nothing can be scored; a partial single-body submission
    is scored on its valid ids and marked ``complete: false`` (multi-body ones are scored
    complete only). The ``allow_*`` overrides apply to single-body tracks. ``protocol``: an
    id, ``id@version``, a YAML path or a :class:`~hoibench.tracks.protocol.Protocol`. ``lead``:
    called with the one line that says the submission was made for another store (most of its
    ids belong to no test split here), before scoring. ``clip_data``: a dict the scorer fills
    with the result's per-clip arrays (:mod:`hoibench.scoring.clip_data`; single-body tracks);
    the result then carries per-slice tables (``slices``, :mod:`hoibench.scoring.slices`).
    """
    from ..core.parallel import map_units, run_early, warm_executor
    from ..evaluator.backends import backend_of, load_evaluator, peek_card
    from ..tracks.protocol import default_protocol_id, get_protocol
    from ..tracks.registry import protocol_misfit, track_for
    from .pipeline import get_scorer

    started = time.perf_counter()
    store = Store(Path(data))
    proto = get_protocol(protocol or default_protocol_id(store.manifest))
    track = track_for(store, proto if protocol else None)
    misfit = protocol_misfit(store, proto, track)
    if misfit:
        raise EvaluationRefused(misfit)
    scorer_cls = get_scorer(track.scorer)
    needs_evaluator = track.evaluator_kind != "none"          # InterAct's o2h/h2o tracks read none
    if needs_evaluator and evaluator is None:
        raise EvaluationRefused(f"--evaluator: required: {data} is scored under {proto.ref} with a "
                                f"{track.evaluator_kind} evaluator")
    backend = backend_of(evaluator) if needs_evaluator else None
    options = {"allow_failed_gate": allow_failed_gate, "allow_protocol_mismatch": allow_protocol_mismatch,
               "allow_evaluator_mismatch": allow_evaluator_mismatch,
               "evaluator_backend": backend.name if backend else track.evaluator_kind, "clip_data": clip_data}
    # the card alone decides a mismatch: refuse it before the weights and the text encoder load
    card = peek_card(evaluator, track.evaluator_kind) if needs_evaluator else {}
    scorer_cls.check_fit(store, proto, card, options)
    # a process pool starts now: its workers build their caches while this process loads the
    # evaluator, embeds the ground truth and validates the submission
    with warm_executor(executor, scorer_cls.warm_up(store, proto)) as pool:
        slices = clip_data is not None and scorer_cls.fills_clip_data
        if slices:                       # the slice labels read only the store: an idle worker reads them
            from .slices import test_clip_labels
            read_labels = run_early(pool, test_clip_labels, str(store.root))
        ev = load_evaluator(evaluator, kind=track.evaluator_kind, **scorer_cls.evaluator_options) \
            if needs_evaluator else None
        scorer = scorer_cls(store, proto, ev, track, submission, options, started=started)
        scorer.pool = pool
        scorer.timings["load_s"] = time.perf_counter() - started      # store, protocol, evaluator
        scorer.prepare()
        with scorer.open_submission() as sub:
            if lead is not None:
                from .validate import foreign_ids_line
                line = foreign_ids_line(submission, data, list(sub.ids), store.clip_ids("test"))
                if line:
                    lead(line)
            ids = scorer.validate(sub)
            units = scorer.stream(sub, ids)          # sets up the unit's settings before the map
            for out in map_units(scorer.unit, units, pool, **scorer.map_options):
                scorer.update(out)
        labels = read_labels() if slices and clip_data else None
    result = scorer.summary(scorer.replications())
    if clip_data:
        from .slices import result_slices
        result["slices"] = result_slices(store, clip_data, proto, labels)
    return result


def check_evaluate_args(submission: str | Path, data: str | Path, evaluator: str | Path | None,
                        out: str | Path | None = None, protocol: str | None = None, executor: str = "serial",
                        overwrite: bool = False):
    """Refuse bad arguments of ``hoibench evaluate`` before any store is read (one line each):
    the executor spec, the protocol id, the store, evaluator and submission paths, and
    ``--out`` (a file that is not there yet, unless ``overwrite``). Returns the protocol
    (resolved once; None when not given)."""
    from ..core.parallel import parse_executor
    from ..tracks.protocol import get_protocol
    parse_executor(executor)
    resolved = get_protocol(protocol) if protocol is not None else None
    if not (Path(data) / "manifest.json").is_file():
        raise FileNotFoundError(f"--data {data}: not a hoibench store (no manifest.json)")
    if evaluator is None:
        if resolved is None or not _reads_no_evaluator(resolved):
            raise ValueError("--evaluator: required (InterAct's o2h and h2o protocols read none: name one of them "
                             "with --protocol to score without)")
    elif not Path(evaluator).is_dir():
        raise FileNotFoundError(f"--evaluator {evaluator}: no such folder (make one with `hoibench train-evaluator "
                                f"DATA --out EV`, or `hoibench train-recognizer` for a multi-body store)")
    sub = Path(submission)
    if not (sub.is_dir() or sub.is_file()):
        what = "does not exist" if not sub.exists() else "is neither a folder nor a regular file"
        raise FileNotFoundError(f"{submission}: {what} (expected a submission folder or .zip)")
    if out is not None:
        check_result_free(out, overwrite)
    return resolved


def _reads_no_evaluator(protocol) -> bool:
    """Whether ``protocol``'s track reads no evaluator (its ``evaluator_kind`` is ``none``)."""
    from ..tracks.registry import get_track
    try:
        return get_track(protocol.track).evaluator_kind == "none"
    except KeyError:
        return False


def check_result_free(out: str | Path, overwrite: bool = False) -> None:
    """Refuse ``--out`` when it is a folder, or a file already there unless ``overwrite``."""
    path = Path(out)
    if path.is_dir():
        raise ValueError(f"--out {out}: is a folder; give a file name such as result.json")
    if (path.exists() or path.is_symlink()) and not overwrite:
        raise FileExistsError(f"--out {out}: exists already (an earlier result?); pass --overwrite to replace it, "
                              f"or choose another file")


def main_evaluate(submission, data, evaluator, out=None, protocol=None, executor="serial",
                  allow_failed_gate: bool = False, allow_protocol_mismatch: bool = False,
                  allow_evaluator_mismatch: bool = False, overwrite: bool = False) -> int:
    """``hoibench evaluate``: exit 0 when complete, 1 when incomplete or overridden. Every
    argument is checked before the store is read; without ``out`` the last line says how to
    keep the result."""
    resolved = check_evaluate_args(submission, data, evaluator, out, protocol, executor, overwrite)
    clips: dict = {}
    result = evaluate(submission, data, evaluator, protocol=resolved, executor=executor,
                      allow_failed_gate=allow_failed_gate, allow_protocol_mismatch=allow_protocol_mismatch,
                      allow_evaluator_mismatch=allow_evaluator_mismatch, lead=print, clip_data=clips)
    if out is not None:
        if clips:
            from .clip_data import write_clip_data
            write_clip_data(result, clips, out)
        atomic_write_json(out, result)
    print(format_result(result))
    print(f"wrote {out}" if out is not None else "not written: pass --out result.json to keep it")
    return 0 if result["complete"] else 1


__all__ = ["evaluate", "format_result", "main_evaluate", "check_evaluate_args", "check_result_free",
           "EvaluationRefused"]
