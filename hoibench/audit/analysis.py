"""What each metric sees of each corruption family: the audit's statistics.

For a metric ``m`` (direction from :data:`hoibench.metrics.catalog.METRICS`) and a family with
severities ``s_0 (identity) < ... < s_k`` by magnitude ``|s|`` (:meth:`FamilySpec.magnitude`):

- ``values``: the result's mean of ``m`` at each severity;
- ``spearman``: Spearman's rho of ``values`` against the magnitudes (average ranks for ties;
  None when either is constant or fewer than 3 values are defined); ``spearman_worse``: the
  same for how much worse ``m`` gets, ``w(v) = v`` (direction ``lower``), ``-v`` (``higher``)
  or ``|v - v_0|`` (``gt``: the severity-0 value is the ground truth's); ``direction_ok``:
  ``spearman_worse > 0``; ``blind``: ``spearman_worse`` undefined or below 0.5 (``|rho| <
  0.5`` or the wrong direction);
- paired tests: the corrupted clips against severity 0 on the same clips, one clip bootstrap
  of ``resamples`` draws shared by every condition (:func:`hoibench.metrics.resampling.bootstrap_weights`,
  the per-clip forms of :func:`hoibench.scoring.paired.compare_pair`): ``diff = b - a`` on all
  clips, ``p`` the two-sided bootstrap p of ``b - a`` per draw, ``p_holm`` Holm-adjusted over
  the metrics of one condition (``compare --paired``'s verdict); ``detectable_severity``: the
  smallest-magnitude severity with ``p_holm < 0.05`` (None: none);
- ``effect_sd``: ``diff`` at the lowest non-zero severity over the standard deviation of the
  metric's clip bootstrap on the corrupted clips (sd 0: 0 when ``diff`` is 0, else None);
- ``clips_needed``: per severity, ``ceil(n (2.80 sd_d / |diff|)^2)``, the clips a paired
  test needs to see that severity with 80% power at a two-sided 5% level (normal
  approximation, ``sd_d`` the bootstrap sd of ``b - a`` on ``n`` clips, shrinking as
  ``1 / sqrt(n)``; None when ``diff`` is 0).
"""
from __future__ import annotations

import hashlib
import math
from statistics import NormalDist
from typing import Mapping, Sequence

import numpy as np

from ..metrics.catalog import METRICS
from ..metrics.resampling import bootstrap_p, bootstrap_weights, holm
from .corruptions import FAMILIES, FamilySpec

#: the paired test's level
ALPHA = 0.05
#: blind below this rho toward worse
BLIND_RHO = 0.5
#: z_{0.975} + z_{0.80}: a two-sided 5% test with 80% power
POWER_Z = NormalDist().inv_cdf(0.975) + NormalDist().inv_cdf(0.80)
#: the metric kinds the audit reports (counts and reported-only entries are left out)
AUDITED_KINDS = ("embedding", "physical", "multibody")


def ranks(x: Sequence[float]) -> np.ndarray:
    """1-based ranks of ``x``, ties given their average rank."""
    x = np.asarray(x, np.float64)
    order = np.argsort(x, kind="stable")
    r = np.empty(len(x))
    i = 0
    while i < len(x):
        j = i
        while j + 1 < len(x) and x[order[j + 1]] == x[order[i]]:
            j += 1
        r[order[i:j + 1]] = (i + j) / 2.0 + 1.0
        i = j + 1
    return r


def spearman(x: Sequence[float], y: Sequence[float]) -> float | None:
    """Spearman's rho: Pearson's correlation of the ranks; None when fewer than 3 pairs or
    either side is constant."""
    if len(x) != len(y):
        raise ValueError(f"y: expected {len(x)} values, got {len(y)}")
    if len(x) < 3:
        return None
    rx, ry = ranks(x), ranks(y)
    rx, ry = rx - rx.mean(), ry - ry.mean()
    den = math.sqrt(float(rx @ rx) * float(ry @ ry))
    return None if den == 0 else float(np.clip(rx @ ry / den, -1.0, 1.0))


def worse(values: Sequence[float], direction: str, v0: float) -> list[float]:
    """How much worse each value is (module docstring): ``v``, ``-v`` or ``|v - v0|``."""
    if direction == "lower":
        return [float(v) for v in values]
    if direction == "higher":
        return [-float(v) for v in values]
    if direction == "gt":
        return [abs(float(v) - v0) for v in values]
    raise ValueError(f"direction: expected higher, lower or gt, got {direction!r}")


def audited_metrics(results: Sequence[dict]) -> list[str]:
    """The metrics any of ``results`` reports, of the audited kinds, in catalogue order."""
    seen = {m for r in results for m in r.get("metrics", {})}
    return [m for m, info in METRICS.items() if m in seen and info.kind in AUDITED_KINDS]


def _digest(*arrays: np.ndarray) -> str:
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype}{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _set_level_job(job: tuple) -> tuple[str, tuple[dict, dict]]:
    """``(key, set_level_draws(...))`` of one embedding set, serially (one unit of work)."""
    from ..scoring.paired import set_level_draws
    key, arrays, proto, W, seed = job
    return key, set_level_draws(arrays, proto, W, seed, "serial")


class Draws:
    """Clip-bootstrap draws of every scored condition, on one shared set of draw counts;
    set-level draws (FID, Diversity) are computed once per distinct embedding set
    (:meth:`prepare` maps them on the executor in one go)."""

    def __init__(self, proto, n: int, resamples: int, seed: int, executor: str = "serial"):
        self.proto, self.resamples, self.seed, self.executor = proto, int(resamples), int(seed), executor
        self.W = bootstrap_weights(n, self.resamples, self.seed).astype(np.float64)
        self._set_level: dict[str, tuple[dict, dict]] = {}

    @staticmethod
    def key(arrays: Mapping[str, np.ndarray]) -> str:
        return _digest(arrays["motion"][0], arrays["real"])

    def prepare(self, many: Sequence[Mapping[str, np.ndarray]]) -> None:
        """Compute the set-level draws of every distinct embedding set of ``many``."""
        from ..core.parallel import map_units
        jobs = {}
        for arrays in many:
            k = self.key(arrays)
            if k not in self._set_level and k not in jobs:
                jobs[k] = (k, dict(arrays), self.proto, self.W, self.seed)
        for k, got in map_units(_set_level_job, [jobs[k] for k in sorted(jobs)], self.executor,
                                progress="audit: bootstrap"):
            self._set_level[k] = got

    def of(self, arrays: Mapping[str, np.ndarray]) -> tuple[dict[str, np.ndarray], dict[str, float]]:
        """``(draws {metric: (B,)}, full {metric: value})`` of one condition's per-clip data."""
        from ..scoring.paired import per_clip_draws
        draws, full = per_clip_draws(dict(arrays), self.proto, self.W)
        k = self.key(arrays)
        if k not in self._set_level:
            self._set_level[k] = _set_level_job((k, dict(arrays), self.proto, self.W, self.seed))[1]
        d, f = self._set_level[k]
        return {**draws, **d}, {**full, **f}


def paired_tests(base: tuple[dict, dict], other: tuple[dict, dict], metrics: Sequence[str], n: int) -> dict:
    """``{metric: {"diff", "p", "p_holm", "sd", "sd_diff", "clips_needed"}}`` of one condition
    against severity 0 (module docstring); metrics without draws are left out."""
    (da, fa), (db, fb) = base, other
    rows = {}
    for m in metrics:
        if m not in da or m not in db:
            continue
        d = db[m] - da[m]
        ok = d[np.isfinite(d)]
        diff = fb[m] - fa[m]
        vb = db[m][np.isfinite(db[m])]
        sd = float(np.std(vb, ddof=1)) if len(vb) > 1 else float("nan")
        sd_d = float(np.std(ok, ddof=1)) if len(ok) > 1 else float("nan")
        need = None
        if np.isfinite(diff) and diff != 0 and np.isfinite(sd_d):
            need = max(2, int(math.ceil(n * (POWER_Z * sd_d / abs(diff)) ** 2)))
        rows[m] = {"diff": float(diff), "p": bootstrap_p(d), "sd": sd, "sd_diff": sd_d, "clips_needed": need}
    names = list(rows)
    for m, ph in zip(names, holm([rows[m]["p"] if np.isfinite(rows[m]["p"]) else 1.0 for m in names])):
        rows[m]["p_holm"] = ph
    return rows


def _clean(x) -> float | None:
    return None if x is None or not np.isfinite(x) else float(x)


def family_summary(metric: str, family: str, severities: Sequence[float], values: Sequence[float | None],
                   tests: Sequence[dict | None], spec: FamilySpec | None = None) -> dict:
    """The summary of one metric and family (module docstring); ``tests[i]`` is the metric's
    paired test at severity ``i`` (None at severity 0 or without draws); ``spec``: the
    family's spec (default: the single-body registry's)."""
    spec, direction = spec or FAMILIES[family], METRICS[metric].direction
    mags = [round(spec.magnitude(s), 9) for s in severities]      # |log2 0.625| and log2 1.6 tie
    ok = [i for i, v in enumerate(values) if v is not None and np.isfinite(v)]
    rho = rho_w = None
    if 0 in ok:
        rho = spearman([mags[i] for i in ok], [values[i] for i in ok])
        rho_w = spearman([mags[i] for i in ok], worse([values[i] for i in ok], direction, float(values[0])))
    order = sorted(range(1, len(severities)), key=lambda i: (mags[i], i))     # by magnitude, then listed order
    detected = [i for i in order if tests[i] is not None and tests[i]["p_holm"] < ALPHA]
    first = tests[order[0]] if order and tests[order[0]] is not None else None
    effect = None
    if first is not None:
        sd, diff = first["sd"], first["diff"]
        effect = (diff / sd) if np.isfinite(sd) and sd > 0 else (0.0 if diff == 0 else None)
    return {
        "direction": direction,
        "spearman": _clean(rho), "spearman_worse": _clean(rho_w),
        "direction_ok": None if rho_w is None else bool(rho_w > 0),
        "blind": bool(rho_w is None or rho_w < BLIND_RHO),
        "effect_sd": _clean(effect), "effect_severity": severities[order[0]] if order else None,
        "detectable_severity": severities[detected[0]] if detected else None,
        "p_holm": [None if t is None else _clean(t["p_holm"]) for t in tests],
        "diff": [None if t is None else _clean(t["diff"]) for t in tests],
        "clips_needed": [None if t is None else t["clips_needed"] for t in tests],
    }


__all__ = ["ALPHA", "BLIND_RHO", "AUDITED_KINDS", "ranks", "spearman", "worse", "audited_metrics", "Draws",
           "paired_tests", "family_summary"]
