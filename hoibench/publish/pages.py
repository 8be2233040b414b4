"""``hoibench leaderboard build``: a track's entries rendered as README.md, leaderboard.csv,
a static index.html (sortable table, CIs, arrows, units, plots) and the plots as PNG.

Row order (:func:`hoibench.publish.leaderboard.order`): the ground truth first, then reproduced rows
by FID, then rows reported in papers -- greyed, with their citation, and marked "not
comparable" (another evaluator). A cell is ``mean ± 95% CI`` over the protocol's
replications; a CI of 0 at K = 1 means the number does not move under the protocol's
resampling (docs/baselines.md). Incomplete results are flagged in every format.
"""
from __future__ import annotations

import base64
import csv
import html
import io
from pathlib import Path

from ..core.io import atomic_write_bytes, atomic_write_text
from .leaderboard import SHORT, LeaderboardError, comparable, comparable_citations, load_track, order, table_columns

ARROW = {True: "↑", False: "↓", None: "≈GT"}


def _info(name: str):
    from ..metrics import METRICS
    return METRICS.get(name)


def fmt(m: dict | None) -> str:
    """``mean ± ci95`` with 3 significant decimals (``-`` when absent); tiny negative FIDs
    of the reference numerics show as 0.000 (entries keep the raw value)."""
    if not m:
        return "-"
    mean, ci = float(m["mean"]), float(m.get("ci95") or 0.0)
    if -1e-6 < mean < 0:
        mean = 0.0
    digits = 3 if abs(mean) >= 0.01 or mean == 0 else 5
    return f"{mean:.{digits}f} ± {ci:.{digits}f}"


def _flags(e: dict, entries: list[dict] = ()) -> list[str]:
    out = []
    if e["source"] == "reported":
        n = sum(comparable(x, e) for x in entries)
        out.append(f"reported, comparable with {n} scored row(s)" if n else "reported, not comparable")
    else:
        out += [f"comparable with {c}" for c in comparable_citations(e, list(entries))]
    if not e.get("complete", True):
        out.append("incomplete")
    if e.get("samples_per_prompt") and e["samples_per_prompt"] > 1:
        out.append(f"K = {e['samples_per_prompt']}")
    if e.get("missing_ids"):
        out.append(f"{len(e['missing_ids'])} missing ids")
    return out


def _columns(entries: list[dict]) -> list[str]:
    """The track's leaderboard columns (:func:`hoibench.publish.leaderboard.table_columns`)
    that some entry has."""
    present = {k for e in entries for k in e["metrics"]}
    track = entries[0]["track"] if entries else ""
    return [k for k in table_columns(track) if k in present]


def _header(name: str) -> str:
    info = _info(name)
    arrow = ARROW[info.higher_is_better] if info else ""
    return f"{SHORT.get(name, name)} {arrow}"


def _context(entries: list[dict]) -> str:
    ours = [e for e in entries if e["source"] == "reproduced"]
    ev = sorted({str(e.get("evaluator_id", ""))[:12] for e in ours})
    pr = sorted({f"{e.get('protocol')}@{e.get('protocol_version')}" for e in ours})
    tv = sorted({str(e.get("toolkit_version")) for e in ours})
    return f"protocol {', '.join(pr) or '-'}; evaluator {', '.join(ev) or '-'}; hoibench {', '.join(tv) or '-'}"


def _multibody(entries: list[dict]) -> bool:
    """Whether the rows are a multi-body track's (SyncDiff's metrics, one replication)."""
    return any("csiou" in e["metrics"] for e in entries)


def markdown(track: str, entries: list[dict], about: str = "") -> str:
    cols = _columns(entries)
    cells = ("value ± 95% half-width of the mean over clips or samples (none for the set-level SD, OD, FID)"
             if _multibody(entries) else "mean ± 95% CI over the protocol's replications")
    lines = [f"# {track} leaderboard", ""] + ([about.strip(), ""] if about.strip() else []) + [_context(entries) + f". Cells: {cells}. "
             "↑ higher is better, ↓ lower is better, ≈GT closest to the ground truth.", "",
             "| # | method | " + " | ".join(_header(c) for c in cols) + " | flags |",
             "|---:|---|" + "|".join("---:" for _ in cols) + "|---|"]
    for i, e in enumerate(entries, 1):
        name = f"**{e['method']}**" if e["role"] == "ground-truth" else e["method"]
        if e["source"] == "reported":
            name += f" ({e.get('citation')})"
        lines.append(f"| {i} | {name} | " + " | ".join(fmt(e["metrics"].get(c)) for c in cols)
                     + f" | {', '.join(_flags(e, entries))} |")
    units = "; ".join(f"{SHORT.get(c, c)}: {_info(c).units}" for c in cols if _info(c))
    lines += ["", f"Units: {units}.", "", "![metrics](metrics.png)", ""]
    if not _multibody(entries):
        lines += ["![FID vs R@1](fid_vs_r1.png)", ""]
    return "\n".join(lines)


def write_csv(entries: list[dict]) -> str:
    names = sorted({k for e in entries for k in e["metrics"]})
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["rank", "method", "role", "source", "citation", "complete", "samples_per_prompt", "evaluator_id",
                "protocol", "protocol_version", "toolkit_version"]
               + [f"{n}{s}" for n in names for s in ("", "_ci95")])
    for i, e in enumerate(entries, 1):
        row = [i, e["method"], e["role"], e["source"], e.get("citation", ""), e.get("complete", True),
               e.get("samples_per_prompt", ""), e.get("evaluator_id", ""), e.get("protocol", ""),
               e.get("protocol_version", ""), e.get("toolkit_version", "")]
        for n in names:
            m = e["metrics"].get(n)
            row += ["", ""] if m is None else [repr(float(m["mean"])), repr(float(m.get("ci95") or 0.0))]
        w.writerow(row)
    return buf.getvalue()


def _figures(track: str, entries: list[dict]) -> dict[str, bytes]:
    """PNG bytes of the metric bars (with CI error bars) and the FID vs R@1 scatter."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    shown = ("csiou", "iv_cm3", "ra", "fid") if _multibody(entries) else ("fid", "r_precision_top1", "cd", "fsr")
    cols = [c for c in shown if any(c in e["metrics"] for e in entries)]
    out = {}
    fig, axes = plt.subplots(1, max(1, len(cols)), figsize=(3.6 * max(1, len(cols)), 0.35 * len(entries) + 1.6),
                             squeeze=False)
    labels = [e["method"] for e in entries]
    colors = ["#2b6cb0" if e["role"] == "ground-truth" else ("#a0aec0" if e["source"] == "reported" else
              ("#718096" if e["role"] == "reference" else "#dd6b20")) for e in entries]
    for ax, c in zip(axes[0], cols):
        vals = [(_m["mean"] if (_m := e["metrics"].get(c)) else float("nan")) for e in entries]
        errs = [((_m.get("ci95") or 0.0) if (_m := e["metrics"].get(c)) else 0.0) for e in entries]
        y = range(len(entries))
        ax.barh(list(y), vals, xerr=errs, color=colors, capsize=3)
        ax.set_yticks(list(y))
        ax.set_yticklabels(labels if ax is axes[0][0] else [""] * len(labels), fontsize=8)
        ax.invert_yaxis()
        info = _info(c)
        ax.set_title(f"{_header(c)}  ({info.units if info else ''})", fontsize=9)
        ax.grid(axis="x", alpha=0.3)
    fig.suptitle(f"{track}: mean ± 95% CI", fontsize=10)
    fig.tight_layout()
    out["metrics.png"] = _png(fig)
    if _multibody(entries):
        return out
    fig, ax = plt.subplots(figsize=(5.5, 4.2))
    for e, col in zip(entries, colors):
        f, r = e["metrics"].get("fid"), e["metrics"].get("r_precision_top1")
        if not (f and r):
            continue
        ax.errorbar(max(f["mean"], 0.0), r["mean"], xerr=f.get("ci95") or 0, yerr=r.get("ci95") or 0, fmt="o",
                    color=col, capsize=3)
        ax.annotate(e["method"], (max(f["mean"], 0.0), r["mean"]), fontsize=7, xytext=(4, 3),
                    textcoords="offset points")
    ax.set_xlabel("FID ↓ (squared embedding distance)")
    ax.set_ylabel("R-precision top-1 ↑")
    ax.set_title(f"{track}: FID vs R@1", fontsize=10)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    out["fid_vs_r1.png"] = _png(fig)
    return out


def _png(fig) -> bytes:
    import matplotlib.pyplot as plt
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return buf.getvalue()


_SORT_JS = """
document.querySelectorAll('th[data-col]').forEach(function (th) {
  th.addEventListener('click', function () {
    var table = th.closest('table'), body = table.tBodies[0], col = +th.dataset.col;
    var asc = th.dataset.dir !== 'asc'; th.dataset.dir = asc ? 'asc' : 'desc';
    var rows = Array.from(body.rows);
    rows.sort(function (a, b) {
      var x = a.cells[col].dataset.v, y = b.cells[col].dataset.v;
      var nx = parseFloat(x), ny = parseFloat(y);
      if (isNaN(nx) || isNaN(ny)) { return asc ? String(x).localeCompare(y) : String(y).localeCompare(x); }
      return asc ? nx - ny : ny - nx;
    });
    rows.forEach(function (r) { body.appendChild(r); });
  });
});
"""


def page(track: str, entries: list[dict], figures: dict[str, bytes]) -> str:
    cols = _columns(entries)
    e_ = html.escape
    head = "".join(f'<th data-col="{i + 2}" title="{e_((_info(c).summary + " (" + _info(c).units + ")") if _info(c) else c)}">'
                   f"{e_(_header(c))}</th>" for i, c in enumerate(cols))
    rows = []
    for i, e in enumerate(entries, 1):
        cls = "gt" if e["role"] == "ground-truth" else ("reported" if e["source"] == "reported" else
                                                        ("reference" if e["role"] == "reference" else ""))
        name = e_(e["method"])
        if e["source"] == "reported":
            badge = "comparable" if any(comparable(x, e) for x in entries) else "not comparable"
            name += f' <span class="cite">{e_(str(e.get("citation")))}</span> <span class="badge">{badge}</span>'
        if not e.get("complete", True):
            name += ' <span class="badge warn">incomplete</span>'
        cells = "".join(
            f'<td data-v="{float(m["mean"]) if m else ""}">{e_(fmt(m))}</td>'
            for m in (e["metrics"].get(c) for c in cols))
        rows.append(f'<tr class="{cls}"><td data-v="{i}">{i}</td><td data-v="{e_(e["method"])}">{name}</td>{cells}'
                    f'<td data-v="{e_(", ".join(_flags(e, entries)))}">{e_(", ".join(_flags(e, entries)))}</td></tr>')
    imgs = "".join(f'<figure><img alt="{e_(n)}" src="data:image/png;base64,{base64.b64encode(b).decode()}">'
                   f"</figure>" for n, b in figures.items())
    units = "; ".join(f"{e_(SHORT.get(c, c))}: {e_(_info(c).units)}" for c in cols if _info(c))
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>{e_(track)} leaderboard - hoibench</title>
<style>
body {{ font-family: system-ui, sans-serif; margin: 2em; color: #1a202c; }}
table {{ border-collapse: collapse; font-size: 13px; }}
.wrap {{ overflow-x: auto; }}
th, td {{ padding: 3px 7px; border-bottom: 1px solid #e2e8f0; text-align: right; white-space: nowrap; }}
th {{ cursor: pointer; background: #edf2f7; }}
td:nth-child(2), th:nth-child(2) {{ text-align: left; }}
tr.gt {{ font-weight: 600; background: #ebf8ff; }}
tr.reference {{ color: #4a5568; font-style: italic; }}
tr.reported {{ color: #a0aec0; }}
.badge {{ font-size: 11px; border: 1px solid #a0aec0; border-radius: 3px; padding: 0 4px; }}
.warn {{ border-color: #dd6b20; color: #dd6b20; }}
.cite {{ font-size: 12px; }}
figure {{ display: inline-block; margin: 1em 1em 0 0; }}
img {{ max-width: 100%; }}
</style></head><body>
<h1>{e_(track)} leaderboard</h1>
<p>{e_(_context(entries))}. Cells: mean ± 95% CI over the protocol's replications. ↑ higher is better,
↓ lower is better, ≈GT closest to the ground truth. Click a column to sort. Units: {units}.</p>
<div class="wrap"><table><thead><tr><th data-col="0">#</th><th data-col="1">method</th>{head}<th data-col="{len(cols) + 2}">flags</th></tr></thead>
<tbody>
{chr(10).join(rows)}
</tbody></table></div>
{imgs}
<script>{_SORT_JS}</script>
</body></html>
"""


def build(track_dir: str | Path) -> dict[str, Path]:
    """Render ``track_dir``'s entries into README.md (``about.md``, when present, above the
    table), leaderboard.csv, index.html and the PNG plots (atomically). Returns the paths."""
    track_dir = Path(track_dir)
    entries = order(load_track(track_dir))
    if not entries:
        raise LeaderboardError(f"{track_dir}/entries: no entries to render")
    track = track_dir.name
    figures = _figures(track, entries)
    about_path = track_dir / "about.md"           # the track's own words, kept above the table
    about = about_path.read_text(encoding="utf-8") if about_path.exists() else ""
    out = {"README.md": atomic_write_text(track_dir / "README.md", markdown(track, entries, about) + "\n"),
           "leaderboard.csv": atomic_write_text(track_dir / "leaderboard.csv", write_csv(entries)),
           "index.html": atomic_write_text(track_dir / "index.html", page(track, entries, figures))}
    for name, data in figures.items():
        out[name] = atomic_write_bytes(track_dir / name, data)
    return out


__all__ = ["build", "markdown", "write_csv", "page", "fmt"]
