"""The rich-cat track on a human-only store (hoibench's synthetic RICH layout): the annotator
names the scene object a clip's action is done on and the body parts that touch it, groups
by the scene object's category; a joints-only ground-truth submission validates and scores
FID ~ 0 with the object metrics reported as not applicable (never NaN); a submission
missing `joints` is refused naming the id and the field."""
from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

pytest.importorskip("smplx")
pytest.importorskip("trimesh")

from hoibench.text import annotate as an  # noqa: E402

N_SEQUENCES = 40           # -> 30 clips of 64 frames at 20 fps (19 train, 5 val, 6 test)
#: scenes.yaml: the synthetic actions' scene objects, and the scene exception the layout hits
SCENE_OBJECT = {"lift": "box", "carry": "box", "putdown": "box", "hold": "box", "push": "table",
                "pull": "chair", "sit": "chair", "kick": "ball"}
SCENE_EXCEPTIONS = {("Gym", "sit"): "bench"}
OBJECT_METRICS = ("cd", "ocd", "ps", "penetration_depth_max_m", "penetration_depth_mean_m", "contact_iou",
                  "hand_contact_ratio", "object_floating_ratio")


@pytest.fixture(scope="module")
def rich_store(tmp_path_factory):
    """(base folder, store) of the synthetic RICH layout prepared at 20 fps and annotated."""
    from hoibench.datasets import rich
    from hoibench.datasets import synthetic_layouts as sl
    from hoibench.datasets.store import PrepareConfig, prepare

    base = tmp_path_factory.mktemp("rich_track")
    raw, data = base / "raw", base / "data"
    sl.write_rich_layout(raw, N_SEQUENCES, seed=0)
    cfg = PrepareConfig("rich", fps=20.0, body_model_type="smplx")
    prepare(rich.prepare_jobs(raw, raw / "body_models", data, cfg), data, cfg, source={"root": str(raw)})
    an.annotate_store(data, seed=0)
    return base, data


@pytest.fixture(scope="module")
def spec():
    return an.load_spec()


@pytest.fixture(scope="module")
def scored(rich_store):
    """A few-epoch tiny evaluator (the gate cannot pass on 6 test clips: scored with the
    override) and the ground-truth submission's result."""
    pytest.importorskip("transformers")
    pytest.importorskip("open3d")
    from hoibench.scoring.evaluate import evaluate
    from hoibench.evaluator import main_train_evaluator
    from hoibench.scoring.submission import from_store

    base, data = rich_store
    main_train_evaluator(data, base / "ev", size="tiny", epochs=3, seed=0)
    from_store(data, base / "gt")
    return base, evaluate(base / "gt", data, base / "ev", allow_failed_gate=True)


def _words(phrase) -> str:
    return " ".join(t.surface for t in phrase if isinstance(t, an.Token))


# ------------------------------------------------------------------ the annotator
def test_real_rich_sequence_names_give_the_action_and_its_scene_object(spec):
    cases = {"Gym_010_pushup1": ("pushup", "ground"), "Gym_013_dips2": ("dips", "bench"),
             "LectureHall_009_021_reparingprojector1": ("reparingprojector", "table"),
             "ParkingLot1_004_005_greetingchattingeating1": ("greetingchattingeating", "table"),
             "ParkingLot2_009_overfence1": ("overfence", "fence"),
             "Pavallion_002_sidebalancerun": ("sidebalancerun", "ground"),
             "LectureHall_019_wipingchairs1": ("wipingchairs", "chair")}
    for seq, (action, obj) in cases.items():
        got = an.scene_action_name(f"{seq}_010_00003", {"sequence": seq, "scene": seq.split("_")[0]})
        assert got == action, seq
        assert an.scene_partner(spec, got, seq.split("_")[0])[0] == obj, seq
    assert an.scene_action_name("Gym_010_pushup1_010_00003") == "pushup"          # from the clip id
    assert an.scene_partner(spec, "sit", "Gym") == ("bench", "scenes.Gym.sit")
    assert an.scene_partner(spec, "sit", "BBQ") == ("chair", "actions.sit")
    assert an.scene_partner(spec, "stretching", "ParkingLot1") == ("fence", "scenes.ParkingLot1.stretching")
    assert an.scene_partner(spec, "cartwheel", "Gym") == ("ground", "default")
    # every action scenes.yaml lists is an action of the lexicon (directly or by alias)
    for name in spec.scenes["actions"]:
        assert an.resolve_action(spec, name)[1], name


def test_human_only_clip_names_the_scene_object_and_only_the_action_kinds_parts(spec):
    T = 60
    c = np.zeros((T, 22), bool)
    c[:, [20, 21, 10, 11, 7, 8]] = True                 # hands and feet on the floor
    ann = an.annotate_clip("Gym_010_pushup1_010_00003", c, 20.0, "ground", "pushup", spec,
                           scene_partner={"object": "ground"})
    assert ann.object_name == "ground" and ann.scene_partner == {"object": "ground"}
    assert ann.group_id.startswith("ground/pushup/") and "left_hand+right_hand" in ann.group_id
    for t in ann.generated:
        assert "ground" in t["caption"] or "floor" in t["caption"], t["caption"]
        assert " a ground" not in t["caption"] and " a floor" not in t["caption"]      # "the ground"
    wipe = an.annotate_clip("LectureHall_019_wipingchairs1_019_00003", c, 20.0, "chair", "wipingchairs", spec,
                            scene_partner={"object": "chair"})
    assert wipe.group_id == "chair/wipe/left_hand+right_hand"        # the feet touch the floor, not the chair
    assert all("feet" not in t["caption"] and "foot" not in t["caption"] for t in wipe.generated)
    # a clip with an object is described as before: no scene partner recorded
    obj = an.annotate_clip("Date01_Sub01_boxsmall_lift", c, 20.0, "boxsmall", "lift", spec)
    assert "scene_partner" not in obj.to_json() and obj.group_id.startswith("box/lift/")


def test_rich_store_texts_name_the_scene_object_and_the_parts_in_contact(rich_store, spec):
    base, data = rich_store
    index = json.loads((data / "annotations" / "index.json").read_text())
    assert index["counts"]["failed"] == 0 and index["counts"]["annotated"] == index["counts"]["clips"] >= 25
    assert index["annotator_version"] == spec.version == "1.1.0"
    seen = set()
    for clip in index["clips"]:
        ann = json.loads((data / "annotations" / f"{clip}.json").read_text())
        partner = ann["scene_partner"]
        scene, action = partner["scene"], partner["action"]
        assert clip.startswith(f"{scene}_") and action in SCENE_OBJECT, clip
        want = SCENE_EXCEPTIONS.get((scene, action), SCENE_OBJECT[action])
        assert ann["object_name"] == partner["object"] == want, clip
        entry = spec.scenes["objects"][want]
        nouns = [_words(p) for p in entry["nouns"]]
        act = ann["actions"][0]
        assert act["action"] == action
        kinds = spec.actions[action]["kinds"]
        assert all(spec.parts[p]["kind"] in kinds for p in act["parts"]), (clip, act["parts"])
        for t in (t for t in ann["texts"] if t["source"] == an.SOURCE):
            assert any(n in t["caption"] for n in nouns), (clip, t["caption"])
            for unit in act["named"]:
                e = spec.combinations.get(unit) or spec.parts[unit]
                assert any(_words(p) in t["caption"] for p in e["phrases"]), (clip, unit, t["caption"])
        if act["parts"]:
            assert ann["group_id"] == f"{entry['category']}/{action}/{'+'.join(act['parts'])}"
            assert clip in index["groups"][ann["group_id"]]
            seen.add(entry["category"])
        else:
            assert ann["group_id"] == f"nocontact/{clip}"
    assert {"box", "chair", "table"} <= seen
    lines = (data / "texts" / f"{index['clips'][0]}.txt").read_text().splitlines()
    assert len(lines) == 3 and all(an.parse_humanml3d_line(l)["tokens"] for l in lines)


# ------------------------------------------------------------------ evaluator, submission, evaluate
def test_hoi_evaluator_on_a_human_only_store_is_one_line(rich_store, tmp_path):
    from hoibench.evaluator import main_train_evaluator
    base, data = rich_store
    with pytest.raises(ValueError, match="human-only") as exc:
        main_train_evaluator(data, tmp_path / "ev", variant="hoi", epochs=1)
    assert "\n" not in str(exc.value) and "--variant human" in str(exc.value)


def test_rich_store_is_scored_under_rich_cat_clean(rich_store):
    from hoibench.tracks.protocol import default_protocol_id
    from hoibench.datasets.store import Store
    assert default_protocol_id(Store(rich_store[1]).manifest) == "rich-cat-clean"


def test_joints_only_gt_submission_validates_and_scores_fid_zero_without_object_metrics(scored):
    from hoibench.scoring.submission import validation_report
    base, res = scored
    rep = validation_report(base / "gt", base / "data")
    assert rep.complete and not rep.errors and not rep.warnings
    for f in (base / "gt" / "samples").glob("*.npz"):
        with np.load(f) as z:
            assert "joints" in z.files and not {"obj_rot", "obj_rotvec", "obj_trans"} & set(z.files)
    assert res["protocol"] == "rich-cat-clean" and res["submission_complete"]
    assert [o["override"] for o in res["overrides"]] == ["failed_gate"]        # 6 test clips
    m = res["metrics"]
    assert abs(m["fid"]["mean"]) < 1e-4
    for name in ("r_precision_top1", "mm_dist", "diversity", "fsr", "fsr_gmd", "jitter_mps3"):
        assert np.isfinite(np.asarray(m[name]["mean"], float)).all(), name
    for name in OBJECT_METRICS:
        assert name not in m and "not applicable" in res["undefined_metrics"][name], name
        assert all(name not in row for row in res["per_replication"])
    json.dumps(res, allow_nan=False)                       # strict JSON: no NaN anywhere


def test_human_only_submission_missing_joints_is_refused_naming_id_and_field(scored, tmp_path, capsys):
    from hoibench.scoring.submission import main_validate, validation_report
    base, _ = scored
    sub = tmp_path / "sub"
    shutil.copytree(base / "gt", sub)
    victim, extra = sorted((sub / "samples").glob("*.npz"))[:2]
    with np.load(victim) as z:
        arrays = {k: z[k] for k in z.files if k != "joints"}
    np.savez(victim, **arrays)
    with np.load(extra) as z:                               # object arrays on a human-only clip: a warning
        arrays = dict(z)
    K, T = arrays["joints"].shape[:2]
    np.savez(extra, **arrays, obj_rotvec=np.zeros((K, T, 3), np.float32), obj_trans=arrays["joints"][:, :, 0])
    rep = validation_report(sub, base / "data")
    assert not rep.complete and victim.stem not in rep.valid_ids and extra.stem in rep.valid_ids
    [err] = rep.errors
    assert (err.id, err.field) == (victim.stem, "joints")
    assert {(w.id, w.field) for w in rep.warnings} == {(extra.stem, "obj_rotvec"), (extra.stem, "obj_trans")}
    assert main_validate(sub, base / "data") == 1
    out = capsys.readouterr().out
    assert f"error: {victim.stem}: joints: missing" in out


def test_catmo_trains_and_samples_a_human_only_store_into_a_joints_only_submission(rich_store, tmp_path):
    """CATMO's home track: no object head, no object condition, joints-only submissions."""
    from hoibench.baselines.catmo.config import preset
    from hoibench.baselines.catmo.trainer import train
    from hoibench.baselines.sampler import sample
    from hoibench.scoring.submission import validation_report

    _, data = rich_store
    cfg = preset("tiny").replace(**{"train.vq_steps": 2, "train.contact_steps": 2, "text.movement_ae_steps": 1,
                                   "text.match_steps": 1, "train.gpt_steps": 2, "object.steps": 5,
                                   "train.batch_size": 4, "vq.window": 16})
    res = train(data, tmp_path / "run", cfg, log=None)
    assert res.card["dataset"]["with_object"] is False and "object" not in res.card["curves"]
    from safetensors.torch import load_file
    keys = load_file(tmp_path / "run" / "weights.safetensors").keys()
    assert any(k.startswith("model.gpt.") for k in keys)
    assert not any(k.startswith(("model.object_head.", "model.points.", "stats.object")) for k in keys)
    sub = sample(tmp_path / "run", data, tmp_path / "sub", samples=2, log=None)
    with np.load(next((sub / "samples").iterdir())) as z:
        assert sorted(z.files) == ["joints"] and z["joints"].shape[0] == 2
    rep = validation_report(sub, data)
    assert rep.complete and not rep.problems, rep.problems[:3]
