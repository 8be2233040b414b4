"""The poorer outcomes of hostile input, each now a one-line refusal naming file and field or
a safe rendering: duplicate JSON keys, a representation of another store, terminal escapes
in printed names, exit 1 when every sequence fails, malformed ``compare`` inputs and
leaderboard entries, README/CSV injection, ``$`` in plotted names, deep JSON, out-of-range
contact pairs, the z-up tie-break and a raw ``.npz`` holding one member twice."""
from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

import numpy as np
import pytest

from hoibench.scoring.submission_read import Problem, Submission


def _sub(tmp_path: Path, meta_text: str) -> Path:
    (tmp_path / "sub" / "samples").mkdir(parents=True)
    (tmp_path / "sub" / "submission.json").write_text(meta_text)
    return tmp_path / "sub"


def test_duplicate_keys_in_submission_json_are_refused(tmp_path):
    sub = Submission(_sub(tmp_path, '{"method": "a", "version": "1", "representation": "joints", "fps": 20, '
                                    '"fps": 30, "flags": {}}'))
    assert sub.meta is None
    assert any(p.field == "submission.json" and "duplicate key 'fps'" in p.message for p in sub.problems)


def test_a_representation_of_another_store_is_refused():
    from hoibench.scoring.validate import _check_meta, accepted_representations
    manifest = {"representations": {"hml263": "hml263-clean-1.0", "hoi269": "hoi269-clean-1.0"}}
    ok = {"method": "m", "version": "1", "fps": 20}
    accepted = accepted_representations(manifest)
    for rep in ("hml263-clean-1.0", "hoi269-clean-1.0", "joints"):
        assert _check_meta({**ok, "representation": rep}, 20.0, None, accepted) == []
    probs = _check_meta({**ok, "representation": "hml263-legacy-1.0"}, 20.0, None, accepted)
    assert [p.field for p in probs] == ["submission.json"] and "does not match the store" in probs[0].message


def test_names_are_printed_with_terminal_escapes_escaped(tmp_path, capsys):
    from hoibench.cli import _one_line
    from hoibench.core.errors import printable
    evil = "samples/\x1b]0;pwned\x07\x1b[2J.npz"
    assert "\x1b" not in str(Problem("*", "zip", f"member {evil}")) and "\\x1b" in str(Problem("*", "zip", evil))
    assert "\x1b" not in _one_line(ValueError(evil)) and "\\x07" in _one_line(ValueError(evil))
    assert printable("Ünïcode ok") == "Ünïcode ok" and printable("rtl \u202e") == "rtl \\u202e"
    from hoibench.scoring.compare import _method
    assert _method({"submission": {"method": "m\x1b[31mred"}}, "x.json") == "m\\x1b[31mred"


def test_prepare_exits_1_when_every_sequence_fails(tmp_path, capsys):
    from hoibench.cli import main
    seq = tmp_path / "raw" / "sequences" / "Date01_Sub01_boxlarge_hand"
    seq.mkdir(parents=True)
    (tmp_path / "raw" / "objects").mkdir()
    (tmp_path / "models").mkdir()
    code = main(["prepare", "behave", "--root", str(tmp_path / "raw"), "--body-models", str(tmp_path / "models"),
                 "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 1 and "every sequence failed (1" in err, err


@pytest.mark.parametrize("metrics,counts,field", [
    ({"fid": 3}, {}, "metrics.fid"), ({"fid": {"mean": "0.3"}}, {}, "metrics.fid.mean"),
    ({"fid": {"mean": []}}, {}, "metrics.fid.mean"), ({"fid": {"mean": 0.1, "ci95": "x"}}, {}, "metrics.fid.ci95"),
    ({"fid": {"mean": 0.1}}, [], "counts"), ({"fid": {"mean": 0.1}}, {"samples_per_prompt": "1"},
                                             "counts.samples_per_prompt"),
    ({"fid": {"mean": 0.1}}, {"missing_ids": 3}, "counts.missing_ids")])
def test_malformed_results_are_refused_naming_file_and_field(tmp_path, metrics, counts, field):
    from hoibench.scoring.results import ResultError, read_result
    p = tmp_path / "r.json"
    p.write_text(json.dumps({"metrics": metrics, "counts": counts}))
    with pytest.raises(ResultError, match=rf"r.json: field {field.replace('.', '[.]')}"):
        read_result(p)


def _entry(**over) -> dict:
    e = {"format": "hoibench-entry-1", "track": "synthetic", "method": "m", "source": "reproduced",
         "metrics": {"fid": {"mean": 0.2, "ci95": 0.01}}, "complete": True}
    e.update(over)
    return e


@pytest.mark.parametrize("over,field", [({"metrics": {"fid": {"mean": 0.2, "ci95": "0.1"}}}, "metrics.fid.ci95"),
                                        ({"samples_per_prompt": "30"}, "samples_per_prompt"),
                                        ({"missing_ids": 3}, "missing_ids"), ({"method": "\udcff"}, "method"),
                                        ({"notes": 5}, "notes")])
def test_malformed_leaderboard_entries_are_refused_naming_the_field(tmp_path, over, field):
    from hoibench.publish.leaderboard import ENTRY_FORMAT, LeaderboardError, read_entry
    p = tmp_path / "e.json"
    p.write_text(json.dumps(_entry(format=ENTRY_FORMAT, **over)))
    with pytest.raises(LeaderboardError, match=rf"e.json: field {field.replace('.', '[.]')}"):
        read_entry(p)


def test_readme_and_csv_neutralise_html_markdown_links_and_formulas():
    from hoibench.publish.pages import markdown, md_about, write_csv
    evil = ["<script>alert(1)</script>", "<img src=x onerror=alert(1)>", "<svg onload=alert(1)>",
            "[click](javascript:alert(1))", "a | b\n| c", "=HYPERLINK(\"http://x\")"]
    entries = [dict(_entry(method=m, role="method"), citation="<b>c</b>") for m in evil]
    entries.append(dict(_entry(method="paper", role="method", source="reported"), citation="[x](javascript:y)"))
    md = markdown("synthetic", entries, about="[a](javascript:alert(1)) <svg onload=x> [ok](https://x.org)")
    import re
    for bad in ("<script", "<img", "<svg", "<b>"):
        assert bad not in md, bad
    assert not re.search(r"(?<!\\)\]\(javascript:", md)              # a link needs an unescaped ']('
    assert "\\[click\\](#))" in md and "javascript:" not in md    # no script scheme survives, even as text
    rows = [line for line in md.splitlines() if line.startswith("| ") and "---" not in line
            and "***" not in line][1:]                                 # band headings are not rows
    cells = {len(re.findall(r"(?<!\\)\|", r)) for r in rows}        # unescaped pipes: one count for every row
    assert len(rows) == len(entries) and len(cells) == 1, rows
    assert "[ok](https://x.org)" in md_about("[ok](https://x.org)")
    import csv
    import io
    cells = [row["method"] for row in csv.DictReader(io.StringIO(write_csv(entries)))]
    assert not any(c.startswith(("=", "+", "-", "@")) for c in cells)
    assert any(c.startswith("'=HYPERLINK") for c in cells)
    assert not any("javascript:" in c for c in cells) and "[click](#))" in cells  # CSV cells: http(s) links only


def test_dollar_signs_in_method_names_are_plotted_as_text():
    pytest.importorskip("matplotlib")
    from hoibench.publish.pages import _figures
    e = _entry(method="$\\frac{1}{$ broken", role="method")
    e["metrics"]["r_precision_top1"] = {"mean": 0.4, "ci95": 0.01}
    figures = _figures("synthetic", [e, _entry(method="$x$", role="method")])
    assert set(figures) == {"metrics.png", "fid_vs_r1.png"} and all(b[:4] == b"\x89PNG" for b in figures.values())


def test_deep_json_in_split_text_and_provenance_names_the_file(tmp_path):
    from hoibench.datasets.splits import SplitFileError, read_split_file
    from hoibench.bodies.multibody import clip_json_fields
    deep = "[" * 100_000 + "]" * 100_000
    p = tmp_path / "split.json"
    p.write_text(deep)
    with pytest.raises(SplitFileError, match="split.json: JSON nested too deeply"):
        read_split_file(p)
    with pytest.raises(ValueError, match="clip7: provenance: JSON nested too deeply"):
        clip_json_fields({"name": np.array("clip7"), "provenance": np.array(deep)})


def test_contact_pairs_out_of_range_name_the_field():
    from test_hostile_budgets import _clip
    from hoibench.bodies.multibody import MultiBodyClip
    z = _clip().to_arrays()
    z["contact_pairs"] = np.array([[0, 7]])
    z["contact_frames"] = np.zeros((1, 12), bool)
    with pytest.raises(ValueError, match=r"mb_a: contact_pairs: body indices must be whole numbers in 0..1"):
        MultiBodyClip.from_arrays(z)


def test_a_z_up_clip_is_called_z_up_not_minus_y_up():
    from hoibench.core.skeleton import SMPL_REST_JOINTS
    from hoibench.scoring.validate_arrays import _check_joints
    J = np.asarray(SMPL_REST_JOINTS, np.float64)[:22] * 1.0
    J = J - J[[7, 8, 10, 11], 1].min() * np.array([0, 1, 0])       # feet on the floor, y-up, facing +z
    walk = np.stack([J + [0, 0, 0.02 * t] for t in range(20)])[None]    # (1, T, 22, 3)
    assert _check_joints("c", walk.astype(np.float32), 20.0)[1] is None
    for facing in (1, -1):      # y-up -> z-up, facing +y or -y: a foot is extreme along two axes
        zup = np.stack([walk[..., 0], -facing * walk[..., 2], walk[..., 1]], -1)
        probs, up = _check_joints("c", zup.astype(np.float32), 20.0)
        assert up == "z" and "looks z-up" in probs[0].message, (facing, up)


def test_a_raw_npz_holding_one_member_twice_is_refused(tmp_path):
    import warnings
    from hoibench.core.io import load_raw_npz
    buf = io.BytesIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with zipfile.ZipFile(buf, "w") as zf:
            for v in (1.0, 2.0):
                member = io.BytesIO()
                np.save(member, np.full(3, v))
                zf.writestr("trans.npy", member.getvalue())
    p = tmp_path / "seq.npz"
    p.write_bytes(buf.getvalue())
    with pytest.raises(ValueError, match="seq.npz: member 'trans.npy' appears twice"):
        load_raw_npz(p)


def test_render_refuses_a_nan_sample_naming_id_and_array(tmp_path):
    from hoibench.core.io import atomic_save_npz
    from hoibench.publish.render import render_comparison
    from hoibench.scoring.submission_write import write_submission
    data = tmp_path / "data"
    (data / "manifest.json").parent.mkdir()
    (data / "manifest.json").write_text(json.dumps({"dataset": "synthetic", "config": {"fps": 20, "mode": "clean"},
                                                    "clips": [{"id": "t0", "split": "test", "frames": 8}]}))
    atomic_save_npz(data / "clips" / "t0.npz", joints=np.zeros((8, 22, 3), np.float32), fps=np.float64(20))
    joints = np.zeros((1, 8, 22, 3), np.float32)
    joints[0, 3, 5, 1] = np.nan
    sub = write_submission(tmp_path / "sub", {"method": "m", "version": "1", "representation": "joints", "fps": 20},
                           {"t0": {"joints": joints}})
    with pytest.raises(ValueError, match=r"samples/t0.npz: joints: non-finite values \(NaN or inf\) in sample 0"):
        render_comparison(sub, data, "t0", tmp_path / "out.png")
    assert not (tmp_path / "out.png").exists()


def test_about_tables_render_as_html_tables_with_every_cell_escaped():
    """A pipe table in about.md becomes an HTML table (right-aligned where the rule says
    ``---:``); its cells are escaped like any about text; a block that only looks like a
    table (no rule row) stays a paragraph."""
    import re
    from hoibench.publish.pages import about_html
    text = ("| row | value |\n|---|---:|\n| <script>x</script> | **1.0** [a](javascript:y) |\n| `ok` | 2 |\n\n"
            "| not | a table |\n| no | rule |")
    out = about_html(text)
    assert out.count("<table") == 1 and "<script" not in out and "javascript:" not in out
    assert re.search(r'<td class="num"><b>1\.0</b> a</td>', out)
    assert "<td>&lt;script&gt;x&lt;/script&gt;</td>" in out and "<td><code>ok</code></td>" in out
    assert "<th>row</th><th class=\"num\">value</th>" in out
    assert "<p>| not | a table | | no | rule |</p>" in out
