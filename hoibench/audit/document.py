"""The audit as one document (``audit.json``, format ``hoibench-audit-1``) and the function
that makes it: :func:`run_audit` scores every corruption (:mod:`hoibench.audit.runner`),
draws the paired tests (:mod:`hoibench.audit.analysis`) and writes the files
(:mod:`hoibench.audit.report`).

``audit.json``::

    format, [layout: multibody (a multi-body store's families; absent: single-body)],
    provenance {store, dataset, store_config_sha256, evaluator_id, evaluator_variant,
                        evaluator_gate_passed, allow_failed_gate, protocol, protocol_version,
                        protocol_sha256, seed, resamples, alpha, test_clips, toolkit, toolkit_version}
    families     [names, in the order audited]
    metrics      [names, catalogue order]
    corruptions  {family: {severities, magnitudes, unit, corrupts, scope, description,
                           values {metric: [mean per severity]}}}
    summary      {metric: {family: {spearman, spearman_worse, direction, direction_ok, blind,
                                    effect_sd, effect_severity, detectable_severity,
                                    p_holm [..], diff [..], clips_needed [..]}}}

Nothing in it depends on the executor or the machine (no timings, no paths but the store's
as given), so the same arguments give the same bytes.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from .. import __version__
from .analysis import ALPHA, Draws, audited_metrics, family_summary, paired_tests
from .families import known_families, registry
from .runner import DEFAULT_SEED, Condition, check_objects, conditions, load_setup, score_conditions

#: the format tag of ``audit.json``
AUDIT_FORMAT = "hoibench-audit-1"


def _value(result: dict, metric: str) -> float | None:
    entry = result.get("metrics", {}).get(metric)
    if not isinstance(entry, dict) or entry.get("mean") is None or not np.isfinite(entry["mean"]):
        return None
    return float(entry["mean"])


def audit_document(setup, scored: Mapping[Condition, tuple[dict, dict]], families: Sequence[str], data: str,
                   seed: int, resamples: int, executor: str = "serial") -> dict:
    """The ``audit.json`` dict (module docstring) from :func:`score_conditions`' output."""
    from ..core.parallel import map_units
    layout = getattr(setup, "layout", "single")
    specs = registry(layout)
    conds = conditions(families, layout)
    metrics = audited_metrics([scored[c][0] for c in conds])
    first = scored[conds[0]]
    n = len(first[1]["ids"])
    draws = Draws(setup.proto, n, resamples, seed, executor)
    draws.prepare([scored[c][1] for c in conds])
    corruptions, summary = {}, {m: {} for m in metrics}

    def one_family(family: str) -> tuple[str, dict, dict]:
        spec = specs[family]
        mine = [c for c in conds if c.family == family]
        base = draws.of(scored[mine[0]][1])
        tests = [None] + [paired_tests(base, draws.of(scored[c][1]), metrics, n) for c in mine[1:]]
        values = {m: [_value(scored[c][0], m) for c in mine] for m in metrics}
        sev = [float(s) for s in spec.severities]
        entry = {"severities": sev, "magnitudes": [spec.magnitude(s) for s in sev], "unit": spec.unit,
                 "corrupts": spec.corrupts, "scope": spec.scope, "description": spec.description, "values": values}
        return family, entry, {m: family_summary(m, family, sev, values[m], [t and t.get(m) for t in tests], spec)
                               for m in metrics}

    for family, entry, rows in map_units(one_family, list(families), "serial", progress="audit: paired tests"):
        corruptions[family] = entry
        for m, row in rows.items():
            summary[m][family] = row
    result = first[0]
    return {"format": AUDIT_FORMAT, **({"layout": layout} if layout != "single" else {}),
            "provenance": _provenance(setup, result, data, seed, resamples, n),
            "families": list(families), "metrics": metrics, "corruptions": corruptions, "summary": summary}


def _provenance(setup, result: dict, data: str, seed: int, resamples: int, n: int) -> dict:
    manifest = setup.store.manifest
    return {"store": str(data), "dataset": manifest.get("dataset"),
            "store_config_sha256": manifest.get("config_sha256"),
            "evaluator_id": result.get("evaluator_id"), "evaluator_variant": result.get("evaluator_variant"),
            "evaluator_gate_passed": bool(result.get("evaluator_gate", {}).get("passed", False)),
            "allow_failed_gate": bool(setup.options.get("allow_failed_gate")),
            "overrides": result.get("overrides", []),
            "protocol": result.get("protocol"), "protocol_version": result.get("protocol_version"),
            "protocol_sha256": result.get("protocol_sha256"), "seed": int(seed), "resamples": int(resamples),
            "alpha": ALPHA, "test_clips": int(n), "toolkit": "hoibench", "toolkit_version": __version__}


def check_audit_args(data, evaluator, out, families: Sequence[str] | None, seed: int, resamples: int,
                     overwrite: bool = False, executor: str = "serial") -> list[str] | None:
    """Refuse bad arguments before anything is read, in one line naming the option; returns
    the families asked for (None: every family of the store's layout, chosen once it is read)."""
    from ..core.parallel import parse_executor
    from ..scoring.paired import MIN_RESAMPLES
    parse_executor(executor)
    known = known_families()
    chosen = list(families) if families else None
    for f in chosen or ():
        if f not in known:
            import difflib
            close = difflib.get_close_matches(f, known, n=1)
            raise ValueError(f"--families: unknown corruption family {f!r}"
                             + (f" (did you mean {close[0]!r}?)" if close else f" (known: {', '.join(known)})"))
    if chosen and len(set(chosen)) != len(chosen):
        raise ValueError("--families: a family is named twice")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"--seed {seed}: expected a non-negative integer")
    if not isinstance(resamples, (int, np.integer)) or resamples < 100:
        raise ValueError(f"--resamples {resamples}: expected at least 100 (the paired tests' default is {MIN_RESAMPLES})")
    if not (Path(data) / "manifest.json").is_file():
        raise FileNotFoundError(f"--data {data}: not a hoibench store (no manifest.json)")
    if not Path(evaluator).is_dir():
        raise FileNotFoundError(f"--evaluator {evaluator}: no such folder (make one with `hoibench train-evaluator "
                                f"DATA --out EV`)")
    o = Path(out)
    if o.exists() and not o.is_dir():
        raise ValueError(f"--out {out}: is a file; give a folder (audit.json, the heatmap and cards/ go in it)")
    if (o / "audit.json").exists() and not overwrite:
        raise FileExistsError(f"--out {out}: holds an audit.json already; pass --overwrite to replace it")
    return chosen


def run_audit(data: str | Path, evaluator: str | Path, out: str | Path, protocol=None,
              families: Sequence[str] | None = None, seed: int = DEFAULT_SEED, resamples: int | None = None,
              executor: str = "serial", allow_failed_gate: bool = False, overwrite: bool = False,
              log=print, allow_protocol_mismatch: bool = False) -> dict:
    """``hoibench audit``: score every severity of ``families`` (all by default) on the store's
    test split, test each against severity 0 and write ``audit.json``, the heatmap, the
    metric cards and ``README.md`` into ``out``. Returns the audit dict."""
    from ..scoring.paired import MIN_RESAMPLES
    from .report import write_report
    resamples = MIN_RESAMPLES if resamples is None else resamples
    chosen = check_audit_args(data, evaluator, out, families, seed, resamples, overwrite, executor)
    t0 = time.perf_counter()
    setup = load_setup(data, evaluator, protocol, allow_failed_gate, allow_protocol_mismatch)
    specs = registry(setup.layout)
    for f in chosen or ():
        if f not in specs:
            kind = {"single": "single-body", "multibody": "multi-body"}[setup.layout]
            raise ValueError(f"--families {f}: not a family of a {kind} store's audit (those are: "
                             f"{', '.join(specs)})")
    chosen = chosen or list(specs)
    kept = check_objects(setup.store, chosen, explicit=bool(families)) if setup.layout == "single" else chosen
    if kept != chosen:
        log(f"audit: {data} has test clips without an object; left out: {', '.join(f for f in chosen if f not in kept)}")
        chosen = kept
    scored = score_conditions(setup, chosen, seed, executor)
    t1 = time.perf_counter()
    doc = audit_document(setup, scored, chosen, str(data), seed, resamples, executor)
    t2 = time.perf_counter()
    paths = write_report(doc, out)
    log(f"audit: {len(conditions(chosen, setup.layout))} corrupted sets of {doc['provenance']['test_clips']} test clips scored in "
        f"{t1 - t0:.1f} s, paired tests ({resamples} resamples) in {t2 - t1:.1f} s; wrote "
        + ", ".join(str(p) for p in paths))
    return doc


__all__ = ["AUDIT_FORMAT", "audit_document", "check_audit_args", "run_audit"]
