"""``hoibench leaderboard site --out site/``: every track's page and an index page, static
files only (ready for GitHub Pages or any web server).

``site/index.html`` lists the tracks with their rows, protocols and evaluator ids, how to
submit (prompts -> samples -> validate -> evaluate -> leaderboard add) and how to reproduce
a row locally; ``site/<track>/`` holds the track's ``index.html``, ``leaderboard.csv`` and
plots, rendered by the functions ``hoibench leaderboard build`` uses (the track folders are
not modified). Every text from an entry is HTML-escaped.
"""
from __future__ import annotations

import html
from pathlib import Path

from ..core.io import atomic_write_text
from .leaderboard import LeaderboardError, track_dirs
from .pages import render, write_rendered

_STYLE = ("body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}"
          "table{border-collapse:collapse;width:100%}td,th{border-bottom:1px solid #ddd;padding:.4em .6em;"
          "text-align:left;vertical-align:top}code{background:#f4f4f4;padding:0 .2em}pre{background:#f4f4f4;"
          "padding:.8em;overflow-x:auto}")


def _track_summary(track: str, entries: list[dict]) -> dict:
    ours = [e for e in entries if e["source"] == "reproduced"]
    return {"track": track, "rows": len(entries), "reproduced": len(ours),
            "reported": len(entries) - len(ours),
            "protocols": sorted({f"{e.get('protocol')}@{e.get('protocol_version')}" for e in ours}),
            "evaluators": sorted({str(e.get("evaluator_id"))[:12] for e in ours if e.get("evaluator_id")})}


def index_page(summaries: list[dict]) -> str:
    """The site's front page."""
    e_ = html.escape
    rows = "".join(
        f'<tr><td><a href="{e_(s["track"])}/index.html">{e_(s["track"])}</a></td><td>{s["reproduced"]} scored, '
        f'{s["reported"]} reported</td><td>{e_(", ".join(s["protocols"]) or "-")}</td>'
        f'<td><code>{e_(", ".join(s["evaluators"]) or "-")}</code></td></tr>' for s in summaries)
    return f"""<!doctype html><html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1"><title>hoibench leaderboards</title>
<style>{_STYLE}</style></head><body>
<h1>hoibench leaderboards</h1>
<p>Text-driven 3D human-object interaction generation, scored under versioned protocols. Each track ranks
methods scored with one evaluator under one protocol; rows copied from papers are shown greyed and marked
comparable only when scored the papers' way.</p>
<table><thead><tr><th>track</th><th>rows</th><th>protocol</th><th>evaluator id</th></tr></thead>
<tbody>{rows}</tbody></table>
<h2>How to submit</h2>
<pre>hoibench submission prompts DATA --out prompts.jsonl      # captions, lengths, fps, object meshes
# write samples/&lt;id&gt;.npz (joints, object pose) and submission.json
hoibench validate SUB --data DATA
hoibench evaluate SUB --data DATA --evaluator EV --protocol PROTOCOL --out result.json
hoibench leaderboard add result.json --track TRACK --method "my model"</pre>
<p>Hosted challenges score the same way on a hidden test split (Codabench or EvalAI; docs/hosting.md).</p>
<h2>How to reproduce a row</h2>
<p>Every row records its protocol (id, version, sha256), evaluator id and toolkit version. With the same store,
evaluator folder and submission, <code>hoibench evaluate</code> gives the same numbers on any machine (results
are deterministic for any number of workers); <code>hoibench compare result.json
leaderboards/TRACK/entries/ROW.json</code> shows the differences.</p>
</body></html>
"""


def build_site(root: str | Path, out: str | Path) -> dict[str, Path]:
    """Render every track under ``root`` (a ``leaderboards/`` folder) into ``out``."""
    root, out = Path(root), Path(out)
    tracks = track_dirs(root)
    if not tracks:
        raise LeaderboardError(f"{root}: no leaderboard tracks (folders with entries/)")
    written: dict[str, Path] = {}
    summaries = []
    for t in tracks:
        entries, files = render(t)
        if not files:
            continue
        files.pop("README.md")                    # the site serves the HTML page
        written.update({f"{t.name}/{name}": p for name, p in write_rendered(files, out / t.name).items()})
        summaries.append(_track_summary(t.name, entries))
    written["index.html"] = atomic_write_text(out / "index.html", index_page(summaries))
    return written


__all__ = ["build_site", "index_page"]
