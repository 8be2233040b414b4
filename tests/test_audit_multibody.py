"""hoibench audit on a multi-body track: the multi-body corruption families (exact, seeded,
identity at severity 0) and the audit with the track's recognizer, end to end."""
from __future__ import annotations


import numpy as np
import pytest

pytest.importorskip("open3d")
pytest.importorskip("trimesh")

from hoibench.audit import multibody_families as mf  # noqa: E402
from hoibench.audit.multibody_families import MULTIBODY_FAMILIES  # noqa: E402
from hoibench.audit.streams import clip_stream  # noqa: E402
from hoibench.datasets import synthetic_multibody as syn  # noqa: E402

#: the families the end-to-end audit runs
AUDITED = ("desync", "penetrate", "action_swap")


def _clips():
    """A hands clip (two hands, two objects) and a carry clip (two people, one box)."""
    return syn.generate(0, "hands", "brush", seed=0), syn.generate(6, "carry", "carry", seed=0)


def _same(a, b) -> bool:
    return all(np.array_equal(x.trans, y.trans) and (x.rot is None or np.array_equal(x.rot, y.rot))
               and (x.joints is None or np.array_equal(x.joints, y.joints)) for x, y in zip(a.bodies, b.bodies))


def test_every_clip_family_is_the_identity_at_severity_0_and_keeps_shapes():
    for clip in _clips():
        for name, spec in MULTIBODY_FAMILIES.items():
            if spec.scope != "clip":
                continue
            for i, s in enumerate(spec.severities):
                out = spec.fn(clip, s, clip_stream(0, name, i, clip.name))
                assert [b.trans.shape for b in out.bodies] == [b.trans.shape for b in clip.bodies]
                assert all(b.trans.dtype == c.trans.dtype for b, c in zip(out.bodies, clip.bodies))
                for b in out.bodies:
                    if b.joints is not None:
                        np.testing.assert_array_equal(b.trans, b.joints[:, 0])       # the root follows joint 0
                assert _same(out, clip) == (s == spec.identity), (name, s)


def test_temporal_families_follow_their_time_maps():
    clip = _clips()[1]
    T = clip.num_frames
    twice = mf.reverse(mf.reverse(clip, 0.5), 0.5)
    assert _same(twice, clip)
    frozen = mf.freeze(clip, 1.0)
    for b, c in zip(frozen.bodies, clip.bodies):
        np.testing.assert_allclose(b.trans, np.repeat(c.trans[:1], T, 0), atol=1e-6)     # frame 0 held
    fast = mf.speed(clip, 2.0)
    half = T // 2
    for b, c in zip(fast.bodies, clip.bodies):
        np.testing.assert_allclose(b.trans[:half], c.trans[0:2 * half:2], atol=1e-5)
    lag = int(round(0.2 * clip.fps))
    late = mf.desync(clip, 0.2)
    first = next(i for i, b in enumerate(clip.bodies) if not b.is_rigid)
    np.testing.assert_allclose(late.bodies[first].joints[lag:], clip.bodies[first].joints[:T - lag], atol=1e-6)
    for i, (b, c) in enumerate(zip(late.bodies, clip.bodies)):
        if i != first:
            np.testing.assert_array_equal(b.trans, c.trans)


def test_spatial_families_move_by_exactly_their_severity():
    clip = _clips()[0]
    rng = np.random.default_rng(0)
    up = mf.object_float(clip, 0.1)
    off = mf.grasp_offset(clip, 0.05, rng)
    pushed = mf.penetrate(clip, 0.02)
    first = next(i for i, b in enumerate(clip.bodies) if not b.is_rigid)
    for i, b in enumerate(clip.bodies):
        if b.is_rigid:
            np.testing.assert_allclose(up.bodies[i].trans - b.trans, [[0, 0.1, 0]] * b.num_frames, atol=1e-6)
            d = off.bodies[i].trans - b.trans
            np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 0.05, atol=1e-6)
            assert np.abs(d[:, 1]).max() < 1e-7                                 # horizontal
            np.testing.assert_array_equal(pushed.bodies[i].trans, b.trans)
    step = np.linalg.norm(pushed.bodies[first].joints - clip.bodies[first].joints, axis=-1)
    np.testing.assert_allclose(step, 0.02, atol=1e-6)
    noisy = [mf.joint_noise(clip, 0.01, clip_stream(7, "joint_noise", 2, clip.name)) for _ in range(2)]
    assert _same(noisy[0], noisy[1])                                   # the same stream: the same clip


def test_action_swap_keeps_the_labels_and_nests_its_selection():
    actions = {f"c{i:02d}": a for i, a in enumerate(["lift", "pass", "shake", "carry", "turn", "brush", "stir", "tap"])}
    prev = set()
    for i, f in enumerate((0.0, 0.25, 0.5, 1.0)):
        out = mf.action_swap(actions, f, seed=3, severity_index=i)
        assert sorted(out.values()) == sorted(actions.values())
        changed = {c for c in actions if out[c] != actions[c]}
        assert prev <= changed and len(changed) == round(f * len(actions))
        prev = changed


@pytest.fixture(scope="module")
def audited(tmp_path_factory):
    """The 54-clip synthetic multi-body track (13 test clips), a 200-step recognizer, the plain
    ground-truth result and the audit of :data:`AUDITED` (processes:2, 500 resamples)."""
    pytest.importorskip("matplotlib")
    from hoibench.audit.document import run_audit
    from hoibench.datasets import multibody as mbl
    from hoibench.datasets.store import PrepareConfig, prepare
    from hoibench.evaluator.recognizer import train_recognizer
    from hoibench.scoring.evaluate import evaluate
    from hoibench.scoring.multibody import write_multibody_submission
    base = tmp_path_factory.mktemp("mbaudit")
    mbl.write_synthetic_layout(base / "raw", 54, seed=0)
    cfg = PrepareConfig("multibody-synthetic", fps=syn.FPS)
    prepare(mbl.prepare_jobs(base / "raw", None, base / "data", cfg), base / "data", cfg)
    train_recognizer(base / "data", base / "rec", steps=200)
    gt = evaluate(write_multibody_submission(base / "data", base / "gt"), base / "data", base / "rec")
    doc = run_audit(base / "data", base / "rec", base / "out", families=list(AUDITED), resamples=500,
                    executor="processes:2", log=lambda _m: None)
    return base, gt, doc


def test_multibody_audit_severity_0_is_the_ground_truth_and_each_metric_sees_its_defect(audited):
    base, gt, doc = audited
    assert doc["layout"] == "multibody" and doc["families"] == list(AUDITED)
    assert doc["metrics"] == ["fid", "csr", "crr", "csiou", "iv_cm3", "id_mm", "od", "ra"]
    for m in doc["metrics"]:
        for f in AUDITED:
            assert doc["corruptions"][f]["values"][m][0] == pytest.approx(gt["metrics"][m]["mean"], abs=1e-12), (m, f)
    s = doc["summary"]
    assert s["fid"]["desync"]["spearman_worse"] > 0.5 and s["fid"]["desync"]["detectable_severity"] is not None
    assert s["iv_cm3"]["penetrate"]["spearman_worse"] > 0.5 and not s["iv_cm3"]["penetrate"]["blind"]
    assert s["ra"]["action_swap"]["spearman_worse"] > 0.5            # a wrong prompt: RA drops
    for m in ("fid", "iv_cm3", "id_mm", "csiou"):                    # the motion is untouched by a label swap
        assert s[m]["action_swap"]["blind"] and len(set(doc["corruptions"]["action_swap"]["values"][m])) == 1
    files = {p.name for p in (base / "out").iterdir()}
    assert {"audit.json", "heatmap.png", "README.md", "cards"} <= files
    assert "the track's recognizer" in (base / "out" / "README.md").read_text()


def test_multibody_audit_refuses_a_family_of_the_other_layout_in_one_line(audited, tmp_path, capsys):
    from hoibench.cli import main
    base = audited[0]
    argv = ["audit", "--data", str(base / "data"), "--evaluator", str(base / "rec"), "--out", str(tmp_path / "a"),
            "--families", "noun_swap"]
    assert main(argv) != 0
    err = [ln for ln in capsys.readouterr().err.strip().splitlines() if ln.strip() and not ln.startswith("[")]
    assert len(err) == 1 and "noun_swap" in err[0] and "multi-body" in err[0] and "Traceback" not in err[0]
    assert main(argv[:-1] + ["desync,nosuch"]) != 0
    assert "nosuch" in capsys.readouterr().err


def test_multibody_corrupted_sets_rerun_identically(audited):
    """A corrupted set scored again (serial) gives the same result as in the audit (processes:2)."""
    from hoibench.audit.runner import Condition, load_setup, score_conditions
    base, _, doc = audited
    setup = load_setup(base / "data", base / "rec")
    again = score_conditions(setup, ["desync"], 0, "serial")
    for i, sev in enumerate(doc["corruptions"]["desync"]["severities"]):
        res = again[Condition("desync", sev, i)][0]
        for m in doc["metrics"]:
            assert res["metrics"][m]["mean"] == doc["corruptions"]["desync"]["values"][m][i]
