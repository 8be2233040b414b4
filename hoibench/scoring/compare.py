"""``hoibench compare A.json B.json ...``: results of ``hoibench evaluate`` side by side.

For every metric the table shows ``mean ± 95% CI`` per result and, against the first result,
whether the difference is outside the confidence intervals: ``|m_A - m_B| > ci_A + ci_B``
(the two intervals do not overlap; a conservative test -- overlapping intervals do not prove
the difference is noise). Results scored with another evaluator, protocol or protocol version
than the first are compared anyway but flagged, and no difference with them is starred:
their numbers are not on one scale. Leaderboard entries (``leaderboards/<track>/entries/*.json``)
are read too: their method and samples per prompt are shown.
``--plot`` draws the main metrics as bars with CI error bars.
"""
from __future__ import annotations

from pathlib import Path

from ..metrics.catalog import GROUPS, METRICS, shown_value
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


def _method(r: dict, path: str | Path) -> str:
    """A row's name: the submission's method (a result), the entry's method (a leaderboard
    entry), else the file's stem."""
    from ..core.errors import printable
    return printable(str((r.get("submission") or {}).get("method") or r.get("method") or Path(path).stem))


def _k(r: dict):
    """Samples per prompt of a result (``counts``) or of a leaderboard entry (top level)."""
    return (r.get("counts") or {}).get("samples_per_prompt", r.get("samples_per_prompt"))


def _scale(r: dict) -> tuple:
    return r.get("evaluator_id"), r.get("protocol"), r.get("protocol_version")


def _cell(name: str, v: tuple[float, float] | None, ref: tuple[float, float] | None, starred: bool,
          width: int) -> str:
    if v is None:
        return f"{'-':>{width}s}"
    star = "*" if starred and ref is not None and outside(v, ref) else " "
    return f"{f'{shown_value(name, v[0]):.4g} ± {v[1]:.2g}{star}':>{width}s}"


def compare(paths: list[str | Path], names: list[str] | None = None) -> str:
    """The side-by-side table (text) of the results (or leaderboard entries) at ``paths``.
    A difference is starred only between results on one scale (same evaluator, protocol
    and version as the first); a tiny negative FID shows as 0, as ``evaluate`` prints it."""
    if len(paths) < 2:
        raise ValueError("compare: give at least two result files")
    results = [load_result(p) for p in paths]
    names = names or [_method(r, p) for r, p in zip(results, paths)]
    base = results[0]
    same = [_scale(r) == _scale(base) for r in results]
    lines = []
    for n, r, p, ok in zip(names, results, paths, same):
        flag = "" if ok else "  [other evaluator/protocol: not on one scale, no *]"
        lines.append(f"{n}: {p} ({r.get('protocol')}@{r.get('protocol_version')}, evaluator "
                     f"{str(r.get('evaluator_id'))[:12]}, K={_k(r)}, "
                     f"{'complete' if r.get('complete') else 'INCOMPLETE'}){flag}")
    width = min(max(18, *(len(n) for n in names)), 26) + 2
    lines += ["", f"{'metric':26s}" + "".join(f"{n[:width - 2]:>{width}s}" for n in names)]
    for group in GROUPS:
        rows = [m for m, i in METRICS.items() if i.group == group and i.kind != "count"
                and any(_mc(r, m) for r in results)]
        if rows:
            lines.append(f"{group}:")
        for m in rows:
            ref = _mc(base, m)
            lines.append(f"  {m:24s}" + "".join(_cell(m, _mc(r, m), ref, i > 0 and same[i], width)
                                                for i, r in enumerate(results)))
    lines += ["", f"* outside the 95% CIs of {names[0]} (the intervals do not overlap; only between results on "
                  f"one scale)"]
    if any(_k(r) == 1 for r in results):
        lines.append("a CI of 0 at K = 1 reflects only the protocol's resampling, not the generator's sampling "
                     "variance: sample K = 30 to compare generators")
    return "\n".join(lines)


def plot(paths: list[str | Path], out: str | Path, names: list[str] | None = None) -> Path:
    """Bars with CI error bars of the first result's track's headline metrics (its registry
    entry's ``headline``; FID, R@1, CD and FSR for a single-body track) for each result."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..core.io import atomic_save_figure
    results = [load_result(p) for p in paths]
    names = names or [_method(r, p) for r, p in zip(results, paths)]
    from ..tracks.registry import headline_of
    metrics = [m for m in headline_of(str(results[0].get("track"))) if any(_mc(r, m) for r in results)]
    fig, axes = plt.subplots(1, len(metrics), figsize=(3.2 * len(metrics), 0.4 * len(names) + 1.8), squeeze=False)
    for ax, m in zip(axes[0], metrics):
        vals = [(_mc(r, m) or (float("nan"), 0.0)) for r in results]
        ax.barh(range(len(names)), [v[0] for v in vals], xerr=[v[1] for v in vals], capsize=3, color="#dd6b20")
        ax.set_yticks(range(len(names)))
        ax.set_yticklabels([n.replace("$", r"\$") for n in names] if ax is axes[0][0] else [""] * len(names),
                           fontsize=8)
        ax.invert_yaxis()
        ax.set_title(m, fontsize=9)
        ax.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    return atomic_save_figure(fig, out) or Path(out)
