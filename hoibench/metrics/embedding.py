"""Embedding metrics: FID, R-precision, MM-Dist, Diversity, MultiModality.

Inputs are evaluator embeddings as arrays (``hoibench.evaluator``'s ``embed_motion`` /
``embed_text`` give (N, 512)); nothing here runs a network. Numerics follow the reference
implementation, text-to-motion (Guo et al., CVPR 2022) ``utils/metrics.py`` and
``final_evaluations.py``, which produced the HumanML3D / KIT-ML table columns "R Precision
Top 1/2/3", "FID", "MM Dist", "Diversity" and "MultiModality" that later papers (MDM,
T2M-GPT, HOI-Diff, ChainHOI) copy:

* every computation is float64 (inputs are cast; the reference computes in the dtype of its
  inputs, float32 embeddings from torch);
* the distance matrix is the reference's expansion ``sqrt(-2 a.b + |a|^2 + |b|^2)`` in
  the same order of operations, except that rounding below zero is clipped to 0 (the
  reference returns NaN there);
* R-precision ranks with a stable order (a tie goes to the lower index; the reference's
  ``argsort`` leaves ties unspecified -- with real-valued embeddings they do not occur);
* the Frechet distance: ``method="sqrtm"`` takes ``scipy.linalg.sqrtm`` of ``sigma1 @ sigma2``,
  retries with ``1e-6`` added to both diagonals when that is not finite, drops an imaginary
  part when the diagonal's is within 1e-3 of zero and raises ``ValueError`` otherwise (the
  reference's numerics, used by legacy protocols); the default ``method="eigh"`` computes the
  same trace exactly from symmetric eigendecompositions, several times faster;
* Diversity and MultiModality draw their index pairs with ``numpy.random.RandomState(seed)``
  exactly as the reference's global ``np.random.choice(n, times, replace=False)`` after
  ``np.random.seed(seed)`` -- so the same seed gives the same pairs and the same number.

``tests/test_metrics.py`` checks every function against values the reference code computed
on seeded random embeddings (``tests/data/metrics_reference.npz``).

Stateful classes (mergeable, see :mod:`hoibench.metrics.state`): :class:`FID` (float64
``n``, sums and sums of outer products), :class:`RPrecision` (per-pool top-k hits, pool
sizes and matching-distance sums; also gives MM-Dist), :class:`Diversity` and
:class:`MultiModality` (embeddings keyed by id: pair sampling needs them all).
"""
from __future__ import annotations

from typing import Hashable, Iterable, Sequence

import numpy as np

from .state import Metric, sorted_items

__all__ = [
    "euclidean_distance_matrix", "activation_statistics", "frechet_distance", "fid",
    "pool_hits", "r_precision", "mm_dist", "make_pools", "diversity", "multimodality",
    "FID", "RPrecision", "Diversity", "MultiModality",
]


def _as_2d(x, name: str, dim: int | None = None) -> np.ndarray:
    a = np.asarray(x)
    if a.ndim != 2:
        raise ValueError(f"{name}: expected a 2-D array (N, D), got shape {a.shape}")
    if not np.issubdtype(a.dtype, np.number):
        raise ValueError(f"{name}: expected a numeric array, got dtype {a.dtype}")
    a = a.astype(np.float64, copy=False)
    if dim is not None and a.shape[1] != dim:
        raise ValueError(f"{name}: expected {dim} features, got {a.shape[1]}")
    if not np.isfinite(a).all():
        raise ValueError(f"{name}: contains {int((~np.isfinite(a)).sum())} non-finite value(s)")
    return a


def _rng(seed) -> np.random.RandomState:
    if isinstance(seed, np.random.RandomState):
        return seed
    if isinstance(seed, np.random.Generator):
        raise ValueError("seed: pass an int or a numpy.random.RandomState (the reference's legacy "
                         "generator), not a numpy.random.Generator")
    return np.random.RandomState(int(seed))


# ===================================================================== distances
def euclidean_distance_matrix(a, b) -> np.ndarray:
    """Pairwise Euclidean distances ``D[i, j] = |a_i - b_j|`` of (N1, D) and (N2, D), float64.

    Computed as the reference does, ``sqrt((-2 a b^T + |a|^2) + |b|^2)`` (the squared
    terms summed per row), with values rounding below zero clipped to 0.
    """
    a, b = _as_2d(a, "a"), _as_2d(b, "b")
    if a.shape[1] != b.shape[1]:
        raise ValueError(f"a, b: feature sizes differ: {a.shape[1]} vs {b.shape[1]}")
    d1 = -2 * np.dot(a, b.T)
    d2 = np.sum(np.square(a), axis=1, keepdims=True)
    d3 = np.sum(np.square(b), axis=1)
    return np.sqrt(np.maximum(d1 + d2 + d3, 0.0))


# ===================================================================== FID
def activation_statistics(embeddings) -> tuple[np.ndarray, np.ndarray]:
    """Mean (D,) and unbiased covariance (D, D) (``np.cov(rowvar=False)``, divisor N - 1)."""
    x = _as_2d(embeddings, "embeddings")
    if len(x) < 2:
        raise ValueError(f"embeddings: need at least 2 rows for a covariance, got {len(x)}")
    return np.mean(x, axis=0), np.cov(x, rowvar=False)


def _sqrtm(m: np.ndarray) -> np.ndarray:
    from scipy import linalg
    return linalg.sqrtm(m)


FRECHET_METHODS = ("eigh", "sqrtm")


def trace_sqrt_product(sigma1: np.ndarray, sigma2: np.ndarray) -> float:
    """``tr(sqrt(sigma1 sigma2))`` of two symmetric positive semi-definite matrices, exactly,
    from symmetric eigendecompositions (float64): with ``sigma1 = V diag(w) V^T`` and
    ``A = V diag(sqrt(w)) V^T``, ``sigma1 sigma2 = A (A sigma2 A) A^-1`` is similar to the
    symmetric PSD ``M = A sigma2 A``, so the trace is ``sum_i sqrt(lambda_i(M))``. Rounding
    below zero (``w``, ``lambda``) is clipped to 0, so a rank-deficient covariance (fewer
    samples than dimensions) needs no retry."""
    w, V = np.linalg.eigh(0.5 * (sigma1 + sigma1.T))
    A = (V * np.sqrt(np.clip(w, 0.0, None))) @ V.T
    M = A @ sigma2 @ A
    lam = np.linalg.eigvalsh(0.5 * (M + M.T))
    return float(np.sqrt(np.clip(lam, 0.0, None)).sum())


def frechet_distance(mu1, sigma1, mu2, sigma2, eps: float = 1e-6, method: str = "eigh") -> float:
    """Frechet distance between N(mu1, sigma1) and N(mu2, sigma2).

    ``d^2 = |mu1 - mu2|^2 + tr(sigma1) + tr(sigma2) - 2 tr(sqrt(sigma1 sigma2))``
    (Dowson & Landau 1982; the FID of Heusel et al. 2017 on evaluator embeddings). Units:
    squared embedding distance. Lower is better.

    ``method="eigh"`` (default): the trace from symmetric eigendecompositions
    (:func:`trace_sqrt_product`). ``method="sqrtm"``: the reference implementation's numerics
    -- ``scipy.linalg.sqrtm(sigma1 @ sigma2)``; when it is not finite, ``eps`` is added to both
    diagonals and it is retried; an imaginary part is dropped when the diagonal's is within
    1e-3 of zero, else ``ValueError``. The two agree to ~1e-7 relative on rank-deficient
    evaluation covariances and ~1e-14 on full-rank ones (``benchmarks/fid.py``); legacy
    protocols use ``sqrtm``.
    """
    if method not in FRECHET_METHODS:
        raise ValueError(f"method: expected one of {FRECHET_METHODS}, got {method!r}")
    mu1, mu2 = np.atleast_1d(np.asarray(mu1, np.float64)), np.atleast_1d(np.asarray(mu2, np.float64))
    s1, s2 = np.atleast_2d(np.asarray(sigma1, np.float64)), np.atleast_2d(np.asarray(sigma2, np.float64))
    if mu1.shape != mu2.shape:
        raise ValueError(f"mu1, mu2: shapes differ: {mu1.shape} vs {mu2.shape}")
    if s1.shape != s2.shape or s1.shape != (len(mu1), len(mu1)):
        raise ValueError(f"sigma1, sigma2: expected ({len(mu1)}, {len(mu1)}), got {s1.shape} and {s2.shape}")
    diff = mu1 - mu2
    if method == "eigh":
        return float(diff.dot(diff) + np.trace(s1) + np.trace(s2) - 2 * trace_sqrt_product(s1, s2))
    covmean = _sqrtm(s1.dot(s2))
    if not np.isfinite(covmean).all():
        offset = np.eye(s1.shape[0]) * eps
        covmean = _sqrtm((s1 + offset).dot(s2 + offset))
    if np.iscomplexobj(covmean):
        if not np.allclose(np.diagonal(covmean).imag, 0, atol=1e-3):
            raise ValueError(f"frechet_distance: the matrix square root has an imaginary component "
                             f"{np.max(np.abs(covmean.imag)):.3g}")
        covmean = covmean.real
    return float(diff.dot(diff) + np.trace(s1) + np.trace(s2) - 2 * np.trace(covmean))


def fid(real, generated, method: str = "eigh") -> float:
    """FID between two sets of embeddings (N1, D), (N2, D): :func:`frechet_distance` of their
    :func:`activation_statistics` (``real`` may also be its precomputed ``(mu, sigma)``).
    Paper column "FID"; lower is better."""
    stats = real if isinstance(real, tuple) else activation_statistics(real)
    return frechet_distance(*stats, *activation_statistics(generated), method=method)


# ===================================================================== R-precision / MM-Dist
def pool_hits(text, motion, top_k: int = 3) -> tuple[np.ndarray, float]:
    """Top-k retrieval hits and matching-distance sum of one pool.

    Row i of the pool's distance matrix ``D = euclidean_distance_matrix(text, motion)``
    ranks every motion for text i; ``hits[k-1]`` counts the texts whose own motion is among
    the k nearest (ties: lower index first). ``dist_sum = trace(D) = sum_i |t_i - m_i|``.

    Returns:
        ``(hits (top_k,) int64, dist_sum float)``.
    """
    t, m = _as_2d(text, "text"), _as_2d(motion, "motion")
    if t.shape != m.shape:
        raise ValueError(f"text, motion: shapes differ: {t.shape} vs {m.shape}")
    if top_k < 1:
        raise ValueError(f"top_k: expected >= 1, got {top_k}")
    d = euclidean_distance_matrix(t, m)
    own = np.diagonal(d)[:, None]
    before = np.tril(np.ones(d.shape, bool), -1)            # j < i: wins a tie
    rank = (d < own).sum(1) + ((d == own) & before).sum(1)
    hits = np.array([(rank < k).sum() for k in range(1, top_k + 1)], dtype=np.int64)
    return hits, float(np.trace(d))


def _pools_or_all(n: int, pools) -> list[np.ndarray]:
    if pools is None:
        return [np.arange(n)]
    out = [np.asarray(p, dtype=np.int64) for p in pools]
    for p in out:
        if p.ndim != 1 or len(p) == 0 or p.min() < 0 or p.max() >= n:
            raise ValueError(f"pools: every pool must be a non-empty 1-D array of row indices in [0, {n})")
    return out


def r_precision(text, motion, pools: Iterable[Sequence[int]] | None = None, top_k: int = 3) -> np.ndarray:
    """R-precision top-1..top_k: fraction of texts whose own motion is among the k nearest of
    its pool (text i pairs with motion i). ``pools`` lists row indices per pool (see
    :func:`make_pools`; the protocol uses pools of 32); ``None`` = one pool of all rows.
    Pooled over pools: ``sum hits / sum pool sizes``. Paper columns "R Precision Top 1/2/3";
    higher is better (the real motion's value is the ceiling that matters)."""
    t, m = _as_2d(text, "text"), _as_2d(motion, "motion")
    hits, size = np.zeros(top_k, np.int64), 0
    for p in _pools_or_all(len(t), pools):
        h, _ = pool_hits(t[p], m[p], top_k)
        hits += h
        size += len(p)
    return hits / size


def mm_dist(text, motion, pools: Iterable[Sequence[int]] | None = None) -> float:
    """MM-Dist (the reference's "Matching Score"): mean Euclidean distance between each text
    embedding and its own motion's, over the rows in ``pools`` (``None``: all rows).
    Paper column "MM Dist"; lower is better. Units: embedding distance."""
    t, m = _as_2d(text, "text"), _as_2d(motion, "motion")
    total, size = 0.0, 0
    for p in _pools_or_all(len(t), pools):
        _, s = pool_hits(t[p], m[p], 1)
        total += s
        size += len(p)
    return total / size


def make_pools(ids: Sequence[Hashable], pool_size: int = 32, seed: int = 0,
               drop_last: bool = True) -> list[list]:
    """R-precision pools: the ids sorted, permuted with ``numpy.random.default_rng(seed)``,
    cut into pools of ``pool_size``. The pools depend only on (ids, pool_size, seed) -- never
    on input order or compute batch size. ``drop_last`` drops the incomplete last pool (the
    reference's ``DataLoader(drop_last=True)``: a smaller pool would make retrieval easier)."""
    items = sorted(ids, key=lambda x: (type(x).__name__, x))
    if len(set(items)) != len(items):
        raise ValueError("ids: contains duplicates")
    if pool_size < 2:
        raise ValueError(f"pool_size: expected >= 2, got {pool_size}")
    perm = np.random.default_rng(int(seed)).permutation(len(items))
    pools = [[items[i] for i in perm[s:s + pool_size]] for s in range(0, len(items), pool_size)]
    if drop_last and pools and len(pools[-1]) < pool_size:
        pools.pop()
    return pools


# ===================================================================== Diversity / MultiModality
def diversity(embeddings, times: int, seed=0) -> float:
    """Diversity: mean distance between ``times`` random pairs of embeddings.

    ``first = rs.choice(N, times, replace=False)``, ``second = rs.choice(N, times,
    replace=False)`` (``rs = numpy.random.RandomState(seed)``, independent draws, so a pair
    may repeat a row), ``mean_i |x_first_i - x_second_i|``. Needs ``N > times`` (as the
    reference). Paper column "Diversity"; best when closest to the real motion's (arrow
    "->" in the tables): ``higher_is_better = None``. Units: embedding distance.
    """
    x = _as_2d(embeddings, "embeddings")
    if not len(x) > times:
        raise ValueError(f"times: diversity needs more embeddings than pairs, got {len(x)} embeddings "
                         f"for {times} pairs")
    rs = _rng(seed)
    first = rs.choice(len(x), times, replace=False)
    second = rs.choice(len(x), times, replace=False)
    return float(np.linalg.norm(x[first] - x[second], axis=1).mean())


def multimodality(embeddings, times: int, seed=0) -> float:
    """MultiModality: for (N_texts, S, D) embeddings of S samples per text, the mean distance
    between ``times`` random pairs of samples of the same text, the same pair indices for
    every text (``first``/``second = rs.choice(S, times, replace=False)``). Needs
    ``S > times``. Paper column "MultiModality"; higher is better. Units: embedding distance.
    """
    x = np.asarray(embeddings)
    if x.ndim != 3:
        raise ValueError(f"embeddings: expected shape (N_texts, samples, D), got {x.shape}")
    x = _as_2d(x.reshape(-1, x.shape[-1]), "embeddings").reshape(x.shape)
    if not x.shape[1] > times:
        raise ValueError(f"times: multimodality needs more samples per text than pairs, got "
                         f"{x.shape[1]} samples for {times} pairs")
    rs = _rng(seed)
    first = rs.choice(x.shape[1], times, replace=False)
    second = rs.choice(x.shape[1], times, replace=False)
    return float(np.linalg.norm(x[:, first] - x[:, second], axis=2).mean())


# ===================================================================== stateful classes
class FID(Metric):
    """FID with mergeable sufficient statistics.

    State (float64, ``reduce="sum"``): for the real and the generated set, the count ``n``,
    the sum ``s = sum x`` (D,) and the sum of outer products ``S = sum x x^T`` (D, D).
    ``compute``: ``mu = s / n``, ``sigma = (S - n mu mu^T) / (n - 1)`` (= ``np.cov``), then
    :func:`frechet_distance`. Shards merge by adding their sums.

    Example:
        >>> import numpy as np
        >>> m = FID(num_features=2)
        >>> m.update(np.array([[0., 0.], [1., 0.], [0., 1.]]), real=True)
        >>> m.update(np.array([[0., 0.], [1., 0.], [0., 1.]]), real=False)
        >>> round(m.compute(), 12)
        0.0
    """

    name = "fid"

    def __init__(self, num_features: int = 512):
        super().__init__()
        self.num_features = int(num_features)
        d = self.num_features
        for side in ("real", "gen"):
            self.add_state(f"{side}_n", 0, "sum")
            self.add_state(f"{side}_sum", np.zeros(d), "sum")
            self.add_state(f"{side}_outer", np.zeros((d, d)), "sum")

    def config(self) -> dict:
        return {"num_features": self.num_features}

    def update(self, embeddings, real: bool) -> None:
        x = _as_2d(embeddings, "embeddings", self.num_features)
        side = "real" if real else "gen"
        setattr(self, f"{side}_n", getattr(self, f"{side}_n") + len(x))
        setattr(self, f"{side}_sum", getattr(self, f"{side}_sum") + x.sum(0))
        setattr(self, f"{side}_outer", getattr(self, f"{side}_outer") + x.T @ x)

    def statistics(self, real: bool) -> tuple[np.ndarray, np.ndarray]:
        """(mu, sigma) of the real or generated set."""
        side = "real" if real else "gen"
        n = getattr(self, f"{side}_n")
        if n < 2:
            raise ValueError(f"FID: need at least 2 {side} embeddings, got {n}")
        mu = getattr(self, f"{side}_sum") / n
        sigma = (getattr(self, f"{side}_outer") - n * np.outer(mu, mu)) / (n - 1)
        return mu, sigma

    def compute(self, method: str = "eigh") -> float:
        return frechet_distance(*self.statistics(True), *self.statistics(False), method=method)


class RPrecision(Metric):
    """R-precision top-1..top_k and MM-Dist from retrieval pools.

    State (``reduce="keyed"``): per pool key, ``(hits (top_k,), pool size, matching-distance
    sum)`` from :func:`pool_hits`. ``compute`` sums them in key order: ``top-k = sum hits /
    sum sizes``, ``mm_dist = sum distance sums / sum sizes`` -- the reference's per-batch
    accumulation with batches = pools. Returns ``{"r_precision_top1": ..., ...,
    "mm_dist": ...}``.
    """

    name = "r_precision"

    def __init__(self, top_k: int = 3):
        super().__init__()
        self.top_k = int(top_k)
        self.add_state("pools", {}, "keyed")

    def config(self) -> dict:
        return {"top_k": self.top_k}

    def update(self, text, motion, key: Hashable) -> None:
        """Add one pool (rows of ``text`` and ``motion`` pair up) under ``key``."""
        if key in self.pools:
            raise ValueError(f"key: pool {key!r} was already added")
        hits, dist_sum = pool_hits(text, motion, self.top_k)
        self.pools[key] = (hits, len(np.asarray(text)), dist_sum)

    def compute(self) -> dict:
        if not self.pools:
            raise ValueError("RPrecision: no pools were added")
        hits, size, dist = np.zeros(self.top_k, np.int64), 0, 0.0
        for _, (h, n, d) in sorted_items(self.pools):
            hits += h
            size += n
            dist += d
        out = {f"r_precision_top{k + 1}": float(hits[k] / size) for k in range(self.top_k)}
        out["mm_dist"] = dist / size
        return out


class Diversity(Metric):
    """Diversity over embeddings keyed by id (``reduce="keyed"``); ``compute(seed)`` orders
    them by key and applies :func:`diversity`. ``higher_is_better = None`` (closest to the
    real motion's value is best)."""

    name = "diversity"

    def __init__(self, times: int = 300):
        super().__init__()
        self.times = int(times)
        self.add_state("embeddings", {}, "keyed")

    def config(self) -> dict:
        return {"times": self.times}

    def update(self, embeddings, keys: Sequence[Hashable]) -> None:
        x = _as_2d(embeddings, "embeddings")
        if len(keys) != len(x):
            raise ValueError(f"keys: expected {len(x)} keys, got {len(keys)}")
        for k, row in zip(keys, x):
            if k in self.embeddings:
                raise ValueError(f"keys: {k!r} was already added")
            self.embeddings[k] = row.copy()

    def compute(self, seed=0) -> float:
        rows = [v for _, v in sorted_items(self.embeddings)]
        if not rows:
            raise ValueError("Diversity: no embeddings were added")
        return diversity(np.stack(rows), self.times, seed)


class MultiModality(Metric):
    """MultiModality over (samples, D) embeddings keyed by text id (``reduce="keyed"``);
    ``compute(seed)`` stacks them in key order and applies :func:`multimodality`."""

    name = "multimodality"

    def __init__(self, times: int = 10):
        super().__init__()
        self.times = int(times)
        self.add_state("texts", {}, "keyed")

    def config(self) -> dict:
        return {"times": self.times}

    def update(self, key: Hashable, embeddings) -> None:
        if key in self.texts:
            raise ValueError(f"key: text {key!r} was already added")
        self.texts[key] = _as_2d(embeddings, "embeddings").copy()

    def compute(self, seed=0) -> float:
        items = [v for _, v in sorted_items(self.texts)]
        if not items:
            raise ValueError("MultiModality: no texts were added")
        shapes = {v.shape for v in items}
        if len(shapes) != 1:
            raise ValueError(f"MultiModality: every text needs the same number of samples, got {sorted(shapes)}")
        return multimodality(np.stack(items), self.times, seed)


# ===================================================================== replications
def retrieval_replications(text_sets: Sequence[np.ndarray], motion, pools_for, caption_seed_for,
                           replications: int, top_k: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """R-precision top-1..k and MM-Dist per replication, the one draw every hoibench number
    uses (``hoibench evaluate`` and an evaluator card's GT scores).

    Replication r draws one caption per item, in item order, with
    ``numpy.random.default_rng(caption_seed_for(r))`` (``text_sets[i]`` holds item i's
    caption embeddings), and scores ``motion`` (N, D) over ``pools_for(r)`` (row-index pools;
    empty = one pool of all rows). Returns ``(tops (R, top_k), mm (R,))``.
    """
    m = _as_2d(motion, "motion")
    if len(text_sets) != len(m):
        raise ValueError(f"text_sets: expected {len(m)} entries, got {len(text_sets)}")
    tops, mm = [], []
    for r in range(int(replications)):
        rng = np.random.default_rng(caption_seed_for(r))
        text = np.stack([ts[rng.integers(len(ts))] for ts in text_sets])
        pools = pools_for(r) or [list(range(len(m)))]
        tops.append(r_precision(text, m, pools, top_k))
        mm.append(mm_dist(text, m, pools))
    return np.array(tops), np.array(mm)
