"""The contact-aware text annotator on a synthetic store: objects, actions and body parts
named as the ground truth says, paraphrases, ordering, determinism, spec-driven output,
groups, HumanML3D text format, errors and kept human texts."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from hoibench.text import annotate as an
from hoibench.text.spec import UPOS
from hoibench.bodies import contact as contact_mod

N_CLIPS = 12


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    """(raw folder, store folder) of 12 synthetic clips prepared at 20 fps, annotated once."""
    pytest.importorskip("smplx")
    pytest.importorskip("trimesh")
    from hoibench.datasets import behave
    from hoibench.datasets.synthetic import write_behave_layout
    from hoibench.datasets.store import PrepareConfig, prepare

    base = tmp_path_factory.mktemp("annotate")
    raw, data = base / "raw", base / "data"
    write_behave_layout(raw, N_CLIPS, seed=0, progress=False)
    cfg = PrepareConfig("synthetic", fps=20.0)
    prepare(behave.prepare_jobs(raw, raw / "body_models", data, cfg, split_file=raw / "split.json"),
            data, cfg, source={"root": str(raw)})
    an.annotate_store(data, seed=0)
    return raw, data


@pytest.fixture(scope="module")
def spec():
    return an.load_spec()


def _copy_store(data: Path, dst: Path) -> Path:
    shutil.copytree(data, dst)
    return dst


def _words(phrase) -> str:
    return " ".join(t.surface for t in phrase if isinstance(t, an.Token))


def _verb_words(spec, action: str) -> set[str]:
    """First word of every 3rd-person paraphrase of the action ("lifts", "picks", ...)."""
    return {next(t.surface for t in v["s"] if isinstance(t, an.Token)) for v in spec.actions[action]["verbs"]}


def _unit_phrases(spec, unit: str) -> list[str]:
    entry = spec.combinations.get(unit) or spec.parts[unit]
    return [_words(p) for p in entry["phrases"]]


def _expected_unit(contacts: np.ndarray) -> tuple[str, list[str]]:
    """Named body part and base parts from ground-truth per-joint contacts."""
    joints = set(np.flatnonzero(contacts.any(0)).tolist())
    if {20, 21} <= joints:
        return "both_hands", ["left_hand", "right_hand"]
    table = {20: "left_hand", 21: "right_hand", 10: "left_foot", 11: "right_foot"}
    for j, part in table.items():
        if j in joints:
            return part, [part]
    assert {1, 2} & joints, joints
    return "hips", ["hips"]


def _annotation(data: Path, clip: str) -> dict:
    return json.loads((data / "annotations" / f"{clip}.json").read_text())


def _generated(ann: dict, whole: bool = True) -> list[dict]:
    return [t for t in ann["texts"] if t["source"] == an.SOURCE and (t["start"] == t["end"] == 0.0) == whole]


# ------------------------------------------------------------------ object, action, parts
def test_texts_name_object_action_and_body_parts(store, spec):
    raw, data = store
    index = json.loads((data / "annotations" / "index.json").read_text())
    assert index["annotator_version"] == spec.version and index["spec_sha256"] == spec.sha256
    assert index["counts"]["annotated"] == N_CLIPS and index["counts"]["failed"] == 0
    for clip in index["clips"]:
        gt = json.loads((raw / "sequences" / clip / "hoibench_gt.json").read_text())
        with np.load(raw / "sequences" / clip / "hoibench_gt.npz") as z:
            gt_contacts = z["contacts"]
        obj, action = gt["spec"]["object"], gt["spec"]["action"]
        ann = _annotation(data, clip)
        assert ann["object_name"] == obj and ann["actions"][0]["action"] == action
        nouns = [_words(p) for p in spec.objects[obj]["nouns"]]
        verbs = _verb_words(spec, action)
        unit, base = _expected_unit(gt_contacts)
        if gt["spec"]["hands"] in ("left", "right"):       # the ground truth's own hand label
            assert unit == f"{gt['spec']['hands']}_hand"
        phrases = _unit_phrases(spec, unit)
        texts = _generated(ann)
        assert len(texts) >= 3
        for t in texts:
            cap = t["caption"]
            assert any(n in cap for n in nouns), (clip, cap)
            assert verbs & set(cap.rstrip(".").replace(",", "").split()), (clip, cap)
            assert any(p in cap for p in phrases), (clip, unit, cap)
        category = spec.objects[obj]["category"]
        assert ann["group_id"] == f"{category}/{action}/{'+'.join(base)}"
        assert clip in index["groups"][ann["group_id"]]


def test_paraphrases_differ(store):
    raw, data = store
    for path in sorted((data / "annotations").glob("Date*.json")):
        caps = [t["caption"] for t in _generated(json.loads(path.read_text()))]
        assert len(caps) >= 3 and len(set(caps)) == len(caps), caps


def test_humanml3d_lines_parse_back(store):
    raw, data = store
    files = sorted((data / "texts").glob("*.txt"))
    assert len(files) == N_CLIPS
    for f in files:
        ann = _annotation(data, f.stem)
        lines = f.read_text().splitlines()
        assert len(lines) == len(ann["texts"])
        for line, t in zip(lines, ann["texts"]):
            fields = line.split("#")
            assert len(fields) == 4, line
            parsed = an.parse_humanml3d_line(line)
            assert parsed["caption"] == t["caption"] and parsed["tokens"] == t["tokens"]
            assert (parsed["start"], parsed["end"]) == (t["start"], t["end"])
            if t["start"] == t["end"] == 0.0:
                assert fields[2:] == ["0.0", "0.0"]
            for tok in fields[1].split(" "):
                word, _, pos = tok.partition("/")
                assert word.isalpha() and pos in UPOS, tok
            # nouns and verbs are lemmatised like HumanML3D ("hands" -> "hand", "lifts" -> "lift")
            assert "hands/" not in fields[1] and "lifts/" not in fields[1]


# ------------------------------------------------------------------ multi-action clips
def _two_segment_labels(T=100):
    lab = np.zeros((T, 22), dtype=bool)
    lab[10:45, [20, 21]] = True          # both hands 0.5-2.25 s
    lab[60:95, [1, 2]] = True            # hips 3.0-4.75 s
    return lab


def test_multi_action_clip_is_ordered_by_start_time(spec):
    lab = _two_segment_labels()
    # given in reverse order: described in order of start time
    ann = an.annotate_clip("Date01_Sub01_boxsmall_multi", lab, 20.0, "boxsmall",
                           [("sit", 3.0, 4.75), ("lift", 0.5, 2.25)], spec, seed=3)
    assert [a["action"] for a in ann.actions] == ["lift", "sit"]
    assert ann.actions[0]["named"] == ["both_hands"] and ann.actions[1]["parts"] == ["hips"]
    assert ann.group_id == "box/lift+sit/left_hand+right_hand+hips"
    lift, sit = _verb_words(spec, "lift"), _verb_words(spec, "sit")
    for t in [t for t in ann.texts if t["start"] == t["end"] == 0.0]:
        words = t["caption"].rstrip(".").replace(",", "").split()
        first_lift = min(i for i, w in enumerate(words) if w in lift)
        first_sit = min(i for i, w in enumerate(words) if w in sit)
        assert first_lift < first_sit, t["caption"]
        assert any(j in t["caption"] for j in ("and then", "then", " and ")), t["caption"]
    timed = [(t["start"], t["end"]) for t in ann.texts if t["end"] > 0]
    assert timed == [(0.5, 2.25), (3.0, 4.75)]


def test_overlapping_actions_join_with_while(spec):
    lab = np.zeros((100, 22), dtype=bool)
    lab[0:100, [20, 21]] = True
    lab[20:80, [1, 2]] = True
    ann = an.annotate_clip("c", lab, 20.0, "boxsmall", [("hold", 0.0, 5.0), ("sit", 1.0, 4.0)], spec)
    # the hands hold, the hips sit (actions.yaml `kinds`), although both overlap both actions
    assert [a["parts"] for a in ann.actions] == [["left_hand", "right_hand"], ["hips"]]
    for t in [t for t in ann.texts if t["start"] == t["end"] == 0.0]:
        assert "while" in t["caption"].split() or "while" in t["caption"].replace(",", "").split(), t["caption"]
        assert "sitting" in t["caption"] or "taking" in t["caption"]


# ------------------------------------------------------------------ determinism, spec-driven
def test_deterministic_for_a_seed_and_varies_with_another(store, tmp_path):
    raw, data = store
    a = an.annotate_store(data, seed=0, write=False)["annotations"]
    b = an.annotate_store(data, seed=0, write=False)["annotations"]
    c = an.annotate_store(data, seed=1, write=False)["annotations"]
    assert a == b
    caps = lambda d: {k: [t["caption"] for t in v["texts"]] for k, v in d.items()}   # noqa: E731
    assert caps(a) != caps(c)
    assert {k: v["group_id"] for k, v in a.items()} == {k: v["group_id"] for k, v in c.items()}
    # the written files are the seed-0 annotation, and a rerun rewrites them byte-identically
    assert all(_annotation(data, k) == v for k, v in a.items())
    copy = _copy_store(data, tmp_path / "copy")
    before = {p.name: p.read_bytes() for p in (copy / "texts").glob("*.txt")}
    an.annotate_store(copy, seed=0)
    assert {p.name: p.read_bytes() for p in (copy / "texts").glob("*.txt")} == before
    assert all(t["source"] == an.SOURCE for k in a for t in _annotation(copy, k)["texts"])


def test_process_executor_gives_identical_annotations(store):
    raw, data = store
    from hoibench.datasets.store import Store
    ids = Store(data).clip_ids()[:3]
    serial = an.annotate_store(data, clip_ids=ids, write=False)["annotations"]
    pooled = an.annotate_store(data, clip_ids=ids, write=False, executor="processes:2")["annotations"]
    assert serial == pooled


def test_editing_a_lexicon_file_changes_the_output(store, tmp_path, spec):
    raw, data = store
    spec_dir = tmp_path / "spec"
    shutil.copytree(an.default_spec_dir(), spec_dir)
    doc = yaml.safe_load((spec_dir / "actions.yaml").read_text())
    doc["actions"]["lift"]["verbs"] = [{"s": "hoists=hoist/VERB {obj}", "ing": "hoisting=hoist/VERB {obj}"}]
    (spec_dir / "actions.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    edited = an.load_spec(spec_dir)
    assert edited.sha256 != spec.sha256
    res = an.annotate_store(data, spec_dir=spec_dir, clip_ids=["Date01_Sub02_boxlarge_lift"], write=False)
    ann = res["annotations"]["Date01_Sub02_boxlarge_lift"]
    assert res["spec_sha256"] == edited.sha256
    for t in _generated(ann):
        assert "hoists" in t["caption"].split() and "hoist/VERB" in t["tokens"]
    assert not any("hoists" in t["caption"] for t in _annotation(data, "Date01_Sub02_boxlarge_lift")["texts"])


def test_bad_spec_is_rejected_with_its_file_and_entry(tmp_path):
    spec_dir = tmp_path / "spec"
    shutil.copytree(an.default_spec_dir(), spec_dir)
    objs = (spec_dir / "objects.yaml").read_text()
    (spec_dir / "objects.yaml").write_text(objs.replace('"stool/NOUN"', '"stool/NOUNS"'))
    with pytest.raises(an.SpecError, match=r"objects.yaml.objects.stool.nouns"):
        an.load_spec(spec_dir)
    (spec_dir / "objects.yaml").write_text(objs)
    top = (spec_dir / "spec.yaml").read_text()
    (spec_dir / "spec.yaml").write_text(top.replace('text: "{person} {verb}"', 'text: "{person} {verb} {method} {parts}"'))
    with pytest.raises(an.SpecError, match="no_contact"):
        an.load_spec(spec_dir)


# ------------------------------------------------------------------ no contact, errors, human texts
def _contact_words(spec) -> set[str]:
    words = set()
    for entry in list(spec.parts.values()) + list(spec.combinations.values()):
        for p in entry["phrases"]:
            words |= {t.surface for t in p if t.pos == "NOUN"}
    for p in spec.method:
        words |= {t.surface for t in p}
    for r in spec.relations.values():
        words |= {t.surface for form in ("s", "ing") for t in r[form] if isinstance(t, an.Token) and t.pos == "VERB"}
    return words


def test_clip_without_contact_has_no_contact_clause_and_its_own_group(spec):
    none = np.zeros((60, 22), dtype=bool)
    a = an.annotate_clip("Date01_Sub01_boxsmall_lift", none, 20.0, "boxsmall", "lift", spec)
    b = an.annotate_clip("Date01_Sub02_boxsmall_lift", none, 20.0, "boxsmall", "lift", spec)
    assert a.group_id == "nocontact/Date01_Sub01_boxsmall_lift" and a.group_id != b.group_id
    banned = _contact_words(spec)
    texts = a.generated
    assert len(texts) >= 3 and len({t["caption"] for t in texts}) == len(texts)
    for t in texts:
        assert not banned & set(t["caption"].rstrip(".").replace(",", "").split()), t["caption"]
        assert "small box" in t["caption"] or "little box" in t["caption"]
    # a clip whose only contact is a transition (shorter than min_frames) has no contact either
    blip = none.copy()
    blip[10:12, 20] = True
    c = an.annotate_clip("x", blip, 20.0, "boxsmall", "lift", spec)
    assert c.group_id == "nocontact/x" and c.timeline[0]["transition"]


def _add_clip(data: Path, src: str, new: str, drop=(), **replace) -> None:
    with np.load(data / "clips" / f"{src}.npz", allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files if k not in drop}
    arrays.update(replace)
    np.savez(data / "clips" / f"{new}.npz", **arrays)
    m = json.loads((data / "manifest.json").read_text())
    entry = dict(next(c for c in m["clips"] if c["id"] == src), id=new)
    m["clips"].append(entry)
    (data / "manifest.json").write_text(json.dumps(m))


def test_store_clip_without_contact_and_without_contacts_array(store, tmp_path, monkeypatch):
    raw, data = store
    copy = _copy_store(data, tmp_path / "copy")
    src = "Date02_Sub07_boxsmall_hold"
    T = len(np.load(copy / "clips" / f"{src}.npz")["joints"])
    _add_clip(copy, src, "Date04_Sub01_boxsmall_hold", contacts=np.zeros((T, 22), dtype=bool))
    _add_clip(copy, src, "Date04_Sub02_boxsmall_hold", drop=("contacts",))
    monkeypatch.delattr(contact_mod, "joint_contact_labels", raising=False)
    res = an.annotate_store(copy)
    assert res["annotations"]["Date04_Sub01_boxsmall_hold"]["group_id"] == "nocontact/Date04_Sub01_boxsmall_hold"
    errors = [json.loads(l) for l in (copy / "annotations" / "errors.jsonl").read_text().splitlines()]
    assert [e["clip"] for e in errors] == ["Date04_Sub02_boxsmall_hold"]
    assert "contacts" in errors[0]["error"]
    assert not (copy / "annotations" / "Date04_Sub02_boxsmall_hold.json").exists()
    index = json.loads((copy / "annotations" / "index.json").read_text())
    assert index["counts"]["failed"] == 1 and "Date04_Sub02_boxsmall_hold" not in index["clips"]
    with pytest.raises(RuntimeError, match="Date04_Sub02_boxsmall_hold"):
        an.annotate_store(copy, strict=True)

    # when hoibench.bodies.contact can compute contacts, the annotator uses it
    calls = []

    def fake_labels(joints, vertices, faces, rot, trans, object_name):
        calls.append(object_name)
        lab = np.zeros((len(joints), 22), dtype=bool)
        lab[:, 21] = True
        return lab

    monkeypatch.setattr(contact_mod, "joint_contact_labels", fake_labels, raising=False)
    res = an.annotate_store(copy, clip_ids=["Date04_Sub02_boxsmall_hold"], write=False)
    ann = res["annotations"]["Date04_Sub02_boxsmall_hold"]
    assert calls == ["boxsmall"] and ann["contacts_source"].startswith("computed")
    assert ann["group_id"] == "box/hold/right_hand"
    assert all("right hand" in t["caption"] for t in _generated(ann))


def test_human_texts_are_kept_beside_generated_ones(store, tmp_path):
    raw, data = store
    copy = _copy_store(data, tmp_path / "copy")
    clip = "Date01_Sub01_yogamat_carry"
    human = "a man walks forward holding a mat.#a/DET man/NOUN walk/VERB forward/ADV hold/VERB a/DET mat/NOUN#0.0#0.0"
    path = copy / "texts" / f"{clip}.txt"
    path.write_text(human + "\n" + path.read_text())       # a human line beside the generated ones
    _add_clip(copy, clip, "Date05_Sub01_yogamat_carry",
              texts=np.array([json.dumps({"caption": "someone carries a yoga mat", "start": 0.0, "end": 0.0,
                                          "source": "omomo_text_anno"})]))
    for _ in range(2):   # a rerun neither loses nor duplicates them
        an.annotate_store(copy)
        ann = _annotation(copy, clip)
        assert ann["texts"][0] == {"caption": "a man walks forward holding a mat.",
                                   "tokens": "a/DET man/NOUN walk/VERB forward/ADV hold/VERB a/DET mat/NOUN",
                                   "start": 0.0, "end": 0.0, "source": "human"}
        assert [t["source"] for t in ann["texts"]].count("human") == 1
        assert path.read_text().splitlines()[0] == human
        other = _annotation(copy, "Date05_Sub01_yogamat_carry")
        assert [t["source"] for t in other["texts"]][:2] == ["omomo_text_anno", an.SOURCE]
        assert [t["caption"] for t in other["texts"]].count("someone carries a yoga mat") == 1


# ------------------------------------------------------------------ per-second labels, preview
def test_behave_per_second_labels_give_timed_actions(store, tmp_path):
    raw, data = store
    clip = "Date01_Sub01_yogamat_carry"
    stamps = [(3.0, "0"), (4.0, "3"), (5.0, "1"), (6.0, "5")]   # raw clips start at t0003.000
    labels = {"label_description": [{"id": "0", "description": "no_interaction"},
                                    {"id": "1", "description": "action_transition"},
                                    {"id": "3", "description": "carry (one hand lift)"},
                                    {"id": "5", "description": "hold (front)"}],
              "action_label": [{"name": clip, "frame": f"t{t:08.3f}", "label": l} for t, l in stamps]}
    path = tmp_path / "action_label.json"
    path.write_text(json.dumps(labels))
    res = an.annotate_store(data, labels=path, clip_ids=[clip], write=False)
    ann = res["annotations"][clip]
    acts = [(a["action"], a["start"], a["end"]) for a in ann["actions"]]
    assert acts == [("none", 0.0, 1.0), ("carry", 1.0, 2.0), ("hold", 3.0, 3.5)]
    assert ann["actions"][0]["parts"] == [] and ann["actions"][1]["named"] == ["both_hands"]
    assert ann["group_id"] == "mat/carry+hold/left_hand+right_hand"
    assert any("provenance source_start_s" in n for n in ann["notes"])
    assert [(t["start"], t["end"]) for t in ann["texts"] if t["end"] > 0] == [(0.0, 1.0), (1.0, 2.0), (3.0, 3.5)]


def test_every_behave_label_description_is_in_the_lexicon(spec):
    ref = Path(__file__).resolve().parents[2] / "shared" / "reference-data" / "hoi-diff" / "action_label.json"
    if not ref.exists():
        pytest.skip("HOI-Diff action_label.json not available")
    descriptions = [d["description"] for d in json.loads(ref.read_text())["label_description"]]
    assert len(descriptions) == 15          # ids 0-14: 13 actions + no_interaction + action_transition
    assert all(d in spec.labels["behave"] for d in descriptions)


def test_preview_table_and_main_annotate_preview_write_nothing(store, tmp_path, capsys):
    raw, data = store
    copy = _copy_store(data, tmp_path / "copy")
    shutil.rmtree(copy / "annotations")
    shutil.rmtree(copy / "texts")
    table = an.preview_table(copy, 3)
    from hoibench.datasets.store import Store
    for clip in Store(copy).clip_ids()[:3]:
        ann = _annotation(data, clip)
        assert clip in table and ann["group_id"] in table and ann["object_name"] in table
        assert ann["texts"][0]["caption"] in table and ann["texts"][1]["caption"] in table
    assert "left_hand 1.1-4.2s" in table        # Date01_Sub01_boxlarge_pull's timeline
    assert an.main_annotate(copy, preview=2) == 0
    assert "Date01_Sub01_boxlarge_pull" in capsys.readouterr().out
    assert not (copy / "annotations").exists() and not (copy / "texts").exists()
    assert an.main_annotate(copy) == 0 and (copy / "annotations" / "index.json").exists()
