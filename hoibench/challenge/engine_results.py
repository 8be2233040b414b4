"""Rows of an engine's exported leaderboard -> hoibench leaderboard entries.

Codabench's results export (``/api/competitions/<id>/results.json``, as its
``collect_leaderboard_data`` writes it) is ``{"<leaderboard> - <phase>(<id>)":
{"<owner>-<submission id>": {"<task>(<id>)-<column title>": score, ...}}}``. A row becomes an
entry when its hidden ``evaluator_id8`` and ``protocol_sha8`` columns equal the challenge's
(``challenge.json`` of the bundle); other rows are refused, naming the row and the column.
Engine scores are means only: the entry records the metrics without CIs and says where it
came from (``source: "hosted"``, the engine and the row); ``hoibench leaderboard build``
renders it beside locally scored rows.
"""
from __future__ import annotations

import re
from pathlib import Path

from ..core.io import read_json_file
from .reference import engine_id

_COLUMN = re.compile(r"^(?P<task>.*)\((?P<tid>\d+)\)-(?P<title>.+)$")


def rows_from_export(export: dict) -> list[tuple[str, str, dict[str, float | str]]]:
    """``(leaderboard, row name, {column title: score})`` for every row of the export."""
    if not isinstance(export, dict):
        raise ValueError("export: expected a JSON object {leaderboard: {row: {column: score}}}")
    out = []
    for board, rows in export.items():
        if not isinstance(rows, dict):
            raise ValueError(f"export: leaderboard {board!r}: expected an object of rows")
        for name, cols in rows.items():
            if not isinstance(cols, dict):
                raise ValueError(f"export: {board!r} row {name!r}: expected an object of columns")
            vals = {}
            for k, v in cols.items():
                m = _COLUMN.match(str(k))
                if m:
                    vals[m.group("title")] = v
            out.append((str(board), str(name), vals))
    return out


def entries_from_export(export_file: str | Path, bundle_info: dict, engine: str = "codabench") -> tuple[list, list]:
    """(entries, refusals) for the rows of ``export_file`` against ``bundle_info`` (the
    bundle's ``challenge.json``)."""
    from ..publish.leaderboard import title as column_title
    export = read_json_file(export_file, 64 << 20, "leaderboard export")
    by_title = {column_title(k): k for k in bundle_info["columns"]}
    want_ev, want_proto = engine_id(bundle_info["evaluator_id"]), engine_id(bundle_info["protocol_sha256"])
    entries, refused = [], []
    for board, name, vals in rows_from_export(export):
        where = f"{Path(export_file).name}: {board!r} row {name!r}"
        try:
            ev, pr = float(vals.get("evaluator id (8 hex as int)", "nan")), float(vals.get("protocol sha (8 hex as int)", "nan"))
        except (TypeError, ValueError):
            ev = pr = float("nan")
        if ev != want_ev:
            refused.append(f"{where}: column evaluator_id8: {vals.get('evaluator id (8 hex as int)')!r} is not "
                           f"the challenge's evaluator {bundle_info['evaluator_id'][:8]} ({want_ev})")
            continue
        if pr != want_proto:
            refused.append(f"{where}: column protocol_sha8: not the challenge's protocol {bundle_info['protocol']}")
            continue
        metrics = {}
        for title, key in by_title.items():
            v = vals.get(title)
            if v in (None, ""):
                continue
            try:
                metrics[key] = {"mean": float(v), "ci95": None, "n": None}
            except (TypeError, ValueError):
                refused.append(f"{where}: column {title}: {v!r} is not a number")
                break
        else:
            from ..publish.leaderboard import ENTRY_FORMAT
            entries.append({"format": ENTRY_FORMAT, "method": name, "track": bundle_info["track"],
                            "source": "reproduced", "role": "method",
                            "hosted": {"engine": engine, "leaderboard": board, "row": name,
                                       "note": "scored by the challenge's scoring program on the hidden split; the "
                                               "engine keeps means only (no CI)"},
                            "evaluator_id": bundle_info["evaluator_id"], "evaluator_backend": "contrastive",
                            "protocol": bundle_info["protocol"], "protocol_version": bundle_info.get("protocol_version"),
                            "metrics": metrics, "undefined_metrics": {}, "complete": True, "missing_ids": [],
                            "flags": {}, "overrides": [], "toolkit_version": bundle_info.get("hoibench_version"),
                            "notes": f"hosted on {engine}"})
    return entries, refused


def add_hosted_rows(export_file: str | Path, bundle_info: dict, track_dir: str | Path,
                    engine: str = "codabench", replace: bool = False) -> tuple[list[Path], list[str]]:
    """Write the accepted rows of an export into ``track_dir/entries`` (refusing a track
    scored with another evaluator or protocol, and existing names unless ``replace``);
    return (written paths, refusals)."""
    from ..publish.leaderboard import LeaderboardError, load_track, slug, write_entry
    track_dir = Path(track_dir)
    existing = [e for e in load_track(track_dir) if e["source"] == "reproduced"]
    ids = {str(e.get("evaluator_id")) for e in existing}
    if ids and bundle_info["evaluator_id"] not in ids:
        raise LeaderboardError(f"{track_dir}: the track's rows use evaluator {', '.join(sorted(i[:12] for i in ids))}, "
                               f"the challenge {bundle_info['evaluator_id'][:12]}")
    protos = {f"{e.get('protocol')}@{e.get('protocol_version')}" for e in existing}
    mine = f"{bundle_info['protocol']}@{bundle_info.get('protocol_version')}"
    if protos and mine not in protos:
        raise LeaderboardError(f"{track_dir}: the track's rows use protocol {', '.join(sorted(protos))}, the "
                               f"challenge {mine}")
    entries, refused = entries_from_export(export_file, bundle_info, engine)
    written = []
    for e in entries:
        path = track_dir / "entries" / f"{slug(e['method'])}.json"
        if path.exists() and not replace:
            refused.append(f"{path}: field method: an entry named {e['method']!r} exists already (pass --replace)")
            continue
        written.append(write_entry(e, track_dir / "entries"))
    return written, refused


__all__ = ["rows_from_export", "entries_from_export", "add_hosted_rows"]
