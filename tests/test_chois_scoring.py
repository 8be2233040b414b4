"""CHOIS's protocol end to end: ``evaluate --protocol omomo-chois`` on a synthetic OMOMO store
with CHOIS's evaluator imported from random weights in its release layout.

What is checked against independent expectations: a ground-truth submission scores zero on
every reference error and CHOIS's contact rules on clips without contact; a submission moved
5 cm scores 50 mm where CHOIS's definitions say so and 0 where they are root-relative; frames
past the protocol's window change nothing; clips shorter than the window are not scored and
are counted; the evaluator's joints24 rows do not depend on where the clip stands or faces.
The synthetic clips are 76-126 frames, so the tests score 95-frame windows (the shipped
protocol's 120 keeps one test clip of this store) with hoibench's embedding loop (CHOIS's
loop needs a full batch of 32 clips); every other setting is the shipped file's.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from hoibench.tracks.protocol import PROTOCOLS_DIR

WINDOW = 95
INTERFACE = ("lhand_jpe", "rhand_jpe", "hand_jpe", "mpvpe", "mpjpe", "rot_dist", "trans_err", "gt_contact_percent",
             "pred_contact_percent", "foot_sliding", "gt_foot_sliding", "contact_precision", "contact_recall",
             "contact_acc", "contact_f1", "obj_rot_dist", "obj_com_pos_err", "start_obj_com_pos_err",
             "end_obj_com_pos_err", "waypoints_xy_pos_err", "penetration", "penetration_percent", "hand_penetration")


def _protocol(tmp: Path, name: str) -> Path:
    """The shipped protocol with a 95-frame window and hoibench's loop (module docstring)."""
    text = (PROTOCOLS_DIR / f"{name}.yaml").read_text()
    assert "  frames: 120 " in text and "\nembedding_loop: " in text
    text = text.replace("  frames: 120 ", f"  frames: {WINDOW} ").replace("embedding_loop: chois ", "embedding_loop: hoibench ")
    out = tmp / f"{name}-{WINDOW}.yaml"
    out.write_text(text)
    return out


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    for module in ("joblib", "sklearn"):
        pytest.importorskip(module)
    from test_chois_evaluator import DIMS, write_release

    from hoibench.datasets import omomo
    from hoibench.datasets import synthetic_layouts as sl
    from hoibench.datasets.store import PrepareConfig, Store, prepare
    from hoibench.evaluator.chois_t2m import import_chois
    from hoibench.scoring.submission_write import from_store
    from hoibench.text.annotate import annotate_store
    base = tmp_path_factory.mktemp("chois_scoring")
    raw, data = base / "raw", base / "data"
    sl.write_omomo_layout(raw, 30, seed=1)
    cfg = PrepareConfig("omomo", fps=30.0, mode="legacy", body_model_type="smplx")
    prepare(omomo.prepare_jobs(raw, raw / "body_models", data, cfg), data, cfg)
    annotate_store(data)
    files = write_release(base / "release")
    import_chois(base / "ev", files["checkpoint"], files["glove"], files["meta"], dims=DIMS)
    from_store(data, base / "gt")
    return {"base": base, "data": data, "ev": base / "ev", "gt": base / "gt", "store": Store(data),
            "legacy": _protocol(base, "omomo-chois"), "clean": _protocol(base, "omomo-chois-clean")}


def _score(world, sub, protocol="legacy") -> dict:
    """Scored on the legacy store (the clean protocol names the clean representation, which the
    CHOIS evaluator does not read: the mismatch is allowed and recorded)."""
    from hoibench.scoring.evaluate import evaluate
    return evaluate(sub, world["data"], world["ev"], protocol=world[protocol], allow_failed_gate=True,
                    allow_protocol_mismatch=protocol == "clean")


def _shifted(world, name: str, change) -> Path:
    """A copy of the ground-truth submission with ``change(arrays)`` applied to every file."""
    import shutil
    out = world["base"] / name
    if not out.exists():
        shutil.copytree(world["gt"], out)
        for f in sorted((out / "samples").glob("*.npz")):
            with np.load(f) as z:
                arrays = {k: z[k] for k in z.files}
            change(arrays)
            np.savez(f, **arrays)
    return out


@pytest.fixture(scope="module")
def gt_result(world):
    return _score(world, world["gt"])


def test_ground_truth_scores_zero_errors_and_chois_contact_rules(world, gt_result):
    r = gt_result
    test = {c["id"]: c["frames"] for c in world["store"].manifest["clips"] if c["split"] == "test"}
    kept = sorted(c for c, n in test.items() if n >= WINDOW)
    assert r["counts"]["scored_ids"] == len(kept) and r["counts"]["window_dropped_ids"] == len(test) - len(kept) > 0
    assert any(n.startswith(f"clip_window: the first {WINDOW} frames") for n in r["notes"])
    rows = r["per_clip"]["rows"]
    assert sorted(row["id"] for row in rows) == kept
    for row in rows:
        assert set(INTERFACE) <= set(row)
        for m in ("lhand_jpe", "rhand_jpe", "hand_jpe", "mpvpe", "mpjpe", "trans_err", "obj_com_pos_err",
                  "start_obj_com_pos_err", "end_obj_com_pos_err", "waypoints_xy_pos_err"):
            assert row[m] == pytest.approx(0.0, abs=1e-9), m
        assert row["rot_dist"] == pytest.approx(0.0, abs=1e-7) and row["obj_rot_dist"] == pytest.approx(0.0, abs=1e-7)
        assert row["foot_sliding"] == pytest.approx(row["gt_foot_sliding"])
        assert row["contact_acc"] == 1.0 and row["gt_contact_percent"] == row["pred_contact_percent"]
        # CHOIS: no contact frame in the ground truth -> precision, recall and F1 are 0, not undefined
        expected = 1.0 if row["gt_contact_percent"] > 0 else 0.0
        assert row["contact_precision"] == row["contact_recall"] == row["contact_f1"] == expected
    for m in INTERFACE:
        assert r["metrics"][m]["mean"] == pytest.approx(np.mean([row[m] for row in rows]), abs=1e-12)


def test_a_translated_submission_scores_the_offset_where_chois_measures_it(world, gt_result):
    def move(a):
        a["joints"] = a["joints"] + np.array([0.03, 0.0, -0.04], np.float32)
        a["obj_trans"] = a["obj_trans"] + np.array([0.03, 0.0, -0.04], np.float32)
    r = _score(world, _shifted(world, "moved", move))
    for row in r["per_clip"]["rows"]:
        for m in ("lhand_jpe", "rhand_jpe", "hand_jpe", "trans_err", "obj_com_pos_err", "start_obj_com_pos_err",
                  "end_obj_com_pos_err", "waypoints_xy_pos_err"):
            assert row[m] == pytest.approx(50.0, abs=1e-3), m
        for m in ("mpjpe", "mpvpe"):                    # root-relative
            assert row[m] == pytest.approx(0.0, abs=1e-3), m
        assert row["rot_dist"] == pytest.approx(0.0, abs=1e-6)
    # the evaluator reads each clip in its own window frame: a moved clip embeds as before
    for m in ("fid", "r_precision_top1", "mm_dist"):
        assert r["metrics"][m]["mean"] == pytest.approx(gt_result["metrics"][m]["mean"], abs=1e-5), m


def test_frames_past_the_window_change_nothing(world, gt_result):
    def scramble(a):
        a["joints"][:, WINDOW:] += np.float32(0.3)
        a["obj_trans"][:, WINDOW:] -= np.float32(0.2)
    r = _score(world, _shifted(world, "tail", scramble))
    for m, v in gt_result["metrics"].items():
        assert r["metrics"][m]["mean"] == pytest.approx(v["mean"], abs=1e-9), m


def test_the_clean_protocol_reads_penetration_in_the_rest_frame(world, gt_result):
    """Same clips, same metrics except the hand penetration's frame (R^T; CHOIS's R)."""
    r = _score(world, world["gt"], "clean")
    for m in ("hand_jpe", "mpjpe", "contact_f1", "penetration", "penetration_percent", "foot_sliding"):
        assert r["metrics"][m]["mean"] == pytest.approx(gt_result["metrics"][m]["mean"], abs=1e-12), m
    assert r["protocol"] == "omomo-chois-clean"
    assert json.loads(json.dumps(r["metrics"]["hand_penetration"]))["unit"] == "m"


def test_window_joints24_do_not_depend_on_where_the_clip_stands_or_faces(world):
    from hoibench.metrics.chois_inputs import proxy_hand_joints, window_joints24
    j = world["store"].load(sorted(world["store"].clip_ids("test"))[0], keys=("joints",))["joints"].astype(np.float64)
    th = 0.7
    yaw = np.array([[np.cos(th), 0, np.sin(th)], [0, 1, 0], [-np.sin(th), 0, np.cos(th)]])
    moved = j @ yaw.T + np.array([2.0, 0.0, -1.5])
    np.testing.assert_allclose(window_joints24(moved), window_joints24(j), atol=1e-9)
    # the proxy hand joint sits 0.094 m (x the body scale) from its wrist, rigid with the forearm
    from hoibench.bodies.contact import body_scale
    hand = proxy_hand_joints(j)
    np.testing.assert_allclose(np.linalg.norm(hand[:, 0] - j[:, 20], axis=1), 0.0942178 * body_scale(j), rtol=1e-5)


def test_clip_window_is_validated_in_one_line(tmp_path):
    from hoibench.tracks.protocol import load_protocol
    text = (PROTOCOLS_DIR / "omomo-chois.yaml").read_text()
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("  drop_shorter: true", "  drop_shorter: maybe"))
    with pytest.raises(ValueError, match="bad.yaml: clip_window: field 'drop_shorter' must be bool"):
        load_protocol(bad)
    bad.write_text(text.replace("  frames: 120 ", "  frames: 0 "))
    with pytest.raises(ValueError, match="field 'clip_window.frames' must be positive"):
        load_protocol(bad)


def test_exact_and_grid_signed_distances_of_a_box():
    """Inside a 0.4 x 0.2 x 0.1 m box the signed distance is minus the nearest face's distance,
    outside the distance to the box; the grid reads node values trilinearly, clamped to its cube."""
    import trimesh

    from hoibench.metrics.chois_clip import MeshSdf, grid_sdf
    box = trimesh.creation.box(extents=(0.4, 0.2, 0.1))
    exact = MeshSdf(box.vertices, box.faces)
    pts = np.array([[0.0, 0.0, 0.0], [0.15, 0.05, 0.0], [0.3, 0.0, 0.0]])
    d = exact.sample(exact.normalise(pts)) * exact.half
    np.testing.assert_allclose(d, [-0.05, -0.05, 0.1], atol=1e-9)
    grid = grid_sdf(box.vertices, box.faces, nodes=41)
    g = grid.sample(grid.normalise(pts)) * exact.half
    # a point outside the grid's cube reads the border (CHOIS's padding_mode='border'): 0 here, not 0.1
    np.testing.assert_allclose(g, [-0.05, -0.05, 0.0], atol=2e-3)


def test_chois_loop_batches_in_listing_order():
    """Items i and i + 32 share a motion: listing-order batches of 32 never hold both (every
    text finds its own motion first), shuffled ones do; a short set is refused in one line."""
    from hoibench.metrics.legacy_loops import LoopRefused, chois_loop, t2m_loop
    rng = np.random.default_rng(0)
    motion = np.tile(rng.normal(size=(32, 16)), (2, 1)).astype(np.float32)
    text = motion + np.float32(0.01) * rng.normal(size=motion.shape).astype(np.float32)
    res = chois_loop(text, motion, motion, seed=0, diversity_times=10)
    assert res.rows()[0]["r_precision_top1"] == 1.0 and len(res.rows()) == 1
    assert [list(b) for b in res.batches[0]["generated"]] == [list(range(32)), list(range(32, 64))]
    assert "multimodality" not in res.rows()[0]
    shuffled = t2m_loop(text, motion, motion, seed=0, diversity_times=10, mm_texts=10, replications=1)
    assert shuffled.rows()[0]["r_precision_top1"] < 1.0
    with pytest.raises(LoopRefused, match="chois: 20 clips, fewer than one batch of 32"):
        chois_loop(text[:20], motion[:20], motion[:20])


def test_imported_chois_files_score_as_the_clips_they_reproduce(world, gt_result):
    """CHOIS saves joints24 in its window frame (z up); ``hoibench import chois`` puts them back
    in the test clip's world frame, so files written from the ground truth score zero errors
    (joints only: a human-only submission, no object metrics)."""
    from hoibench.metrics.chois_inputs import window_joints24
    from hoibench.scoring.importers import import_results
    store, folder = world["store"], world["base"] / "chois_files"
    folder.mkdir()
    ids = [row["id"] for row in gt_result["per_clip"]["rows"]]
    for cid in ids:
        joints = store.load(cid, keys=("joints",))["joints"][:120]
        np.savez(folder / f"{cid}.npz", seq_name=np.array(cid), global_jpos=window_joints24(joints).astype(np.float32))
    sub, report = import_results("chois", folder, world["data"], world["base"] / "chois_sub")
    assert report["matched"] == len(ids) and report["human_only"]
    assert report["conversions"]["frame"].startswith("CHOIS's window frame")
    for cid in ids:
        with np.load(sub / "samples" / f"{cid}.npz") as z:
            got = z["joints"][0]
        want = store.load(cid, keys=("joints",))["joints"][:len(got)]
        np.testing.assert_allclose(got, want, atol=2e-5)
    r = _score(world, sub)
    for row in r["per_clip"]["rows"]:
        for m in ("hand_jpe", "mpjpe", "trans_err", "mpvpe"):
            assert row[m] == pytest.approx(0.0, abs=0.05), m          # mm: float32 files
        assert row.get("obj_com_pos_err") is None                     # undefined without an object


def test_the_shipped_window_on_short_clips_is_refused_in_one_line(world):
    """The synthetic clips are shorter than CHOIS's 120 frames: too few are left to score."""
    from hoibench.scoring.evaluate import evaluate
    from hoibench.scoring.pipeline import EvaluationRefused
    with pytest.raises(EvaluationRefused, match=r"omomo-chois@1.0's clip_window of 120 frames keeps \d of \d+ test clips"):
        evaluate(world["gt"], world["data"], world["ev"], protocol="omomo-chois@1.0", allow_failed_gate=True)


def test_the_audit_runs_with_chois_evaluator_and_metrics(world, tmp_path):
    """``hoibench audit`` with CHOIS's evaluator (random weights) and CHOIS's per-clip metrics:
    jitter leaves severity 0 at the ground truth (0 mm) and raises CHOIS's joint errors with
    its amplitude (the object families' arithmetic is the translated submission's, above)."""
    from hoibench.audit.document import run_audit
    doc = run_audit(world["data"], world["ev"], tmp_path / "audit", protocol=world["clean"], families=["jitter"],
                    allow_failed_gate=True, allow_protocol_mismatch=True, log=lambda _m: None)
    hand = doc["corruptions"]["jitter"]["values"]["hand_jpe"]
    assert hand[0] == pytest.approx(0.0, abs=1e-6) and all(b > a for a, b in zip(hand, hand[1:]))
    assert doc["summary"]["hand_jpe"]["jitter"]["spearman"] == pytest.approx(1.0)
    assert doc["corruptions"]["jitter"]["values"]["fid"][0] == pytest.approx(0.0, abs=1e-6)
