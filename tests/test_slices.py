"""Per-slice tables and the slices where two methods differ most, on constructed values."""
from __future__ import annotations

import numpy as np
import pytest

from hoibench.scoring.slices import (MIN_SLICE_CLIPS, contact_label, first_verb, slice_differences, slice_tables)


def test_contact_labels_name_the_touching_parts():
    c = np.zeros((5, 22), bool)
    assert contact_label(c) == "none" and contact_label(None) == "none"
    c[2, 20] = True
    assert contact_label(c) == "hands"
    c[4, 10] = True
    assert contact_label(c) == "hands+feet"
    s = np.zeros((5, 22), bool)
    s[:, 0] = True
    assert contact_label(s) == "sitting/lying"


def test_first_verb_skips_auxiliaries():
    from hoibench.evaluator.text import parse_text_file
    cap = parse_text_file("a person is lifting the box.#a/DET person/NOUN be/AUX lift/VERB the/DET box/NOUN#0.0#0.0\n")[0]
    assert first_verb(cap) == "lift"


def test_slice_tables_are_the_means_over_each_labels_clips():
    ids = ["a", "b", "c", "d"]
    labels = {"object": {"a": "box", "b": "box", "c": "ball", "d": "ball"}}
    vals = {"cd": np.array([1.0, 3.0, 10.0, np.nan])}
    t = slice_tables(labels, ids, vals)["object"]
    assert t["box"] == {"n": 2, "cd": 2.0}
    assert t["ball"] == {"n": 2, "cd": 10.0}                 # the NaN clip is left out of the mean, not the count


def test_the_slice_with_a_planted_difference_comes_first():
    rng = np.random.default_rng(0)
    n = 60
    ids = [f"c{i:02d}" for i in range(n)]
    objects = {cid: ("chair" if i < 10 else "box" if i < 35 else "ball") for i, cid in enumerate(ids)}
    lengths = {cid: ("short" if i % 2 else "long") for i, cid in enumerate(ids)}
    a = {"cd": rng.normal(0.0, 0.01, n)}
    b = {"cd": a["cd"] + rng.normal(0.0, 0.01, n)}
    b["cd"][:10] += 0.05                                     # B is worse on chairs only
    gaps = slice_differences({"object": objects, "motion_length": lengths}, ids, a, b, ["cd"], top=3)
    first = gaps[0]
    assert (first["slice"], first["label"], first["metric"], first["n"]) == ("object", "chair", "cd", 10)
    assert first["diff"] == pytest.approx(np.mean(b["cd"][:10] - a["cd"][:10]))
    assert first["z"] > 3 and len(gaps) == 3
    # a label with fewer clips than MIN_SLICE_CLIPS is never named
    few = {cid: ("rare" if i < MIN_SLICE_CLIPS - 1 else "common") for i, cid in enumerate(ids)}
    assert all(g["label"] != "rare" for g in slice_differences({"object": few}, ids, a, b, ["cd"], top=10))


def test_identical_methods_show_no_slice_gap():
    ids = [f"c{i}" for i in range(12)]
    v = {"cd": np.linspace(0, 1, 12)}
    gaps = slice_differences({"object": {c: ("x" if i < 6 else "y") for i, c in enumerate(ids)}}, ids, v, v, ["cd"])
    assert all(g["diff"] == 0.0 and g["z"] == 0.0 for g in gaps)
