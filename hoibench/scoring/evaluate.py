"""``hoibench evaluate``: score a submission under a versioned protocol, for every track.

:func:`evaluate` is the one evaluation function: the store names its track
(:func:`hoibench.tracks.registry.track_for_store`), the track its protocol kind, evaluator
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
from .hoi import EMBED_BATCH, EvaluationRefused, _finite_rows, format_result  # noqa: F401  (public names of 0.6)


def evaluate(submission: str | Path, data: str | Path, evaluator: str | Path, protocol: str | None = None,
             executor: str = "serial", allow_failed_gate: bool = False, allow_protocol_mismatch: bool = False,
             allow_evaluator_mismatch: bool = False) -> dict:
    """Score ``submission`` against the store ``data`` with the evaluator folder ``evaluator``.

    Returns the result dictionary (also what ``--out`` writes). Raises
    :class:`EvaluationRefused` when the protocol or evaluator does not fit the store (unless
    allowed), when the evaluator fails its sanity gate on this store (unless
    ``allow_failed_gate``), or when nothing can be scored; a partial single-body submission
    is scored on its valid ids and marked ``complete: false`` (multi-body ones are scored
    complete only). The ``allow_*`` overrides apply to single-body tracks.
    """
    from ..core.parallel import map_units
    from ..evaluator.backends import backend_of, load_evaluator
    from ..tracks.protocol import default_protocol_id, get_protocol
    from ..tracks.registry import track_for_store
    from .pipeline import get_scorer

    started = time.perf_counter()
    store = Store(Path(data))
    track = track_for_store(store)
    proto = get_protocol(protocol or default_protocol_id(store.manifest))
    if proto.kind != track.protocol_kind:
        raise EvaluationRefused(f"protocol {proto.ref} is a {proto.kind} protocol; {data} is a store of the "
                                f"{track.name} track, scored under {track.protocol_kind} protocols "
                                f"({', '.join(track.protocols)})")
    scorer_cls = get_scorer(track.scorer)
    ev = load_evaluator(evaluator, kind=track.evaluator_kind, **scorer_cls.evaluator_options)
    backend = backend_of(evaluator)
    scorer = scorer_cls(store, proto, ev, track, submission,
                        {"allow_failed_gate": allow_failed_gate, "allow_protocol_mismatch": allow_protocol_mismatch,
                         "allow_evaluator_mismatch": allow_evaluator_mismatch,
                         "evaluator_backend": backend.name if backend else track.evaluator_kind}, started=started)
    scorer.prepare()
    with scorer.open_submission() as sub:
        ids = scorer.validate(sub)
        units = scorer.stream(sub, ids)          # sets up the unit's settings before the map
        for out in map_units(scorer.unit, units, executor, **scorer.map_options):
            scorer.update(out)
    return scorer.summary(scorer.replications())


def format_any(result: dict) -> str:
    """A result of any track as text (its scorer's format)."""
    from .pipeline import get_scorer
    return get_scorer("multibody" if result.get("kind") == "multibody" else "hoi").format_result(result)


def main_evaluate(submission, data, evaluator, out=None, protocol=None, executor="serial",
                  allow_failed_gate: bool = False, allow_protocol_mismatch: bool = False,
                  allow_evaluator_mismatch: bool = False) -> int:
    """``hoibench evaluate``: exit 0 when complete, 1 when incomplete or overridden."""
    if out is not None and Path(out).is_dir():
        raise ValueError(f"--out {out}: is a folder; give a file name such as result.json")
    result = evaluate(submission, data, evaluator, protocol=protocol, executor=executor,
                      allow_failed_gate=allow_failed_gate, allow_protocol_mismatch=allow_protocol_mismatch,
                      allow_evaluator_mismatch=allow_evaluator_mismatch)
    if out is not None:
        atomic_write_json(out, result)
    print(format_any(result))
    if out is not None:
        print(f"wrote {out}")
    return 0 if result["complete"] else 1


__all__ = ["evaluate", "format_result", "format_any", "main_evaluate", "EvaluationRefused"]
