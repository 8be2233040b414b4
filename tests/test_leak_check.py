"""``hoibench datasets leak-check``: planted duplicates are found, a clean store has none.

The store is a synthetic InterAct-layout store (12 sequences, sequence split: 8 train, 4
test); :func:`hoibench.datasets.leak_plant.plant_duplicates` adds renamed, mirrored and
shifted (3.3 frames, a fraction of a frame interpolated) copies of train clips to a copy of
its test split. Expected captions, sets and distances are computed here from the files.
"""
from __future__ import annotations

import json
import re
import shutil

import numpy as np
import pytest

from hoibench.cli import main
from hoibench.datasets import leak_motion, leak_text


@pytest.fixture(scope="module")
def stores(tmp_path_factory):
    pytest.importorskip("smplx")
    from interact_fixture import prepare_interact_store
    from hoibench.datasets.leak_plant import plant_duplicates
    base = tmp_path_factory.mktemp("leak")
    raw, clean = base / "raw", base / "clean"
    prepare_interact_store(raw, clean, fps=20.0)
    planted = plant_duplicates(clean, base / "planted", n=2, seed=0)
    return clean, base / "planted", planted


def _captions(store, cid):
    p = store / "texts" / f"{cid}.txt"
    return [line.split("#")[0].strip() for line in p.read_text().splitlines()] if p.is_file() else []


def _norm(c):
    return " ".join(re.sub(r"[^a-z0-9 ]", " ", c.lower()).split())


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_planted_duplicates_found_and_nothing_else(stores, capsys, tmp_path):
    clean, planted_store, planted = stores
    assert sorted(p["kind"] for p in planted.values()) == ["mirrored"] * 2 + ["renamed"] * 2 + ["shifted"] * 2
    code, out, err = _run(capsys, "datasets", "leak-check", str(planted_store), "--out", str(tmp_path / "r"),
                          "--fail-on-leak")
    assert code == 1 and "6 pairs" in out
    report = json.loads((tmp_path / "r" / "leak_check.json").read_text())
    assert (tmp_path / "r" / "leak_check.md").read_text().startswith("# Leak check")
    dups = {d["query"]: d for d in report["motion"]["duplicates"]}
    assert set(dups) == set(planted)                    # every planted clip, no original test clip
    for cid, p in planted.items():
        d = dups[cid]
        assert d["reference"] == p["source"]
        assert d["variant"] == ("mirror" if p["kind"] == "mirrored" else "same")
        assert d["coverage"] == 1.0
        if p["kind"] == "shifted":                      # the crop starts 3.3 frames (20 fps) in
            assert abs(d["offset_s"] - 3.3 / 20) <= 0.25 / 20 / 2 + 1e-9
            assert 0 < d["distance_m"] < 0.005
        else:
            assert d["offset_s"] == 0 and d["distance_m"] < 1e-4
    kinds = {t["query"]: t["kind"] for t in report["text"]["duplicates"]}
    want = {"renamed": "exact", "shifted": "normalised", "mirrored": "ngram"}
    for cid, p in planted.items():
        assert kinds[cid] == want[p["kind"]]
        assert dups[cid]["caption_match"] == want[p["kind"]]
    assert report["summary"]["by_variant"] == {"same": 4, "mirror": 2}


def test_clean_store_has_no_motion_duplicates(stores):
    from hoibench.datasets.leak_check import leak_check
    from hoibench.datasets.store import Store
    clean, _, _ = stores
    report = leak_check(clean)
    assert report["motion"]["duplicates"] == [] and report["summary"]["motion_duplicates"] == 0
    near = report["summary"]["nearest_distance_m"]
    assert near is None or near["min"] > 3 * leak_motion.THRESHOLD_M     # a margin, not a hairline
    st = Store(clean)
    test, train = st.clip_ids("test"), st.clip_ids("train")
    # captions: the expected duplicates from the text files themselves
    train_norm = {_norm(c) for t in train for c in _captions(clean, t)}
    expect = sorted(t for t in test if any(_norm(c) in train_norm for c in _captions(clean, t)))
    got = sorted(t["query"] for t in report["text"]["duplicates"] if t["kind"] in ("exact", "normalised"))
    assert got == expect
    # object and subject sets, from the manifest and clip files
    objs = {c["id"]: c["object"] for c in st.manifest["clips"]}
    shared = sorted({objs[t] for t in test} & {objs[t] for t in train})
    assert report["sets"]["objects"]["shared"] == shared
    subj = {c: str(st.load(c, keys=("subject",))["subject"]) for c in test + train}
    assert report["sets"]["subjects"]["shared"] == sorted({subj[t] for t in test} & {subj[t] for t in train})
    assert report["sets"]["subjects"]["query_clips_with_shared"] == \
        sum(subj[t] in {subj[x] for x in train} for t in test)


def test_against_another_store(stores):
    from hoibench.datasets.leak_check import leak_check
    from hoibench.datasets.store import Store
    clean, planted_store, planted = stores
    report = leak_check(planted_store, against=clean)
    assert report["reference"]["split"] == "all"
    best = {}
    for d in report["motion"]["duplicates"]:
        best.setdefault(d["query"], d)                  # sorted by distance: the first is the closest
    test = Store(planted_store).clip_ids("test")
    assert set(best) == set(test)                       # the clean store holds every test clip or its source
    for cid in test:
        assert best[cid]["reference"] == planted.get(cid, {}).get("source", cid)
    # the store against itself: a clip never matches itself
    own = leak_check(clean, against=clean)
    assert all(d["query"] != d["reference"] for d in own["motion"]["duplicates"])


def test_bad_input_is_one_line(stores, capsys, tmp_path):
    clean, _, _ = stores
    code, _, err = _run(capsys, "datasets", "leak-check", str(tmp_path / "nowhere"))
    assert code == 2 and err.count("\n") == 1 and "manifest.json" in err and "Traceback" not in err
    code, _, err = _run(capsys, "datasets", "leak-check", str(clean), "--split", "val")
    assert code == 2 and err.count("\n") == 1 and "clips[].split" in err and "'val'" in err
    only_train = tmp_path / "train_only"
    shutil.copytree(clean, only_train)
    m = json.loads((only_train / "manifest.json").read_text())
    for c in m["clips"]:
        c["split"] = "train"
    (only_train / "manifest.json").write_text(json.dumps(m))
    code, _, err = _run(capsys, "datasets", "leak-check", str(only_train))
    assert code == 2 and err.count("\n") == 1
    assert f"{only_train / 'manifest.json'}: clips[].split: no clip in split 'test'" in err
    bad = tmp_path / "bad_clip"
    shutil.copytree(clean, bad)
    victim = _first_test_id(bad)
    np.savez(bad / "clips" / f"{victim}.npz", joints=np.zeros((5, 21, 3), np.float32), fps=np.float64(20))
    code, _, err = _run(capsys, "datasets", "leak-check", str(bad))
    assert code == 2 and err.count("\n") == 1 and f"{victim}.npz: joints:" in err
    code, _, err = _run(capsys, "datasets", "leak-check", str(clean), "--threshold", "-1")
    assert code == 2 and "--threshold" in err


def _first_test_id(root):
    from hoibench.datasets.store import Store
    return Store(root).clip_ids("test")[0]


def test_deterministic(stores, capsys, tmp_path):
    _, planted_store, _ = stores
    for name in ("a", "b"):
        assert _run(capsys, "datasets", "leak-check", str(planted_store), "--out", str(tmp_path / name))[0] == 0
    for f in ("leak_check.json", "leak_check.md"):
        assert (tmp_path / "a" / f).read_bytes() == (tmp_path / "b" / f).read_bytes()


def _walker(T=60, seed=0):
    """A clip with a moving root, varying heading and limb swing (not from the store code)."""
    from hoibench.core.skeleton import SMPL_REST_JOINTS
    rng = np.random.default_rng(seed)
    t = np.arange(T)[:, None, None] / 20
    J = SMPL_REST_JOINTS[None] + np.array([0, 1.0, 0]) + 0.1 * np.sin(2 * np.pi * rng.uniform(0.3, 1.5, (22, 3)) * t
                                                                      + rng.uniform(0, 6, (22, 3)))
    J[..., 2] += np.linspace(0, 1.5, T)[:, None]
    return J.astype(np.float32)


def test_distance_invariances_and_subframe_shift():
    a = _walker()
    yaw = 1.1
    R = np.array([[np.cos(yaw), 0, np.sin(yaw)], [0, 1, 0], [-np.sin(yaw), 0, np.cos(yaw)]])
    moved = (a @ R.T + np.array([3.0, 0.0, -2.0])).astype(np.float32)      # yaw + floor translation
    assert leak_motion.overlap_distance(moved, a, 0)[0] < 1e-5
    lifted = a + np.array([0, 0.05, 0], np.float32)                         # height is kept: 5 cm apart
    assert abs(leak_motion.overlap_distance(lifted, a, 0)[0] - 0.05) < 1e-5
    mirrored = leak_motion.mirror(moved)
    assert leak_motion.overlap_distance(mirrored, a, 0)[0] > 0.01
    assert leak_motion.overlap_distance(leak_motion.mirror(mirrored), a, 0)[0] < 1e-5
    # a crop half a frame in: linear interpolation of the same clip at offset 10.5
    half = 0.5 * (a[10:40] + a[11:41])
    d, n = leak_motion.overlap_distance(half, a, 10.5)
    assert d < 1e-5 and n == 30
    assert leak_motion.overlap_distance(half, a, 10)[0] > 1e-3
    ms = leak_motion.match_sets([half, leak_motion.mirror(a[5:50])], [_walker(seed=1), a])
    best = {m.query: m for m in ms if m.distance_m < leak_motion.THRESHOLD_M}
    assert (best[0].ref, best[0].variant, best[0].offset) == (1, "same", 10.5)
    assert (best[1].ref, best[1].variant, best[1].offset) == (1, "mirror", 5.0)
    # the reverse: a train clip cropped out of the test clip (query frame t on reference t - 20)
    ms = leak_motion.match_sets([a], [_walker(seed=2), a[20:52].copy()])
    hit = [m for m in ms if m.distance_m < leak_motion.THRESHOLD_M]
    assert [(m.ref, m.variant, m.offset, m.overlap) for m in hit] == [(1, "same", -20.0, 32)]


def test_caption_kinds():
    assert leak_text.normalise("  A person, LIFTS the box!! ") == "a person lifts the box"
    q = [["A person lifts the box."], ["a person, LIFTS the box"], ["the man pushes a heavy chair across the room"],
         ["nothing alike"]]
    r = [["x y"], ["A person lifts the box."], ["the man pushes a heavy chair across the floor"],
         ["a person lifts the box"]]
    got = {m.query: (m.ref, m.kind, m.jaccard, m.shared_by) for m in leak_text.match_captions(q, r)}
    # 3-grams of the pushes captions: 7 each, 6 shared -> 6 / 8
    assert got == {0: (1, "exact", 1.0, 2), 1: (1, "normalised", 1.0, 2), 2: (2, "ngram", 0.75, 1)}
    assert leak_text.match_captions(q, r, threshold=0.8)[-1].query == 1
