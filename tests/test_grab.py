"""GRAB loader (hoibench.datasets.grab) on license-free fixtures in GRAB's layout
(hoibench.datasets.grab_layout): accuracy against independently computed ground truth,
resampling by time, per-sequence failures, ids, splits, a deterministic writer."""
import json
import shutil

import numpy as np
import pytest

from hoibench.datasets import grab
from hoibench.datasets.grab_layout import GT_DIR, grab_npz_bytes, write_grab_layout
from hoibench.bodies.multibody import MultiBodyClip
from hoibench.datasets.store import PrepareConfig, Store, prepare

N_SEQ = 4           # s2 (train), s1 (val), s10 (test), s5 (train, female)
TOL = 1e-4          # metres


@pytest.fixture(scope="module")
def layout(tmp_path_factory):
    root = tmp_path_factory.mktemp("grab_raw")
    manifest = write_grab_layout(root, N_SEQ, seed=0)
    return root, manifest


def _prepare(root, out, fps, with_table=False, split_file=None):
    cfg = PrepareConfig("grab", fps=fps, body_model_type="smplx")
    jobs = grab.prepare_jobs(root, root / "body_models", out, cfg, split_file=split_file, with_table=with_table)
    return prepare(jobs, out, cfg, source={"root": str(root)})


def _clips(out):
    store = Store(out)
    return {cid: MultiBodyClip.from_arrays(store.load(cid), store.object_template) for cid in store.clip_ids()}


def _errors(out):
    return {e["sequence"]: e["error"] for e in map(json.loads, (out / "errors.jsonl").read_text().splitlines())}


def _max_errors(clip, gt, step):
    """Largest distance (m) per body between the clip and the ground truth at every
    ``step``-th source frame."""
    err = {}
    for b in clip.bodies:
        if b.kind == "human":
            ref, got = gt["human_joints"], b.joints
        elif b.kind == "hand":
            ref, got = gt[f"{b.side}_hand_joints"], b.joints
        else:
            ref, got = gt["table_vertices" if b.name == "table" else "object_vertices"], clip.object_vertices(b.name)
        ref = ref[::step]
        assert got.shape == ref.shape, (clip.name, b.name)
        err[b.name] = float(np.linalg.norm(got - ref, axis=-1).max())
    return err


@pytest.fixture(scope="module")
def store30(layout, tmp_path_factory):
    pytest.importorskip("smplx")
    root, _ = layout
    out = tmp_path_factory.mktemp("grab_store30")
    return out, _prepare(root, out, 30.0, with_table=True)


def test_prepare_matches_ground_truth_at_source_rate(layout, tmp_path):
    pytest.importorskip("smplx")
    root, manifest = layout
    out = tmp_path / "store120"
    m = _prepare(root, out, 120.0)
    assert m["counts"]["clips"] == N_SEQ
    clips = _clips(out)
    worst = 0.0
    for entry in manifest["sequences"]:
        clip = clips[entry["clip_id"]]
        gt = dict(np.load(root / GT_DIR / f"{entry['clip_id']}.npz"))
        assert clip.signature() == "human,hand:left,hand:right,object"            # no table by default
        assert clip.num_frames == entry["frames"] and clip.fps == 120.0
        assert {b.owner for b in clip.of_kind("hand")} == {"human"}
        err = _max_errors(clip, gt, 1)
        worst = max(worst, max(err.values()))
        obj = entry["object"]
        for body, key in (("right_hand", "contact_right"), ("left_hand", "contact_left"), ("human", "contact_human")):
            np.testing.assert_array_equal(clip.contacts[(body, obj)], gt[key])
        assert clip.provenance["floor_shift_m"] == pytest.approx(float(gt["floor_shift_m"]), abs=1e-6)
    assert worst < TOL, worst


def test_resampled_to_30fps_with_table(layout, store30):
    root, manifest = layout
    out, m = store30
    assert m["counts"]["clips"] == N_SEQ
    clips = _clips(out)
    for entry in manifest["sequences"]:
        clip = clips[entry["clip_id"]]
        gt = dict(np.load(root / GT_DIR / f"{entry['clip_id']}.npz"))
        assert clip.fps == 30.0 and clip.num_frames == len(gt["human_joints"][::4])
        assert clip.signature() == "human,hand:left,hand:right,object,object"
        assert clip.provenance["source_fps"] == 120.0 and clip.provenance["resampled_to_fps"] == 30.0
        err = _max_errors(clip, gt, 4)
        assert max(err.values()) < TOL, (entry["clip_id"], err)
        for body, key in (("right_hand", "contact_right"), ("left_hand", "contact_left"), ("human", "contact_human")):
            np.testing.assert_array_equal(clip.contacts[(body, entry["object"])], gt[key][::4])
    # templates: centred on their vertex mean
    v, _ = Store(out).object_template(manifest["sequences"][0]["object"])
    assert np.abs(v.mean(0)).max() < 1e-6


def test_split_subjects_and_incomplete(layout, store30):
    _, manifest = layout
    out, m = store30
    split = {c["id"]: c["split"] for c in m["clips"]}
    imos = {"s1": "val", "s10": "test"}
    assert split == {e["clip_id"]: imos.get(e["subject"], "train") for e in manifest["sequences"]}
    # the synthetic fixture holds 4 of GRAB's 10 subject folders and says so (hoibench_synthetic.json)
    assert m["incomplete"] == []


def test_a_real_download_missing_subject_folders_is_incomplete(layout, tmp_path):
    import shutil
    root, _ = layout
    copy = tmp_path / "raw"
    shutil.copytree(root, copy)
    (copy / "hoibench_synthetic.json").unlink()
    cfg = PrepareConfig("grab", fps=30.0, body_model_type="smplx")
    m = prepare(grab.prepare_jobs(copy, copy / "body_models", tmp_path / "out", cfg), tmp_path / "out", cfg)
    assert len(m["incomplete"]) == 10 - N_SEQ and all("missing" in x for x in m["incomplete"])


def test_rerun_skips_and_keeps_bytes(layout, store30):
    root, _ = layout
    out, m = store30
    before = {p.name: p.read_bytes() for p in (out / "clips").iterdir()}
    again = _prepare(root, out, 30.0, with_table=True)
    assert again["clips"] == m["clips"]
    assert {p.name: p.read_bytes() for p in (out / "clips").iterdir()} == before


def test_split_file_overrides(layout, tmp_path):
    root, manifest = layout
    ids = [e["clip_id"] for e in manifest["sequences"]]
    sf = tmp_path / "split.json"
    sf.write_text(json.dumps({"train": ids[:2], "test": [ids[2], "s9_not_there"]}))
    jobs = grab.prepare_jobs(root, root / "body_models", tmp_path / "out", PrepareConfig("grab", fps=30.0),
                             split_file=sf)
    by_id = {j[0]: j for j in jobs}
    assert [by_id[i][1] for i in ids[:3]] == ["train", "train", "test"]
    assert "not listed in split file" in by_id[ids[3]][5][0]
    assert "listed in split file" in by_id["s9_not_there"][5][0]


def _rewrite(path, change):
    """Load a fixture sequence (our own file: pickles trusted), ``change`` its entries, write
    it back as GRAB stores it."""
    with np.load(path, allow_pickle=True) as z:
        d = {k: z[k].item() if z[k].shape == () else z[k] for k in z.files}
    change(d)
    path.write_bytes(grab_npz_bytes(d))


class _Foreign:
    def __reduce__(self):
        return (print, ("this must never run",))


def test_bad_sequences_fail_alone(layout, tmp_path):
    pytest.importorskip("smplx")
    src, manifest = layout
    root = tmp_path / "raw"
    shutil.copytree(src, root)
    s2 = root / "grab" / "s2"
    base = s2 / "cubesmall_lift.npz"
    for k in range(2, 7):
        shutil.copy(base, s2 / f"cubesmall_lift_{k}.npz")
    shutil.copy(base, s2 / "bad name.npz")                          # not a valid id
    shutil.copy(base, s2 / "Cubesmall_lift_6.npz")                  # case-folded duplicate of _6
    shutil.copy(base, s2 / "cubesmall_lift_verts_body.npz")         # save_grab_vertices.py output: skipped
    _rewrite(base, lambda d: d.pop("rhand"))
    _rewrite(s2 / "cubesmall_lift_2.npz",
             lambda d: d["rhand"]["params"].update(hand_pose=d["rhand"]["params"]["hand_pose"][:, :23]))

    def nan(d):
        d["body"]["params"]["transl"][5, 1] = np.nan
    _rewrite(s2 / "cubesmall_lift_3.npz", nan)
    _rewrite(s2 / "cubesmall_lift_4.npz", lambda d: d["body"].update(vtemp="../../outside.ply"))
    _rewrite(s2 / "cubesmall_lift_5.npz", lambda d: d["object"]["params"].update(transl=_Foreign()))

    out = tmp_path / "store"
    m = _prepare(root, out, 30.0)
    good = {e["clip_id"] for e in manifest["sequences"]} - {"s2_cubesmall_lift"}
    assert {c["id"] for c in m["clips"]} == good
    err = _errors(out)
    assert "cubesmall_lift.npz" in err["s2_cubesmall_lift"] and "'rhand'" in err["s2_cubesmall_lift"]
    e2 = err["s2_cubesmall_lift_2"]
    assert "cubesmall_lift_2.npz" in e2 and "rhand/params/hand_pose" in e2 and "(97, 23)" in e2
    e3 = err["s2_cubesmall_lift_3"]
    assert "cubesmall_lift_3.npz" in e3 and "body/params/transl" in e3 and "non-finite" in e3
    e4 = err["s2_cubesmall_lift_4"]
    assert "body/vtemp" in e4 and "leaves the GRAB folder" in e4
    e5 = err["s2_cubesmall_lift_5"]
    assert "cubesmall_lift_5.npz" in e5 and "refused global builtins.print" in e5
    assert "duplicate clip id" in err["s2_cubesmall_lift_6"] and "duplicate clip id" in err["s2_Cubesmall_lift_6"]
    invalid = [v for k, v in err.items() if k.startswith("invalid-id-")]
    assert len(invalid) == 1 and "bad name" in invalid[0] and "not a valid id" in invalid[0]
    assert not any("verts_body" in k for k in err) and not (out / "clips" / "s2_cubesmall_lift_verts_body.npz").exists()
    assert sorted(p.stem for p in (out / "clips").iterdir()) == sorted(good)


def test_mesh_must_be_the_sequences_own(layout, tmp_path):
    """A vtemp naming another subject's template is refused (the checksum would miss it)."""
    pytest.importorskip("smplx")
    src, _ = layout
    root = tmp_path / "raw"
    shutil.copytree(src, root)
    path = root / "grab" / "s2" / "cubesmall_lift.npz"
    _rewrite(path, lambda d: d["body"].update(vtemp="tools/subject_meshes/male/s1.ply"))
    assets = tuple(str(p) for p in grab.conventional_assets(root, "s2", "cubesmall"))
    with pytest.raises(grab.SequenceError, match="body/vtemp.*not one of GRAB's files"):
        grab.load_sequence(path, root / "body_models", 30.0, root=root, assets=assets)


def test_writer_is_deterministic(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    write_grab_layout(a, 2, seed=3)
    write_grab_layout(b, 2, seed=3)
    files_a = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    files_b = sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file())
    assert files_a == files_b and len(files_a) > 10
    for rel in files_a:
        assert (a / rel).read_bytes() == (b / rel).read_bytes(), rel


def test_file_is_read_as_grab_reads_it(layout):
    """GRAB's own reader (np.load + .item()) and hoibench's restricted one agree."""
    root, manifest = layout
    path = root / manifest["sequences"][0]["file"]
    seq = grab.read_sequence_npz(path)
    with np.load(path, allow_pickle=True) as z:
        ref = {k: z[k].item() for k in z.files}
    assert set(seq) == set(ref) == {"gender", "sbj_id", "obj_name", "motion_intent", "framerate", "n_frames",
                                    "n_comps", "body", "lhand", "rhand", "object", "table", "contact"}
    assert seq["framerate"] == 120.0 and seq["n_comps"] == 24 and isinstance(seq["gender"], str)
    for part in ("body", "lhand", "rhand", "object", "table"):
        for k, v in ref[part]["params"].items():
            np.testing.assert_array_equal(seq[part]["params"][k], v)
    assert seq["body"]["params"]["fullpose"].shape[1] == 165 and seq["rhand"]["params"]["fullpose"].shape[1] == 45
    assert seq["contact"]["body"].shape[1] == 10475
