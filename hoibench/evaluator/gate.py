"""Sanity gate: an evaluator is only used when its ground-truth scores show it works.

Two checks on the GT retrieval scores of the test split (:mod:`hoibench.evaluator.retrieval`):

1. **R-precision top-1 well above chance**: ``top1 >= max(MIN_TOP1_TIMES_CHANCE * chance,
   chance + MIN_TOP1_MARGIN)`` with ``chance = 1 / pool_size`` (1/32 = 0.031 for full pools,
   so top-1 must reach 0.125). For comparison, the HumanML3D evaluator scores about 0.51 on
   its ground truth (16x chance), and on hoibench's synthetic data a tiny evaluator
   reaches 0.7-0.9 (docs/evaluator.md) while random weights and shuffled-text training stay
   near chance.
2. **GT-vs-GT FID near zero**: two disjoint halves of the same GT split must look alike:
   ``fid_gt_relative = FID(half A, half B) / (2 tr S) <= MAX_FID_GT_RELATIVE``, where ``2 tr S``
   is the mean squared distance between two random GT embeddings (the FID of a point mass
   against the data is of that order). A value near 1 means the halves are as far apart as
   random items are: the embedding is dominated by per-clip noise, or the split is too small
   for a meaningful FID.

A failing evaluator is still written (its card says why), but :func:`load_evaluator` refuses
it unless ``allow_failed_gate=True`` (for diagnostics and controls).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

MIN_TOP1_TIMES_CHANCE = 4.0
MIN_TOP1_MARGIN = 0.10
MAX_FID_GT_RELATIVE = 0.5


class SanityGateError(RuntimeError):
    """An evaluator whose ground-truth scores do not show that it works."""


@dataclass(frozen=True)
class GateResult:
    passed: bool
    top1: float
    chance: float
    min_top1: float
    fid_gt_relative: float
    max_fid_gt_relative: float
    reasons: tuple[str, ...]

    def to_card(self) -> dict:
        d = asdict(self)
        if d["fid_gt_relative"] == float("inf"):
            d["fid_gt_relative"] = None
        d["reasons"] = list(self.reasons)
        d["rule"] = (f"top1 >= max({MIN_TOP1_TIMES_CHANCE:g} x chance, chance + {MIN_TOP1_MARGIN:g}) and "
                     f"FID(GT half, GT half) / (2 tr S) <= {MAX_FID_GT_RELATIVE:g}")
        return d

    def diagnostic(self) -> str:
        if self.passed:
            return (f"sanity gate passed: GT R-precision top-1 {self.top1:.3f} (chance {self.chance:.3f}, "
                    f"needed {self.min_top1:.3f}); GT-vs-GT FID relative {self.fid_gt_relative:.3f} "
                    f"(<= {self.max_fid_gt_relative:g})")
        return "sanity gate FAILED: " + "; ".join(self.reasons)


def sanity_gate(scores: dict) -> GateResult:
    """Apply the gate to GT scores (:func:`retrieval.gt_scores`)."""
    top1 = float(scores["top1"]["mean"])
    chance = float(scores["chance_top1"])
    need = max(MIN_TOP1_TIMES_CHANCE * chance, chance + MIN_TOP1_MARGIN)
    rel = scores["fid_gt_relative"]
    rel = float("inf") if rel is None else float(rel)
    reasons = []
    if not top1 >= need:
        reasons.append(f"GT R-precision top-1 {top1:.3f} is not well above chance {chance:.3f} "
                       f"(pool of {scores['pool_size']}; needed >= {need:.3f}): the evaluator does not match "
                       f"captions to their motions (untrained, too few epochs, texts not matching clips, "
                       f"or a shuffled-text control)")
    if rel == float("inf"):
        reasons.append("all GT motion embeddings are identical (collapsed evaluator)")
    elif not rel <= MAX_FID_GT_RELATIVE:
        reasons.append(f"GT-vs-GT FID {scores['fid_gt_halves']:.4f} is {rel:.3f} of the embedding spread "
                       f"(allowed <= {MAX_FID_GT_RELATIVE:g}): two halves of the same GT split do not look "
                       f"alike ({scores['half_size']} items per half)")
    return GateResult(not reasons, top1, chance, need, rel, MAX_FID_GT_RELATIVE, tuple(reasons))


def check_card_gate(card: dict) -> None:
    """Raise :class:`SanityGateError` with the card's diagnostic when its gate failed."""
    gate = card.get("gate") or {}
    if not gate.get("passed", False):
        reasons = gate.get("reasons") or ["the card records no sanity-gate result"]
        raise SanityGateError(f"evaluator {card.get('evaluator_id', '?')[:12]} failed the sanity gate: "
                              + "; ".join(reasons) + " (load with allow_failed_gate=True to inspect it anyway)")
