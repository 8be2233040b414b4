"""hoibench audit: the corrupted ground truth scored by the evaluation pipeline, the audit's
statistics and its files."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from hoibench.audit.analysis import family_summary, paired_tests, ranks, spearman, worse
from hoibench.audit.corruptions import FAMILIES

#: the families the end-to-end audit runs (a motion and a text one: each motion family costs
#: its severities x the test clips in physical metrics)
AUDITED = ("object_float", "noun_swap")


@pytest.fixture(scope="module")
def scored(tmp_path_factory):
    """An 8-clip store (4 train / 4 test), a 1-epoch tiny evaluator, the plain ground-truth
    result, and the audit of :data:`AUDITED` (serial, seed 0, 2,000 resamples)."""
    pytest.importorskip("matplotlib")
    from hoibench.audit.document import run_audit
    from hoibench.scoring.evaluate import evaluate
    from hoibench.scoring.submission import from_store
    from _small_store import eight_clip_store
    base = tmp_path_factory.mktemp("audit")
    data, ev = eight_clip_store(base)
    from_store(data, base / "gt")
    gt = evaluate(base / "gt", data, ev, allow_failed_gate=True)
    doc = run_audit(data, ev, base / "out", families=list(AUDITED), allow_failed_gate=True, log=lambda _m: None)
    return data, base, gt, doc


# ------------------------------------------------------------------ statistics, analytic cases
def test_spearman_is_the_rank_correlation_with_average_ranks_for_ties():
    assert list(ranks([3.0, 1.0, 3.0, 2.0])) == [3.5, 1.0, 3.5, 2.0]
    assert spearman([0, 1, 2, 3], [5, 7, 8, 100]) == pytest.approx(1.0)
    assert spearman([0, 1, 2, 3], [9, 4, 1, 0]) == pytest.approx(-1.0)
    x, y = [0.0, 0.32, 0.32, 0.68, 0.68, 1.0], [1.0, 2.0, 1.5, 2.0, 3.0, 2.5]
    rx, ry = ranks(x) - 3.5, ranks(y) - 3.5                # the definition, by hand
    assert spearman(x, y) == pytest.approx(float(rx @ ry / np.sqrt((rx @ rx) * (ry @ ry))))
    scipy = pytest.importorskip("scipy.stats")
    assert spearman(x, y) == pytest.approx(scipy.spearmanr(x, y).statistic)
    assert spearman([0, 1, 2], [4, 4, 4]) is None and spearman([0, 1], [1, 2]) is None


def test_worse_follows_the_declared_direction():
    assert worse([1.0, 2.0], "lower", 1.0) == [1.0, 2.0]
    assert worse([1.0, 2.0], "higher", 1.0) == [-1.0, -2.0]
    assert worse([1.0, 0.5, 1.7], "gt", 1.0) == pytest.approx([0.0, 0.5, 0.7])
    with pytest.raises(ValueError, match="direction"):
        worse([1.0], "sideways", 1.0)


def _test(diff: float, p_holm: float, sd: float = 0.1, need: int | None = 10) -> dict:
    return {"diff": diff, "p": p_holm, "p_holm": p_holm, "sd": sd, "sd_diff": sd, "clips_needed": need}


def test_family_summary_of_planted_series():
    sev = list(FAMILIES["grasp_offset"].severities)              # 0, 0.02, 0.05, 0.1, 0.2, 0.5
    falling = [0.9, 0.85, 0.7, 0.5, 0.3, 0.1]                   # R@1 (higher is better) falls: it sees it
    tests = [None] + [_test(v - falling[0], p) for v, p in zip(falling[1:], (0.3, 0.01, 0.001, 0.001, 0.001))]
    row = family_summary("r_precision_top1", "grasp_offset", sev, falling, tests)
    assert row["spearman"] == pytest.approx(-1.0) and row["spearman_worse"] == pytest.approx(1.0)
    assert row["direction_ok"] is True and row["blind"] is False
    assert row["detectable_severity"] == 0.05                   # 0.02 is not significant
    assert row["effect_sd"] == pytest.approx(-0.05 / 0.1) and row["effect_severity"] == 0.02
    rising = family_summary("r_precision_top1", "grasp_offset", sev, falling[::-1], tests)
    assert rising["direction_ok"] is False and rising["blind"] is True      # gets better: the wrong way
    flat = family_summary("cd", "grasp_offset", sev, [0.01] * 6, [None] + [_test(0.0, 1.0)] * 5)
    assert flat["spearman"] is None and flat["blind"] is True and flat["detectable_severity"] is None
    assert flat["effect_sd"] == 0.0
    # gt direction: moving away from the severity-0 value either way is worse
    away = family_summary("diversity", "grasp_offset", sev, [1.0, 0.9, 1.2, 0.7, 1.5, 0.2], [None] * 6)
    assert away["spearman_worse"] == pytest.approx(1.0) and away["blind"] is False
    # speed: magnitudes |log2 c| tie for 0.8 and 1.25; the lowest non-zero severity is the first listed
    sp = FAMILIES["speed"].severities
    row = family_summary("fid", "speed", list(sp), [0.0, 1, 1, 2, 2, 3, 3, 4, 4], [None] + [_test(1.0, 0.01)] * 8)
    assert row["spearman"] == pytest.approx(1.0) and row["effect_severity"] == 0.8 and row["detectable_severity"] == 0.8


def test_paired_tests_against_independent_bootstrap_sums():
    rng = np.random.default_rng(0)
    B, n = 400, 20
    a = {"cd": rng.normal(1.0, 0.1, B), "fid": rng.normal(0.0, 0.01, B)}
    b = {"cd": a["cd"] + 0.5, "fid": a["fid"] + rng.normal(0.0, 0.01, B)}
    rows = paired_tests((a, {"cd": 1.0, "fid": 0.0}), (b, {"cd": 1.5, "fid": 0.001}), ["cd", "fid", "ocd"], n)
    assert set(rows) == {"cd", "fid"}                             # no draws: not tested
    assert rows["cd"]["diff"] == pytest.approx(0.5) and rows["cd"]["p"] == pytest.approx(2 / (B + 1))
    assert rows["cd"]["p_holm"] == pytest.approx(min(1.0, 2 * rows["cd"]["p"]))
    assert rows["cd"]["sd"] == pytest.approx(np.std(b["cd"], ddof=1))
    assert rows["cd"]["clips_needed"] == 2                       # a constant shift: the minimum
    assert rows["fid"]["p"] > 0.05
    sd_d = np.std(b["fid"] - a["fid"], ddof=1)
    assert rows["fid"]["clips_needed"] == math.ceil(n * ((1.959964 + 0.841621) * sd_d / 0.001) ** 2)


# ------------------------------------------------------------------ the audit, end to end
def test_audit_json_schema(scored):
    data, base, gt, doc = scored
    on_disk = json.loads((base / "out" / "audit.json").read_text())
    assert on_disk == json.loads(json.dumps(doc))
    p = on_disk["provenance"]
    assert p["store"] == str(data) and p["evaluator_id"] == gt["evaluator_id"] and p["seed"] == 0
    assert (p["protocol"], p["protocol_version"], p["protocol_sha256"]) == \
        (gt["protocol"], gt["protocol_version"], gt["protocol_sha256"])
    assert p["toolkit_version"] == gt["toolkit_version"] and p["resamples"] == 2000 and p["test_clips"] == 4
    metrics = on_disk["metrics"]
    assert {"fid", "r_precision_top1", "mm_dist", "cd", "ps", "fsr"} <= set(metrics)
    assert set(on_disk["corruptions"]) == set(AUDITED) and on_disk["families"] == list(AUDITED)
    for f in AUDITED:
        c = on_disk["corruptions"][f]
        assert c["severities"] == list(FAMILIES[f].severities)
        assert set(c["values"]) == set(metrics)
        assert all(len(v) == len(c["severities"]) for v in c["values"].values())
    for m in metrics:
        for f in AUDITED:
            row = on_disk["summary"][m][f]
            assert {"spearman", "detectable_severity", "direction_ok", "effect_sd", "blind"} <= set(row)
            assert row["detectable_severity"] is None or row["detectable_severity"] in FAMILIES[f].severities[1:]
    for m in metrics:
        text = (base / "out" / "cards" / f"{m}.md").read_text()
        assert "Unit:" in text and "## Blind to" in text and "## How many clips it needs" in text
    readme = (base / "out" / "README.md").read_text()
    assert "heatmap.png" in readme and all(f"cards/{m}.md" in readme for m in metrics)
    assert (base / "out" / "heatmap.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_severity_zero_of_every_family_is_the_plain_ground_truth_scoring(scored):
    from hoibench.audit.runner import Corrupted, corrupted_split, ground_truth
    from hoibench.audit.corruptions import split_context
    from hoibench.datasets.store import Store
    data, _, gt, doc = scored
    for f in AUDITED:
        for m in doc["metrics"]:
            want = gt["metrics"][m]["mean"] if m in gt["metrics"] else None
            assert doc["corruptions"][f]["values"][m][0] == pytest.approx(want, rel=1e-12, abs=1e-15), (f, m)
    # every other family's severity 0 hands the scorer the ground truth's very arrays and captions
    store = Store(data)
    clips, captions = ground_truth(store, store.clip_ids("test"))
    ctx = split_context(clips, captions)
    identity = Corrupted({c: {k: a[k][None] for k in ("joints", "obj_rot", "obj_trans")} for c, a in clips.items()},
                         captions).digest()
    for f, spec in FAMILIES.items():
        assert corrupted_split(store, clips, captions, f, spec.identity, 0, ctx, {}).digest() == identity, f


def test_a_floating_object_is_seen_by_the_object_metrics(scored):
    _, _, _, doc = scored
    for m in ("cd", "ocd", "contact_iou", "object_floating_ratio"):
        row = doc["summary"][m]["object_float"]
        assert row["spearman_worse"] > 0.5 and row["direction_ok"] and not row["blind"], m
        assert row["detectable_severity"] is not None and row["detectable_severity"] <= 0.5, m
    values = doc["corruptions"]["object_float"]["values"]
    assert values["cd"][-1] > 100 * max(values["cd"][0], 1e-6)       # 0.5 m up: far from every joint
    assert values["contact_iou"][-1] < values["contact_iou"][0]
    # the human-variant evaluator reads no object channel: the embedding metrics cannot see it
    assert doc["summary"]["fid"]["object_float"]["blind"] and doc["summary"]["fid"]["object_float"]["spearman"] is None


def test_a_text_family_changes_only_what_reads_captions(scored):
    _, _, _, doc = scored
    values = doc["corruptions"]["noun_swap"]["values"]
    for m in ("fid", "diversity", "cd", "ps", "fsr", "jitter_mps3"):
        assert len(set(values[m])) == 1, m                              # the motion is the ground truth's
    assert len(set(values["mm_dist"])) > 1                              # the captions it reads changed


def test_same_seed_gives_identical_audit_json_on_every_executor(scored, tmp_path):
    from hoibench.audit.document import run_audit
    data, base, _, _ = scored
    run_audit(data, base / "ev", tmp_path / "pool", families=list(AUDITED), executor="processes:2",
              allow_failed_gate=True, log=lambda _m: None)
    assert (tmp_path / "pool" / "audit.json").read_bytes() == (base / "out" / "audit.json").read_bytes()


def test_bad_arguments_give_one_line_naming_the_field(scored, tmp_path, capsys):
    from hoibench.cli import main
    data, base, _, _ = scored
    assert main(["audit", "--data", str(tmp_path / "nowhere"), "--evaluator", str(base / "ev"),
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--data" in err and "no manifest.json" in err
    assert main(["audit", "--data", str(data), "--evaluator", str(base / "ev"), "--out", str(tmp_path / "o"),
                 "--families", "jitter,noun_swop"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--families" in err and "'noun_swop'" in err and "noun_swap" in err
    assert main(["audit", "--data", str(data), "--evaluator", str(base / "ev"), "--out", str(base / "out"),
                 "--families", "jitter"]) == 2                           # an audit is there already
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--out" in err and "--overwrite" in err


def test_a_legacy_protocol_on_a_clean_store_needs_the_mismatch_flag_and_is_recorded(scored, tmp_path, capsys):
    from hoibench.audit.runner import load_setup
    from hoibench.cli import main
    data, base, _, _ = scored
    args = ["audit", "--data", str(data), "--evaluator", str(base / "ev"), "--out", str(tmp_path / "o"),
            "--protocol", "synthetic-legacy", "--families", "jitter", "--allow-failed-gate"]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "legacy protocol" in err and "--allow-protocol-mismatch" in err
    setup = load_setup(data, base / "ev", "synthetic-legacy", True, allow_protocol_mismatch=True)
    assert setup.proto.id == "synthetic-legacy" and setup.options["allow_protocol_mismatch"] is True
    # with the flag the audit reaches ChainHOI's loop, which refuses 4 test clips in one line
    assert main(args + ["--allow-protocol-mismatch"]) == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]                # after the progress lines
    assert last.startswith("hoibench audit: error: protocol synthetic-legacy@") and "needs more than 16 items" in last


def test_a_mirrored_or_swapped_clip_poses_its_mirrored_or_new_template(scored):
    from hoibench.audit.corruptions import split_context
    from hoibench.audit.runner import corrupted_split, ground_truth
    from hoibench.datasets.store import Store
    data = scored[0]
    store = Store(data)
    clips, captions = ground_truth(store, store.clip_ids("test"))
    ctx = split_context(clips, captions)
    mirrored = corrupted_split(store, clips, captions, "mirror", 1.0, 0, ctx, {})
    for cid, a in clips.items():
        name, v, f = mirrored.templates[cid]
        v0, f0 = store.object_template(str(a["object_name"]))
        assert name == str(a["object_name"])
        np.testing.assert_array_equal(v, v0 * np.array([-1.0, 1.0, 1.0], dtype=v0.dtype))
        np.testing.assert_array_equal(f, f0[:, ::-1])                     # normals still point out
    swapped = corrupted_split(store, clips, captions, "object_swap", 1.0, 0, ctx, {})
    for cid, (name, v, _) in swapped.templates.items():
        assert name != str(clips[cid]["object_name"])
        np.testing.assert_array_equal(v, store.object_template(name)[0])


def test_object_families_need_an_object_on_every_test_clip():
    from types import SimpleNamespace
    from hoibench.audit.runner import check_objects
    store = SimpleNamespace(root="human-store", manifest={"clips": [
        {"id": "a", "split": "test", "object": "box"}, {"id": "b", "split": "test", "object": ""},
        {"id": "c", "split": "train"}]})
    assert check_objects(store, ["jitter", "object_float", "noun_swap"], explicit=False) == ["jitter", "noun_swap"]
    with pytest.raises(ValueError, match=r"--families object_float: test clip b of human-store has no object"):
        check_objects(store, ["jitter", "object_float"], explicit=True)
    store.manifest["clips"][1]["object"] = "stool"
    assert check_objects(store, ["object_float"], explicit=True) == ["object_float"]
