"""``hoibench compare A.json B.json [C.json ...] --paired``: does a difference mean anything?

Every result after the first is compared with the first (A) over the test clips both scored,
by a paired bootstrap: each of ``resamples`` (at least 2,000) draws the shared clips with
replacement once, and every metric of both results is recomputed on that draw from their
per-clip data (:mod:`hoibench.scoring.clip_data`, :mod:`hoibench.metrics.resampling`):

- FID, Diversity: on the drawn clips' embeddings (sample 0), less each set's bootstrap bias
  (:func:`~hoibench.metrics.resampling.debiased`: a draw repeats clips, which inflates FID
  more for a set farther from the real one); R-precision top-k and MM-Dist:
  per-clip values under the protocol's replication-0 pools of the shared clips, each clip's
  first caption (so they differ from the result's mean over replications; the difference is
  what is tested); the physical metrics (and a multi-body result's per-clip metrics): the mean
  of their per-clip values (a pooled metric such as PS or FSR weighs frames, the per-clip mean
  weighs clips);
- ``diff = B - A`` on all shared clips, its 95% percentile interval, a two-sided bootstrap
  p-value (for a metric best closest to the ground truth: of ``|B - GT| - |A - GT|``, the
  ground truth's value drawn with the same clips: Diversity, and the per-clip metrics whose
  data carry the ground truth's values, ``reference``), Holm's
  adjustment across the metrics of one pair, and a verdict: ``A better``, ``B better`` or
  ``not distinguishable on N clips`` (adjusted p >= 0.05).

The pairs over the same clips share their draws (:func:`compare_many`): per draw, A's and the
ground truth's set-level values and the real embeddings' covariance factor are computed once,
and each result's FID takes one eigenvalue problem
(:func:`~hoibench.metrics.resampling.draw_fids`); the point values on all clips are
:func:`~hoibench.metrics.resampling.weighted_fid`'s.

Results scored with another evaluator, protocol (id and version) or store are refused in one
line naming the field. The same seed gives the same numbers on every executor: the draws are
made up front and the per-resample work is split in fixed chunks.
"""
from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from ..metrics.catalog import METRICS
from ..metrics.resampling import (bootstrap_p, bootstrap_weights, debiased, draw_fids, holm, resampled_diversity,
                                  retrieval_per_clip, weighted_fid)

#: fewest resamples a paired comparison runs
MIN_RESAMPLES = 2000
#: the fields two results must share to be compared, and what they mean
SCALE_FIELDS = (("evaluator_id", "evaluator"), ("protocol", "protocol"), ("protocol_version", "protocol version"),
                ("dataset", "store dataset"), ("store_config_sha256", "store"))
ALPHA = 0.05
_CHUNK = 100


def _seed(*parts) -> int:
    return int.from_bytes(hashlib.sha256(repr(parts).encode()).digest()[:4], "little")


def _is_entry(r: dict) -> bool:
    """A leaderboard entry (read as a result): it keeps no store fields."""
    return "dataset" not in r and "store_config_sha256" not in r and "method" in r


def _test_ids(r: dict):
    """The test-split size of a result (``counts.test_ids``) or a leaderboard entry (``test_ids``)."""
    return (r.get("counts") or {}).get("test_ids", r.get("test_ids"))


def check_same_scale(a: dict, b: dict, a_path, b_path) -> None:
    """ValueError naming the first field on which ``b`` was scored differently from ``a``, or
    its test-split size (``counts.test_ids``) when it is not ``a``'s: two stores prepared with
    the same settings share ``store_config_sha256`` but not their clips. A leaderboard entry
    keeps no store fields: with one, the two must name the same track instead."""
    fields = SCALE_FIELDS
    if _is_entry(a) or _is_entry(b):
        fields = tuple(f for f in SCALE_FIELDS if f[0] not in ("dataset", "store_config_sha256")) + \
            (("track", "track"),)
    for field, what in fields:
        if a.get(field) != b.get(field):
            raise ValueError(f"{b_path}: field {field}: {str(b.get(field))[:16]} is not {a_path}'s "
                             f"{str(a.get(field))[:16]}: a paired comparison needs one {what}")
    na, nb = _test_ids(a), _test_ids(b)          # whole numbers (counts_problem)
    if na is not None and nb is not None and na != nb:
        raise ValueError(f"{b_path}: field {'test_ids' if _is_entry(b) else 'counts.test_ids'}: {nb} test clips, "
                         f"not {a_path}'s {na}: results of different stores or splits")


class _Side:
    """One result's per-clip statistics on the shared clips."""

    def __init__(self, arrays: dict, order: np.ndarray, pools: list, top_k: int):
        self.motion = arrays["motion"][0][order].astype(np.float64)
        self.real = arrays["real"][order].astype(np.float64)
        self.hits = self.mmd = None
        if has_text(arrays):               # a multi-body result's recognizer has no text branch
            offsets = arrays["text_offsets"]
            text = arrays["text"][offsets[:-1][order]].astype(np.float64)    # each clip's first caption
            self.hits, self.mmd = retrieval_per_clip(text, self.motion, pools, top_k)
        names = [str(n) for n in arrays["physical_names"]]
        self.physical = {n: arrays["physical"][0][order, j] for j, n in enumerate(names)}
        #: the ground truth's per-clip values of the same metrics, where the data carry them
        self.reference = {n: arrays["reference"][order, j] for j, n in enumerate(names)} \
            if "reference" in arrays else {}

    def per_clip(self) -> dict[str, np.ndarray]:
        out = {}
        if self.hits is not None:
            out = {f"r_precision_top{k + 1}": self.hits[:, k] for k in range(self.hits.shape[1])}
            out["mm_dist"] = self.mmd
        out.update(self.physical)
        return out


def has_text(arrays: dict) -> bool:
    """Whether per-clip data carry caption embeddings (single-body results; a multi-body
    result's recognizer embeds no text)."""
    return "text" in arrays and len(arrays["text"]) > 0


def _means(values: np.ndarray, W: np.ndarray) -> np.ndarray:
    """Weighted means of per-clip ``values`` for every row of ``W`` (NaN clips left out)."""
    ok = np.isfinite(values)
    den = W[:, ok].sum(1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, W[:, ok] @ values[ok] / np.maximum(den, 1), np.nan)


def _set_level(job: tuple) -> dict[str, np.ndarray]:
    """On a chunk ``W`` of draws starting at draw ``start``: every generated set's FID
    (:func:`~hoibench.metrics.resampling.draw_fids`: the real side's statistics once per draw)
    and Diversity, ``(len(W), len(motions))``, and the ground truth's Diversity ``div_gt``
    ``(len(W),)``; draw ``i``'s Diversity pairs are seeded by ``(seed, start + i)``. BLAS runs
    on one thread: the executor runs chunks side by side, two BLAS threads per process made the
    eigenvalue steps many times slower on a busy machine, and the numbers do not depend on how
    many threads a machine would give BLAS."""
    from threadpoolctl import threadpool_limits
    start, W, motions, real, pairs, seed = job
    out = {"fid": np.empty((len(W), len(motions))), "div": np.empty((len(W), len(motions))),
           "div_gt": np.empty(len(W))}
    with threadpool_limits(limits=1, user_api="blas"):
        for i, w in enumerate(W):
            s = _seed(seed, start + i)
            out["fid"][i] = draw_fids(real, motions, w)
            out["div"][i] = [resampled_diversity(m, w, pairs, s) for m in motions]
            out["div_gt"][i] = resampled_diversity(real, w, pairs, s)
    return out


def _set_level_draws(motions: list[np.ndarray], real: np.ndarray, W: np.ndarray, pairs: int, seed: int,
                     executor: str = "serial") -> dict[str, np.ndarray]:
    """:func:`_set_level` on every row of ``W``, in fixed chunks of :data:`_CHUNK` draws on
    ``executor`` (the same numbers on every executor)."""
    from ..core.parallel import map_units
    jobs = [(s, W[s:s + _CHUNK], motions, real, pairs, seed) for s in range(0, len(W), _CHUNK)]
    chunks = list(map_units(_set_level, jobs, executor))
    return {k: np.concatenate([c[k] for c in chunks]) for k in chunks[0]}


def _set_level_debiased(motions: list[np.ndarray], real: np.ndarray, W: np.ndarray, pairs: int, seed: int,
                        executor: str = "serial") -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """``(draws, points)``: :func:`_set_level_draws` less each set's bootstrap bias
    (:func:`~hoibench.metrics.resampling.debiased` against :func:`_set_level_full`'s points),
    and those points."""
    boot = _set_level_draws(motions, real, W, pairs, seed, executor)
    full = _set_level_full(motions, real, pairs, seed)
    return {k: debiased(v, full[k]) for k, v in boot.items()}, full


def _set_level_full(motions: list[np.ndarray], real: np.ndarray, pairs: int, seed: int) -> dict[str, np.ndarray]:
    """The point values on all clips: :func:`weighted_fid` with unit weights and the Diversity of
    draw 0's seed, per generated set (``fid``, ``div``), and the ground truth's ``div_gt``."""
    ones, s = np.ones(len(real)), _seed(seed, 0)
    return {"fid": np.array([weighted_fid(real, m, ones) for m in motions]),
            "div": np.array([resampled_diversity(m, ones, pairs, s) for m in motions]),
            "div_gt": np.array(resampled_diversity(real, ones, pairs, s))}


def favours_b(direction: str, diff: float) -> bool | None:
    """Whether ``diff = B - A`` favours B for a metric of catalogue ``direction`` (None for a
    metric best closest to the ground truth, whose side a plain difference does not tell)."""
    return {"lower": diff < 0, "higher": diff > 0}.get(direction)


def _verdict(p_holm: float, better_b: bool | None, n: int) -> str:
    """``A better`` / ``B better`` when the adjusted p is under :data:`ALPHA`, else not distinguishable."""
    if not np.isfinite(p_holm) or p_holm >= ALPHA:
        return f"not distinguishable on {n} clips"
    if better_b is None:
        return f"different on {n} clips (neither end is better)"
    return "B better" if better_b else "A better"


def _shared(a_arrays: dict, b_arrays: dict) -> tuple[str, ...]:
    """The sorted clip ids both results scored (ValueError under 2)."""
    shared = tuple(sorted({str(x) for x in a_arrays["ids"]} & {str(x) for x in b_arrays["ids"]}))
    if len(shared) < 2:
        raise ValueError(f"the two results share {len(shared)} scored test clip(s): a paired comparison needs 2 or more")
    return shared


def _sides(arrays: list[dict], shared: tuple[str, ...], proto) -> list[_Side]:
    """Each result's :class:`_Side` on the ``shared`` clips (replication-0 pools of them)."""
    pools = _pools(proto, list(shared)) if all(has_text(a) for a in arrays) else []
    top_k = int(proto.r_precision_top_k or 3)
    out = []
    for arr in arrays:
        at = {str(c): i for i, c in enumerate(arr["ids"])}
        out.append(_Side(arr, np.array([at[c] for c in shared]), pools, top_k))
    return out


def compare_pair(a: dict, a_arrays: dict, b: dict, b_arrays: dict, proto, resamples: int = MIN_RESAMPLES,
                 seed: int = 0, executor: str = "serial") -> dict:
    """The paired comparison of two results (module docstring): ``{"n_clips", "metrics": {name:
    {"diff", "ci95", "p", "p_holm", "verdict", "a", "b", "direction", "unit", "tested"}}}``."""
    return compare_many(a, a_arrays, [(b, b_arrays)], proto, resamples, seed, executor)[0]


def compare_many(a: dict, a_arrays: dict, others: list[tuple[dict, dict]], proto, resamples: int = MIN_RESAMPLES,
                 seed: int = 0, executor: str = "serial", stages: dict[str, float] | None = None) -> list[dict]:
    """:func:`compare_pair` of ``a`` with each ``(b, b_arrays)`` of ``others``, in order. Pairs
    that share the same clips share the draws: A's, the ground truth's and each B's set-level
    values are computed once per draw (not once per pair). ``stages``, when given, gets the
    seconds spent per stage added to it."""
    import time
    shared = [_shared(a_arrays, b_arrays) for _, b_arrays in others]
    out: list[dict | None] = [None] * len(others)
    for ids in dict.fromkeys(shared):
        group = [j for j, s in enumerate(shared) if s == ids]
        t0 = time.perf_counter()
        sides = _sides([a_arrays] + [others[j][1] for j in group], ids, proto)
        W = bootstrap_weights(len(ids), resamples, seed).astype(np.float64)
        pairs = int(min(proto.diversity_pairs or 300, 300))
        motions = [side.motion for side in sides]
        t1 = time.perf_counter()
        boot, full = _set_level_debiased(motions, sides[0].real, W, pairs, seed, executor)
        t2 = time.perf_counter()
        for k, j in enumerate(group, 1):
            out[j] = _pair_rows(a, others[j][0], sides[0], sides[k], W, _column(boot, 0, k), _column(full, 0, k))
        if stages is not None:
            for name, sec in (("per-clip data of the shared clips", t1 - t0),
                              ("set-level draws and points (FID, Diversity)", t2 - t1),
                              ("per-clip draws and tests", time.perf_counter() - t2)):
                stages[name] = stages.get(name, 0.0) + sec
    return out


def _column(values: dict[str, np.ndarray], i: int, j: int) -> dict[str, np.ndarray]:
    """Sides ``i`` (A) and ``j`` (B) of :func:`_set_level` values: ``fid_a``, ``fid_b``, ``div_a``,
    ``div_b``, ``div_gt``."""
    return {"fid_a": values["fid"][..., i], "fid_b": values["fid"][..., j], "div_a": values["div"][..., i],
            "div_b": values["div"][..., j], "div_gt": values["div_gt"]}


def _pair_rows(a: dict, b: dict, A: _Side, B: _Side, W: np.ndarray, boot: dict, full: dict) -> dict:
    """One pair's rows (:func:`compare_pair`) from the draws ``W``, the set-level draws ``boot``
    and the set-level points ``full`` (:func:`_column`)."""
    n = W.shape[1]
    ones = np.ones((1, n))
    names = [m for m in METRICS if m in a["metrics"] and m in b["metrics"]]
    pa, pb = A.per_clip(), B.per_clip()
    rows, pvals = {}, []
    for m in names:
        info = METRICS[m]
        if m in pa and m in pb:
            va, vb = _means(pa[m], W), _means(pb[m], W)
            vg = _means(A.reference[m], W) if m in A.reference else None
            fa, fb = float(_means(pa[m], ones)[0]), float(_means(pb[m], ones)[0])
        elif m == "fid":
            va, vb, vg, fa, fb = boot["fid_a"], boot["fid_b"], None, float(full["fid_a"]), float(full["fid_b"])
        elif m == "diversity":
            va, vb, vg = boot["div_a"], boot["div_b"], boot["div_gt"]
            fa, fb = float(full["div_a"]), float(full["div_b"])
        else:
            continue                          # no per-clip data for it (e.g. MultiModality)
        diff = vb - va
        tested = "difference"
        stat = diff
        if info.direction == "gt" and vg is not None:
            stat, tested = np.abs(vb - vg) - np.abs(va - vg), "distance to the ground truth"
        ok = diff[np.isfinite(diff)]
        lo, hi = (np.percentile(ok, [2.5, 97.5]) if len(ok) else (np.nan, np.nan))
        p = bootstrap_p(stat)
        point = fb - fa
        better = favours_b(info.direction, point)
        if tested.startswith("distance"):
            better = float(np.nanmean(stat)) < 0
        rows[m] = {"a": fa, "b": fb, "diff": point, "ci95": [float(lo), float(hi)], "p": p, "direction": info.direction,
                   "unit": info.unit, "tested": tested, "_better_b": better}
        pvals.append(p)
    adjusted = holm([x if np.isfinite(x) else 1.0 for x in pvals])
    for (m, row), ph in zip(rows.items(), adjusted):
        row["p_holm"] = ph
        row["verdict"] = _verdict(ph, row.pop("_better_b"), n)
    return {"n_clips": n, "metrics": rows}


def paired_compare(paths: list, resamples: int = MIN_RESAMPLES, seed: int = 0, executor: str = "serial",
                   extra=None) -> dict:
    """Every result after the first against the first (module docstring; :func:`compare_many`:
    the draws of pairs over the same clips are shared); the ``cmp.json`` dict.
    ``extra(a, a_arrays, b, b_arrays, proto)``, when given, returns more fields for each pair
    (the CLI adds :func:`hoibench.scoring.slices.slice_gaps`)."""
    from ..tracks.protocol import get_protocol
    from .clip_data import read_clip_data
    from .compare import _method
    from .results import read_result
    if len(paths) < 2:
        raise ValueError("compare --paired: give at least two result files")
    if resamples < MIN_RESAMPLES:
        raise ValueError(f"--resamples {resamples}: a paired comparison runs at least {MIN_RESAMPLES}")
    seen: dict = {}
    for p in paths:
        key = Path(p).resolve()
        if key in seen:
            raise ValueError(f"{p}: given twice (as {seen[key]}): a paired comparison needs two results")
        seen[key] = p
    results = [read_result(p) for p in paths]
    for r, p in zip(results[1:], paths[1:]):
        check_same_scale(results[0], r, paths[0], p)
    arrays = [read_clip_data(r, p) for r, p in zip(results, paths)]
    proto = get_protocol(f"{results[0]['protocol']}@{results[0]['protocol_version']}")
    got = compare_many(results[0], arrays[0], list(zip(results[1:], arrays[1:])), proto, resamples, seed, executor)
    pairs = []
    for r, arr, p, pair in zip(results[1:], arrays[1:], paths[1:], got):
        pairs.append({"a": _method(results[0], paths[0]), "b": _method(r, p), "a_file": str(paths[0]),
                      "b_file": str(p), **pair,
                      **(extra(results[0], arrays[0], r, arr, proto) if extra is not None else {})})
    return {"format": "hoibench-compare-1", "resamples": resamples, "seed": seed, "alpha": ALPHA,
            "protocol": f"{results[0]['protocol']}@{results[0]['protocol_version']}",
            "evaluator_id": results[0].get("evaluator_id"), "pairs": pairs}


def format_paired(cmp: dict) -> str:
    """One line per metric and pair: difference, interval, adjusted p and verdict."""
    lines = [f"paired bootstrap, {cmp['resamples']} resamples of the shared test clips (seed {cmp['seed']}), "
             f"{cmp['protocol']}, evaluator {str(cmp['evaluator_id'])[:12]}; diff = B - A, Holm-adjusted p"]
    for pair in cmp["pairs"]:
        lines.append(f"A = {pair['a']}  vs  B = {pair['b']}  ({pair['n_clips']} clips)")
        for m, row in pair["metrics"].items():
            lines.append(f"  {m:26s} {row['diff']:+11.4g} [{row['ci95'][0]:+.3g}, {row['ci95'][1]:+.3g}]  "
                         f"p {row['p_holm']:.3g}  {row['verdict']}")
        if pair.get("slices"):
            lines.append("  slices where they differ most (mean of B - A over the slice's clips; z in standard "
                         "errors of the split's per-clip differences):")
            lines += [f"    {g['slice']}={g['label']} ({g['n']} clips): {g['metric']} {g['diff']:+.4g} (z {g['z']:+.1f})"
                      for g in pair["slices"]]
    return "\n".join(lines)




#: resamples of the clip-bootstrap interval a result carries
CLIP_RESAMPLES = 1000
#: set-level metrics (FID, Diversity) get a clip interval in the result up to this many clips
#: (beyond it the per-resample cost grows with the embedding size; compare --paired computes it)
SET_LEVEL_MAX_CLIPS = 256


def clip_intervals(arrays: dict, proto, resamples: int = CLIP_RESAMPLES, seed: int = 0) -> dict[str, dict]:
    """``{metric: {"ci95": [lo, hi], "resamples": B, "over": "test clips"}}``: the 2.5 and 97.5
    percentiles of each metric recomputed on ``resamples`` seeded draws of the scored clips
    (sample 0; the per-clip forms of :func:`compare_pair`); set-level metrics only up to
    :data:`SET_LEVEL_MAX_CLIPS` clips."""
    n = len(arrays["ids"])
    if n < 2:
        return {}
    side, W = _draw_side(arrays, proto, bootstrap_weights(n, resamples, seed))
    boot = {m: _means(v, W) for m, v in side.per_clip().items()}
    if n <= SET_LEVEL_MAX_CLIPS:
        pairs = int(min(proto.diversity_pairs or 300, 300))
        got, _ = _set_level_debiased([side.motion], side.real, W, pairs, seed)
        boot.update(fid=got["fid"][:, 0], diversity=got["div"][:, 0])
    return _percentile_intervals(boot, resamples)


def mean_intervals(values: dict[str, np.ndarray], resamples: int = CLIP_RESAMPLES,
                   seed: int = 0) -> dict[str, dict]:
    """:func:`clip_intervals`' records for metrics that are means of per-clip ``values``
    (``{metric: (N,)}``, aligned clips; NaN clips left out): the 2.5 and 97.5 percentiles of
    the mean over ``resamples`` seeded draws of the N clips; none below 2 clips."""
    n = len(next(iter(values.values()), ()))
    if n < 2:
        return {}
    W = bootstrap_weights(n, resamples, seed).astype(np.float64)
    return _percentile_intervals({m: _means(np.asarray(v, np.float64), W) for m, v in values.items()}, resamples)


def _percentile_intervals(boot: dict[str, np.ndarray], resamples: int) -> dict[str, dict]:
    """``{metric: {"ci95": [2.5th, 97.5th percentile], "resamples", "over"}}`` of each metric's
    draws (non-finite draws left out; a metric with fewer than 2 gets none)."""
    out = {}
    for m, v in boot.items():
        v = v[np.isfinite(v)]
        if len(v) > 1:
            lo, hi = np.percentile(v, [2.5, 97.5])
            out[m] = {"ci95": [float(lo), float(hi)], "resamples": int(resamples), "over": "test clips"}
    return out


def per_clip_draws(arrays: dict, proto, W: np.ndarray) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """One result's per-clip metrics (R-precision top-k, MM-Dist, the physical ones) on every
    row of the draw counts ``W`` (B, N) and on all its clips: ``(draws {metric: (B,)}, full
    {metric: value})``, in the forms of :func:`compare_pair` (sample 0; each clip's first
    caption under the replication-0 pools of the result's own ids). Two results with the same
    ids and ``W`` are paired draw by draw: ``b - a`` per row is :func:`compare_pair`'s
    bootstrap of the difference."""
    side, W = _draw_side(arrays, proto, W)
    ones = np.ones((1, W.shape[1]))
    per_clip = side.per_clip()
    return ({m: _means(v, W) for m, v in per_clip.items()},
            {m: float(_means(v, ones)[0]) for m, v in per_clip.items()})


def set_level_draws(arrays: dict, proto, W: np.ndarray, seed: int = 0,
                    executor: str = "serial") -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """FID and Diversity of one result (sample 0's embeddings) on every row of ``W`` and on
    all its clips, as :func:`per_clip_draws` returns them (the draws less their bootstrap
    bias, :func:`~hoibench.metrics.resampling.debiased`); the Diversity pairs of draw ``i``
    are seeded by ``(seed, i)`` as in :func:`compare_pair`. Draws run in fixed chunks on
    ``executor`` (the same numbers on every executor)."""
    side, W = _draw_side(arrays, proto, W)
    pairs = int(min(proto.diversity_pairs or 300, 300))
    got, whole = _set_level_debiased([side.motion], side.real, W, pairs, seed, executor)
    return ({"fid": got["fid"][:, 0], "diversity": got["div"][:, 0]},
            {"fid": float(whole["fid"][0]), "diversity": float(whole["div"][0])})


def _draw_side(arrays: dict, proto, W: np.ndarray) -> tuple[_Side, np.ndarray]:
    ids = [str(x) for x in arrays["ids"]]
    n = len(ids)
    if n < 2 or np.shape(W)[1:] != (n,):
        raise ValueError(f"W: expected draw counts of shape (B, {n}) over at least 2 clips, got {np.shape(W)}")
    pools = _pools(proto, ids) if has_text(arrays) else []
    return _Side(arrays, np.arange(n), pools, int(proto.r_precision_top_k or 3)), np.asarray(W, np.float64)


def _pools(proto, ids: list[str]) -> list[list[int]]:
    """The protocol's replication-0 R-precision pools of ``ids``, as indices into ``ids``
    (one pool of all of them when the protocol makes none)."""
    where = {c: i for i, c in enumerate(ids)}
    return [[where[c] for c in p] for p in proto.pools(ids, 0)] or [list(range(len(ids)))]


def clip_values(arrays: dict, proto) -> dict[str, np.ndarray]:
    """One result's per-clip metric values (sample 0), aligned with ``arrays["ids"]``: the
    forms :func:`per_clip_draws` averages (R-precision top-k hits and MM-Dist of each clip's
    first caption under the replication-0 pools, the physical metrics' per-clip values)."""
    side, _ = _draw_side(arrays, proto, np.ones((1, len(arrays["ids"]))))
    return side.per_clip()


__all__ = ["paired_compare", "compare_pair", "compare_many", "clip_values", "favours_b", "check_same_scale", "format_paired", "clip_intervals", "mean_intervals", "per_clip_draws",
           "set_level_draws", "MIN_RESAMPLES", "CLIP_RESAMPLES"]
