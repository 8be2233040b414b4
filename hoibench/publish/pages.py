"""``hoibench leaderboard build``: a track's entries rendered as README.md, leaderboard.csv,
a static index.html (sortable table, CIs, arrows, units, legend, plots) and the plots as PNG.

Rows come in bands (:data:`hoibench.publish.leaderboard.BANDS`, :func:`~hoibench.publish.
leaderboard.order`): the ground truth; methods and baselines, ranked by FID and the only rows
with a rank number; reference rows (unnumbered, italic); rows reported in papers (greyed,
with their citation, marked "not comparable": another evaluator). A cell is ``mean ± 95%
CI`` over the protocol's replications; a CI of exactly 0 at K = 1 (the number does not move
under the protocol's resampling, docs/baselines.md) shows as "n/a (K = 1)". Incomplete
results are flagged in every format.
"""
from __future__ import annotations

import base64
import csv
import html
import io
import re
from pathlib import Path

from ..core.io import atomic_write_bytes, atomic_write_text, read_text_file
from ..metrics.catalog import ARROWS, METRICS, shown_value
from .significance import SIGNIFICANCE_NOTE, rank_text, track_significance, vs_above_detail, vs_above_text
from .leaderboard import (BANDS, LeaderboardError, band, comparable, comparable_citations, load_track, order,
                          ranks, shares_evaluator_text_encoder, table_columns, title, training_of)

#: a track's about.md is read up to this size
MAX_ABOUT_BYTES = 1024 ** 2

#: bar and point colour of each band (:data:`~hoibench.publish.leaderboard.BANDS`)
COLORS = {"ground-truth": "#2b6cb0", "ranked": "#dd6b20", "reference": "#718096", "reported": "#a0aec0"}
#: what a CI cell shows at K = 1 when the metric did not move over the replications
K1_CI = "n/a (K = 1)"
#: marks a half-width over the test clips (a clip bootstrap) in place of one over replications
CLIPS_MARK = "(clips)"
CLIPS_NOTE = ("(clips): half the width of the 95% clip-bootstrap interval (1,000 seeded resamples of the scored "
              "test clips, sample 0), shown at K = 1 where the replications do not move the number")
K1_NOTE = ("n/a (K = 1): one sample per prompt, so every replication scores the same samples and a metric "
           "of the samples alone (FID, CD, PS, FSR, ...) has no spread to report; sample K > 1 times "
           "(--samples) for a CI that includes sampling variance")
BAND_LEGEND = {"ground-truth": "bold on blue: hoibench's ground truth (the test clips), the ceiling of every metric",
               "ranked": "numbered: methods and baselines scored by hoibench, ranked by FID (lower is better)",
               "reference": "italic grey, unnumbered: reference rows (noise, static pose, mismatched texts, "
                            "untrained models) that calibrate each metric's scale",
               "reported": "light grey, unnumbered: rows copied from papers (another evaluator: not ranked "
                           "against hoibench's rows)"}


def _info(name: str):
    return METRICS.get(name)


def _parts(m: dict | None, k=None, name: str = "") -> tuple[str, str]:
    """(mean, CI) texts of a cell: 3 decimals (5 under 0.01); tiny negative FIDs of the
    reference numerics show as 0.000 (entries keep the raw value); a CI of exactly 0 at
    K = 1 shows as :data:`K1_CI` (an interval over replications only: one over clips or
    samples of exactly 0 is a zero spread)."""
    if not m:
        return "-", ""
    mean, ci = float(m["mean"]), float(m.get("ci95") or 0.0)
    mean = shown_value(name, mean)
    digits = 3 if abs(mean) >= 0.01 or mean == 0 else 5
    if "ci95" in m and m["ci95"] is None:          # a hosted row: the engine keeps means only
        return f"{mean:.{digits}f}", ""
    if k == 1 and ci == 0 and m.get("interval", "replications") == "replications":
        clips = m.get("clips") if isinstance(m.get("clips"), dict) else None
        if clips and len(clips.get("ci95") or []) == 2:          # an interval over the test clips instead
            half = (float(clips["ci95"][1]) - float(clips["ci95"][0])) / 2
            return f"{mean:.{digits}f}", f"{half:.{digits}f} {CLIPS_MARK}"
        return f"{mean:.{digits}f}", K1_CI
    small = 0 < ci < 0.5 * 10 ** -digits            # a real spread that the digits would round to 0
    return f"{mean:.{digits}f}", (f"{ci:.1e}" if small else f"{ci:.{digits}f}")


def fmt(m: dict | None, k=None, name: str = "") -> str:
    """``mean ± ci95`` (``-`` when absent); ``k``: the row's samples per prompt."""
    mean, ci = _parts(m, k, name)
    return mean if not ci else f"{mean} ± {ci}"


def budget(e: dict) -> str:
    """The row's training budget in words (``1,500 steps, 1.78 M params, 10.2 min, CPU ...``;
    a time that does not reach back to step 0 says where it starts, ``33.5 min since step
    1,308``), ``not stated`` for a baseline row without one, "" for other rows."""
    t = training_of(e)
    if not t:
        return "not stated" if e.get("role") == "baseline" and e.get("source") != "reported" else ""
    parts = []
    if isinstance(t.get("steps"), int):
        parts.append(f"{t['steps']:,} steps")
    if isinstance(t.get("parameters"), int):
        parts.append(f"{t['parameters'] / 1e6:.2f} M params")
    if isinstance(t.get("wall_seconds"), (int, float)):
        since = t.get("wall_seconds_from", t.get("resumed_from"))   # the first step the time covers
        parts.append(f"{t['wall_seconds'] / 60:.1f} min" + (f" since step {since:,}" if isinstance(since, int)
                                                             and since > 0 else ""))
    if t.get("hardware"):
        parts.append(short_hardware(str(t["hardware"])))
    return ("~" if t.get("approximate") else "") + ", ".join(parts)


def short_hardware(text: str) -> str:
    """A hardware string without trademark marks and filler words, for a table cell
    (``CPU Intel(R) Xeon(R) Processor @ 2.80GHz, 1 thread(s)`` -> ``CPU Intel Xeon 2.80GHz, 1 thread``)."""
    import re
    text = re.sub(r"\((?:R|TM|tm)\)| Processor", "", text)
    text = re.sub(r"(?: CPU)? @", " ", text)
    text = re.sub(r"\b1 thread\(s\)", "1 thread", text).replace("thread(s)", "threads")
    return re.sub(r"\s+", " ", text).strip()


def _flags(e: dict, entries: list[dict] = ()) -> list[str]:
    out = []
    if shares_evaluator_text_encoder(e):
        out.append("conditioned on the evaluator's text encoder")
    if e.get("role") == "baseline" and e.get("source") != "reported" and not training_of(e):
        out.append("training budget not stated")
    if e["source"] == "reported":
        n = sum(comparable(x, e) for x in entries)
        out.append(f"reported, comparable with {n} scored row(s)" if n else "reported, not comparable")
    else:
        out += [f"comparable with {c}" for c in comparable_citations(e, list(entries))]
    if not e.get("complete", True):
        out.append("incomplete")
    if (e.get("flags") or {}).get("human_only") is True:
        out.append("human-only (object metrics n/a)")
    if isinstance(e.get("hosted"), dict):
        out.append(f"hosted on {e['hosted'].get('engine', 'an engine')} (means only)")
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
    arrow = ARROWS[info.direction] if info else ""
    return f"{title(name)} {arrow}"


def _context(entries: list[dict]) -> str:
    ours = [e for e in entries if e["source"] == "reproduced"]
    ev = sorted({str(e.get("evaluator_id", ""))[:12] for e in ours})
    pr = sorted({f"{e.get('protocol')}@{e.get('protocol_version')}" for e in ours})
    tv = sorted({str(e.get("toolkit_version")) for e in ours})
    return f"protocol {', '.join(pr) or '-'}; evaluator {', '.join(ev) or '-'}; hoibench {', '.join(tv) or '-'}"


def _bands(entries: list[dict]) -> list[tuple[str, str, list[tuple[int | None, dict]]]]:
    """(band, heading, [(rank, entry), ...]) for each band that has rows, in display order."""
    rk = ranks(entries)
    return [(b, head, [(r, e) for r, e in zip(rk, entries) if band(e) == b]) for b, head in BANDS
            if any(band(e) == b for e in entries)]


def _replication_k(e: dict):
    """The K that decides whether a zero CI over replications means "n/a (K = 1)": the row's
    samples per prompt (:func:`_parts` applies it to intervals over replications only)."""
    return e.get("samples_per_prompt")


def _any_clips(entries: list[dict], cols: list[str]) -> bool:
    return any(_parts(e["metrics"].get(c), _replication_k(e), c)[1].endswith(CLIPS_MARK)
               for e in entries for c in cols)


def _any_k1(entries: list[dict], cols: list[str]) -> bool:
    return any(_replication_k(e) == 1 and _parts(e["metrics"].get(c), 1, c)[1] == K1_CI
               for e in entries for c in cols)


_MD_SPECIAL = re.compile(r"([\\`\[\]|])")


_UNSAFE_SCHEME = re.compile(r"(?i)\b(javascript|vbscript|data|file):(?=\S)")
_MD_LINK = re.compile(r"(\]\(\s*)([^)\s]*)")


def _defanged(text: str, colon: str) -> str:
    """``text`` with every link whose target is not http(s) or relative pointed at ``#`` and
    the colon of a script-like scheme (``javascript:``, ``vbscript:``, ``data:``, ``file:``)
    written as ``colon``, so that no renderer turns it into a link."""
    text = _MD_LINK.sub(lambda m: m.group(1) + (m.group(2) if safe_link(m.group(2)) else "#"), text)
    return _UNSAFE_SCHEME.sub(lambda m: m.group(1) + colon, text)


def md_text(text) -> str:
    """Entry text (method, citation, flags) for a README table cell: one line, HTML escaped
    (no tag, image or script survives), the Markdown punctuation that makes links, images,
    code or cells (backslash, backtick, brackets, pipe) backslash-escaped, and no link but
    http(s) or relative ones (:func:`_defanged`), as on the HTML page."""
    one = _defanged(" ".join(str(text).split()), "&#58;")
    return _MD_SPECIAL.sub(r"\\\1", html.escape(one, quote=False)).replace("&amp;#58;", "&#58;")


def csv_text(text) -> str:
    """Entry text for a CSV cell: a cell a spreadsheet would read as a formula (leading ``=``,
    ``+``, ``-``, ``@``, tab or carriage return) gets a leading apostrophe; links other than
    http(s) or relative ones are defanged (:func:`_defanged`)."""
    text = _defanged(str(text), " :")
    return "'" + text if text[:1] in ("=", "+", "-", "@", "\t", "\r") else text


def plot_text(text) -> str:
    """A method name drawn by matplotlib as plain text (``$`` would start mathtext)."""
    return str(text).replace("$", r"\$")


def safe_link(target: str) -> bool:
    """Whether a link target may stay: an http(s) URL or a relative path (no ``javascript:``,
    ``data:``, ``file:`` or any other scheme)."""
    target = target.strip()
    return bool(re.match(r"(?i)^https?://", target)) or not re.match(r"^[A-Za-z][A-Za-z0-9+.-]*:", target)


def md_about(text: str) -> str:
    """A track's ``about.md`` for README.md: its Markdown kept, raw HTML escaped, and every
    link or image whose target is not http(s) or relative pointed at ``#``."""
    text = text.replace("&", "&amp;").replace("<", "&lt;")      # no tag; '>' stays for block quotes
    return re.sub(r"\]\(\s*([^)\s]*)", lambda m: "](" + (m.group(1) if safe_link(m.group(1)) else "#"), text)


_CODE = re.compile(r"`([^`]+)`")
_BOLD = re.compile(r"\*\*(.+?)\*\*")
_LINK = re.compile(r"\[([^\]]+)\]\(\s*([^)\s]*)\s*\)")


def _inline_html(text: str) -> str:
    """One line of ``about.md`` as HTML: escaped, then inline code, bold and safe links."""
    t = html.escape(text, quote=True)
    t = _CODE.sub(r"<code>\1</code>", t)
    t = _BOLD.sub(r"<b>\1</b>", t)
    return _LINK.sub(lambda m: f'<a href="{m.group(2)}">{m.group(1)}</a>' if safe_link(html.unescape(m.group(2)))
                     else m.group(1), t)


_RULE_ROW = re.compile(r"^\|(\s*:?-+:?\s*\|)+$")


def _table_html(lines: list[str]) -> str | None:
    """A Markdown pipe table (header, ``|---|`` rule, rows) as an HTML table; None when the
    block is not one. Cells right-aligned where the rule says ``---:``."""
    rows = [line.strip() for line in lines]
    if len(rows) < 2 or not all(r.startswith("|") and r.endswith("|") for r in rows) or not _RULE_ROW.match(rows[1]):
        return None
    right = [c.strip().endswith(":") for c in rows[1].strip("|").split("|")]

    def cells(row: str, tag: str) -> str:
        parts = [c.strip() for c in row.strip("|").split("|")]
        num = ' class="num"'
        return "".join(f"<{tag}{num if i < len(right) and right[i] else ''}>{_inline_html(c)}</{tag}>"
                       for i, c in enumerate(parts))
    body = "".join(f"<tr>{cells(r, 'td')}</tr>" for r in rows[2:])
    return f'<table class="about-table"><tr>{cells(rows[0], "th")}</tr>{body}</table>'


def about_html(text: str) -> str:
    """A track's ``about.md`` for index.html: paragraphs, indented code blocks, pipe tables,
    inline code, bold and links (http(s) or relative only; others keep their text). Every
    piece of text is HTML-escaped first, so no tag of the file survives."""
    blocks = [b for b in re.split(r"\n\s*\n", text.strip()) if b.strip()]
    out = []
    for b in blocks:
        lines = b.split("\n")
        if all(line.startswith("    ") or not line.strip() for line in lines):
            out.append("<pre>" + html.escape("\n".join(line[4:] for line in lines)) + "</pre>")
            continue
        table = _table_html(lines)
        out.append(table if table is not None else f"<p>{_inline_html(' '.join(line.strip() for line in lines))}</p>")
    return '<div class="about">' + "\n".join(out) + "</div>" if out else ""


def _over_replications(entries: list[dict]) -> bool:
    """Whether the rows' intervals are over the protocol's replications (else over clips or
    samples: each metric block says, ``interval``)."""
    over = {m.get("interval") for e in entries for m in e["metrics"].values() if isinstance(m, dict)}
    return "replications" in over or not (over - {"none", None})


def _cells_text(entries: list[dict], form: str = "md") -> str:
    """What a cell's ± means: over replications, or over clips or samples (naming the
    track's columns that have no interval)."""
    if not _over_replications(entries):
        track = entries[0]["track"] if entries else ""
        none = ", ".join(title(c) for c in table_columns(track) if c in METRICS and METRICS[c].set_level)
        tail = f" (none for the set-level {none})" if none else ""
        return (f"value ± 95% half-width of the mean over clips or samples{tail}"
                if form == "md" else f"value, and below it the 95% half-width (±) of the mean over clips or "
                f"samples{tail}")
    return ("mean ± 95% CI over the protocol's replications" if form == "md" else
            "mean, and below it the 95% CI (±) over the protocol's replications")


def markdown(track: str, entries: list[dict], about: str = "") -> str:
    """README.md: one table, its rows in bands (:func:`_bands`); only methods and baselines
    carry a rank."""
    cols = _columns(entries)
    cells = _cells_text(entries)
    sig = _has_significance(entries)
    sig_head, sig_rule = (" | rank 95% | vs row above", "|---:|---") if sig else ("", "")
    lines = [f"# {track} leaderboard", ""] + ([md_about(about.strip()), ""] if about.strip() else []) + [
        _context(entries) + f". Cells: {cells}. ↑ higher is better, "
        "↓ lower is better, ≈GT closest to the ground truth.", "",
        "Rows: " + "; ".join(f"{BAND_LEGEND[b]}" for b, _, _ in _bands(entries)) + ".", "",
        "| # | method | flags" + sig_head + " | " + " | ".join(_header(c) for c in cols) + " | training |",
        "|---:|---|---" + sig_rule + "|" + "|".join("---:" for _ in cols) + "|---|"]
    for b, head, rows in _bands(entries):
        lines.append(f"| | ***{head}*** | |" + " |" * (len(cols) + 1 + 2 * sig))
        for r, e in rows:
            m = md_text(e["method"])
            name = f"**{m}**" if b == "ground-truth" else (f"*{m}*" if b == "reference" else m)
            if e["source"] == "reported":
                name += f" ({md_text(e.get('citation'))})"
            k = _replication_k(e)
            lines.append(f"| {r or ''} | {name} | {md_text(', '.join(_flags(e, entries)))}"
                         + (f" | {rank_text(e.get('_sig'))} | {md_text(vs_above_text(e.get('_sig')))}" if sig else "")
                         + " | " + " | ".join(fmt(e["metrics"].get(c), k, c) for c in cols)
                         + f" | {md_text(budget(e))} |")
    units = "; ".join(f"{title(c)}: {_info(c).units}" for c in cols if _info(c))
    lines += ["", f"Units: {units}."] + (["", f"CI {K1_NOTE}."] if _any_k1(entries, cols) else []) \
        + (["", f"CI {CLIPS_NOTE}."] if _any_clips(entries, cols) else []) \
        + (["", f"{SIGNIFICANCE_NOTE}."] if sig else [])
    lines += ["", "Bar and point colours: " + ", ".join(f"{_COLOR_NAMES[b]} {b.replace('-', ' ')}"
                                                       for b, _, _ in _bands(entries)) + ".", "",
              "![metrics](metrics.png)", ""] + (["![FID vs R@1](fid_vs_r1.png)", ""] if _has_fid_r1(entries) else [])
    return "\n".join(lines)


def _has_significance(entries: list[dict]) -> bool:
    """Whether some row carries a rank interval or a paired test (:func:`with_significance`)."""
    return any(e.get("_sig") for e in entries)


def with_significance(track_dir: str | Path, entries: list[dict]) -> list[dict]:
    """``entries`` (display order) with ``_sig`` set on the ranked rows that kept per-clip
    data (:func:`hoibench.publish.significance.track_significance` on the track's headline
    metrics); unchanged when none did."""
    if not any(isinstance(e.get("per_clip_data"), dict) for e in entries):
        return entries
    from ..tracks.registry import headline_of
    sig = track_significance(track_dir, entries, headline_of(Path(track_dir).name))
    return [dict(e, _sig=sig[e["_file"]]) if e["_file"] in sig else e for e in entries]


def _has_fid_r1(entries: list[dict]) -> bool:
    """Whether some row has FID and R@1 (the FID vs R@1 plot)."""
    return any("fid" in e["metrics"] and "r_precision_top1" in e["metrics"] for e in entries)


_COLOR_NAMES = {"ground-truth": "blue", "ranked": "orange", "reference": "grey", "reported": "light grey"}


def write_csv(entries: list[dict]) -> str:
    names = sorted({k for e in entries for k in e["metrics"]})
    sig = _has_significance(entries)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["rank", "band", "method", "role", "source", "citation", "complete", "samples_per_prompt",
                "evaluator_id", "protocol", "protocol_version", "toolkit_version", "train_steps", "train_parameters",
                "train_wall_seconds", "train_hardware", "conditioner_text_encoder"]
               + [f"{n}{s}" for n in names for s in ("", "_ci95")]
               + (["rank_ci95", "vs_above_distinguishable", "vs_above"] if sig else []))
    for r, e in zip(ranks(entries), entries):
        row = ["" if r is None else r, band(e)] + [csv_text(e.get(k) or "") for k in ("method", "role", "source",
                                                                                     "citation")] \
            + [e.get("complete", True), e.get("samples_per_prompt", "")] \
            + [csv_text(e.get(k) or "") for k in ("evaluator_id", "protocol", "protocol_version", "toolkit_version")]
        t = training_of(e)
        row += [t.get("steps", ""), t.get("parameters", ""), t.get("wall_seconds", ""), t.get("hardware", ""),
                (t.get("text_encoder") or {}).get("encoder", "")]
        for n in names:
            m = e["metrics"].get(n)
            row += ["", ""] if m is None else [repr(float(m["mean"])), repr(float(m.get("ci95") or 0.0))]
        if sig:
            vs = (e.get("_sig") or {}).get("vs_above")
            rank = rank_text(e.get("_sig"))
            row += ["" if rank == "-" else rank, "" if not vs else vs["distinguishable"], csv_text(vs_above_detail(e.get("_sig")))]
        w.writerow(row)
    return buf.getvalue()


def _label(r: int | None, e: dict) -> str:
    return f"{r}. {e['method']}" if r else e["method"]


def _band_handles(entries: list[dict]):
    from matplotlib.patches import Patch
    present = [b for b, _ in BANDS if any(band(e) == b for e in entries)]
    return [Patch(color=COLORS[b], label=b.replace("-", " ")) for b in present]


def _figures(track: str, entries: list[dict]) -> dict[str, bytes]:
    """PNG bytes of the metric bars (with CI error bars, bands separated by lines, a colour
    legend) and the FID vs R@1 scatter (labels placed without overlap)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from ..tracks.registry import headline_of
    cols = [c for c in headline_of(track) if any(c in e["metrics"] for e in entries)]
    out = {}
    rk = ranks(entries)
    fig, axes = plt.subplots(1, max(1, len(cols)), figsize=(3.6 * max(1, len(cols)), 0.35 * len(entries) + 2.0),
                             squeeze=False)
    labels = [plot_text(_label(r, e)) for r, e in zip(rk, entries)]
    colors = [COLORS[band(e)] for e in entries]
    breaks = [i - 0.5 for i in range(1, len(entries)) if band(entries[i]) != band(entries[i - 1])]
    for ax, c in zip(axes[0], cols):
        vals = [(_m["mean"] if (_m := e["metrics"].get(c)) else float("nan")) for e in entries]
        errs = [((_m.get("ci95") or 0.0) if (_m := e["metrics"].get(c)) else 0.0) for e in entries]
        y = range(len(entries))
        ax.barh(list(y), vals, xerr=errs, color=colors, capsize=3)
        for yb in breaks:
            ax.axhline(yb, color="#4a5568", lw=0.6, ls="--")
        ax.set_yticks(list(y))
        ax.set_yticklabels(labels if ax is axes[0][0] else [""] * len(labels), fontsize=8)
        ax.invert_yaxis()
        info = _info(c)
        ax.set_title(f"{_header(c)}  ({info.units if info else ''})", fontsize=9)
        ax.grid(axis="x", alpha=0.3)
    fig.suptitle(f"{track}: mean ± 95% CI (numbers: rank of methods and baselines)", fontsize=10)
    fig.legend(handles=_band_handles(entries), loc="lower center", ncol=4, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    out["metrics.png"] = _png(fig)
    if not _has_fid_r1(entries):
        return out
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    pts, names, pcol, errs = [], [], [], []
    for r, e, col in zip(rk, entries, colors):
        f, r1 = e["metrics"].get("fid"), e["metrics"].get("r_precision_top1")
        if not (f and r1):
            continue
        ax.errorbar(max(f["mean"], 0.0), r1["mean"], xerr=f.get("ci95") or 0, yerr=r1.get("ci95") or 0, fmt="o",
                    color=col, capsize=3)
        pts.append((max(f["mean"], 0.0), r1["mean"]))
        errs.append((f.get("ci95") or 0.0, r1.get("ci95") or 0.0))
        names.append(plot_text(_label(r, e)))
        pcol.append(col)
    ax.set_xlabel("FID ↓ (squared embedding distance)")
    ax.set_ylabel("R-precision top-1 ↑")
    ax.set_title(f"{track}: FID vs R@1", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(handles=_band_handles(entries), fontsize=7, loc="best")
    fig.tight_layout()
    place_labels(ax, pts, names, pcol, errors=errs)
    out["fid_vs_r1.png"] = _png(fig)
    return out


def _candidates() -> list[tuple[float, float]]:
    """Label offsets in points: rings of 12 directions at growing radii, nearest first."""
    import math
    out = [(5.0, 4.0)]
    for radius in (10, 18, 28, 40, 55, 72):
        out += [(radius * math.cos(a), radius * math.sin(a))
                for a in (2 * math.pi * i / 12 + (0.3 if radius % 20 else 0.0) for i in range(12))]
    return out


def _obstacles(ax, points, errors, renderer) -> list:
    """Display-space boxes a label must not cover: each marker, its error bars, the legend."""
    from matplotlib.transforms import Bbox
    out = []
    for (x, y), (ex, ey) in zip(points, errors or [(0.0, 0.0)] * len(points)):
        (x0, y0), (x1, y1) = ax.transData.transform([(x - ex, y - ey), (x + ex, y + ey)])
        cx, cy = ax.transData.transform((x, y))
        out += [Bbox.from_extents(cx - 5, cy - 5, cx + 5, cy + 5), Bbox.from_extents(cx - 4, y0 - 1, cx + 4, y1 + 1),
                Bbox.from_extents(x0 - 1, cy - 2, x1 + 1, cy + 2)]
    if ax.get_legend() is not None:
        out.append(ax.get_legend().get_window_extent(renderer))
    return out


def place_labels(ax, points: list[tuple[float, float]], labels: list[str], colors: list[str] | None = None,
                 fontsize: float = 7, errors: list[tuple[float, float]] | None = None) -> list:
    """Annotate ``points`` with ``labels`` so that no two labels overlap and no label covers
    a marker, an error bar (``errors``: (x, y) half-widths) or the legend: each label takes
    the nearest free offset of :func:`_candidates` (inside the figure), with a thin leader
    line when it sits away from its point; when none is free, the one with the least
    overlap. Returns the text artists."""
    from matplotlib.text import Text
    fig = ax.figure
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    dots = _obstacles(ax, points, errors, renderer)
    frame = fig.bbox
    placed: list = []
    texts = []
    for i, ((px, py), label) in enumerate(zip(points, labels)):
        best = None
        for dx, dy in _candidates():
            ha = "left" if dx > 2 else ("right" if dx < -2 else "center")
            va = "bottom" if dy > 2 else ("top" if dy < -2 else "center")
            far = abs(dx) > 8 or abs(dy) > 8
            t = ax.annotate(label, (px, py), xytext=(dx, dy), textcoords="offset points", fontsize=fontsize, ha=ha,
                            va=va, color="#1a202c", annotation_clip=False,
                            arrowprops=dict(arrowstyle="-", lw=0.5, color=(colors or ["#4a5568"] * len(points))[i],
                                            shrinkA=0, shrinkB=3) if far else None)
            t.update_positions(renderer)
            bb = Text.get_window_extent(t, renderer).expanded(1.04, 1.15)     # the text alone, not its leader
            cost = sum(bb.overlaps(o) for o in placed) + sum(bb.overlaps(d) for d in dots) \
                + (0 if (frame.contains(bb.x0, bb.y0) and frame.contains(bb.x1, bb.y1)) else 5)
            if best is None or cost < best[0]:
                if best is not None:
                    best[1].remove()
                best = (cost, t, bb)
            else:
                t.remove()
            if cost == 0:
                break
        placed.append(best[2])
        texts.append(best[1])
    return texts


def _png(fig) -> bytes:
    import matplotlib.pyplot as plt
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return buf.getvalue()


_SORT_JS = """
document.querySelectorAll('th[data-col]').forEach(function (th) {
  th.addEventListener('click', function () {
    var table = th.closest('table'), col = +th.dataset.col;
    var asc = th.dataset.dir !== 'asc'; th.dataset.dir = asc ? 'asc' : 'desc';
    Array.from(table.tBodies).forEach(function (body) {   // each band sorts on its own
      var rows = Array.from(body.rows).filter(function (r) { return !r.classList.contains('band'); });
      rows.sort(function (a, b) {
        var x = a.cells[col].dataset.v, y = b.cells[col].dataset.v;
        var nx = parseFloat(x), ny = parseFloat(y);
        if (isNaN(nx) || isNaN(ny)) { return asc ? String(x).localeCompare(y) : String(y).localeCompare(x); }
        return asc ? nx - ny : ny - nx;
      });
      rows.forEach(function (r) { body.appendChild(r); });
    });
  });
});
"""

_CSS = """
body { font-family: system-ui, sans-serif; margin: 1.5em; color: #1a202c; }
table { border-collapse: collapse; font-size: 13px; }
.wrap { overflow-x: auto; }
th, td { padding: 3px 6px; border-bottom: 1px solid #e2e8f0; text-align: right; white-space: nowrap; }
th { cursor: pointer; background: #edf2f7; vertical-align: bottom; }
td.name, th.name, td.flags, th.flags { text-align: left; }
td.name { white-space: normal; min-width: 12em; max-width: 22em; }
td.flags { white-space: normal; max-width: 12em; font-size: 12px; }
td.training { white-space: normal; min-width: 16em; max-width: 22em; font-size: 11px; text-align: left; color: #4a5568; }
td small { display: block; color: #718096; font-size: 11px; }
tr.band th { text-align: left; background: #f7fafc; font-weight: 600; color: #2d3748; cursor: default;
             border-top: 2px solid #cbd5e0; }
tr.gt { font-weight: 600; background: #ebf8ff; }
tr.reference { color: #4a5568; font-style: italic; }
tr.reported { color: #a0aec0; }
.badge { font-size: 11px; border: 1px solid #a0aec0; border-radius: 3px; padding: 0 4px; }
.warn { border-color: #dd6b20; color: #dd6b20; }
.cite { font-size: 12px; }
.legend { font-size: 13px; margin: 0.6em 0 1em; padding: 0.5em 0.8em; background: #f7fafc; border: 1px solid #e2e8f0;
          max-width: 70em; }
.legend ul { margin: 0.2em 0; padding-left: 1.2em; }
.about { font-size: 14px; max-width: 70em; }
.about pre { background: #f7fafc; padding: 0.5em; overflow-x: auto; }
.about-table { border-collapse: collapse; margin: 0.5em 0; }
.about-table th, .about-table td { border-bottom: 1px solid #e2e8f0; padding: 2px 8px; text-align: left; }
.about-table td.num { text-align: right; font-variant-numeric: tabular-nums; }
.swatch { display: inline-block; width: 0.9em; height: 0.9em; vertical-align: middle; margin-right: 0.3em; }
figure { display: inline-block; margin: 1em 1em 0 0; }
img { max-width: 100%; }
"""


def _legend(entries: list[dict], cols: list[str]) -> str:
    e_ = html.escape
    bands = [b for b, _, _ in _bands(entries)]
    rows = "".join(f"<li>{e_(BAND_LEGEND[b])}</li>" for b in bands)
    swatches = " ".join(f'<span class="swatch" style="background:{COLORS[b]}"></span>{e_(b.replace("-", " "))}'
                        for b in bands)
    k1 = (f"<li>{e_(K1_NOTE)}</li>" if _any_k1(entries, cols) else "") + \
        (f"<li>{e_(CLIPS_NOTE)}</li>" if _any_clips(entries, cols) else "") + \
        (f"<li>{e_(SIGNIFICANCE_NOTE)}.</li>" if _has_significance(entries) else "")
    return (f'<div class="legend"><b>Legend</b><ul>{rows}{k1}<li>Each cell: {html.escape(_cells_text(entries, "html"), quote=False)}.'
            f"</li><li>Bar and point colours in the plots: {swatches}.</li></ul></div>")


def page(track: str, entries: list[dict], figures: dict[str, bytes], about: str = "") -> str:
    """index.html: the bands of :func:`_bands` as one table body each (a column click sorts
    inside each band), rank numbers on methods and baselines only, the flags next to the
    method name, a legend, and the plots."""
    cols = _columns(entries)
    e_ = html.escape
    sig = _has_significance(entries)
    n_extra = 2 if sig else 0
    head = "".join(f'<th data-col="{i + 3 + n_extra}" title="{e_((_info(c).summary + " (" + _info(c).units + ")") if _info(c) else c)}">'
                   f"{e_(_header(c))}</th>" for i, c in enumerate(cols))
    bodies = []
    for b, heading, members in _bands(entries):
        rows = [f'<tr class="band"><th colspan="{len(cols) + 4 + n_extra}">{e_(heading)}</th></tr>']
        for r, e in members:
            cls = {"ground-truth": "gt", "reported": "reported", "reference": "reference"}.get(b, "ranked")
            name = e_(e["method"])
            if e["source"] == "reported":
                badge = "comparable" if any(comparable(x, e) for x in entries) else "not comparable"
                name += f' <span class="cite">{e_(str(e.get("citation")))}</span> <span class="badge">{badge}</span>'
            if not e.get("complete", True):
                name += ' <span class="badge warn">incomplete</span>'
            k = _replication_k(e)
            cells = []
            for c, m in ((c, e["metrics"].get(c)) for c in cols):
                mean, ci = _parts(m, k, c)
                ci_html = f"<small>± {e_(ci)}</small>" if ci else ""
                cells.append(f'<td data-v="{float(m["mean"]) if m else ""}">{e_(mean)}{ci_html}</td>')
            flags = e_(", ".join(_flags(e, entries)))
            lead = ""
            if sig:
                rank, vs = rank_text(e.get("_sig")), vs_above_text(e.get("_sig"), short=True)
                lead = (f'<td data-v="{e_(rank)}">{e_(rank)}</td><td class="flags" data-v="{e_(vs)}" '
                        f'title="{e_(vs_above_detail(e.get("_sig")))}">{e_(vs)}</td>')
            rows.append(f'<tr class="{cls}"><td data-v="{r or ""}">{r or ""}</td>'
                        f'<td class="name" data-v="{e_(e["method"])}">{name}</td>'
                        f'<td class="flags" data-v="{flags}">{flags}</td>{lead}{"".join(cells)}'
                        f'<td class="training" data-v="{e_(budget(e))}">{e_(budget(e))}</td></tr>')
        bodies.append(f'<tbody class="band-{b}">\n' + "\n".join(rows) + "\n</tbody>")
    imgs = "".join(f'<figure><img alt="{e_(n)}" src="data:image/png;base64,{base64.b64encode(b).decode()}">'
                   f"</figure>" for n, b in figures.items())
    units = "; ".join(f"{e_(title(c))}: {e_(_info(c).units)}" for c in cols if _info(c))
    sig_head = (f'<th data-col="3" title="{e_(SIGNIFICANCE_NOTE)}">rank 95%</th>'
                f'<th class="flags" data-col="4" title="{e_(SIGNIFICANCE_NOTE)}">vs row above</th>'
                if sig else "")
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>{e_(track)} leaderboard - hoibench</title>
<meta name="viewport" content="width=device-width, initial-scale=1">
<style>{_CSS}</style></head><body>
<h1>{e_(track)} leaderboard</h1>
<p>{e_(_context(entries))}. ↑ higher is better, ↓ lower is better, ≈GT closest to the ground truth.
Click a column to sort (inside each band). Units: {units}.</p>
{about_html(about)}
{_legend(entries, cols)}
<div class="wrap"><table><thead><tr><th data-col="0">#</th><th class="name" data-col="1">method</th><th class="flags" data-col="2">flags</th>{sig_head}{head}<th data-col="{len(cols) + 3 + n_extra}">training</th></tr></thead>
{chr(10).join(bodies)}
</table></div>
{imgs}
<script>{_SORT_JS}</script>
</body></html>
"""


def read_about(track_dir: str | Path) -> str:
    """The track's ``about.md`` (empty when absent), a regular file of at most
    :data:`MAX_ABOUT_BYTES` read through the guarded reader."""
    path = Path(track_dir) / "about.md"
    return read_text_file(path, MAX_ABOUT_BYTES, "about.md") if path.exists() or path.is_symlink() else ""


def render(track_dir: str | Path) -> tuple[list[dict], dict[str, str | bytes]]:
    """``(entries in display order, {file name: text or bytes})`` of a track: README.md
    (``about.md``, when present, above the table), leaderboard.csv, index.html and the PNG
    plots; no files when the track has no entries."""
    track_dir = Path(track_dir)
    entries = with_significance(track_dir, order(load_track(track_dir)))
    if not entries:
        return entries, {}
    track = track_dir.name
    figures = _figures(track, entries)
    about = read_about(track_dir)                 # the track's own words, kept above the table
    return entries, {"README.md": markdown(track, entries, about) + "\n", "leaderboard.csv": write_csv(entries),
                     "index.html": page(track, entries, figures, about), **figures}


def write_rendered(files: dict[str, str | bytes], folder: str | Path) -> dict[str, Path]:
    """Write :func:`render`'s files into ``folder`` (atomically); ``{name: path}``."""
    return {name: (atomic_write_bytes if isinstance(data, bytes) else atomic_write_text)(Path(folder) / name, data)
            for name, data in files.items()}


def build(track_dir: str | Path) -> dict[str, Path]:
    """Render ``track_dir``'s entries (:func:`render`) into the track folder. Returns the paths."""
    _, files = render(track_dir)
    if not files:
        raise LeaderboardError(f"{track_dir}/entries: no entries to render")
    return write_rendered(files, track_dir)


__all__ = ["build", "render", "write_rendered", "markdown", "write_csv", "page", "fmt", "place_labels"]
