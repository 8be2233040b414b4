"""Which ranked rows of a leaderboard a paired test tells apart, and how sure each rank is.

Entries keep their result's per-clip data beside them (``entries/<slug>.clips.npz``,
:func:`hoibench.publish.leaderboard.attach_clip_data`: the evaluator embeddings of each
scored test clip's samples, of its ground truth and captions, and the per-clip physical
values; at most 1 MiB: a larger file keeps sample 0 of each prompt only, and the entry's
``per_clip_data.samples`` says so). From them ``leaderboard build`` computes, for the ranked
rows (methods and baselines) in display order:

- **vs the row above**: the paired clip bootstrap of :func:`hoibench.scoring.paired.compare_pair`
  (:data:`RESAMPLES` seeded draws of the shared test clips) on the track's headline metrics,
  Holm-adjusted across those metrics; the row is *distinguishable* from the one above when
  some headline metric's adjusted p is under :data:`~hoibench.scoring.paired.ALPHA`;
- **rank interval**: on each draw every ranked row's FID is recomputed on the drawn clips
  (sample 0 of each prompt), the rows are ranked by it, and the interval runs from the 2.5th
  percentile of each row's best rank to the 97.5th of its worst (rows tied on a draw may take
  either rank; integers, rounded outwards). Computed only when every
  ranked row has per-clip data for the same test clips (a partial ranking would mislead).

The draws depend on the seed and the clip ids only, so a rebuild gives the same bytes.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .leaderboard import LeaderboardError, band

#: seeded draws of the paired tests and rank intervals
RESAMPLES = 2000
SEED = 0


def _arrays(entry: dict, entries_dir: Path) -> dict | None:
    from ..scoring.clip_data import read_clip_data
    if not isinstance(entry.get("per_clip_data"), dict):
        return None
    try:
        return read_clip_data(entry, entries_dir / entry["_file"])
    except ValueError as exc:
        raise LeaderboardError(str(exc)) from None


def _rank_intervals(arrays: list[dict], proto, resamples: int, seed: int) -> list[list[int]]:
    """Each row's [lo, hi] rank (1 = lowest FID) over the draws (module docstring)."""
    from ..metrics.resampling import bootstrap_weights
    from ..scoring.paired import set_level_draws
    W = bootstrap_weights(len(arrays[0]["ids"]), resamples, seed)
    fid = np.array([set_level_draws(a, proto, W, seed)[0]["fid"] for a in arrays])     # (rows, draws)
    better = (fid[None, :, :] < fid[:, None, :]).sum(1)             # rows strictly better, per draw
    tied = (fid[None, :, :] == fid[:, None, :]).sum(1) - 1           # other rows with the same FID
    lo, hi = better + 1, better + 1 + tied                           # a tie may take either rank
    return [[int(np.floor(np.percentile(a, 2.5))), int(np.ceil(np.percentile(b, 97.5)))] for a, b in zip(lo, hi)]


def _better(metric: str, diff: float) -> str:
    """Which side a significant difference ``diff`` (this row minus the row above) favours."""
    from ..metrics.catalog import METRICS
    from ..scoring.paired import favours_b
    this_row = favours_b(METRICS[metric].direction, diff)
    if this_row is None:
        return "different (neither end is better)"
    return "this row better" if this_row else "the row above better"


def track_significance(track_dir: str | Path, entries: list[dict], headline: tuple[str, ...],
                       resamples: int = RESAMPLES, seed: int = SEED) -> dict[str, dict]:
    """``{entry file: {"vs_above": {...}, "rank_ci95": [lo, hi]}}`` for the ranked rows of
    ``entries`` (in display order) that kept per-clip data (module docstring). ``vs_above``:
    ``{"method", "n_clips", "distinguishable", "metrics": {name: {"diff", "ci95", "p",
    "p_holm", "verdict"}}}``, diff = this row minus the row above."""
    from ..metrics.resampling import holm
    from ..scoring.paired import ALPHA, compare_pair
    from ..tracks.protocol import get_protocol
    folder = Path(track_dir) / "entries"
    ranked = [e for e in entries if band(e) == "ranked"]
    loaded = [(e, _arrays(e, folder)) for e in ranked]
    out: dict[str, dict] = {e["_file"]: {} for e, a in loaded if a is not None}
    for (prev, pa), (e, a) in zip(loaded, loaded[1:]):
        if pa is None or a is None:
            continue
        proto = get_protocol(f"{e['protocol']}@{e['protocol_version']}")
        try:
            pair = compare_pair(prev, pa, e, a, proto, resamples, seed)
        except ValueError as exc:
            raise LeaderboardError(f"{folder / e['_file']}: against the row above ({prev['_file']}): {exc}") from None
        names = [m for m in headline if m in pair["metrics"]]
        adjusted = holm([pair["metrics"][m]["p"] if np.isfinite(pair["metrics"][m]["p"]) else 1.0 for m in names])
        rows = {}
        for m, ph in zip(names, adjusted):
            r = pair["metrics"][m]
            verdict = f"not distinguishable on {pair['n_clips']} clips" if ph >= ALPHA else _better(m, r["diff"])
            rows[m] = {"diff": r["diff"], "ci95": r["ci95"], "p": r["p"], "p_holm": float(ph), "verdict": verdict}
        out[e["_file"]]["vs_above"] = {"method": prev["method"], "n_clips": pair["n_clips"], "metrics": rows,
                                       "distinguishable": any(v["p_holm"] < ALPHA for v in rows.values())}
    with_data = [(e, a) for e, a in loaded if a is not None]
    same_ids = with_data and all(np.array_equal(a["ids"], with_data[0][1]["ids"]) for _, a in with_data)
    if len(with_data) == len(ranked) and len(ranked) > 1 and same_ids:
        e0 = with_data[0][0]
        proto = get_protocol(f"{e0['protocol']}@{e0['protocol_version']}")
        for (e, _), iv in zip(with_data, _rank_intervals([a for _, a in with_data], proto, resamples, seed)):
            out[e["_file"]]["rank_ci95"] = iv
    return out


def rank_text(sig: dict | None) -> str:
    """``lo-hi`` (or ``k`` when both ends agree); ``-`` without an interval."""
    iv = (sig or {}).get("rank_ci95")
    if not iv:
        return "-"
    return f"{iv[0]}" if iv[0] == iv[1] else f"{iv[0]}-{iv[1]}"


def vs_above_text(sig: dict | None, short: bool = False) -> str:
    """``yes: FID p 0.001 (above better), ...`` (the headline metrics whose Holm-adjusted p is
    under the level, and which row each favours; ``short``: their names only), ``no (N
    clips)``, or ``-`` (no test: the first ranked row, or no per-clip data)."""
    from ..scoring.paired import ALPHA
    from .leaderboard import title
    vs = (sig or {}).get("vs_above")
    if not vs:
        return "-"
    if not vs["distinguishable"]:
        return f"no ({vs['n_clips']} clips)"
    if short:
        return "yes: " + ", ".join(title(m) for m, r in vs["metrics"].items() if r["p_holm"] < ALPHA)
    parts = [f"{title(m)} p {r['p_holm']:.2g} ({'this row' if r['verdict'] == 'this row better' else 'above'} "
             f"better)" if "better" in r["verdict"] else f"{title(m)} p {r['p_holm']:.2g}"
             for m, r in vs["metrics"].items() if r["p_holm"] < ALPHA]
    return "yes: " + ", ".join(parts)


def vs_above_detail(sig: dict | None) -> str:
    """Every headline metric's paired difference: ``FID +0.012 [-0.03, +0.05] p_holm 0.6; ...``."""
    from .leaderboard import title
    vs = (sig or {}).get("vs_above")
    if not vs:
        return ""
    return f"vs {vs['method']}: " + "; ".join(
        f"{title(m)} {r['diff']:+.3g} [{r['ci95'][0]:+.3g}, {r['ci95'][1]:+.3g}] p_holm {r['p_holm']:.2g}"
        for m, r in vs["metrics"].items())


SIGNIFICANCE_NOTE = ("rank 95%: the 2.5th-97.5th percentile of the row's FID rank over 2,000 seeded draws of the "
                     "test clips (every ranked row recomputed on each draw, sample 0); vs row above: a paired clip "
                     "bootstrap (2,000 draws) against the ranked row above on the track's headline metrics, "
                     "Holm-adjusted, 'yes' naming each metric with adjusted p < 0.05")


__all__ = ["RESAMPLES", "SIGNIFICANCE_NOTE", "rank_text", "track_significance", "vs_above_detail", "vs_above_text"]
