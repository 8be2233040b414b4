"""InterAct's object-to-human and human-to-object tasks as tracks (interact-o2h, interact-h2o)
on a synthetic InterAct-layout store (12 sequences, 4 test clips of 36 frames).

The synthetic clips hold the object 7-50 cm from the body, never within InterAct's 5 cm, so
the scoring tests use a copy of each protocol with a 0.3 m contact threshold (every test
clip's full marker set then touches the object in some frames): the contact scores have
something to score. The shipped 5 cm is tested where it is read (the protocol fields)."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from hoibench.cli import main

TASKS = ("o2h", "h2o")
#: metrics each row must lose strictly against the ground truth (the errors and full-marker F1)
STRICT = {"o2h": ("o2h_hand_jpe", "o2h_mpvpe", "o2h_jpe_full", "o2h_contact_f1_full"),
          "h2o": ("h2o_mpvpe", "h2o_mpmpe", "h2o_t_err", "h2o_o_err", "h2o_contact_f1")}


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    pytest.importorskip("smplx")
    from interact_fixture import prepare_interact_store
    from hoibench.scoring.interact_task_files import write_task_reference
    from hoibench.tracks.protocol import get_protocol
    root = tmp_path_factory.mktemp("interact_tasks")
    prepare_interact_store(root / "raw", root / "data")
    protos = {}
    for task in TASKS:
        text = open(get_protocol(f"interact-{task}-clean").source).read()
        protos[task] = root / f"{task}.yaml"
        protos[task].write_text(text.replace("contact_threshold_m: 0.05 ", "contact_threshold_m: 0.3 "))
        for kind in ("gt", "static-first-pose"):
            write_task_reference(kind, root / "data", root / f"{task}-{kind}", task)
    return root, protos


def _evaluate(root, sub, proto, executor="serial"):
    from hoibench.scoring.evaluate import evaluate
    return evaluate(sub, root / "data", None, protocol=str(proto), executor=executor)


def test_tracks_are_listed_and_a_protocol_selects_its_track(setup, capsys, tmp_path):
    from hoibench.datasets.store import Store
    from hoibench.scoring.evaluate import evaluate
    from hoibench.scoring.pipeline import EvaluationRefused
    from hoibench.tracks.protocol import get_protocol
    from hoibench.tracks.registry import track_for
    root, _ = setup
    assert main(["tracks", "ls"]) == 0
    out = capsys.readouterr().out
    assert "interact-o2h" in out and "interact-h2o" in out and "interact-o2h-clean" in out
    st = Store(root / "data")
    assert track_for(st).name == "interact"                          # the default is unchanged
    assert track_for(st, get_protocol("interact-clean")).name == "interact"
    for task in TASKS:
        p = get_protocol(f"interact-{task}-clean")
        assert track_for(st, p).name == f"interact-{task}" and p.contact_threshold_m == 0.05
    assert (get_protocol("interact-o2h-clean").samples_per_prompt, get_protocol("interact-o2h-clean").selection) == \
        (10, "o2h_jpe_full")
    assert (get_protocol("interact-h2o-clean").samples_per_prompt, get_protocol("interact-h2o-clean").selection) == \
        (5, "h2o_mpvpe")
    # a store of another dataset: the task protocol belongs to no track of it, refused in one line
    other = tmp_path / "other"
    shutil.copytree(root / "data", other)
    m = json.loads((other / "manifest.json").read_text())
    (other / "manifest.json").write_text(json.dumps({**m, "dataset": "behave"}))
    with pytest.raises(EvaluationRefused, match=r"^protocol interact-o2h-clean@1.0 is a interact-task protocol; .* "
                                                r"behave track, scored under hoi protocols [^\n]*$"):
        evaluate(root / "o2h-gt", other, None, protocol="interact-o2h-clean")


def test_prompts_carry_each_tasks_condition(setup, tmp_path):
    from hoibench.datasets.store import Store
    root, _ = setup
    st = Store(root / "data")
    for task in TASKS:
        out = tmp_path / task / "prompts.jsonl"
        assert main(["submission", "prompts", str(root / "data"), "--protocol", f"interact-{task}-clean",
                     "--out", str(out)]) == 0
        lines = [json.loads(s) for s in out.read_text().splitlines()]
        assert [p["id"] for p in lines] == st.clip_ids("test")
        for p in lines:
            assert p["task"] == task and p["condition"] == str((out.parent / "conditions" / f"{p['id']}.npz").resolve())
            cond, clip = dict(np.load(p["condition"])), st.load(p["id"])
            np.testing.assert_allclose(cond["object_points"], clip["object_sample_points"])
            if task == "o2h":       # the object's motion, not the human's
                assert set(cond) == {"object_points", "obj_rot", "obj_rotvec", "obj_trans"}
                np.testing.assert_allclose(cond["obj_rot"], clip["obj_rot"])
                np.testing.assert_allclose(cond["obj_trans"], clip["obj_trans"])
                assert "markers" in p["submit"]
            else:                   # the human's markers, not the object's pose
                assert set(cond) == {"object_points", "markers"}
                assert cond["markers"].shape == (p["frames"], 77, 3)
                np.testing.assert_allclose(cond["markers"], clip["markers"])
                assert set(p["submit"]) == {"obj_rot", "obj_trans"}
    with pytest.raises(ValueError, match="--out is required"):
        from hoibench.scoring.prompts import write_prompts
        write_prompts(root / "data", None, protocol="interact-h2o-clean")


@pytest.mark.parametrize("task", TASKS)
def test_ground_truth_is_perfect_and_the_static_row_worse(setup, task):
    from hoibench.metrics.catalog import METRICS
    root, protos = setup
    gt = _evaluate(root, root / f"{task}-gt", protos[task])
    static = _evaluate(root, root / f"{task}-static-first-pose", protos[task])
    g, s = gt["metrics"], static["metrics"]
    assert gt["complete"] and gt["track"] == f"interact-{task}" and gt["counts"]["scored_ids"] == 4
    errors = [n for n in g if METRICS[n].direction == "lower" and "foot_sliding" not in n]
    assert all(abs(g[n]["mean"]) < 1e-9 for n in errors), {n: g[n]["mean"] for n in errors}
    f1 = f"{task}_contact_f1" + ("_full" if task == "o2h" else "")
    assert g[f1]["mean"] == 1.0 and g[f1]["interval"] == "clips" and g[f1]["n"] == 4
    for name in g:
        a, b, info = g[name]["mean"], s[name]["mean"], METRICS[name]
        if name.startswith(f"{task}_gt_"):
            assert a == b                                     # the ground truth's own value
        elif "foot_sliding" in name:
            assert b == 0.0 < a                               # a body held still cannot slide
        elif info.direction == "lower":
            assert b >= a, name
        elif info.direction == "higher":
            assert b <= a, name
        else:                                                 # best at the ground truth's value
            twin = g[f"{task}_gt_{name.partition('_')[2]}"]["mean"]
            assert abs(b - twin) >= abs(a - twin), name
    for name in STRICT[task]:
        worse = s[name]["mean"] > g[name]["mean"] if METRICS[name].direction == "lower" else \
            s[name]["mean"] < g[name]["mean"]
        assert worse, name


def test_best_of_k_keeps_the_selected_sample_and_k_over_the_protocol_is_refused(setup, tmp_path):
    from hoibench.scoring.submission import validation_report, write_submission
    root, protos = setup
    meta = json.loads((root / "o2h-gt" / "submission.json").read_text())
    samples = {}
    for sid in sorted(p.stem for p in (root / "o2h-gt" / "samples").glob("*.npz")):
        g = np.load(root / "o2h-gt" / "samples" / f"{sid}.npz")["markers"][0]
        s = np.load(root / "o2h-static-first-pose" / "samples" / f"{sid}.npz")["markers"][0]
        samples[sid] = {"markers": np.stack([s, g, g + 0.02]).astype(np.float32)}
    write_submission(tmp_path / "k3", {**meta, "flags": {**meta["flags"], "samples_per_prompt": 3}}, samples)
    res = _evaluate(root, tmp_path / "k3", protos["o2h"])
    assert res["counts"]["samples_per_prompt"] == 3 and res["metrics"]["o2h_jpe_full"]["mean"] == 0.0
    assert {r["sample"] for r in res["per_clip"]["rows"]} == {1}
    h = {sid: {"obj_rot": np.repeat(a["obj_rot"], 6, 0), "obj_trans": np.repeat(a["obj_trans"], 6, 0)}
         for sid, a in ((p.stem, np.load(p)) for p in (root / "h2o-gt" / "samples").glob("*.npz"))}
    write_submission(tmp_path / "k6", meta, h)
    errs = validation_report(tmp_path / "k6", root / "data", protocol="interact-h2o-clean").errors
    assert errs and all("K = 6 samples, over the protocol's 5" in p.message for p in errs if p.id != "*")


def test_a_wrong_shaped_array_is_refused_in_one_line_naming_file_id_and_field(setup, tmp_path, capsys):
    from hoibench.scoring.evaluate import evaluate
    from hoibench.scoring.pipeline import EvaluationRefused
    from hoibench.scoring.submission import write_submission
    root, _ = setup
    meta = json.loads((root / "o2h-gt" / "submission.json").read_text())
    ids = sorted(p.stem for p in (root / "o2h-gt" / "samples").glob("*.npz"))
    bad = {sid: {"markers": np.load(root / "o2h-gt" / "samples" / f"{sid}.npz")["markers"][:, :, :70]}
           for sid in ids}
    write_submission(tmp_path / "bad", meta, bad)
    assert main(["validate", str(tmp_path / "bad"), "--data", str(root / "data"),
                 "--protocol", "interact-o2h-clean"]) == 1
    lines = [s for s in capsys.readouterr().out.splitlines() if s.startswith("error:")]
    want = f"error: {ids[0]}: markers: samples/{ids[0]}.npz: expected shape (K, T, 77, 3), got (1, 36, 70, 3)"
    assert want in lines
    with pytest.raises(EvaluationRefused, match=rf"^{tmp_path / 'bad'}: no valid test id to score \(4 error\(s\), e\.g\. "
                                                rf"{ids[0]}: markers: samples/{ids[0]}\.npz: expected shape [^\n]*$"):
        evaluate(tmp_path / "bad", root / "data", None, protocol="interact-o2h-clean")
    rot = {sid: {"obj_rotvec": np.zeros((1, 36, 3), np.float32), "obj_trans": np.zeros((1, 36, 2), np.float32)}
           for sid in ids}
    write_submission(tmp_path / "badh", meta, rot)
    assert main(["validate", str(tmp_path / "badh"), "--data", str(root / "data"),
                 "--protocol", "interact-h2o-clean"]) == 1
    assert f"error: {ids[0]}: obj_trans: samples/{ids[0]}.npz: expected shape (K, T, 3), got (1, 36, 2)" in \
        capsys.readouterr().out


def test_results_are_identical_on_serial_and_processes_and_the_cli_needs_no_evaluator(setup, tmp_path, capsys):
    root, protos = setup
    for task in TASKS:
        sub = root / f"{task}-static-first-pose"
        a, b = _evaluate(root, sub, protos[task]), _evaluate(root, sub, protos[task], "processes:2")
        for r in (a, b):
            r.pop("timings_s")
        assert a == b
    out = tmp_path / "r.json"
    assert main(["evaluate", str(root / "h2o-gt"), "--data", str(root / "data"), "--protocol", "interact-h2o-clean",
                 "--out", str(out)]) == 0
    res = json.loads(out.read_text())
    assert res["evaluator_backend"] == "none" and res["metrics"]["h2o_mpvpe"]["mean"] == 0.0
    assert "interact-h2o-clean@1.0" in capsys.readouterr().out
    assert main(["evaluate", str(root / "h2o-gt"), "--data", str(root / "data")]) != 0
    assert "--evaluator: required" in capsys.readouterr().err


def test_the_documented_generation_loop_makes_a_valid_submission(setup, tmp_path, monkeypatch):
    """docs/leaderboards.md's o2h loop, run as written with a stand-in model."""
    from pathlib import Path

    from hoibench.datasets.store import Store
    from hoibench.scoring.submission import validation_report
    root, _ = setup
    doc = (Path(__file__).resolve().parent.parent / "docs" / "leaderboards.md").read_text()
    code = doc.split("Ten lines (o2h):\n\n```python\n", 1)[1].split("```", 1)[0]
    monkeypatch.chdir(tmp_path)
    assert main(["submission", "prompts", str(root / "data"), "--protocol", "interact-o2h-clean",
                 "--out", "o2h/prompts.jsonl"]) == 0
    first = Store(root / "data").load(Store(root / "data").clip_ids("test")[0], keys=("markers",))["markers"][0]

    def my_model(caption, obj_rot, obj_trans, points):
        return np.repeat(first[None, None], len(obj_rot), 1).repeat(2, 0)     # (K = 2, T, 77, 3)
    exec(code, {"my_model": my_model})
    rep = validation_report(tmp_path / "my_o2h", root / "data", protocol="interact-o2h-clean")
    assert rep.complete and rep.samples_per_prompt == 2, [str(p) for p in rep.problems]


def test_a_task_protocol_on_another_datasets_store_is_refused_in_one_line(template_store, tmp_path, capsys):
    """prompts and reference rows refuse an o2h/h2o protocol on a store of another dataset, as
    evaluate does, instead of writing the store's own rows under it."""
    for argv in (["submission", "prompts", str(template_store), "--protocol", "interact-h2o-clean",
                  "--out", str(tmp_path / "p.jsonl")],
                 ["submission", "reference", str(template_store), "--protocol", "interact-o2h-clean", "--kind", "gt",
                  "--out", str(tmp_path / "ref")]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "interact-task protocol" in err and "synthetic track" in err, err
    assert not (tmp_path / "p.jsonl").exists() and not (tmp_path / "ref").exists()
