"""compare --paired: the paired bootstrap against direct computations on constructed results."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from hoibench.metrics.embedding import fid
from hoibench.metrics.resampling import bootstrap_p, bootstrap_weights, draw_fids, holm, weighted_fid

N, D = 40, 8


def _result(tmp_path: Path, name: str, motion: np.ndarray, real: np.ndarray, cd: np.ndarray,
            evaluator: str = "e" * 64, keep: slice = slice(None)) -> Path:
    """A result of the clips ``keep`` of the N constructed ones."""
    from hoibench.scoring.clip_data import write_clip_data
    from hoibench.scoring.results import metric_entry
    ids = [f"clip_{i:03d}" for i in range(N)][keep]
    rng = np.random.default_rng(7)
    text = (real + 0.05 * rng.standard_normal(real.shape))[keep]    # captions near their real motion
    motion, real, cd = motion[keep], real[keep], cd[keep]
    arrays = {"ids": np.array(ids), "motion": motion[None].astype(np.float32), "real": real.astype(np.float32),
              "text": text.astype(np.float32), "text_offsets": np.arange(len(ids) + 1),
              "physical": cd[None, :, None], "physical_samples": np.array([0]), "physical_names": np.array(["cd"])}
    result = {"format": "hoibench-result-2", "protocol": "synthetic-clean", "protocol_version": "1.1",
              "evaluator_id": evaluator, "dataset": "synthetic", "store_config_sha256": "s" * 64,
              "submission": {"method": name},
              "counts": {"test_ids": N, "scored_ids": len(ids), "samples_per_prompt": 1},
              "metrics": {m: metric_entry(m, 0.0, 0.0, 20) for m in
                          ("fid", "r_precision_top1", "r_precision_top2", "r_precision_top3", "mm_dist", "diversity",
                           "cd")}}
    path = tmp_path / f"{name}.json"
    write_clip_data(result, arrays, path)
    path.write_text(json.dumps(result))
    return path


@pytest.fixture
def world():
    rng = np.random.default_rng(0)
    real = rng.standard_normal((N, D))
    return rng, real


def test_weighted_fid_is_the_fid_of_the_drawn_rows_in_both_forms(world):
    rng, real = world
    gen = real + 0.3 * rng.standard_normal(real.shape)
    assert weighted_fid(real, gen, np.ones(N, np.int64)) == pytest.approx(fid(real, gen), rel=1e-6)
    w = bootstrap_weights(N, 1, 3)[0]
    rows = np.repeat(np.arange(N), w)
    assert weighted_fid(real, gen, w) == pytest.approx(fid(real[rows], gen[rows]), rel=1e-6)
    wide = rng.standard_normal((N, 64))                  # fewer clips than dimensions: the small form
    wide_gen = wide + 0.2
    assert weighted_fid(wide, wide_gen, w) == pytest.approx(fid(wide[rows], wide_gen[rows]), rel=1e-5)


@pytest.mark.parametrize("n, d, rank, rtol_ref", [
    (300, 16, 16, 1e-8),        # many more distinct clips than dimensions, full rank
    (120, 64, 64, 1e-7),        # about as many: weighted_fid's eigh route is itself off by ~1e-8 here
    (400, 24, 10, 1e-3),        # rank-deficient real embeddings: the eigh route's roots of rounding, ~5e-5
    (40, 64, 64, 0.0)])         # fewer clips than dimensions: weighted_fid's nuclear-norm form, bit for bit
def test_per_draw_fids_are_the_fid_of_the_drawn_rows(n, d, rank, rtol_ref):
    """draw_fids (the real side's factor shared by every result; eigenvalues of R^T C_g R) is
    the FID of the drawn rows to 1e-8 relative: against the nuclear-norm identity
    ``tr sqrt(a^T a b^T b) = |a b^T|_*`` (valid in every regime, no roots of eigenvalues), and
    against weighted_fid and the direct FID of the repeated rows where those forms are themselves
    that accurate (``rtol_ref`` where they are not: measured at 1.1e-8 and 6e-5 against the
    identity, which a 40-digit computation confirms to 1e-11)."""
    from hoibench.metrics.resampling import _centred, _small_form
    rng = np.random.default_rng(n + d + rank)
    real = rng.standard_normal((n, rank)) @ rng.standard_normal((rank, d))
    gens = [real + s * rng.standard_normal(real.shape) + s for s in (0.05, 0.3, 1.0)]
    for w in bootstrap_weights(n, 4, 1):
        rows = np.repeat(np.arange(n), w)
        assert ((w > 0).sum() >= d) == (n > d)                  # which regime the case tests
        got = draw_fids(real, gens, w)
        mu, a, _ = _centred(real, w)
        np.testing.assert_allclose(got, [_small_form(mu, a, *_centred(g, w)[:2]) for g in gens], rtol=1e-8, atol=0)
        np.testing.assert_allclose(got, [weighted_fid(real, g, w) for g in gens], rtol=rtol_ref, atol=0)
        if rtol_ref:
            np.testing.assert_allclose(got, [fid(real[rows], g[rows]) for g in gens], rtol=rtol_ref, atol=0)


def test_comparing_four_results_gives_each_pair_the_numbers_of_that_pair_alone(world, tmp_path):
    """compare A B C D shares A's and the ground truth's draws between the pairs (and a result
    of other clips gets its own draws): each pair is bit for bit the pair compared alone."""
    from hoibench.scoring.paired import paired_compare
    rng, real = world
    cd = np.abs(rng.normal(0.01, 0.002, N))
    a, b, c = (_result(tmp_path, k, real + s * rng.standard_normal(real.shape), real, cd * (1 + s))
               for k, s in (("a", 0.1), ("b", 0.2), ("c", 0.15)))
    d = _result(tmp_path, "d", real + 0.3 * rng.standard_normal(real.shape), real, cd, keep=slice(3, None))
    together = paired_compare([a, b, c, d], resamples=2000, seed=3, executor="processes:2")
    assert [p["n_clips"] for p in together["pairs"]] == [N, N, N - 3]
    for other, pair in zip((b, c, d), together["pairs"]):
        alone = paired_compare([a, other], resamples=2000, seed=3)["pairs"][0]
        assert json.dumps(pair, sort_keys=True) == json.dumps(alone, sort_keys=True)


def test_holm_and_the_bootstrap_p_value_as_defined():
    assert holm([0.01, 0.04, 0.03]) == pytest.approx([0.03, 0.06, 0.06])
    assert holm([0.5, 0.001]) == pytest.approx([0.5, 0.002])
    assert bootstrap_p(np.zeros(100)) == 1.0
    assert bootstrap_p(np.ones(1999)) == pytest.approx(2 / 2000)


def test_a_planted_difference_is_found_and_identical_results_are_not_distinguished(world, tmp_path):
    from hoibench.scoring.paired import paired_compare
    rng, real = world
    cd = np.abs(rng.normal(0.01, 0.002, N))
    good = _result(tmp_path, "good", real + 0.05 * rng.standard_normal(real.shape), real, cd)
    bad = _result(tmp_path, "bad", real + 1.0 * rng.standard_normal(real.shape), real, cd + 0.01)
    same = _result(tmp_path, "same", np.load(good.with_name("good.clips.npz"))["motion"][0], real, cd)
    cmp = paired_compare([good, bad, same], resamples=2000, seed=0)
    worse, twin = cmp["pairs"]
    assert worse["a"] == "good" and worse["b"] == "bad" and worse["n_clips"] == N
    assert worse["metrics"]["fid"]["diff"] > 0 and worse["metrics"]["fid"]["ci95"][0] > 0
    assert worse["metrics"]["fid"]["verdict"] == "A better"
    assert worse["metrics"]["cd"]["diff"] == pytest.approx(0.01) and worse["metrics"]["cd"]["verdict"] == "A better"
    assert worse["metrics"]["mm_dist"]["verdict"] == "A better"
    for m, row in twin["metrics"].items():
        lo, hi = row["ci95"]
        assert lo <= 0 <= hi and row["p"] == 1.0 and row["verdict"] == f"not distinguishable on {N} clips", m
    ps = [r["p"] for r in worse["metrics"].values()]
    assert [r["p_holm"] for r in worse["metrics"].values()] == pytest.approx(holm(ps))


def test_the_same_seed_gives_the_same_interval_on_any_executor(world, tmp_path):
    from hoibench.scoring.paired import paired_compare
    rng, real = world
    cd = np.abs(rng.normal(0.01, 0.002, N))
    a = _result(tmp_path, "a", real + 0.1 * rng.standard_normal(real.shape), real, cd)
    b = _result(tmp_path, "b", real + 0.2 * rng.standard_normal(real.shape), real, cd * 1.1)
    serial = paired_compare([a, b], resamples=2000, seed=5)
    pool = paired_compare([a, b], resamples=2000, seed=5, executor="processes:2")
    assert json.dumps(serial, sort_keys=True) == json.dumps(pool, sort_keys=True)
    assert paired_compare([a, b], resamples=2000, seed=6) != serial


def test_results_of_another_evaluator_are_refused_in_one_line(world, tmp_path, capsys):
    from hoibench.cli import main
    rng, real = world
    cd = np.ones(N) * 0.01
    a = _result(tmp_path, "a", real, real, cd)
    b = _result(tmp_path, "b", real, real, cd, evaluator="f" * 64)
    assert main(["compare", str(a), str(b), "--paired"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "b.json: field evaluator_id" in err[0] and "one evaluator" in err[0]


def test_a_result_whose_per_clip_file_changed_is_refused(world, tmp_path):
    from hoibench.scoring.paired import paired_compare
    rng, real = world
    a = _result(tmp_path, "a", real, real, np.ones(N))
    b = _result(tmp_path, "b", real + 0.1, real, np.ones(N))
    with open(b.with_name("b.clips.npz"), "ab") as f:
        f.write(b"x")
    with pytest.raises(ValueError, match=r"b.clips.npz: per_clip_data.sha256"):
        paired_compare([a, b])


def test_evaluate_keeps_per_clip_data_and_clip_intervals_and_compare_paired_reads_them(
        annotated_store_with_evaluator, tmp_path, capsys):
    from hoibench.cli import main
    _, data, ev = annotated_store_with_evaluator
    for kind, sigma in (("gt", None), ("gt-noise", "0.05")):
        args = ["submission", "from-store", str(data), "--out", str(tmp_path / kind)] if kind == "gt" else \
            ["submission", "reference", str(data), "--kind", kind, "--sigma", sigma, "--out", str(tmp_path / kind)]
        assert main(args) == 0
        assert main(["evaluate", str(tmp_path / kind), "--data", str(data), "--evaluator", str(ev),
                     "--out", str(tmp_path / f"{kind}.json")]) == 0
    res = json.loads((tmp_path / "gt.json").read_text())
    ref = res["per_clip_data"]
    assert ref["file"] == "gt.clips.npz" and (tmp_path / ref["file"]).stat().st_size == ref["bytes"]
    cd = res["metrics"]["cd"]
    lo, hi = cd["clips"]["ci95"]
    assert lo <= cd["mean"] <= hi and cd["clips"]["over"] == "test clips"       # CD is a mean over clips
    assert "clips" in res["metrics"]["fid"] and "clips" in res["metrics"]["r_precision_top1"]
    capsys.readouterr()
    assert main(["compare", str(tmp_path / "gt.json"), str(tmp_path / "gt-noise.json"), "--paired",
                 "--out", str(tmp_path / "cmp.json")]) == 0
    cmp = json.loads((tmp_path / "cmp.json").read_text())
    pair = cmp["pairs"][0]
    assert pair["n_clips"] == res["counts"]["scored_ids"] and cmp["resamples"] == 2000
    fid = pair["metrics"]["fid"]
    assert set(fid) >= {"diff", "ci95", "p", "p_holm", "verdict"} and fid["diff"] > 0
    assert pair["metrics"]["jitter_mps3"]["verdict"] == "A better"            # 5 cm noise jitters every frame
    out = capsys.readouterr().out
    assert "A better" in out
    assert main(["compare", str(tmp_path / "gt.json"), str(tmp_path / "gt-noise.json"), "--paired",
                 "--out", str(tmp_path / "cmp.json")]) == 2                   # kept unless --overwrite
    assert "exists already" in capsys.readouterr().err
    # slices: every scored clip has a label per slice, the tables count every clip once
    sl = res["slices"]
    ids = set(np.load(tmp_path / "gt.clips.npz")["ids"].tolist())
    for name in ("object", "verb", "contact", "source", "text_length", "motion_length"):
        assert set(sl["labels"][name]) == ids
        assert sum(row["n"] for row in sl["tables"][name].values()) == len(ids)
    objects = {}
    for cid, obj in sl["labels"]["object"].items():
        objects.setdefault(obj, []).append(cid)
    assert set(objects) <= {str(np.load(data / "clips" / f"{c}.npz")["object_name"]) for c in ids}
    assert pair["slices"] and all(g["n"] >= 3 for g in pair["slices"])
    assert "slices where they differ most" in out


def test_legacy_protocols_embed_the_windows_the_physical_metrics_see(annotated_store_with_evaluator, tmp_path):
    """ChainHOI's loader feeds its evaluator the cropped motions: under a legacy protocol with
    crop_embeddings, each clip is embedded on the replication-0 window of length_crop."""
    from hoibench.datasets.store import Store
    from hoibench.evaluator.backends import load_evaluator
    from hoibench.metrics.legacy_rules import length_window
    from hoibench.scoring.evaluate import evaluate
    from hoibench.scoring.hoi import _real_features
    from hoibench.scoring.submission_write import from_store
    from hoibench.tracks.protocol import get_protocol
    _, data, ev = annotated_store_with_evaluator
    sub = from_store(data, tmp_path / "gt")
    store, model = Store(data), load_evaluator(ev, allow_failed_gate=True)
    cropped: dict = {}
    proto = get_protocol("synthetic-legacy")
    evaluate(sub, data, ev, protocol=proto, allow_protocol_mismatch=True, clip_data=cropped)
    assert proto.crop_embeddings and not get_protocol("synthetic-legacy@1.2").crop_embeddings
    frames = {c["id"]: c["frames"] for c in store.manifest["clips"]}
    ids = [str(i) for i in cropped["ids"]][:6]
    for i, cid in enumerate(ids):
        start, length = length_window(frames[cid], "unit4_random", proto.seed_for(f"length_crop/{cid}", 0))
        rows = _real_features(store, cid, model)
        want = model.embed_motion([rows[start:start + length]])[0]
        np.testing.assert_allclose(cropped["real"][i], want, atol=1e-5)
        np.testing.assert_allclose(cropped["motion"][0, i], want, atol=1e-3)     # the GT sample, re-encoded
        if length < len(rows):                  # the whole clip embeds elsewhere (the crop mattered)
            assert not np.allclose(model.embed_motion([rows])[0], want, atol=1e-5), cid


def test_set_level_draws_are_debiased_so_the_interval_is_centred_on_the_value():
    """A bootstrap draw repeats clips, which inflates FID more for a set far from the real one:
    on a constructed far set the raw draws run well above FID on all clips.
    The draws the comparisons use are less their estimated bias: their mean is the point
    value, the interval contains it, and their spread is the raw draws' spread."""
    from hoibench.metrics.resampling import debiased
    from hoibench.scoring.paired import _set_level_debiased, _set_level_draws, clip_intervals
    from hoibench.tracks.protocol import get_protocol
    rng = np.random.default_rng(3)
    real = rng.standard_normal((30, 12))
    far = real + 1.5 * rng.standard_normal((30, 12))
    W = bootstrap_weights(30, 400, 0).astype(np.float64)
    raw = _set_level_draws([far], real, W, 50, 0)["fid"][:, 0]
    point = weighted_fid(real, far, np.ones(30))
    assert raw.mean() > 1.15 * point and np.mean(raw > point) > 0.85    # the raw draws run high
    got, full = _set_level_debiased([far], real, W, 50, 0)
    assert full["fid"][0] == pytest.approx(point, rel=1e-12)
    assert got["fid"][:, 0].mean() == pytest.approx(point, rel=1e-12)
    np.testing.assert_allclose(got["fid"][:, 0] - raw, point - raw.mean(), rtol=1e-12)
    lo, hi = np.percentile(got["fid"][:, 0], [2.5, 97.5])
    assert lo < point < hi
    np.testing.assert_array_equal(debiased(np.array([[1.0, np.nan], [3.0, 5.0]]), [1.0, 2.0]),
                                  np.array([[0.0, np.nan], [2.0, 2.0]]))
    arrays = {"ids": np.array([f"c{i:02d}" for i in range(30)]), "motion": far[None].astype(np.float32),
              "real": real.astype(np.float32), "text": np.zeros((0, 12), np.float32),
              "text_offsets": np.zeros(31, np.int64), "physical": np.zeros((1, 30, 0)),
              "physical_samples": np.array([0]), "physical_names": np.array([], dtype=str)}
    iv = clip_intervals(arrays, get_protocol("multibody-synthetic"))["fid"]["ci95"]
    assert iv[0] < weighted_fid(real.astype(np.float32).astype(np.float64),
                                far.astype(np.float32).astype(np.float64), np.ones(30)) < iv[1]


def test_the_same_file_twice_and_another_split_size_are_refused_in_one_line(world, tmp_path, capsys):
    from hoibench.cli import main
    rng, real = world
    cd = np.ones(N) * 0.01
    a = _result(tmp_path, "a", real, real, cd)
    assert main(["compare", str(a), str(tmp_path / "." / "a.json"), "--paired"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "given twice" in err[0]
    b = _result(tmp_path, "b", real, real, cd)
    other = json.loads(b.read_text())
    other["counts"]["test_ids"] = N + 5                     # a store prepared alike, with other clips
    b.write_text(json.dumps(other))
    assert main(["compare", str(a), str(b), "--paired"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"b.json: field counts.test_ids: {N + 5} test clips, not" in err[0]


def test_a_leaderboard_entry_compares_with_a_result_of_its_track(world, tmp_path, capsys):
    """An entry keeps no store fields (dataset, store_config_sha256): paired with a result it
    must name the same track, evaluator, protocol and split size, and gives the numbers its
    result gives."""
    from hoibench.cli import main
    from hoibench.publish.leaderboard import add_result
    from hoibench.scoring.paired import paired_compare
    rng, real = world
    cd = np.abs(rng.normal(0.01, 0.002, N))
    a = _result(tmp_path, "a", real + 0.1 * rng.standard_normal(real.shape), real, cd)
    b = _result(tmp_path, "b", real + 0.5 * rng.standard_normal(real.shape), real, cd + 0.01)
    for p in (a, b):
        r = json.loads(p.read_text())
        r.update(track="synthetic", complete=True)
        p.write_text(json.dumps(r))
    (tmp_path / "lb" / "synthetic" / "entries").mkdir(parents=True)
    entry = add_result(b, tmp_path / "lb" / "synthetic", method="row b", role="baseline")
    direct = paired_compare([a, b], resamples=2000, seed=1)["pairs"][0]["metrics"]
    via_entry = paired_compare([a, entry], resamples=2000, seed=1)["pairs"][0]
    assert via_entry["b"] == "row b" and via_entry["metrics"] == direct
    other = json.loads(a.read_text())
    other["track"] = "behave"
    a.write_text(json.dumps(other))
    assert main(["compare", str(a), str(entry), "--paired"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "field track" in err[0] and "one track" in err[0]
