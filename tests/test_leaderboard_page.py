"""The rendered track: rank numbers on methods and baselines only, reference and reported rows
in their own bands, a legend for row styles and plot colours, "n/a (K = 1)" for a CI that
cannot move at K = 1, the flags next to the method name, and scatter labels that do not
overlap."""
from __future__ import annotations

import csv
import io
import json
import re

import pytest

from hoibench.publish import leaderboard as lb
from hoibench.publish.pages import K1_CI, build, fmt, place_labels

EV = "e" * 64


def _result(fid: float, r1: float, k: int = 1, ci: float = 0.0) -> dict:
    return {"metrics": {"fid": {"mean": fid, "ci95": ci, "n": 20},
                        "r_precision_top1": {"mean": r1, "ci95": 0.02, "n": 20}},
            "evaluator_id": EV, "protocol": "synthetic-clean", "protocol_version": "1.1", "toolkit_version": "0.6.0",
            "replications": 20, "complete": True, "overrides": [],
            "counts": {"samples_per_prompt": k, "scored_ids": 34, "test_ids": 34, "missing_ids": []},
            "submission": {"flags": {"samples_per_prompt": k}}, "representation": {"hml263": "hml263-clean-1.0"}}


ROWS = (("GT (real motion)", 0.0, 0.61, "ground-truth", 1), ("mismatched texts", 0.0, 0.03, "reference", 1),
        ("Model B", 0.30, 0.50, "method", 1), ("Baseline A", 0.20, 0.55, "baseline", 1),
        ("Model C, K = 30", 0.25, 0.52, "method", 30), ("GT + 1 cm noise", 0.56, 0.51, "reference", 1))


@pytest.fixture(scope="module")
def track(tmp_path_factory):
    tmp_path = tmp_path_factory.mktemp("page")
    t = tmp_path / "leaderboards" / "synthetic"
    for name, fid, r1, role, k in ROWS:
        p = tmp_path / f"{lb.slug(name)}.json"
        p.write_text(json.dumps(_result(fid, r1, k, ci=0.004 if k > 1 else 0.0)))
        lb.add_result(p, t, method=name, role=role)
    paper = {**lb.entry_from_result(_result(0.1, 0.6), method="Paper X", track="synthetic", source="reported"),
             "citation": "X et al. 2025, Table 1", "role": "method", "evaluator_id": "f" * 64}
    lb.write_entry(paper, t / "entries")
    return t


@pytest.fixture(scope="module")
def built(track):
    """The track rendered once (README.md, leaderboard.csv, index.html, plots)."""
    return build(track)


def test_bands_and_ranks(track):
    entries = lb.order(lb.load_track(track))
    assert [e["method"] for e in entries] == ["GT (real motion)", "Baseline A", "Model C, K = 30", "Model B",
                                              "mismatched texts", "GT + 1 cm noise", "Paper X"]
    assert lb.ranks(entries) == [None, 1, 2, 3, None, None, None]
    assert [lb.band(e) for e in entries] == ["ground-truth", "ranked", "ranked", "ranked", "reference", "reference",
                                             "reported"]


def test_html_ranks_methods_only_and_has_a_legend(built):
    page = built["index.html"].read_text()
    rows = re.findall(r'<tr class="(\w+)"><td data-v="([^"]*)">([^<]*)</td><td class="name" data-v="([^"]*)"', page)
    numbered = {name: num for cls, _, num, name in rows}
    assert numbered == {"GT (real motion)": "", "Baseline A": "1", "Model C, K = 30": "2", "Model B": "3",
                        "mismatched texts": "", "GT + 1 cm noise": "", "Paper X": ""}
    # mismatched texts has FID 0 (the best) yet no rank, in the reference band after the ranked rows
    assert page.index("Model B") < page.index('<tbody class="band-reference">') < page.index(">mismatched texts<")
    legend = page[page.index('<div class="legend">'):page.index("</div>", page.index('<div class="legend">'))]
    for words in ("ranked by FID", "reference rows", "Bar and point colours", "#dd6b20", "#718096", K1_CI):
        assert words in legend
    # the flags column comes right after the method name (visible without scrolling)
    head = page[page.index("<thead>"):page.index("</thead>")]
    assert head.index(">method<") < head.index(">flags<") < head.index("FID")
    k30 = page[page.index('data-v="Model C, K = 30"'):]
    assert k30.index("K = 30") < k30.index("0.250")


def test_a_k1_ci_of_zero_reads_not_applicable(built):
    assert fmt({"mean": 0.163, "ci95": 0.0}, 1) == f"0.163 ± {K1_CI}"
    assert fmt({"mean": 0.163, "ci95": 0.0}, 30) == "0.163 ± 0.000"      # K > 1: a measured zero spread
    assert fmt({"mean": 0.163, "ci95": 0.004}, 1) == "0.163 ± 0.004"
    assert fmt({"mean": 0.024, "ci95": 0.0004}, 30) == "0.024 ± 4.0e-04"  # a real spread is never shown as 0
    paths = built
    md, page = paths["README.md"].read_text(), paths["index.html"].read_text()
    assert "± 0.000" not in md and md.count(K1_CI) >= 4 and K1_CI in page
    gt = next(line for line in md.splitlines() if "GT (real motion)" in line)
    assert f"0.000 ± {K1_CI}" in gt and "0.610 ± 0.020" in gt             # R@1 keeps its CI
    assert "± 0.004" in next(line for line in md.splitlines() if "Model C" in line)


def test_markdown_and_csv_number_only_ranked_rows(built):
    paths = built
    lines = [ln for ln in paths["README.md"].read_text().splitlines() if ln.startswith("|")]
    ranks = {ln.split("|")[2].strip().strip("*"): ln.split("|")[1].strip() for ln in lines[2:]}
    assert ranks["Baseline A"] == "1" and ranks["Model B"] == "3"
    assert ranks["mismatched texts"] == ranks["GT (real motion)"] == ranks["Paper X (X et al. 2025, Table 1)"] == ""
    assert any("reference rows" in ln for ln in lines)
    rows = list(csv.DictReader(io.StringIO(paths["leaderboard.csv"].read_text())))
    assert [(r["method"], r["rank"], r["band"]) for r in rows][:5] == [
        ("GT (real motion)", "", "ground-truth"), ("Baseline A", "1", "ranked"), ("Model C, K = 30", "2", "ranked"),
        ("Model B", "3", "ranked"), ("mismatched texts", "", "reference")]


def test_scatter_labels_do_not_overlap():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.text import Text
    fig, ax = plt.subplots(figsize=(5.5, 4.2))
    # a crowded corner: five points within 0.05 of each other, and two pairs on top of each other
    pts = [(0.0, 0.61), (0.20, 0.61), (0.20, 0.58), (0.21, 0.56), (0.16, 0.49), (0.16, 0.47), (1.95, 0.06),
           (2.05, 0.06), (0.0, 0.03), (0.0, 0.03)]
    ax.scatter(*zip(*pts))
    ax.set_xlim(-0.1, 2.2)
    fig.tight_layout()
    texts = place_labels(ax, pts, [f"method number {i}" for i in range(len(pts))])
    fig.canvas.draw()
    boxes = [Text.get_window_extent(t, fig.canvas.get_renderer()) for t in texts]
    assert len(boxes) == len(pts)
    clashes = [(i, j) for i in range(len(boxes)) for j in range(i) if boxes[i].overlaps(boxes[j])]
    assert clashes == []
    assert all(fig.bbox.contains(b.x0, b.y0) and fig.bbox.contains(b.x1, b.y1) for b in boxes)
    plt.close(fig)


def test_training_cells_shorten_hardware_names():
    from hoibench.publish.pages import budget
    e = {"role": "baseline", "source": "reproduced", "submission_source": {"training": {
        "steps": 1500, "parameters": 1780000, "wall_seconds": 612.0,
        "hardware": "CPU Intel(R) Xeon(R) Processor @ 2.80GHz, 1 thread(s)"}}}
    assert budget(e) == "1,500 steps, 1.78 M params, 10.2 min, CPU Intel Xeon 2.80GHz, 1 thread"


def test_a_resumed_runs_time_says_it_is_the_last_segments():
    from hoibench.publish.pages import budget
    e = {"role": "baseline", "source": "reproduced", "submission_source": {"training": {
        "steps": 1500, "parameters": 1815320, "wall_seconds": 2007.3, "resumed_from": 1308, "hardware": "cpu"}}}
    assert budget(e) == "1,500 steps, 1.82 M params, 33.5 min since step 1,308, cpu"
    e["submission_source"]["training"]["resumed_from"] = 0
    assert budget(e) == "1,500 steps, 1.82 M params, 33.5 min, cpu"
