"""CORE4D-Real loader on hoibench's license-free CORE4D layout (proxy SMPL-X body), checked
against ground truth the writer computes with the proxy's numpy forward pass; resampling by
time; bad files through the store; the writer's determinism; ids and the official split."""
from __future__ import annotations

import hashlib
import json
import shutil

import numpy as np
import pytest

pytest.importorskip("smplx")
pytest.importorskip("trimesh")

from hoibench.bodies.proxy import write_proxy_model  # noqa: E402
from hoibench.datasets import core4d  # noqa: E402
from hoibench.datasets import core4d_layout as cl  # noqa: E402
from hoibench.bodies.multibody import MultiBodyClip  # noqa: E402
from hoibench.datasets.store import PrepareConfig, Store, prepare  # noqa: E402

TOL_M = 1e-4
N_SEQ = 3
#: sha256 of json.dumps(sorted(ids)) of the three official lists in
#: leolyliu/CORE4D-Instructions benchmarks/dataset_statistics/ (commit 96b9084).
OFFICIAL_SHA = {
    "train": ("93f07b0760ddd9223ec5995790acdf6f1de2c86cc91760be9a1558eeb0dec1cd", 482),
    "test_seen_obj": ("8aa945103a92d31ffd977338f17f63d10e3349b4b4355710b815a7b55caf6c43", 225),
    "test_unseen_obj": ("c6d1c923c69d3815b8376a26c7e347321dfd1344b6b228df4644d8e890f07a78", 255),
}


def _prepare(raw, out, fps, split_file=None):
    cfg = PrepareConfig("core4d", fps=fps, body_model_type="smplx")
    jobs = core4d.prepare_jobs(raw, raw / "body_models", out, cfg, split_file=split_file)
    manifest = prepare(jobs, out, cfg)
    errors = [json.loads(x) for x in (out / "errors.jsonl").read_text().splitlines()]
    return manifest, errors


def _clips(out):
    st = Store(out)
    return {cid: MultiBodyClip.from_arrays(st.load(cid), st.object_template) for cid in st.clip_ids()}


def _gt(raw, cid):
    with np.load(raw / "hoibench_gt" / f"{cid}.npz") as z:
        return {k: z[k] for k in z.files}


def _errors(clip, gt, frames, gt_frames):
    obj = clip.of_kind("object")[0].name
    return (max(float(np.abs(clip.body(p).joints[frames] - gt[f"{p}_joints"][gt_frames]).max())
                for p in core4d.PERSONS),
            float(np.abs(clip.object_vertices(obj, frames) - gt["object_vertices"][gt_frames]).max()))


@pytest.fixture(scope="module")
def raw(tmp_path_factory):
    root = tmp_path_factory.mktemp("core4d") / "raw"
    cl.write_core4d_layout(root, N_SEQ, seed=0)
    return root


@pytest.fixture(scope="module")
def store15(raw):
    out = raw.parent / "out15"
    manifest, errors = _prepare(raw, out, 15.0)
    return out, manifest, errors


# --------------------------------------------------------------------------- split
def test_official_split_is_the_released_lists():
    lists = core4d.official_lists()
    for name, (sha, count) in OFFICIAL_SHA.items():
        assert len(lists[name]) == count
        assert hashlib.sha256(json.dumps(sorted(lists[name])).encode()).hexdigest() == sha
    assert not set(lists["train"]) & (set(lists["test_seen_obj"]) | set(lists["test_unseen_obj"]))
    assert core4d.official_split("20231002.004") == ("train", "train")
    assert core4d.official_split("20231108.0-1") == ("test", "test_seen_obj")
    assert core4d.official_split("20231002.009") == ("test", "test_unseen_obj")
    with pytest.raises(KeyError):
        core4d.official_split("20231002.099")


# --------------------------------------------------------------------------- fidelity
def test_prepared_clips_match_independent_ground_truth(raw, store15):
    out, manifest, errors = store15
    assert errors == [] and manifest["counts"]["clips"] == N_SEQ and manifest["incomplete"] == []
    splits = {c["id"]: c["split"] for c in manifest["clips"]}
    assert splits == {"20231002.004": "train", "20231002.001": "test", "20231002.009": "test"}
    clips = _clips(out)
    worst = 0.0
    for k, (date, seq, obj, action) in enumerate(cl.SEQUENCES[:N_SEQ]):
        cid = f"{date}.{seq}"
        clip, gt = clips[cid], _gt(raw, cid)
        assert clip.signature() == "human,human,object" and clip.dataset == "core4d" and clip.fps == 15.0
        assert [b.name for b in clip.bodies] == ["person1", "person2", obj]
        assert clip.num_frames == len(gt["times"]) == 24 + 3 * k
        ej, ev = _errors(clip, gt, slice(None), slice(None))
        assert ej < TOL_M and ev < TOL_M, (cid, ej, ev)
        worst = max(worst, ej, ev)
        v, _ = clip.templates[obj]
        assert np.abs(np.asarray(v, np.float64).mean(0)).max() < 1e-6          # centred template
        assert clip.action == action and clip.texts == [] and clip.contacts == {}
        assert clip.body("person1").joints[:, :, 1].min() > -0.01             # floor at y = 0
        prov = clip.provenance
        assert abs(prov["floor_shift_m"] - float(gt["floor_shift_m"])) < 1e-5
        assert prov["source_fps"] == 15.0 and prov["core4d_split_list"] == core4d.official_split(cid)[1]
        assert all(d < 1e-5 for d in prov["stored_joints_max_dev_m"].values())
        np.testing.assert_allclose(clip.body("person1").trans, clip.body("person1").joints[:, 0], atol=1e-6)
    print(f"max error vs ground truth at 15 fps: {worst:.3g} m")


def test_resampled_by_time(raw, store15):
    out15, _, _ = store15
    c15 = _clips(out15)
    for fps, step_gt in ((30.0, 1), (10.0, 3)):      # output frame 2m is at source frame m * step_gt
        out = raw.parent / f"out{int(fps)}"
        manifest, errors = _prepare(raw, out, fps)
        assert errors == [] and manifest["counts"]["clips"] == N_SEQ
        for cid, clip in _clips(out).items():
            gt = _gt(raw, cid)
            T = len(gt["times"])
            assert clip.num_frames == int(np.floor((T - 1) / 15.0 * fps + 1e-9)) + 1 and clip.fps == fps
            frames = np.arange(0, clip.num_frames, 2)
            ej, ev = _errors(clip, gt, frames, frames // 2 * step_gt)
            assert ej < TOL_M and ev < TOL_M, (fps, cid, ej, ev)
            assert clip.provenance["resampled_to_fps"] == fps
            assert clip.provenance["floor_shift_m"] == c15[cid].provenance["floor_shift_m"]
            if fps == 30.0:      # in-between frames lie between their neighbours (smooth motion)
                J = clip.body("person2").joints
                mid = 0.5 * (J[0:-2:2] + J[2::2])
                assert np.abs(J[1:-1:2] - mid).max() < 0.01


# --------------------------------------------------------------------------- bad input
def _corrupt_layout(root):
    """Six sequences, five of them broken in one file each."""
    real = root / "CORE4D_Real"
    broken = {}
    for k in range(6):
        prm = cl.sequence_params(k, seed=3)
        p1, p2, poses = dict(prm["person1"]), dict(prm["person2"]), prm["obj_poses"].copy()
        for p in (p1, p2):
            p.pop("vertices")                          # not read by the loader: keeps the test small
        if k == 0:
            p1.pop("transl")
        elif k == 1:
            p2["body_pose"] = p2["body_pose"][:, :20]
        elif k == 2:
            poses[5, 1, 3] = np.nan
        elif k == 4:
            p1["joints"] = p1["joints"] + np.float32(0.1)
        cl.write_sequence(real, prm["date"], prm["seq"], p1, p2, poses, prm["obj_name"], prm["vertices"],
                          prm["faces"])
        broken[f"{prm['date']}.{prm['seq']}"] = k
        if k == 3:                                     # a truncated person file
            path = real / "human_object_motions" / prm["date"] / prm["seq"] / "person2_poses.npz"
            path.write_bytes(path.read_bytes()[:5000])
    write_proxy_model(root / "body_models", "smplx")
    return broken


def test_a_bad_file_fails_only_its_sequence(tmp_path):
    raw = tmp_path / "raw"
    broken = _corrupt_layout(raw)
    manifest, errors = _prepare(raw, tmp_path / "out", 15.0)
    assert [c["id"] for c in manifest["clips"]] == ["20231108.0-1"]
    msg = {e["sequence"]: e["error"] for e in errors}
    assert len(msg) == 5
    by_k = {k: msg[cid] for cid, k in broken.items() if k != 5}
    assert "20231002.004: human_object_motions/20231002/004/person1_poses.npz: missing key 'transl'" in by_k[0]
    assert "person2_poses.npz: body_pose: expected shape (T, 21, 3) or (T, 63), got (27, 20, 3)" in by_k[1]
    assert "smooth_objposes.npy" in by_k[2] and "non-finite" in by_k[2] and "(5, 1, 3)" in by_k[2]
    assert "person2_poses.npz: unreadable" in by_k[3]
    assert "person1_poses.npz: joints:" in by_k[4] and "0.1" in by_k[4]
    for cid, k in broken.items():
        if k != 5:
            assert msg[cid].startswith(cid)


def test_bad_action_labels_and_the_legacy_pose_file(tmp_path):
    raw = tmp_path / "raw"
    cl.write_core4d_layout(raw, 1, seed=0)
    real = raw / "CORE4D_Real"
    seq_dir = real / "human_object_motions" / "20231002" / "004"
    (seq_dir / "smooth_objposes.npy").rename(seq_dir / "object_poses_box001.npy")   # the pre-July-2024 name
    (real / "action_labels.json").write_text(json.dumps({"20231002/004": 7}))
    manifest, errors = _prepare(raw, tmp_path / "out1", 15.0)
    assert manifest["counts"]["clips"] == 0
    assert "action_labels.json: entry '20231002/004': expected an action label" in errors[0]["error"]
    (real / "action_labels.json").write_text("{not json")
    manifest, errors = _prepare(raw, tmp_path / "out2", 15.0)
    assert manifest["counts"]["clips"] == 1 and len(manifest["incomplete"]) == 1
    assert "action_labels.json: unreadable" in manifest["incomplete"][0]
    clip = _clips(tmp_path / "out2")["20231002.004"]
    assert clip.action is None and clip.provenance["object_pose_file"] == "object_poses_box001.npy"
    ej, ev = _errors(clip, _gt(raw, "20231002.004"), slice(None), slice(None))
    assert ej < TOL_M and ev < TOL_M


def test_ids_and_split_are_checked(tmp_path):
    raw = tmp_path / "raw"
    cl.write_core4d_layout(raw, 1, seed=0)
    motions = raw / "CORE4D_Real" / "human_object_motions"
    shutil.copytree(motions / "20231002" / "004", motions / "20231002" / "bad seq")
    shutil.copytree(motions / "20231002" / "004", motions / "20231002" / "099")
    manifest, errors = _prepare(raw, tmp_path / "out", 15.0)
    assert [c["id"] for c in manifest["clips"]] == ["20231002.004"]
    msg = {e["sequence"]: e["error"] for e in errors}
    assert "not listed in CORE4D's official split" in msg["20231002.099"]
    bad = [m for s, m in msg.items() if s.startswith("invalid-id-")]
    assert len(bad) == 1 and "'bad seq'" in bad[0] and "not a valid id" in bad[0]
    split = tmp_path / "split.json"
    split.write_text(json.dumps({"train": ["20231002.099"], "test": ["20231002.004", "20231002.555"]}))
    manifest, errors = _prepare(raw, tmp_path / "out_split", 15.0, split_file=split)
    assert {c["id"]: c["split"] for c in manifest["clips"]} == {"20231002.099": "train", "20231002.004": "test"}
    msg = {e["sequence"]: e["error"] for e in errors}
    assert "listed in split file" in msg["20231002.555"] and len(msg) == 2


# --------------------------------------------------------------------------- writer
def test_writer_is_deterministic_and_in_core4d_format(tmp_path):
    a, b, c = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    for root, seed in ((a, 5), (b, 5), (c, 6)):
        cl.write_core4d_layout(root, 2, seed=seed, body_model=False)
    files = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file())
    for f in files:
        assert (a / f).read_bytes() == (b / f).read_bytes(), f
    person = "CORE4D_Real/human_object_motions/20231002/004/person1_poses.npz"
    assert (a / person).read_bytes() != (c / person).read_bytes()
    # read as CORE4D's instructions read it
    d = np.load(a / person, allow_pickle=True)["arr_0"].item()
    shapes = {k: (v.shape, v.dtype) for k, v in d.items()}
    T = 24
    assert shapes == {"vertices": ((T, 10475, 3), np.float32), "joints": ((T, 127, 3), np.float32),
                      "betas": ((T, 10), np.float32), "expression": ((T, 10), np.float32),
                      "global_orient": ((T, 3), np.float32), "transl": ((T, 3), np.float32),
                      "body_pose": ((T, 21, 3), np.float32), "left_hand_pose": ((T, 12), np.float32),
                      "right_hand_pose": ((T, 12), np.float32)}
    seq = a / "CORE4D_Real/human_object_motions/20231002/004"
    poses = np.load(seq / "smooth_objposes.npy")
    assert poses.shape == (T, 4, 4) and poses.dtype == np.float64
    assert json.loads((seq / "object_metadata.json").read_text())["obj_name"] == "box001"
    assert (a / "CORE4D_Real/object_models/box/box001_m.obj").is_file()
    assert len((seq / "aligned_frame_ids.txt").read_text().splitlines()) == T
    assert json.loads((a / "CORE4D_Real/action_labels.json").read_text()) == {"20231002/001": "raise_rot",
                                                                              "20231002/004": "move1"}
