"""Ground-truth retrieval scores written in an evaluator's card.

R-precision (top-1/2/3) and MM-Dist follow text-to-motion's ``calculate_R_precision`` /
``euclidean_distance_matrix``: within a pool of ``P`` (motion, caption) pairs, each caption
ranks the ``P`` motions by Euclidean distance between embeddings; top-k counts the captions
whose own motion is among the k nearest. MM-Dist is the mean distance between a caption and
its own motion. Embeddings are L2-normalised here, so distances lie in [0, 2] (the
reference's unnormalised embeddings give larger MM-Dist values; compare within one
evaluator only).

Per-pool hits come from :func:`hoibench.metrics.embedding.pool_hits` (the metrics' own code).

Pools: the items are permuted with ``numpy.random.default_rng([seed, replication])`` and cut
into consecutive pools of ``pool_size`` (32); an incomplete last pool is dropped. When the
split has fewer than ``pool_size`` items, one pool of *all* items is used and the card says
so (``pool_size`` then holds the actual size and chance is ``1 / pool_size``). Each
replication also draws one caption per item from the same generator. Reported: mean over
replications and the 95% CI ``1.96 * std / sqrt(replications)`` (population std).

GT-vs-GT FID: the item embeddings are permuted with ``default_rng([seed, 'fid'])`` (the
integer 4242 stands for 'fid'; split j > 0 of the ``FID_SPLITS`` = 10 averaged in
``fid_gt_relative_mean`` uses ``[seed, 4242, j]``) and split into two disjoint halves of
``floor(N / 2)``; the
Frechet distance between Gaussians fitted to each half (``np.cov``, unbiased) is
``|mu1 - mu2|^2 + tr(S1 + S2 - 2 (S1 S2)^(1/2))``, with the trace of the matrix square root
computed from the eigenvalues of the symmetric ``S1^(1/2) S2 S1^(1/2)`` (the same quantity
as the reference's ``sqrtm`` form, stable for the rank-deficient covariances of small splits).
``fid_gt_relative`` divides it by ``2 * tr(S)`` of all items (the expected squared distance
between two random items): a scale-free "near zero". It is computed in the span of the
centred embeddings (exact, and cheap when N - 1 < D). ``fid_noise_relative`` is the same
quantity for isotropic Gaussian noise of the same N and D, what the sanity gate compares
with (:mod:`hoibench.evaluator.gate`).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..metrics.embedding import frechet_distance, pool_hits  # noqa: F401  (frechet_distance: eigh form)

FID_SEED_TAG = 4242
NOISE_SEED_TAG = 4243
#: seeded half splits averaged for ``fid_gt_relative_mean``
FID_SPLITS = 10


def _ci(values: np.ndarray) -> float:
    return float(1.96 * np.std(values) / np.sqrt(len(values))) if len(values) > 1 else 0.0


def retrieval_scores(motion: np.ndarray, text_sets: list[np.ndarray], pool_size: int = 32,
                     replications: int = 20, seed: int = 0, top_k: int = 3) -> dict:
    """R-precision top-1..k and MM-Dist of ``motion`` (N, D) against one caption per item
    drawn from ``text_sets[i]`` (n_i, D).

    Returns ``{"top1", "top2", "top3", "mm_dist"}`` (each ``{"mean", "ci95"}``) and the pool
    facts: ``pool_size`` (actual), ``requested_pool_size``, ``pools_per_replication``,
    ``replications``, ``items``, ``chance_top1``, ``pool_rule``.
    """
    n = len(motion)
    if n < 2:
        raise ValueError(f"retrieval: need at least 2 items, got {n}")
    if len(text_sets) != n:
        raise ValueError(f"text_sets: expected {n} entries, got {len(text_sets)}")
    if n < pool_size:
        size, rule = n, f"fewer than {pool_size} items: one pool of all {n}"
    else:
        size, rule = pool_size, f"pools of {pool_size} from a seeded permutation, remainder dropped"
    per = n // size
    tops, mm = [], []
    for r in range(replications):
        rng = np.random.default_rng([int(seed), r])
        perm = rng.permutation(n)
        choice = [int(rng.integers(len(text_sets[i]))) for i in range(n)]
        texts = np.stack([text_sets[i][choice[i]] for i in range(n)])
        hits, dist = np.zeros(top_k), 0.0
        for p in range(per):
            idx = perm[p * size:(p + 1) * size]
            h, d = pool_hits(texts[idx], motion[idx], top_k)
            hits += h
            dist += d
        tops.append(hits / (per * size))
        mm.append(dist / (per * size))
    tops = np.array(tops)
    mm = np.array(mm)
    out = {f"top{k + 1}": {"mean": float(tops[:, k].mean()), "ci95": _ci(tops[:, k])} for k in range(top_k)}
    out["mm_dist"] = {"mean": float(mm.mean()), "ci95": _ci(mm)}
    out.update(pool_size=size, requested_pool_size=pool_size, pools_per_replication=per,
               replications=replications, items=n, chance_top1=1.0 / size, pool_rule=rule, seed=int(seed))
    return out


def span_coordinates(x: np.ndarray) -> np.ndarray:
    """Centred rows of ``x`` (N, D) in an orthonormal basis of their span (N, r), r <= N - 1.

    Exact for any Frechet distance between subsets of the rows (means, covariances and
    the matrix square root all live in that span) and much cheaper when N - 1 < D."""
    c = x - x.mean(0)
    if len(x) - 1 >= x.shape[1]:
        return c
    _, s, vt = np.linalg.svd(c, full_matrices=False)
    keep = s > (s[0] * 1e-12 if s.size and s[0] > 0 else np.inf)
    return c @ vt[keep].T if keep.any() else np.zeros((len(x), 1))


def split_fid(y: np.ndarray, perm: np.ndarray) -> float:
    """FID between rows ``perm[:h]`` and ``perm[h:2h]`` of ``y``, ``h = floor(N / 2)``."""
    h = len(y) // 2
    a, b = y[perm[:h]], y[perm[h:2 * h]]
    return frechet_distance(a.mean(0), np.cov(a, rowvar=False), b.mean(0), np.cov(b, rowvar=False))


def _split_perm(n: int, seed: int, j: int) -> np.ndarray:
    key = [int(seed), FID_SEED_TAG] if j == 0 else [int(seed), FID_SEED_TAG, int(j)]
    return np.random.default_rng(key).permutation(n)


@lru_cache(maxsize=128)
def noise_fid_relative(n: int, dim: int) -> float:
    """Expected ``FID(half, half) / (2 tr S)`` of *structureless* embeddings: ``n`` rows of an
    isotropic Gaussian in ``dim`` dimensions, split into halves of ``floor(n / 2)``.

    Mean over seeded draws (16 when ``n <= dim``, else 4: the value concentrates as ``n``
    grows). About ``1 + 1/h - sqrt((h - 1) / dim)`` for ``h << dim`` (1.27 for h = 3,
    0.95 for h = 13 at dim 512); it falls like ``dim / h`` once ``h >> dim``."""
    draws = 16 if n <= dim else 4
    vals = []
    for b in range(draws):
        rng = np.random.default_rng([int(n), int(dim), b, NOISE_SEED_TAG])
        x = rng.standard_normal((n, dim))
        spread = 2.0 * float(np.trace(np.atleast_2d(np.cov(x, rowvar=False))))
        vals.append(split_fid(span_coordinates(x), rng.permutation(n)) / spread)
    return float(np.mean(vals))


def gt_fid_halves(motion: np.ndarray, seed: int = 0, splits: int = FID_SPLITS) -> dict:
    """FID between two disjoint seeded halves of ``motion`` (N, D), relative values, and the
    noise reference the sanity gate compares with.

    ``fid_gt_halves``/``fid_gt_relative``: the first split (permutation
    ``default_rng([seed, 4242])``); ``fid_gt_relative_mean``: mean of ``FID / (2 tr S)`` over
    ``splits`` seeded splits (split j > 0: ``default_rng([seed, 4242, j])``), a steadier
    estimate of the same quantity; ``fid_noise_relative``: :func:`noise_fid_relative` for
    the same N and D."""
    x = np.asarray(motion, np.float64)
    n = len(x)
    if n < 4:
        raise ValueError(f"GT FID: need at least 4 items, got {n}")
    spread = float(2.0 * np.trace(np.atleast_2d(np.cov(x, rowvar=False))))
    y = span_coordinates(x)
    fids = [split_fid(y, _split_perm(n, seed, j)) for j in range(max(1, splits))]
    rel = (lambda f: f / spread if spread > 0 else None)   # None: collapsed embeddings
    rels = [rel(f) for f in fids]
    return {"fid_gt_halves": fids[0], "half_size": n // 2, "embedding_spread": spread,
            "fid_gt_relative": rels[0], "fid_gt_splits": len(fids),
            "fid_gt_relative_mean": None if rels[0] is None else float(np.mean(rels)),
            "fid_noise_relative": noise_fid_relative(n, x.shape[1]), "embed_dim": int(x.shape[1])}


def protocol_retrieval_scores(motion: np.ndarray, text_sets: list[np.ndarray], ids: list[str], protocol) -> dict:
    """R-precision and MM-Dist with ``protocol``'s pools and caption draws
    (:func:`hoibench.metrics.embedding.retrieval_replications`), so that ``hoibench
    evaluate`` of the ground-truth submission reproduces these numbers exactly."""
    from ..metrics.embedding import retrieval_replications
    where = {cid: i for i, cid in enumerate(ids)}
    pools_for = lambda r: [[where[c] for c in p] for p in protocol.pools(ids, r)]  # noqa: E731
    tops, mm = retrieval_replications(text_sets, motion, pools_for, lambda r: protocol.seed_for("caption", r),
                                      protocol.replications, protocol.r_precision_top_k)
    pools = protocol.pools(ids, 0)
    size = len(pools[0]) if pools else len(ids)
    out = {f"top{k + 1}": {"mean": float(tops[:, k].mean()), "ci95": _ci(tops[:, k])} for k in range(tops.shape[1])}
    out["mm_dist"] = {"mean": float(mm.mean()), "ci95": _ci(mm)}
    rule = (f"protocol {protocol.ref}: pools of {size}" if pools else
            f"protocol {protocol.ref}: fewer than {protocol.r_precision_pool_size} items: one pool of all {len(ids)}")
    out.update(pool_size=size, requested_pool_size=protocol.r_precision_pool_size,
               pools_per_replication=max(1, len(pools)), replications=protocol.replications, items=len(ids),
               chance_top1=1.0 / size, pool_rule=rule, seed=int(protocol.seed), protocol=protocol.ref)
    return out


def embedding_scores(motion: np.ndarray, text_sets: list[np.ndarray], ids: list[str] | None = None,
                     protocol=None, pool_size: int = 32, replications: int = 20, seed: int | None = None) -> dict:
    """GT retrieval and GT-vs-GT FID from embeddings: ``motion`` (N, D), ``text_sets[i]``
    (n_i, D) the caption embeddings of item i.

    With ``protocol`` (and one id per row) the rows are put in sorted-id order and the
    retrieval uses the protocol's pools and caption draws, the FID halves the protocol's
    seed (``seed`` overrides it); otherwise pools of ``pool_size``, ``replications`` and
    ``seed`` (default 0), rows in the given order."""
    motion = np.asarray(motion)
    if len(text_sets) != len(motion):
        raise ValueError(f"text_sets: expected {len(motion)} entries (one per motion row), got {len(text_sets)}")
    if protocol is not None:
        if ids is None or len(ids) != len(motion):
            raise ValueError("embedding_scores: a protocol needs one id per motion row")
        order = sorted(range(len(ids)), key=lambda i: ids[i])
        motion = motion[order]
        out = protocol_retrieval_scores(motion, [text_sets[i] for i in order], [ids[i] for i in order], protocol)
        out.update(gt_fid_halves(motion, int(protocol.seed) if seed is None else int(seed)))
        return out
    out = retrieval_scores(motion, list(text_sets), pool_size, replications, seed or 0)
    out.update(gt_fid_halves(motion, seed or 0))
    return out


def embed_items(evaluator, items) -> tuple[np.ndarray, list[np.ndarray]]:
    """(motion embeddings (N, D), caption embeddings per item) of :class:`data.Item` s."""
    motion = evaluator.embed_motion([it.features for it in items])
    emb = evaluator.embed_text([c for it in items for c in it.captions])
    bounds = np.cumsum([0] + [len(it.captions) for it in items])
    return motion, [emb[a:b] for a, b in zip(bounds[:-1], bounds[1:])]


def gt_scores(evaluator, items, pool_size: int = 32, replications: int = 20, seed: int = 0,
              protocol=None) -> dict:
    """GT retrieval and GT-vs-GT FID of ``evaluator`` on ``items`` (:class:`data.Item`):
    :func:`embed_items` + :func:`embedding_scores`.

    With ``protocol`` (a :class:`hoibench.tracks.protocol.Protocol`) and whole-clip items, the
    retrieval uses the protocol's pools and caption draws (items sorted by clip id) and the
    FID halves the protocol's seed, instead of ``pool_size``/``replications``/``seed``
    (so :func:`hoibench.evaluator.gate.recompute_gate` reproduces these numbers)."""
    if protocol is not None and any(it.segment for it in items):
        protocol = None
    motion, sets = embed_items(evaluator, items)
    if protocol is not None:
        return embedding_scores(motion, sets, [it.clip_id for it in items], protocol)
    return embedding_scores(motion, sets, pool_size=pool_size, replications=replications, seed=seed)
    motion = evaluator.embed_motion([it.features for it in items])
    caps = [c for it in items for c in it.captions]
    emb = evaluator.embed_text(caps)
    sets, k = [], 0
    for it in items:
        sets.append(emb[k:k + len(it.captions)])
        k += len(it.captions)
    out = retrieval_scores(motion, sets, pool_size, replications, seed)
    out.update(gt_fid_halves(motion, seed))
    return out
