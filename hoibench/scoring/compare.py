"""``hoibench compare A.json B.json ...``: results of ``hoibench evaluate`` side by side.

For every metric the table shows ``mean ± 95% CI`` per result and, against the first result,
whether the difference is outside the confidence intervals: ``|m_A - m_B| > ci_A + ci_B``
(the two intervals do not overlap; a conservative test -- overlapping intervals do not prove
the difference is noise). Results scored with another evaluator, protocol or protocol version
than the first are compared anyway but flagged: their numbers are not on one scale.
``--plot`` draws the main metrics as bars with CI error bars.
"""
from __future__ import annotations

from pathlib import Path

from .hoi import GROUPS
from .results import read_result as load_result


def _mc(r: dict, name: str) -> tuple[float, float] | None:
    m = r["metrics"].get(name)
    if m is None:
        return None
    mean, ci = m["mean"], m.get("ci95", 0.0)
    if isinstance(mean, list):
        mean, ci = mean[0], ci[0]
    return float(mean), float(ci or 0.0)


def outside(a: tuple[float, float], b: tuple[float, float]) -> bool:
    """The two 95% intervals ``mean ± ci`` do not overlap."""
    return abs(a[0] - b[0]) > a[1] + b[1]


def compare(paths: list[str | Path], names: list[str] | None = None) -> str:
    """The side-by-side table (text) of the results at ``paths``."""
    if len(paths) < 2:
        raise ValueError("compare: give at least two result files")
    results = [load_result(p) for p in paths]
    names = names or [str(r.get("submission", {}).get("method") or Path(p).stem) for r, p in zip(results, paths)]
    base = results[0]
    key = lambda r: (r.get("evaluator_id"), r.get("protocol"), r.get("protocol_version"))  # noqa: E731
    lines = []
    for n, r, p in zip(names, results, paths):
        flag = "" if key(r) == key(base) else "  [other evaluator/protocol: not on one scale]"
        lines.append(f"{n}: {p} ({r.get('protocol')}@{r.get('protocol_version')}, evaluator "
                     f"{str(r.get('evaluator_id'))[:12]}, K={r.get('counts', {}).get('samples_per_prompt')}, "
                     f"{'complete' if r.get('complete') else 'INCOMPLETE'}){flag}")
    width = min(max(18, *(len(n) for n in names)), 26) + 2
    lines += ["", f"{'metric':26s}" + "".join(f"{n[:width - 2]:>{width}s}" for n in names)]
    for group, metric_names in GROUPS:
        rows = [m for m in metric_names if any(_mc(r, m) for r in results)]
        if rows:
            lines.append(f"{group}:")
        for m in rows:
            cells = []
            ref = _mc(base, m)
            for i, r in enumerate(results):
                v = _mc(r, m)
                if v is None:
                    cells.append(f"{'-':>{width}s}")
                    continue
                star = "*" if (i > 0 and ref is not None and outside(v, ref)) else " "
                cells.append(f"{f'{v[0]:.4g} ± {v[1]:.2g}{star}':>{width}s}")
            lines.append(f"  {m:24s}" + "".join(cells))
    lines += ["", f"* outside the 95% CIs of {names[0]} (the intervals do not overlap)"]
    if any(r.get("counts", {}).get("samples_per_prompt") == 1 for r in results):
        lines.append("a CI of 0 at K = 1 reflects only the protocol's resampling, not the generator's sampling "
                     "variance: sample K = 30 to compare generators")
    return "\n".join(lines)


def plot(paths: list[str | Path], out: str | Path, names: list[str] | None = None) -> Path:
    """Bars with CI error bars of FID, R@1, MM-Dist, CD and FSR for each result."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..core.io import atomic_save_figure
    results = [load_result(p) for p in paths]
    names = names or [str(r.get("submission", {}).get("method") or Path(p).stem) for r, p in zip(results, paths)]
    metrics = [m for m in ("fid", "r_precision_top1", "mm_dist", "cd", "fsr") if any(_mc(r, m) for r in results)]
    fig, axes = plt.subplots(1, len(metrics), figsize=(3.2 * len(metrics), 0.4 * len(names) + 1.8), squeeze=False)
    for ax, m in zip(axes[0], metrics):
        vals = [(_mc(r, m) or (float("nan"), 0.0)) for r in results]
        ax.barh(range(len(names)), [v[0] for v in vals], xerr=[v[1] for v in vals], capsize=3, color="#dd6b20")
        ax.set_yticks(range(len(names)))
        ax.set_yticklabels(names if ax is axes[0][0] else [""] * len(names), fontsize=8)
        ax.invert_yaxis()
        ax.set_title(m, fontsize=9)
        ax.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    return atomic_save_figure(fig, out) or Path(out)
