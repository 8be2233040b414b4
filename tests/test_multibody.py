"""Multi-body clips end to end: the representation's exact round trip, single-body stores
read as multi-body, the synthetic multi-body track (prepare, recognizer, evaluate), analytic
checks of the surfaces the metrics measure, executor invariance and one-line errors."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

pytest.importorskip("open3d")
pytest.importorskip("trimesh")

from hoibench.representations import multibody as rep  # noqa: E402
from hoibench.datasets import synthetic_multibody as syn  # noqa: E402
from hoibench.bodies.multibody import Body, MultiBodyClip, check_clip  # noqa: E402
from hoibench.bodies.capsules import ObjectField, pair_penetration, skeleton_object_distance  # noqa: E402


@pytest.fixture(scope="module")
def family_clips():
    return [syn.generate(i, fam, act, seed=3) for i, fam, act in syn.plan(9, 3)]


def test_representation_round_trip_is_exact_and_relative_blocks_are_consistent(family_clips):
    for clip in family_clips:
        x, blocks = rep.encode(clip)
        widths = {b.body: b.width for b in blocks if b.ref is None}
        assert sum(b.width for b in blocks) == x.shape[1]
        back = {b.name: b for b in rep.decode(x, clip)}
        for b in clip.bodies:
            if b.is_rigid:
                np.testing.assert_allclose(back[b.name].trans, b.trans, atol=1e-12)
                np.testing.assert_allclose(back[b.name].rot, b.rot, atol=1e-12)
                assert widths[b.name] == 7
            else:
                np.testing.assert_allclose(back[b.name].joints, b.joints, atol=1e-12)
        assert rep.consistency(x, clip) < 1e-9
        # SyncDiff's comb(a, rel(a, b)) == b for every rigid reference
        for a in clip.of_kind("object"):
            for b in clip.bodies:
                if b.name == a.name:
                    continue
                c = rep.combine(a, rep.relative(a, b), b)
                if b.is_rigid:
                    np.testing.assert_allclose(c.rot, b.rot, atol=1e-12)
                    np.testing.assert_allclose(c.trans, b.trans, atol=1e-12)
                else:
                    np.testing.assert_allclose(c.joints, b.joints, atol=1e-12)
        # no relative block between two skeletons (the paper's rule)
        kinds = {b.name: b.kind for b in clip.bodies}
        assert all(kinds[b.ref] == "object" for b in blocks if b.ref is not None)
        # a generated array whose object moved without its relative blocks is inconsistent
        y = x.copy()
        obj = next(b for b in blocks if b.ref is None and b.kind == "rigid")
        y[:, obj.start] += 0.05
        assert rep.consistency(y, clip) > 0.05 / np.sqrt(2) - 1e-9      # |R^T (0.05, 0, 0)|_inf, R a yaw


def test_a_translation_of_the_scene_leaves_relative_blocks_unchanged(family_clips):
    clip = family_clips[0]
    x, blocks = rep.encode(clip)
    moved = dataclasses.replace(clip, bodies=[dataclasses.replace(
        b, trans=b.trans + [1.0, 0.0, -2.0], joints=None if b.joints is None else b.joints + [1.0, 0.0, -2.0])
        for b in clip.bodies])
    y, _ = rep.encode(moved)
    for b in blocks:
        if b.ref is not None:
            np.testing.assert_allclose(y[:, b.columns], x[:, b.columns], atol=1e-9)


def test_a_single_body_store_clip_is_the_one_human_one_object_case(tmp_path):
    from hoibench.datasets.synthetic_store import build_synthetic_store
    from hoibench.datasets.store import Store
    _, data, _ = build_synthetic_store(tmp_path, 3, seed=1)
    store = Store(data)
    cid = store.clip_ids()[0]
    z = store.load(cid)
    clip = MultiBodyClip.from_arrays(z, store.object_template)
    assert clip.signature() == "human,object"
    check_clip(clip)
    np.testing.assert_array_equal(clip.bodies[0].joints, z["joints"])
    tmpl = store.object_template(str(z["object_name"]))[0].astype(np.float64)
    want = np.einsum("ij,vj->vi", z["obj_rot"][0].astype(np.float64), tmpl) + z["obj_trans"][0]
    np.testing.assert_allclose(clip.object_vertices(clip.bodies[1].name)[0], want, atol=1e-6)
    x, blocks = rep.encode(clip)
    assert x.shape == (len(z["joints"]), 66 + 7 + 66)


def _box_body(name, centre, T=1):
    return Body(name, "object", np.repeat(np.asarray(centre, float)[None], T, 0), np.repeat(np.eye(3)[None], T, 0),
                None, "box")


def test_two_boxes_overlapping_by_a_known_volume_give_that_iv():
    import trimesh
    m = trimesh.creation.box(extents=(0.1, 0.1, 0.1))
    tmpl = {"box": (np.asarray(m.vertices), np.asarray(m.faces))}
    fields = {"box": ObjectField(*tmpl["box"])}
    a = _box_body("a", (0.0, 0.0, 0.0))
    b = _box_body("b", (0.07, 0.02, 0.0))
    clip = MultiBodyClip("boxes", "t", "s", 20.0, [a, b], tmpl)
    want = 0.03 * 0.08 * 0.1                            # overlap 3 cm x 8 cm x 10 cm
    for voxel in (0.005, 0.0025):
        vol, dep = pair_penetration(clip, 0, 1, fields, voxel_m=voxel)
        assert vol[0] == pytest.approx(want, rel=0.12 if voxel == 0.005 else 0.06)
        assert dep[0] == pytest.approx(0.03, abs=2e-3)    # b's vertices 3 cm inside a along x
    far = MultiBodyClip("boxes", "t", "s", 20.0, [a, _box_body("b", (0.2, 0.0, 0.0))], tmpl)
    vol, dep = pair_penetration(far, 0, 1, fields)
    assert vol[0] == 0.0 and dep[0] == 0.0


def _hand_above(top_y: float, gap: float) -> Body:
    """A straight proxy-sized hand lying flat whose lowest capsule surface is ``gap`` above
    ``top_y``: every joint on one horizontal line (capsule radius 12 mm palm, 9 mm fingers)."""
    from hoibench.bodies.capsules import bones
    J = np.zeros((1, 21, 3))
    J[0, :, 0] = np.linspace(-0.03, 0.03, 21)
    pa, pb, r = bones("hand")
    J[0, :, 1] = top_y + gap + r.max()
    return Body("right_hand", "hand", J[:, 0], None, J, None, "right")


def test_a_hand_at_a_known_distance_flips_contact_at_the_threshold():
    import trimesh
    from hoibench.scoring.multibody import _contacts
    from hoibench.tracks.protocol import get_protocol
    proto = get_protocol("multibody-synthetic")
    m = trimesh.creation.box(extents=(0.2, 0.1, 0.2))
    tmpl = {"box": (np.asarray(m.vertices), np.asarray(m.faces))}
    fields = {"box": ObjectField(*tmpl["box"])}
    box = _box_body("box", (0.0, 0.0, 0.0))
    for gap, touching in ((0.0049, True), (0.0051, False), (0.0, True), (0.02, False)):
        hand = _hand_above(0.05, gap)
        d = skeleton_object_distance(hand, fields["box"], box)[0]
        assert d == pytest.approx(gap, abs=2e-4)
        clip = MultiBodyClip("h", "t", "s", 20.0, [hand, box], tmpl)
        assert bool(_contacts(clip, fields, proto)["right_hand"][0]) is touching


@pytest.fixture(scope="module")
def track(tmp_path_factory):
    """The synthetic multi-body track: 54 clips (6 per action), a recognizer, GT and defects."""
    from hoibench.datasets import multibody as mbl
    from hoibench.scoring.multibody import write_multibody_submission
    from hoibench.evaluator.recognizer import train_recognizer
    from hoibench.datasets.store import PrepareConfig, prepare
    base = tmp_path_factory.mktemp("mbtrack")
    mbl.write_synthetic_layout(base / "raw", 54, seed=0)
    cfg = PrepareConfig("multibody-synthetic", fps=syn.FPS)
    manifest = prepare(mbl.prepare_jobs(base / "raw", None, base / "data", cfg), base / "data", cfg)
    card = train_recognizer(base / "data", base / "rec", steps=200)
    subs = {}
    for kind in ("gt", "desync", "lost_contact", "interpenetration", "static"):
        subs[kind] = write_multibody_submission(base / "data", base / f"sub_{kind}", kind=kind)
    return base, manifest, card, subs


def test_the_track_prepares_and_clips_equal_the_generator(track):
    from hoibench.datasets.store import Store
    base, manifest, _, _ = track
    assert manifest["counts"]["failed"] == 0 and manifest["counts"]["by_split"] == {"test": 13, "train": 41}
    store = Store(base / "data")
    for cid in store.clip_ids()[:9]:
        clip = MultiBodyClip.from_arrays(store.load(cid), store.object_template)
        i, fam, act = cid.split("_")
        want = syn.generate(int(i[2:]), fam, act, seed=0)
        assert clip.action == act and clip.signature() == want.signature()
        for b, w in zip(clip.bodies, want.bodies):
            np.testing.assert_allclose(b.trans, w.trans, atol=1e-6)
            if w.joints is not None:
                np.testing.assert_allclose(b.joints, w.joints, atol=1e-6)
        for k, v in want.contacts.items():
            np.testing.assert_array_equal(clip.contacts[k], v)


def test_the_recognizer_is_far_above_chance_on_the_ground_truth_and_deterministic(track, tmp_path):
    from hoibench.evaluator.recognizer import train_recognizer
    base, _, card, _ = track
    assert card["gt_accuracy"]["test"] >= 0.8 > 3 * card["chance_accuracy"]
    again = train_recognizer(base / "data", tmp_path / "rec", steps=200)
    assert again["recognizer_id"] == card["recognizer_id"]
    assert (tmp_path / "rec" / "recognizer.safetensors").read_bytes() == \
        (base / "rec" / "recognizer.safetensors").read_bytes()


def test_ground_truth_scores_best_and_defects_score_worse(track):
    from hoibench.scoring.evaluate import evaluate
    base, _, _, subs = track
    res = {k: evaluate(p, base / "data", base / "rec") for k, p in subs.items()}
    means = {k: {m: v["mean"] for m, v in r["metrics"].items()} for k, r in res.items()}
    gt = means["gt"]
    assert gt["csiou"] == 1.0 and gt["ra"] >= 0.8 and abs(gt["fid"]) < 1e-2     # 0 up to rank-deficient numerics
    assert gt["iv_cm3"] < 0.01 and gt["id_mm"] < 0.1
    for kind in ("desync", "lost_contact", "interpenetration"):
        m = means[kind]
        assert m["csiou"] < gt["csiou"], kind
        assert m["fid"] > gt["fid"] + 0.1, kind
    for kind in ("desync", "interpenetration"):
        assert means[kind]["iv_cm3"] > 100 * max(gt["iv_cm3"], 1e-4), kind
        assert means[kind]["id_mm"] > 1.0, kind
    assert means["static"]["ra"] < gt["ra"]
    assert res["gt"]["evaluator_trained_on_split"] == "train" and not res["gt"]["notes"]


def test_serial_and_process_executors_give_identical_results(track):
    from hoibench.scoring.evaluate import evaluate
    base, _, _, subs = track
    a = evaluate(subs["desync"], base / "data", base / "rec", executor="serial")
    b = evaluate(subs["desync"], base / "data", base / "rec", executor="processes:2")
    assert json.dumps(a["metrics"], sort_keys=True) == json.dumps(b["metrics"], sort_keys=True)


def test_bad_submissions_get_one_line_naming_the_id_and_field(track, tmp_path, capsys):
    import shutil
    from hoibench.cli import main
    from hoibench.core.io import npz_bytes
    base, _, _, subs = track
    bad = tmp_path / "bad"
    shutil.copytree(subs["gt"], bad)
    first = sorted((bad / "samples").glob("*.npz"))[0]
    with np.load(first) as z:
        arrays = {k: z[k] for k in z.files}
    key = next(k for k in arrays if k.endswith("__joints"))
    arrays[key] = arrays[key][:, :, :5]
    first.write_bytes(npz_bytes(arrays))
    argv = ["evaluate", str(bad), "--data", str(base / "data"), "--evaluator", str(base / "rec")]
    assert main(argv) != 0
    err = [ln for ln in capsys.readouterr().err.strip().splitlines() if not ln.startswith("[")]
    assert len(err) == 1 and first.stem in err[0] and key in err[0] and "Traceback" not in err[0]
    first.unlink()
    assert main(argv) != 0
    err = capsys.readouterr().err
    assert first.stem in err and "missing" in err and "Traceback" not in err
    assert main(["evaluate", str(subs["gt"]), "--data", str(base / "data"), "--evaluator", str(tmp_path)]) != 0
    err = capsys.readouterr().err
    assert "recognizer.json" in err and "Traceback" not in err


def test_a_multibody_clip_renders_as_a_strip_of_frames(track, tmp_path, capsys):
    pytest.importorskip("pyvista")
    from hoibench.cli import main
    base, _, _, _ = track
    clip = sorted((base / "data" / "clips").glob("*carry*.npz"))[0]
    out = tmp_path / "strip.png"
    assert main(["render", str(clip), "--out", str(out)]) == 0
    from PIL import Image
    w, h = Image.open(out).size
    assert (w, h) == (4 * 360, 320)
    assert main(["render", str(clip), "--out", str(tmp_path / "x.gif")]) != 0
    assert "writes .png" in capsys.readouterr().err


def test_validate_accepts_every_reference_submission_of_a_real_multibody_store(track):
    """``hoibench validate`` reads a multi-body submission as the scorer does (no single-body
    checks): the ground truth and the defect rows are complete, with no problem at all."""
    from hoibench.scoring.validate import validation_report
    base, _, _, subs = track
    for kind, path in subs.items():
        rep = validation_report(path, base / "data")
        assert rep.complete and not rep.problems, (kind, [str(p) for p in rep.problems[:3]])
        assert rep.valid_ids == rep.test_ids and len(rep.test_ids) == 13


def test_evaluate_reads_a_deflate_bomb_sample_within_its_budget(track, tmp_path, capsys):
    """A 64 MiB deflate bomb as one sample: refused from its member sizes (the single-body
    budget over the clip's own arrays), naming the sample, before anything is inflated."""
    import shutil
    from test_hostile_budgets import _bomb_npz
    from hoibench.cli import main
    base, _, _, subs = track
    bomb = tmp_path / "bomb"
    shutil.copytree(subs["gt"], bomb)
    first = sorted((bomb / "samples").glob("*.npz"))[0]
    first.write_bytes(_bomb_npz("left_hand__joints", 64 << 20))
    assert main(["evaluate", str(bomb), "--data", str(base / "data"), "--evaluator", str(base / "rec")]) != 0
    err = [ln for ln in capsys.readouterr().err.strip().splitlines() if not ln.startswith("[")]
    assert len(err) == 1 and first.stem in err[0] and ("budget" in err[0] or "limit" in err[0]), err


# ---------------------------------------------------------------------------- per-clip data, slices, paired
@pytest.fixture(scope="module")
def scored(track, tmp_path_factory):
    """GT, desync and static results written with their per-clip data, as ``evaluate --out`` does."""
    from hoibench.scoring.evaluate import main_evaluate
    base, _, _, subs = track
    out = tmp_path_factory.mktemp("mbscored")
    paths = {}
    for kind in ("gt", "desync", "static"):
        paths[kind] = out / f"{kind}.json"
        assert main_evaluate(subs[kind], base / "data", base / "rec", out=paths[kind]) == 0
    return paths


def test_multibody_per_clip_data_reproduce_the_result(scored):
    """The per-clip means are the result's CSR, CSIoU, IV, ID and RA (K = 1: one sample per
    clip), the recognizer features give its FID, and the ground truth's per-clip values are
    the result's ``ground_truth`` block."""
    from hoibench.core.io import read_json_file as read_json
    from hoibench.metrics.resampling import weighted_fid
    from hoibench.scoring.clip_data import read_clip_data
    for kind, path in scored.items():
        res = read_json(path)
        arr = read_clip_data(res, path)
        n = res["counts"]["test_ids"]
        assert arr["motion"].shape[:2] == (1, n) and arr["real"].shape[0] == n and len(arr["text"]) == 0
        names = [str(x) for x in arr["physical_names"]]
        assert names == sorted(["csr", "crr", "csiou", "iv_cm3", "id_mm", "ra"])
        for j, m in enumerate(names):
            assert np.nanmean(arr["physical"][0, :, j]) == pytest.approx(res["metrics"][m]["mean"], rel=1e-9, abs=1e-12), (kind, m)
            if m in res["ground_truth"]:
                assert np.nanmean(arr["reference"][:, j]) == pytest.approx(res["ground_truth"][m], rel=1e-9, abs=1e-12)
        fid = weighted_fid(arr["real"].astype(np.float64), arr["motion"][0].astype(np.float64), np.ones(n))
        assert fid == pytest.approx(res["metrics"]["fid"]["mean"], rel=1e-4, abs=1e-2)   # GT: 0 up to numerics
        lo, hi = res["metrics"]["fid"]["clips"]["ci95"]
        assert lo <= hi and res["metrics"]["ra"]["clips"]["over"] == "test clips"


def test_multibody_slices_label_each_clip_from_the_store(scored, track):
    """Verb = the clip's action, object = its templates, contact = the skeleton kinds its
    contact labels name: the carry family is two people, the hand families hands."""
    from hoibench.core.io import read_json_file as read_json
    from hoibench.datasets.store import Store
    base = track[0]
    res = read_json(scored["desync"])
    labels = res["slices"]["labels"]
    store = Store(base / "data")
    for cid in store.clip_ids("test"):
        z = store.load(cid)
        assert labels["verb"][cid] == str(z["action"])
        assert labels["object"][cid] == "+".join(sorted(str(t) for t in z["body_templates"] if str(t)))
        assert labels["contact"][cid] == ("people" if "_carry_" in cid else "hands"), cid
    table = res["slices"]["tables"]["contact"]
    assert sum(row["n"] for row in table.values()) == res["counts"]["test_ids"]
    assert "ra" in table["hands"] and "crr" in table["people"] and "csr" not in table["people"]


def test_multibody_paired_compare_finds_the_defects_and_not_the_identity(scored, tmp_path, capsys):
    from hoibench.cli import main
    from hoibench.core.io import read_json_file as read_json
    from hoibench.scoring.paired import paired_compare
    import shutil
    (tmp_path / "copy").mkdir()
    for name in ("gt.json", "gt.clips.npz"):                  # the same result under another path
        shutil.copy(scored["gt"].with_name(name), tmp_path / "copy" / name)
    cmp = paired_compare([scored["gt"], scored["desync"], scored["static"], tmp_path / "copy" / "gt.json"], seed=3)
    desync, static, same = cmp["pairs"]
    assert desync["metrics"]["fid"]["diff"] > 0 and desync["metrics"]["iv_cm3"]["diff"] > 0
    assert desync["metrics"]["csiou"]["diff"] < 0
    assert static["metrics"]["ra"]["verdict"] == "A better" and static["metrics"]["fid"]["verdict"] == "A better"
    assert static["metrics"]["csr"]["tested"] == "distance to the ground truth"
    for m, row in same["metrics"].items():
        assert row["diff"] == 0 and row["ci95"][0] <= 0 <= row["ci95"][1] and row["p_holm"] == 1.0, m
    assert {"sd", "od"}.isdisjoint(desync["metrics"])            # set-level without per-clip data: not tested
    # a single-body result (another evaluator) is refused in one line naming the field
    res = read_json(scored["gt"])
    other = dict(res, evaluator_id="0" * 64)
    from hoibench.core.io import atomic_write_json
    atomic_write_json(tmp_path / "other.json", other)
    import shutil
    shutil.copy(scored["gt"].with_name("gt.clips.npz"), tmp_path / "gt.clips.npz")
    assert main(["compare", str(scored["gt"]), str(tmp_path / "other.json"), "--paired"]) != 0
    err = [ln for ln in capsys.readouterr().err.strip().splitlines() if ln.strip()]
    assert len(err) == 1 and "evaluator_id" in err[0] and "Traceback" not in err[0]


def test_multibody_per_clip_data_are_identical_on_every_executor(track, tmp_path):
    from hoibench.scoring.evaluate import evaluate
    base, _, _, subs = track
    a, b = {}, {}
    ra = evaluate(subs["lost_contact"], base / "data", base / "rec", executor="serial", clip_data=a)
    rb = evaluate(subs["lost_contact"], base / "data", base / "rec", executor="processes:2", clip_data=b)
    assert sorted(a) == sorted(b)
    for k in a:
        np.testing.assert_array_equal(a[k], b[k])
    assert json.dumps(ra["slices"], sort_keys=True) == json.dumps(rb["slices"], sort_keys=True)


def _physics_protocol():
    """multibody-synthetic@1.1 with coarser physics settings (fewer windows, shorter releases)."""
    from hoibench.tracks.protocol import get_protocol
    p = get_protocol("multibody-synthetic@1.1")
    coarse = {**p.settings_for("physics"), "stride_s": 1.0, "settle_frames": 10, "timestep_s": 0.005}
    return dataclasses.replace(p, settings={"physics": coarse})


def test_the_physics_tier_is_scored_per_sample_and_for_the_ground_truth_on_every_executor(track, scored):
    pytest.importorskip("mujoco")
    from hoibench.metrics.physics import NAMES
    from hoibench.scoring.evaluate import evaluate
    base, _, _, subs = track
    proto = _physics_protocol()
    a, b = {}, {}
    ra = evaluate(subs["static"], base / "data", base / "rec", protocol=proto, executor="serial", clip_data=a)
    rb = evaluate(subs["static"], base / "data", base / "rec", protocol=proto, executor="processes:2", clip_data=b)
    assert json.dumps(ra["metrics"], sort_keys=True) == json.dumps(rb["metrics"], sort_keys=True)
    for k in a:
        np.testing.assert_array_equal(a[k], b[k])
    names = list(a["physical_names"])
    for n in NAMES:
        col = names.index(n)
        assert ra["metrics"][n]["mean"] == pytest.approx(np.nanmean(a["physical"][0, :, col]), rel=1e-12)
        assert ra["ground_truth"][n] == pytest.approx(np.nanmean(a["reference"][:, col]), rel=1e-12)
        assert "clips" in ra["metrics"][n]
    # the synthetic objects hover at table height with no table (docs/multibody.md): most windows fail
    assert ra["ground_truth"]["phys_unsupported_ratio"] > 0.5
    from hoibench.core.io import read_json_file
    before = read_json_file(scored["static"])                       # 1.0: the other metrics are unchanged
    assert {k: v["mean"] for k, v in before["metrics"].items()} == \
        {k: v["mean"] for k, v in ra["metrics"].items() if k not in NAMES}


def test_without_the_engine_the_multibody_physics_tier_reads_not_computed(track, monkeypatch):
    from hoibench.metrics import catalog
    from hoibench.metrics.physics import NAMES
    from hoibench.scoring.evaluate import evaluate
    base, _, _, subs = track
    for n in NAMES:
        monkeypatch.setitem(catalog.METRICS, n, dataclasses.replace(catalog.METRICS[n], requires="hoibench_no_such_engine"))
    res = evaluate(subs["gt"], base / "data", base / "rec", protocol=_physics_protocol(), executor="serial")
    for n in NAMES:
        assert n not in res["metrics"] and n not in res["ground_truth"]
        assert res["undefined_metrics"][n] == "not computed: install hoibench[physics]"
    assert "csiou" in res["metrics"]


def test_a_multibody_track_ranks_rows_with_paired_tests_and_rank_intervals(scored, tmp_path):
    """Entries keep the multi-body per-clip data; the page tells the desync row from the static
    one by the paired test and gives each ranked row a rank interval."""
    from hoibench.publish.leaderboard import add_result, load_track
    from hoibench.publish.pages import render
    track = tmp_path / "multibody-synthetic"
    add_result(scored["gt"], track, method="GT", role="ground-truth")
    add_result(scored["desync"], track, method="desync", role="baseline")
    add_result(scored["static"], track, method="static", role="baseline")
    entries, files = render(track)
    ranked = [e for e in entries if e["role"] == "baseline"]
    assert [e["method"] for e in ranked] == ["desync", "static"]             # ranked by FID
    assert all((track / "entries" / e["per_clip_data"]["file"]).is_file() for e in load_track(track))
    vs = ranked[1]["_sig"]["vs_above"]
    assert vs["method"] == "desync" and vs["distinguishable"] and vs["metrics"]["fid"]["diff"] > 0
    assert ranked[0]["_sig"]["rank_ci95"][0] == 1 and ranked[1]["_sig"]["rank_ci95"][1] == 2
    header = files["leaderboard.csv"].splitlines()[0]
    assert "rank_ci95" in header and "vs_above_distinguishable" in header
    assert render(track)[1]["leaderboard.csv"] == files["leaderboard.csv"]       # a rebuild: the same bytes
