"""Sanity gate: an evaluator is only used when its ground-truth scores show that it works.

Two checks on the GT retrieval scores of a test split (:mod:`hoibench.evaluator.retrieval`).
Both thresholds follow from the size of the split, so a small split is neither waved
through by luck nor refused for being small when the evaluator clearly works.

**1. R-precision top-1 above chance, by more than luck allows.** With pools of ``P``
items (``P = N`` when the split has fewer items ``N`` than the pool size) and ``M =
pools_per_replication * P`` captions scored per replication, the null hypothesis is an
evaluator whose captions carry no information about their motions: each caption's own
motion is the nearest of its pool with probability ``p = 1/P``, so the hits of one
replication are ``Binomial(M, p)``. The reported top-1 is a mean over replications, which
varies less than one replication does, so the bound is conservative. The gate requires::

    top1 >= min_top1 = max(k* / M, p + MIN_TOP1_MARGIN),
    k* = min { k : P(Binomial(M, p) >= k) <= FALSE_ACCEPTANCE }

``FALSE_ACCEPTANCE`` = 0.001: at most 1 in 1000 evaluators without text-motion
association passes check 1 (measured on random embeddings: ``tests/test_evaluator_trust.py``).
``MIN_TOP1_MARGIN`` = 0.10 keeps a floor where ``M`` is large and a barely-above-chance
top-1 would be significant but useless. Examples: ``N = 7`` (one pool of 7) 0.714;
``N = 17..31`` with pools of 16: 0.375; ``N = 32..47``, pools of 16: 0.25; pools of 32,
``M = 32``: 0.188; HumanML3D-size splits (``M = 4384``, pools of 32): 0.131 (the floor).

**2. GT-vs-GT FID below what structureless embeddings give.** Two disjoint halves of the
same split should look alike. ``fid_gt_relative_mean`` = mean over 10 seeded half splits
of ``FID(half, half) / (2 tr S)`` (``2 tr S``: mean squared distance between two GT
embeddings). Halves of a few items have a large FID from sampling alone, so the value is
compared with ``fid_noise_relative``, the same quantity for isotropic Gaussian noise with the
same N and dimension (:func:`retrieval.noise_fid_relative`: about 1.27 for halves of 3, 1.03
for halves of 8, 0.95 for 13, 0.91 for 17, 0.06 for 2192 at dimension 512)::

    fid_noise_ratio = fid_gt_relative_mean / fid_noise_relative <= MAX_FID_NOISE_RATIO (0.5)

Null model: embeddings that are per-clip noise give a ratio of 1 (measured 1.00 +- 0.01 for
N = 7..57 at dimension 512; the smallest of 1000 seeded draws was 0.98, none passed); a ratio
above 0.5 means that more than about half of the embedding spread behaves like per-clip
noise at this split size (or that the split is too small for a GT FID to mean anything).
Collapsed embeddings (zero spread) fail.

Measured false acceptance of check 1 (random Gaussian embeddings): 4.8e-4 in the bound's
worst case (one pool of 7, one caption, one replication; 100,000 draws), 0 in 20,000 draws
with several captions and 20 replications. Measured false refusal (docs/evaluator.md,
"Sanity gate"): the README workflow's tiny evaluators on 120 synthetic clips passed in 9 of
9 seeds (weakest top-1 0.577 against 0.250, FID ratio at most 0.235); 24 clips failed in 5 of
5 (7 test items: top-1 must reach 0.714), 44-48 clips passed in 3 of 5. Random-weights and
shuffled-text evaluators fail check 1. The FID check does not detect an untrained network --
R-precision does -- it detects embeddings dominated by per-clip noise and splits too small
for an FID.

A failing evaluator is still written (its card says why), but :func:`load_evaluator` refuses
it unless ``allow_failed_gate=True``. The card's ``gate`` block is never trusted:
:func:`card_gate` re-applies this rule to the card's GT scores on load, and
:func:`recompute_gate` / :func:`gate_from_embeddings` measure the gate afresh from the
weights on a store's test split (what ``hoibench evaluate`` records).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from functools import lru_cache
from pathlib import Path
from typing import Sequence

import numpy as np

from .errors import SanityGateError

__all__ = ["FALSE_ACCEPTANCE", "MIN_TOP1_MARGIN", "MAX_FID_NOISE_RATIO", "GateResult", "SanityGateError",
           "binomial_threshold", "min_top1", "sanity_gate", "card_gate", "check_card_gate",
           "gate_from_embeddings", "recompute_gate"]

FALSE_ACCEPTANCE = 1e-3
MIN_TOP1_MARGIN = 0.10
MAX_FID_NOISE_RATIO = 0.5
RULE = (f"top1 >= max(k*/M, chance + {MIN_TOP1_MARGIN:g}) with k* the smallest k such that "
        f"P(Binomial(M, chance) >= k) <= {FALSE_ACCEPTANCE:g} (M captions scored per replication); and "
        f"mean FID(GT half, GT half) / (2 tr S) <= {MAX_FID_NOISE_RATIO:g} x the same for isotropic noise "
        f"of the same size and dimension")


@lru_cache(maxsize=256)
def binomial_threshold(m: int, p: float, alpha: float = FALSE_ACCEPTANCE) -> int:
    """``k* = min {k : P(Binomial(m, p) >= k) <= alpha}`` (exact; log-space pmf)."""
    if m < 1 or not 0.0 < p < 1.0:
        raise ValueError(f"binomial_threshold: need m >= 1 and 0 < p < 1, got m={m}, p={p}")
    logpmf = [math.lgamma(m + 1) - math.lgamma(k + 1) - math.lgamma(m - k + 1)
              + k * math.log(p) + (m - k) * math.log1p(-p) for k in range(m + 1)]
    tail = 0.0
    for k in range(m, -1, -1):           # tail = P(X >= k)
        tail += math.exp(logpmf[k])
        if tail > alpha:
            return k + 1
    return 0


def min_top1(pool_size: int, scored_per_replication: int, alpha: float = FALSE_ACCEPTANCE,
             margin: float = MIN_TOP1_MARGIN) -> float:
    """``max(k*/M, 1/P + margin)`` for pools of ``P = pool_size`` and ``M`` captions per replication."""
    p = 1.0 / pool_size
    m = max(1, int(scored_per_replication))
    return max(binomial_threshold(m, p, alpha) / m, p + margin)


@dataclass(frozen=True)
class GateResult:
    passed: bool
    top1: float
    chance: float
    min_top1: float
    fid_gt_relative: float          # mean over seeded half splits (inf: collapsed)
    max_fid_gt_relative: float      # MAX_FID_NOISE_RATIO x fid_noise_relative
    reasons: tuple[str, ...]
    pool_size: int = 0
    scored_per_replication: int = 0
    items: int = 0
    half_size: int = 0
    fid_noise_relative: float = float("nan")
    fid_noise_ratio: float = float("nan")
    false_acceptance: float = FALSE_ACCEPTANCE

    def to_card(self) -> dict:
        """JSON-ready record (``inf``/``nan`` as ``None``) with the rule."""
        d = asdict(self)
        for k, v in d.items():
            if isinstance(v, float) and not math.isfinite(v):
                d[k] = None
        d["reasons"] = list(self.reasons)
        d["rule"] = RULE
        return d

    def diagnostic(self) -> str:
        if self.passed:
            return (f"sanity gate passed: GT R-precision top-1 {self.top1:.3f} (chance {self.chance:.3f}, "
                    f"needed {self.min_top1:.3f}); GT-vs-GT FID {self.fid_noise_ratio:.2f} x the noise level "
                    f"(<= {MAX_FID_NOISE_RATIO:g})")
        return "sanity gate FAILED: " + "; ".join(self.reasons)


def _num(scores: dict, *path: str) -> float:
    v = scores
    for k in path:
        v = v[k]
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise TypeError(f"{'.'.join(path)}: expected a number, got {type(v).__name__}")
    return float(v)


def _top1_check(scores: dict) -> tuple[float, float, float, int, str | None]:
    top1 = _num(scores, "top1", "mean")
    pool = int(_num(scores, "pool_size"))
    m = pool * max(1, int(_num(scores, "pools_per_replication")))
    chance = 1.0 / pool
    need = min_top1(pool, m)
    if top1 >= need:
        return top1, chance, need, m, None
    return top1, chance, need, m, (
        f"GT R-precision top-1 {top1:.3f} is not well above chance {chance:.3f} (pools of {pool}, {m} captions "
        f"per replication; needed >= {need:.3f}, which a text-blind evaluator reaches with probability "
        f"<= {FALSE_ACCEPTANCE:g}): the evaluator does not match captions to their motions (untrained, too "
        f"few epochs or clips, texts not matching clips, or a shuffled-text control)")


def _fid_check(scores: dict, embed_dim: int) -> tuple[float, float, float, str | None]:
    from .retrieval import noise_fid_relative
    items = int(_num(scores, "items"))
    rel = scores.get("fid_gt_relative_mean", scores.get("fid_gt_relative"))
    noise = noise_fid_relative(items, int(scores.get("embed_dim") or embed_dim))
    if rel is None:
        return math.inf, noise, math.inf, "all GT motion embeddings are identical (collapsed evaluator)"
    rel = float(rel)
    ratio = rel / noise
    if ratio <= MAX_FID_NOISE_RATIO:
        return rel, noise, ratio, None
    return rel, noise, ratio, (
        f"GT-vs-GT FID is {rel:.3f} of the embedding spread, {ratio:.2f} x what structureless noise gives "
        f"for {items} items in halves of {items // 2} ({noise:.3f}; allowed <= {MAX_FID_NOISE_RATIO:g} x): two "
        f"halves of the same GT split do not look alike (embeddings dominated by per-clip noise, or a split "
        f"too small for a GT FID)")


def sanity_gate(scores: dict, embed_dim: int = 512) -> GateResult:
    """Apply the gate to GT scores (:func:`retrieval.gt_scores` or a card's ``gt_retrieval``)."""
    top1, chance, need, m, why1 = _top1_check(scores)
    rel, noise, ratio, why2 = _fid_check(scores, embed_dim)
    reasons = tuple(r for r in (why1, why2) if r)
    return GateResult(not reasons, top1, chance, need, rel, MAX_FID_NOISE_RATIO * noise, reasons,
                      pool_size=int(round(1 / chance)), scored_per_replication=m, items=int(_num(scores, "items")),
                      half_size=int(_num(scores, "items")) // 2, fid_noise_relative=noise, fid_noise_ratio=ratio)


def card_gate(card: dict) -> GateResult:
    """The gate re-derived from a card's ``gt_retrieval`` scores with this version's rule (the
    card's own ``gate`` block is not read). ``CorruptEvaluatorFile`` when the scores are
    missing or malformed."""
    from .errors import CorruptEvaluatorFile
    g = card.get("gt_retrieval")
    try:
        if not isinstance(g, dict):
            raise TypeError("missing or not an object")
        dim = card.get("config", {}).get("model", {}).get("embed_dim", 512)
        return sanity_gate(g, int(dim))
    except (KeyError, TypeError, ValueError, ZeroDivisionError) as exc:
        raise CorruptEvaluatorFile(f"card.json: field gt_retrieval: {exc!s} (the GT scores the sanity gate "
                                   f"is re-derived from)") from None


def check_card_gate(card: dict) -> GateResult:
    """:func:`card_gate`, raising :class:`SanityGateError` with its diagnostic when it fails."""
    gate = card_gate(card)
    if not gate.passed:
        raise SanityGateError(f"evaluator {str(card.get('evaluator_id', '?'))[:12]} fails the sanity gate "
                              f"(re-derived from its card's GT scores): " + "; ".join(gate.reasons)
                              + " (load with allow_failed_gate=True to inspect it anyway)")
    return gate


# --------------------------------------------------------------------------- measured afresh
def gate_from_embeddings(motion: np.ndarray, text_sets: Sequence[np.ndarray], ids: Sequence[str] | None = None,
                         protocol=None, *, seed: int | None = None, pool_size: int = 32,
                         replications: int = 20) -> dict:
    """The sanity gate measured from GT embeddings: ``motion`` (N, D) and ``text_sets[i]``
    (n_i, D), the caption embeddings of item i.

    With ``protocol`` (and ``ids``), R-precision uses the protocol's pools and caption draws
    and the FID halves its seed, exactly as ``hoibench evaluate`` scores the ground-truth
    submission (rows are put in sorted-id order first, so the input order does not matter);
    otherwise pools of ``pool_size``, ``replications`` and ``seed`` (default 0). Returns the
    JSON-ready record ``GateResult.to_card()`` plus ``scores`` (the GT scores it was derived from).
    """
    from .retrieval import embedding_scores
    scores = embedding_scores(motion, list(text_sets), None if ids is None else list(ids), protocol,
                              pool_size, replications, seed)
    record = sanity_gate(scores, np.asarray(motion).shape[1]).to_card()
    record["scores"] = scores
    return record


def recompute_gate(evaluator, store, protocol=None, split: str = "test") -> dict:
    """The sanity gate measured afresh from ``evaluator``'s weights on ``store``'s ``split``
    (a :class:`hoibench.datasets.store.Store` or its folder): its items and captions
    (``DATA/texts/``) as training scored them, embedded, then :func:`gate_from_embeddings`.

    ``protocol``: a :class:`hoibench.tracks.protocol.Protocol`, a protocol id, or None for the
    store's default protocol (``<dataset>-<mode>``; the evaluator's own pools of 32 when none
    ships). On the store an evaluator was trained on this reproduces its card's gate.
    Returns the JSON-ready gate record, with ``measured_on`` (store, split, protocol)."""
    from ..datasets.store import Store
    from .data import load_items, store_protocol
    store = store if isinstance(store, Store) else Store(Path(store))
    if isinstance(protocol, str):
        from ..tracks.protocol import get_protocol
        protocol = get_protocol(protocol)
    elif protocol is None:
        protocol = store_protocol(store)
    tc = evaluator.config.train
    items = load_items(store, split, evaluator.variant, tc.min_frames).items
    if len(items) < 4:
        raise ValueError(f"{store.root}: the {split} split has {len(items)} captioned items; the sanity gate "
                         f"needs at least 4 (run hoibench annotate?)")
    if protocol is not None and any(it.segment for it in items):
        protocol = None                              # segment items: the trainer's own pools
    from .retrieval import embed_items
    motion, sets = embed_items(evaluator, items)
    seed = int(evaluator.card.get("seed", tc.seed) or 0) if protocol is None else None
    record = gate_from_embeddings(motion, sets, [it.key for it in items], protocol, seed=seed)
    record["measured_on"] = {"store": str(store.root), "split": split, "items": len(items),
                             "protocol": getattr(protocol, "ref", None)}
    return record
