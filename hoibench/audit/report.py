"""The audit's files, from its document (:mod:`hoibench.audit.document`):

- ``audit.json`` (strict JSON, sorted keys);
- ``heatmap.png``: metrics x families, each cell coloured by Spearman's rho toward worse
  (+1: the metric worsens monotonically with the severity; -1: it improves), annotated with
  the detectable severity ("-": no severity detected), hatched where the metric is blind;
- ``cards/<metric>.md``: what one metric responds to, what it is blind to and how many clips
  it needs (from the paired tests' effect sizes);
- ``README.md``: the provenance, the heatmap and an index of the cards.
"""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from ..core.io import atomic_write_bytes, atomic_write_json, atomic_write_text
from ..metrics.catalog import METRICS
from .analysis import BLIND_RHO
from .families import layout_of, registry

HEATMAP = "heatmap.png"
#: what a direction asks of a metric, in words
_DIRECTION_WORDS = {"higher": "higher is better", "lower": "lower is better",
                    "gt": "best when closest to the ground truth's value"}


def _g(x) -> str:
    return "-" if x is None else f"{x:g}"


def _families(doc: dict) -> list[str]:
    return [f for f in registry(layout_of(doc)) if f in doc["corruptions"]]


def heatmap_png(doc: dict) -> bytes:
    """The heatmap (module docstring) as PNG bytes (matplotlib, Agg; no timestamp in the file)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle
    metrics, families = doc["metrics"], _families(doc)
    rho = np.array([[np.nan if doc["summary"][m][f]["spearman_worse"] is None else doc["summary"][m][f]["spearman_worse"]
                     for f in families] for m in metrics], dtype=float)
    fig, ax = plt.subplots(figsize=(max(7.0, 2.6 + 0.62 * len(families)), 1.9 + 0.3 * len(metrics)), dpi=110)
    cmap = matplotlib.colormaps["RdBu_r"].with_extremes(bad="#d9d9d9")
    im = ax.imshow(np.ma.masked_invalid(rho), cmap=cmap, vmin=-1, vmax=1, aspect="auto")
    for i, m in enumerate(metrics):
        for j, f in enumerate(families):
            row = doc["summary"][m][f]
            if row["blind"]:
                ax.add_patch(Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, hatch="///", edgecolor="#888888",
                                       linewidth=0))
            v = rho[i, j]
            ax.text(j, i, _g(row["detectable_severity"]), ha="center", va="center", fontsize=7.5,
                    color="white" if np.isfinite(v) and abs(v) > 0.6 else "black",
                    fontweight="normal" if row["blind"] else "bold")
    ax.set_xticks(range(len(families)))
    specs = registry(layout_of(doc))
    ax.set_xticklabels([f"{f}\n({specs[f].unit.split(' (')[0]})" for f in families], rotation=60, ha="right",
                       fontsize=7.5, rotation_mode="anchor")
    ax.set_yticks(range(len(metrics)))
    ax.set_yticklabels([f"{METRICS[m].title} {METRICS[m].arrow}" for m in metrics], fontsize=8)
    bar = fig.colorbar(im, ax=ax, fraction=0.03, pad=0.02)
    bar.set_label("Spearman rho toward worse", fontsize=8)
    p = doc["provenance"]
    ax.set_title(f"Metric audit: {p['dataset']} ({p['test_clips']} test clips), evaluator {str(p['evaluator_id'])[:12]}, "
                 f"{p['protocol']}@{p['protocol_version']}\ncell: smallest severity a paired clip bootstrap detects "
                 f"(p_holm < {p['alpha']:g}; - none); hatched: blind (rho toward worse < {BLIND_RHO:g})", fontsize=8.5)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", metadata={"Software": None})
    plt.close(fig)
    return buf.getvalue()


def card(doc: dict, metric: str) -> str:
    """The Markdown card of one metric (module docstring)."""
    info, p = METRICS[metric], doc["provenance"]
    rows = doc["summary"][metric]
    families = _families(doc)
    seen = [f for f in families if not rows[f]["blind"]]
    blind = [f for f in families if rows[f]["blind"]]
    lines = [f"# {info.title} ({metric})", "",
             f"{info.summary[:1].upper() + info.summary[1:]}. Unit: {info.unit}. Direction: "
             f"{_DIRECTION_WORDS[info.direction]} ({info.arrow}).", "",
             f"Audited on {p['test_clips']} test clips of the `{p['dataset']}` store, evaluator "
             f"`{str(p['evaluator_id'])[:12]}`, protocol {p['protocol']}@{p['protocol_version']}, seed {p['seed']}, "
             f"{p['resamples']} paired bootstrap resamples (hoibench {p['toolkit_version']}). Values per severity are "
             f"in `../audit.json`; docs/audit.md says how to read them.", ""]
    lines += [f"## Responds to ({len(seen)} of {len(families)} families)", ""]
    if seen:
        lines += ["| family | corrupts | rho toward worse | detected from | effect at the lowest severity | "
                  "clips to detect the lowest severity |", "|---|---|---:|---:|---:|---:|"]
        for f in sorted(seen, key=lambda f: -(rows[f]["spearman_worse"] or 0)):
            lines.append(_family_row(doc, metric, f))
    else:
        lines.append("No family: every corruption leaves this metric flat or moves it the wrong way.")
    lines += ["", f"## Blind to ({len(blind)} of {len(families)} families)", ""]
    if blind:
        lines += ["| family | corrupts | rho toward worse | why | detected from |", "|---|---|---:|---|---:|"]
        for f in blind:
            r = rows[f]
            why = ("does not change" if r["spearman_worse"] is None else
                   f"no clear trend (|rho| < {BLIND_RHO:g})" if abs(r["spearman_worse"]) < BLIND_RHO else
                   "moves the wrong way (better with the corruption)")
            spec = registry(layout_of(doc))[f]
            lines.append(f"| {f} | {spec.corrupts} | {_rho(r['spearman_worse'])} | {why} | "
                         f"{_sev(r['detectable_severity'], spec.unit)} |")
    else:
        lines.append("No family.")
    lines += ["", "## How many clips it needs", ""] + _clips_text(doc, metric, seen)
    return "\n".join(lines) + "\n"


def _rho(x) -> str:
    return "undefined" if x is None else f"{x:+.2f}"


def _sev(s, unit: str) -> str:
    return "-" if s is None else f"{s:g} {unit.split(' (')[0]}"


def _family_row(doc: dict, metric: str, family: str) -> str:
    r, spec = doc["summary"][metric][family], registry(layout_of(doc))[family]
    effect = "-" if r["effect_sd"] is None else f"{r['effect_sd']:+.2f} sd at {_sev(r['effect_severity'], spec.unit)}"
    need = r["clips_needed"][spec.severities.index(r["effect_severity"])] if r["effect_severity"] is not None else None
    return (f"| {family} | {spec.corrupts} | {_rho(r['spearman_worse'])} | {_sev(r['detectable_severity'], spec.unit)} | "
            f"{effect} | {'-' if need is None else f'{need:,}'} |")


def _clips_text(doc: dict, metric: str, seen: list[str]) -> list[str]:
    p, rows = doc["provenance"], doc["summary"][metric]
    n = p["test_clips"]
    detected = [f for f in seen if rows[f]["detectable_severity"] is not None]
    out = [f"With the {n} test clips audited, a paired test (p_holm < {p['alpha']:g}) sees {len(detected)} of "
           f"{len(seen)} families it responds to."]
    needs = []
    specs = registry(layout_of(doc))
    for f in seen:
        spec = specs[f]
        s = rows[f]["effect_severity"]
        need = rows[f]["clips_needed"][spec.severities.index(s)] if s is not None else None
        if need is not None:
            needs.append((need, f, s))
    if needs:
        needs.sort()
        listed = ", ".join(f"{f} at {_sev(s, specs[f].unit)}: {need:,}" for need, f, s in needs)
        out += ["", f"Clips a paired test needs to see the lowest severity of each family with 80% power at a "
                    f"two-sided 5% level (from the bootstrap sd of the difference on {n} clips, scaled as "
                    f"1/sqrt(n)): {listed}."]
    return out


def readme(doc: dict) -> str:
    """``README.md``: provenance, the heatmap and the cards' index."""
    p, families = doc["provenance"], _families(doc)
    variant = p.get("evaluator_variant") or ("the track's recognizer" if layout_of(doc) == "multibody" else None)
    lines = ["# Metric audit", "",
             f"What each metric of protocol {p['protocol']}@{p['protocol_version']} sees when the ground-truth test "
             f"clips of the `{p['dataset']}` store (`{p['store']}`, config {str(p['store_config_sha256'])[:12]}, "
             f"{p['test_clips']} test clips) are corrupted in controlled ways, scored with evaluator "
             f"`{str(p['evaluator_id'])[:12]}` ({variant}); seed {p['seed']}, {p['resamples']} paired "
             f"bootstrap resamples, hoibench {p['toolkit_version']}. Made by `hoibench audit`; docs/audit.md "
             f"explains the families and the statistics.", "",
             f"![heatmap]({HEATMAP})", "",
             "Cell: the smallest severity at which a paired clip bootstrap against severity 0 finds a difference "
             f"(Holm-adjusted p < {p['alpha']:g}); colour: Spearman's rho of how much worse the metric gets "
             "against the severity; hatched: blind (rho toward worse below "
             f"{BLIND_RHO:g}, or undefined).", "",
             "| metric | unit | direction | responds to | blind to | card |", "|---|---|---|---:|---:|---|"]
    for m in doc["metrics"]:
        rows = doc["summary"][m]
        seen = sum(1 for f in families if not rows[f]["blind"])
        lines.append(f"| {METRICS[m].title} | {METRICS[m].unit} | {METRICS[m].arrow} | {seen} | "
                     f"{len(families) - seen} | [cards/{m}.md](cards/{m}.md) |")
    lines += ["", "Families (severities in their unit; severity 0 is the ground truth):", ""]
    for f in families:
        c = doc["corruptions"][f]
        lines.append(f"- `{f}` ({c['corrupts']}): {c['description']}; {', '.join(f'{s:g}' for s in c['severities'])} "
                     f"{c['unit']}")
    return "\n".join(lines) + "\n"


def write_report(doc: dict, out: str | Path) -> list[Path]:
    """Write ``audit.json``, the heatmap, the cards and ``README.md`` into ``out``."""
    out = Path(out)
    paths = [atomic_write_json(out / "audit.json", doc), atomic_write_bytes(out / HEATMAP, heatmap_png(doc))]
    for m in doc["metrics"]:
        atomic_write_text(out / "cards" / f"{m}.md", card(doc, m))
    paths.append(out / "cards")
    paths.append(atomic_write_text(out / "README.md", readme(doc)))
    return paths


__all__ = ["HEATMAP", "heatmap_png", "card", "readme", "write_report"]
