"""``hoibench compare A.json B.json [C.json ...] --paired``: does a difference mean anything?

Every result after the first is compared with the first (A) over the test clips both scored,
by a paired bootstrap: each of ``resamples`` (at least 2,000) draws the shared clips with
replacement once, and every metric of both results is recomputed on that draw from their
per-clip data (:mod:`hoibench.scoring.clip_data`, :mod:`hoibench.metrics.resampling`):

- FID, Diversity: on the drawn clips' embeddings (sample 0); R-precision top-k and MM-Dist:
  per-clip values under the protocol's replication-0 pools of the shared clips, each clip's
  first caption (so they differ from the result's mean over replications; the difference is
  what is tested); the physical metrics: the mean of their per-clip values (a pooled metric
  such as PS or FSR weighs frames, the per-clip mean weighs clips);
- ``diff = B - A`` on all shared clips, its 95% percentile interval, a two-sided bootstrap
  p-value (for a metric best closest to the ground truth: of ``|B - GT| - |A - GT|``), Holm's
  adjustment across the metrics of one pair, and a verdict: ``A better``, ``B better`` or
  ``not distinguishable on N clips`` (adjusted p >= 0.05).

Results scored with another evaluator, protocol (id and version) or store are refused in one
line naming the field. The same seed gives the same numbers on every executor: the draws are
made up front and the per-resample work is split in fixed chunks.
"""
from __future__ import annotations

import hashlib

import numpy as np

from ..metrics.catalog import METRICS
from ..metrics.resampling import (bootstrap_p, bootstrap_weights, holm, resampled_diversity, retrieval_per_clip,
                                  weighted_fid)

#: fewest resamples a paired comparison runs
MIN_RESAMPLES = 2000
#: the fields two results must share to be compared, and what they mean
SCALE_FIELDS = (("evaluator_id", "evaluator"), ("protocol", "protocol"), ("protocol_version", "protocol version"),
                ("dataset", "store dataset"), ("store_config_sha256", "store"))
ALPHA = 0.05
_CHUNK = 100


def _seed(*parts) -> int:
    return int.from_bytes(hashlib.sha256(repr(parts).encode()).digest()[:4], "little")


def check_same_scale(a: dict, b: dict, a_path, b_path) -> None:
    """ValueError naming the first field on which ``b`` was scored differently from ``a``."""
    for field, what in SCALE_FIELDS:
        if a.get(field) != b.get(field):
            raise ValueError(f"{b_path}: field {field}: {str(b.get(field))[:16]} is not {a_path}'s "
                             f"{str(a.get(field))[:16]}: a paired comparison needs one {what}")


class _Side:
    """One result's per-clip statistics on the shared clips."""

    def __init__(self, arrays: dict, order: np.ndarray, pools: list, top_k: int):
        offsets = arrays["text_offsets"]
        self.motion = arrays["motion"][0][order].astype(np.float64)
        self.real = arrays["real"][order].astype(np.float64)
        text = arrays["text"][offsets[:-1][order]].astype(np.float64)    # each clip's first caption
        self.hits, self.mmd = retrieval_per_clip(text, self.motion, pools, top_k)
        names = [str(n) for n in arrays["physical_names"]]
        self.physical = {n: arrays["physical"][0][order, j] for j, n in enumerate(names)}

    def per_clip(self) -> dict[str, np.ndarray]:
        out = {f"r_precision_top{k + 1}": self.hits[:, k] for k in range(self.hits.shape[1])}
        out["mm_dist"] = self.mmd
        out.update(self.physical)
        return out


def _means(values: np.ndarray, W: np.ndarray) -> np.ndarray:
    """Weighted means of per-clip ``values`` for every row of ``W`` (NaN clips left out)."""
    ok = np.isfinite(values)
    den = W[:, ok].sum(1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, W[:, ok] @ values[ok] / np.maximum(den, 1), np.nan)


def _set_level(job: tuple) -> dict[str, np.ndarray]:
    """FID and Diversity of both sides (and the ground truth's Diversity) on a chunk of draws;
    side A only when ``b_motion`` is None (a single result's clip interval)."""
    start, W, a_motion, b_motion, real, pairs, seed = job
    sides = (("a", a_motion),) if b_motion is None else (("a", a_motion), ("b", b_motion))
    names = [f"{m}_{side}" for side, _ in sides for m in ("fid", "div")] + ([] if b_motion is None else ["div_gt"])
    out = {k: np.empty(len(W)) for k in names}
    for i, w in enumerate(W):
        s = _seed(seed, start + i)
        for side, motion in sides:
            out[f"fid_{side}"][i] = weighted_fid(real, motion, w)
            out[f"div_{side}"][i] = resampled_diversity(motion, w, pairs, s)
        if b_motion is not None:
            out["div_gt"][i] = resampled_diversity(real, w, pairs, s)
    return out


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


def compare_pair(a: dict, a_arrays: dict, b: dict, b_arrays: dict, proto, resamples: int = MIN_RESAMPLES,
                 seed: int = 0, executor: str = "serial") -> dict:
    """The paired comparison of two results (module docstring): ``{"n_clips", "metrics": {name:
    {"diff", "ci95", "p", "p_holm", "verdict", "a", "b", "direction", "unit", "tested"}}}``."""
    from ..core.parallel import map_units
    a_ids, b_ids = [str(x) for x in a_arrays["ids"]], [str(x) for x in b_arrays["ids"]]
    shared = sorted(set(a_ids) & set(b_ids))
    if len(shared) < 2:
        raise ValueError(f"the two results share {len(shared)} scored test clip(s): a paired comparison needs 2 or more")
    ia, ib = {c: i for i, c in enumerate(a_ids)}, {c: i for i, c in enumerate(b_ids)}
    where = {c: i for i, c in enumerate(shared)}
    pools = [[where[c] for c in p] for p in proto.pools(shared, 0)] or [list(range(len(shared)))]
    top_k = int(proto.r_precision_top_k or 3)
    A = _Side(a_arrays, np.array([ia[c] for c in shared]), pools, top_k)
    B = _Side(b_arrays, np.array([ib[c] for c in shared]), pools, top_k)
    n = len(shared)
    W = bootstrap_weights(n, resamples, seed).astype(np.float64)
    ones = np.ones((1, n))
    names = [m for m in METRICS if m in a["metrics"] and m in b["metrics"]]
    pa, pb = A.per_clip(), B.per_clip()
    pairs = int(min(proto.diversity_pairs or 300, 300))
    jobs = [(s, W[s:s + _CHUNK], A.motion, B.motion, A.real, pairs, seed) for s in range(0, resamples, _CHUNK)]
    chunks = list(map_units(_set_level, jobs, executor))
    full = _set_level((0, ones, A.motion, B.motion, A.real, pairs, seed))
    boot = {k: np.concatenate([c[k] for c in chunks]) for k in full}
    rows, pvals = {}, []
    for m in names:
        info = METRICS[m]
        if m in pa and m in pb:
            va, vb, vg = _means(pa[m], W), _means(pb[m], W), None
            fa, fb = float(_means(pa[m], ones)[0]), float(_means(pb[m], ones)[0])
        elif m == "fid":
            va, vb, vg, fa, fb = boot["fid_a"], boot["fid_b"], None, float(full["fid_a"][0]), float(full["fid_b"][0])
        elif m == "diversity":
            va, vb, vg = boot["div_a"], boot["div_b"], boot["div_gt"]
            fa, fb = float(full["div_a"][0]), float(full["div_b"][0])
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
    """Every result after the first against the first (module docstring); the ``cmp.json`` dict.
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
    results = [read_result(p) for p in paths]
    for r, p in zip(results[1:], paths[1:]):
        check_same_scale(results[0], r, paths[0], p)
    arrays = [read_clip_data(r, p) for r, p in zip(results, paths)]
    proto = get_protocol(f"{results[0]['protocol']}@{results[0]['protocol_version']}")
    pairs = []
    for r, arr, p in zip(results[1:], arrays[1:], paths[1:]):
        pair = compare_pair(results[0], arrays[0], r, arr, proto, resamples, seed, executor)
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
        got = _set_level((0, W, side.motion, None, side.real, pairs, seed))
        boot.update(fid=got["fid_a"], diversity=got["div_a"])
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
    all its clips, as :func:`per_clip_draws` returns them; the Diversity pairs of draw ``i``
    are seeded by ``(seed, i)`` as in :func:`compare_pair`. Draws run in fixed chunks on
    ``executor`` (the same numbers on every executor)."""
    from ..core.parallel import map_units
    side, W = _draw_side(arrays, proto, W)
    pairs = int(min(proto.diversity_pairs or 300, 300))
    jobs = [(s, W[s:s + _CHUNK], side.motion, None, side.real, pairs, seed) for s in range(0, len(W), _CHUNK)]
    chunks = list(map_units(_set_level, jobs, executor))
    whole = _set_level((0, np.ones((1, W.shape[1])), side.motion, None, side.real, pairs, seed))
    return ({"fid": np.concatenate([c["fid_a"] for c in chunks]),
             "diversity": np.concatenate([c["div_a"] for c in chunks])},
            {"fid": float(whole["fid_a"][0]), "diversity": float(whole["div_a"][0])})


def _draw_side(arrays: dict, proto, W: np.ndarray) -> tuple[_Side, np.ndarray]:
    ids = [str(x) for x in arrays["ids"]]
    n = len(ids)
    if n < 2 or np.shape(W)[1:] != (n,):
        raise ValueError(f"W: expected draw counts of shape (B, {n}) over at least 2 clips, got {np.shape(W)}")
    where = {c: i for i, c in enumerate(ids)}
    pools = [[where[c] for c in p] for p in proto.pools(ids, 0)] or [list(range(n))]
    return _Side(arrays, np.arange(n), pools, int(proto.r_precision_top_k or 3)), np.asarray(W, np.float64)


def clip_values(arrays: dict, proto) -> dict[str, np.ndarray]:
    """One result's per-clip metric values (sample 0), aligned with ``arrays["ids"]``: the
    forms :func:`per_clip_draws` averages (R-precision top-k hits and MM-Dist of each clip's
    first caption under the replication-0 pools, the physical metrics' per-clip values)."""
    side, _ = _draw_side(arrays, proto, np.ones((1, len(arrays["ids"]))))
    return side.per_clip()


__all__ = ["paired_compare", "compare_pair", "clip_values", "favours_b", "check_same_scale", "format_paired", "clip_intervals", "per_clip_draws",
           "set_level_draws", "MIN_RESAMPLES", "CLIP_RESAMPLES"]
