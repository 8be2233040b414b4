"""TACO and OAKINK2 loaders on hoibench's license-free release-layout fixtures (proxy MANO),
checked against ground truth the writers compute with the proxy hand's numpy forward and the
object poses directly; resampling by time; the official lists; refusals; the torch-free
tensor pickles against torch itself; the multi-body track scoring the prepared stores."""
from __future__ import annotations

import hashlib
import json
import pickle
import shutil
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("smplx")
pytest.importorskip("trimesh")

from hoibench.bodies.multibody import MultiBodyClip  # noqa: E402
from hoibench.cli import main  # noqa: E402
from hoibench.datasets import oakink2, taco, torch_pickle as tp  # noqa: E402
from hoibench.datasets import oakink2_layout as ol, taco_layout as tl  # noqa: E402
from hoibench.datasets.behave import SequenceError  # noqa: E402
from hoibench.datasets.store import PrepareConfig, Store, prepare  # noqa: E402

TOL_M = 1e-4
#: sha256 of json.dumps(sorted lines) of leolyliu/TACO-Instructions c06f82c
#: data_lists/v1_overall_data_train_test_split.txt ("<seq>,<list>" lines, 2317).
TACO_LIST_SHA = "6a7ba59d4a5880634c4898f002bcfce510f56a4ed59f79216cb50e381e2504ea"
#: sha256 of json.dumps(sorted keys) of oakink/OakInk2-TaMF 4cb9c46 asset/split/<split>.txt.
OAKINK2_SHA = {"train": ("d9789ddbb3ca63fbfd0f90d402ce663d5c52092d85955f7eed734f6a02aef5ab", 431),
               "val": ("2913eb95245bd2cb4f38dd3853a3c6f4a050bc38763b90f2ed6a7619ed9939aa", 39),
               "test": ("0e838880d72cd2b7824a364efa0910459d25ece2e1fd2ca1169dc287baa608b2", 157)}


def _clips(out):
    st = Store(out)
    return {cid: MultiBodyClip.from_arrays(st.load(cid), st.object_template) for cid in st.clip_ids()}


def _gt(path):
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def _worst(clip, gt, step=1):
    errs = []
    for name, want in gt.items():
        got = clip.body(name).joints if name.endswith("_hand") else clip.object_vertices(name)
        assert got.shape == want[::step].shape, name
        errs.append(float(np.abs(got - want[::step]).max()))
    return max(errs)


def _layout_fixtures(prefix: str, layout: str, clips: int, fps: int):
    """The module-scoped fixtures ``<prefix>_raw`` (``clips`` clips of ``layout``'s release
    layout, synthesised) and ``<prefix>_store`` (those prepared at ``fps``)."""
    @pytest.fixture(scope="module", name=f"{prefix}_raw")
    def raw(tmp_path_factory) -> Path:
        root = tmp_path_factory.mktemp(layout) / "raw"
        assert main(["synth", "--layout", layout, "--out", str(root), "--clips", str(clips)]) == 0
        return root

    @pytest.fixture(scope="module", name=f"{prefix}_store")
    def store(request) -> Path:
        root = request.getfixturevalue(f"{prefix}_raw")
        out = root.parent / "data"
        assert main(["prepare", layout, "--root", str(root), "--body-models", str(root / "body_models"),
                     "--out", str(out), "--fps", str(fps)]) == 0
        return out

    return raw, store


taco_raw, taco_store = _layout_fixtures("taco", "taco", 5, 30)
oi_raw, oi_store = _layout_fixtures("oi", "oakink2", 3, 120)


# --------------------------------------------------------------------------- splits
def test_official_lists_are_the_released_ones():
    lists = taco.official_lists()
    lines = sorted(f"{s},{n}" for s, n in lists.items())
    assert len(lines) == 2317 and hashlib.sha256(json.dumps(lines).encode()).hexdigest() == TACO_LIST_SHA
    assert taco.official_split("20231105_019") == ("test", "test_4") and taco.official_split("20990101_001") is None
    from hoibench.datasets.splits import get
    sp = get("oakink2", "official")
    for s, (sha, n) in OAKINK2_SHA.items():
        keys = sorted(i.replace(".", "/", 1) for i in sp[s])
        assert len(keys) == n and hashlib.sha256(json.dumps(keys).encode()).hexdigest() == sha, s
    assert not set(sp["train"]) & set(sp["test"]) and not set(sp["val"]) & set(sp["test"])


def test_datasets_ls_and_the_docs_list_every_loader(capsys):
    from hoibench.datasets.catalog import loader_names
    from hoibench.cli import SYNTH_LAYOUTS, build_parser
    names = loader_names()
    prepare = next(a for a in build_parser()._subparsers._group_actions[0].choices["prepare"]._actions
                   if a.dest == "dataset")
    assert list(prepare.choices) == names and {"taco", "oakink2"} <= set(SYNTH_LAYOUTS)
    assert main(["datasets", "ls"]) == 0
    out = capsys.readouterr().out
    docs = (Path(__file__).resolve().parents[1] / "docs" / "datasets.md").read_text()
    table = docs[docs.index("## Every loader"):docs.index("## BEHAVE")]
    for n in names:
        assert f"\n{n}\n" in f"\n{out}" and f"| `{n}` |" in table, n


# --------------------------------------------------------------------------- TACO
def test_taco_prepares_to_the_ground_truth(taco_raw, taco_store):
    manifest = json.loads((taco_store / "manifest.json").read_text())
    assert {c["id"]: c["split"] for c in manifest["clips"]} == {
        s: ("train" if lst == "train" else "test") for s, *_, lst in tl.SEQUENCES}
    clips = _clips(taco_store)
    worst = 0.0
    for seq, folder, tool, target, lst in tl.SEQUENCES:
        clip = clips[seq]
        assert clip.signature() == "hand:left,hand:right,object,object" and clip.fps == 30.0
        assert [b.name for b in clip.bodies] == ["left_hand", "right_hand", "tool", "target"]
        assert clip.body("tool").template == f"taco_{tool}" and clip.provenance["taco_split"] == lst
        assert clip.action == taco.parse_triplet(folder)[0] and clip.texts[0]["source"] == "taco-triplet-template"
        worst = max(worst, _worst(clip, _gt(taco_raw / "hoibench_gt" / f"{seq}.npz")))
    assert worst < TOL_M, worst
    assert clips["20230917_032"].provenance["betas_source"]["left"].startswith("absent")
    # resampled by time: 15 fps = every second source frame
    seq, folder = tl.SEQUENCES[0][:2]
    c15 = taco.load_sequence(taco_raw / "Hand_Poses" / folder / seq, taco_raw, taco_raw / "body_models", 15.0)
    assert _worst(c15, _gt(taco_raw / "hoibench_gt" / f"{seq}.npz"), step=2) < TOL_M


def test_taco_tips_are_smplx_vertices_not_manopth(taco_raw, taco_store):
    """Joints 16-20 are smplx's MANO tips; manopth's 745/317/444/556/673 would miss them."""
    from hoibench.bodies.proxy_hand import ProxyHand
    clip = _clips(taco_store)[tl.SEQUENCES[1][0]]
    gt = _gt(taco_raw / "hoibench_gt" / f"{tl.SEQUENCES[1][0]}.npz")
    h = ProxyHand("right")
    v, j = h.forward(np.zeros(3), np.zeros(45))
    assert np.abs(v[0, [745, 317, 444, 556, 673]] - v[0, h.tip_ids]).max() > TOL_M
    assert np.abs(clip.body("right_hand").joints[:, 16:] - gt["right_hand"][:, 16:]).max() < TOL_M


def _copy_taco(taco_raw, tmp_path, k=0):
    seq, folder = tl.SEQUENCES[k][:2]
    root = tmp_path / "raw"
    for sub in ("Hand_Poses", "Object_Poses"):
        shutil.copytree(taco_raw / sub / folder / seq, root / sub / folder / seq)
    shutil.copytree(taco_raw / "Object_Models", root / "Object_Models")
    return root, root / "Hand_Poses" / folder / seq, root / "Object_Poses" / folder / seq


@pytest.mark.parametrize("defect, message", [
    ("global", "refused global (os|posix).system"), ("pose47", r"hand_pose \(47,\)"), ("nonrigid", "not a rotation"),
    ("count", "frame counts differ"), ("two_tools", "exactly one tool_")])
def test_taco_refuses_bad_files(taco_raw, tmp_path, defect, message):
    import os
    root, hdir, odir = _copy_taco(taco_raw, tmp_path)
    if defect == "global":
        (hdir / "left_hand.pkl").write_bytes(pickle.dumps({"00001": os.system}))
    elif defect == "pose47":
        d = tp.load(hdir / "right_hand.pkl")
        d["00003"]["hand_pose"] = tp.Tensor(d["00003"]["hand_pose"][:47])
        (hdir / "right_hand.pkl").write_bytes(tp.dumps({k: {n: tp.Tensor(v) if not isinstance(v, tp.Tensor) else v
                                                            for n, v in fr.items()} for k, fr in d.items()}))
    else:
        tool = next(odir.glob("tool_*.npy"))
        P = np.load(tool)
        if defect == "nonrigid":
            P[4, :3, :3] *= 1.1
        elif defect == "count":
            P = P[:-1]
        else:
            np.save(odir / "tool_999.npy", P)
        np.save(tool, P)
    with pytest.raises(SequenceError, match=message):
        taco.load_sequence(hdir, root, taco_raw / "body_models", 30.0)


def test_taco_refuses_a_folder_triplet_other_than_the_list(taco_raw, tmp_path):
    assert taco.official_triplets()["20231105_019"] == "(stir, spoon, bowl)" and len(taco.official_triplets()) == 2317
    root, hdir, odir = _copy_taco(taco_raw, tmp_path)
    other = "(brush, brush, bowl)"
    for d in (hdir, odir):
        (d.parent.parent / other).mkdir()
        shutil.move(d, d.parent.parent / other / d.name)
    with pytest.raises(SequenceError, match=r"puts 20230927_032 under \(dust, roller, pan\)"):
        taco.load_sequence(root / "Hand_Poses" / other / hdir.name, root, taco_raw / "body_models", 30.0)


def test_taco_unlisted_sequence_fails_through_the_store(taco_raw, tmp_path):
    root, hdir, odir = _copy_taco(taco_raw, tmp_path)
    shutil.move(hdir, hdir.parent / "20990101_001")
    shutil.move(odir, odir.parent / "20990101_001")
    cfg = PrepareConfig("taco", fps=30.0)
    manifest = prepare(taco.prepare_jobs(root, taco_raw / "body_models", tmp_path / "out", cfg), tmp_path / "out", cfg)
    err = (tmp_path / "out" / "errors.jsonl").read_text()
    assert manifest["counts"]["clips"] == 0 and "20990101_001" in err and "not listed" in err


def test_tensor_pickles_match_torch():
    torch = pytest.importorskip("torch")
    x = torch.arange(24, dtype=torch.float64).reshape(2, 3, 4)
    data = {"00001": {"hand_pose": x.transpose(0, 2), "i": torch.tensor([3, -1])}, 7: np.eye(3)}
    back = tp.loads(pickle.dumps(data))
    np.testing.assert_array_equal(back["00001"]["hand_pose"], x.transpose(0, 2).numpy())
    np.testing.assert_array_equal(back["00001"]["i"], [3, -1])
    ours = tp.dumps({"a": tp.Tensor(np.linspace(0, 1, 6, dtype=np.float32).reshape(2, 3))})
    np.testing.assert_array_equal(pickle.loads(ours)["a"].numpy(), np.linspace(0, 1, 6, dtype=np.float32).reshape(2, 3))


def test_tensor_pickles_refuse_truncated_or_foreign_storages():
    import pickle as pk
    blob = tp._storage_obj(np.ones(4, np.float32), "cuda:0").blob
    assert np.array_equal(tp._load_from_bytes(blob), np.ones(4, np.float32))      # the location is ignored
    with pytest.raises(pk.UnpicklingError, match="12 bytes present, 16 expected"):
        tp._load_from_bytes(blob[:-4])
    foreign = blob.replace(b"torch\nFloatStorage", b"torch\nTensorBase\n\n\n\n"[:len(b"torch\nFloatStorage")])
    with pytest.raises(pk.UnpicklingError, match="refused global"):
        tp._load_from_bytes(foreign)


# --------------------------------------------------------------------------- OAKINK2
def test_oakink2_prepares_to_the_ground_truth(oi_raw, oi_store):
    manifest = json.loads((oi_store / "manifest.json").read_text())
    splits = {c["id"]: c["split"] for c in manifest["clips"]}
    assert len(splits) == 6 and not any(".hold." in c for c in splits)            # transient dropped
    clips = _clips(oi_store)
    worst = 0.0
    for key, lst, objs in ol.SEQUENCES:
        sid = oakink2.seq_id(key)
        for name in ("pour.00", "uncap.00"):
            cid = f"{sid}.{name}"
            assert splits[cid] == lst
            clip = clips[cid]
            worst = max(worst, _worst(clip, _gt(oi_raw / "hoibench_gt" / f"{cid}.npz")))
            assert clip.action == name.split(".")[0] and clip.fps == 120.0
            assert [t["source"] for t in clip.texts] == ["oakink2-seg_desc", "oakink2-task_target"]
        pour = clips[f"{sid}.pour.00"]
        assert pour.signature() == "hand:left,hand:right,object,object"
        assert pour.provenance["dropped_objects"] == ["O09@9999@00000"]
        assert pour.provenance["up_axis"] == ("+z" if key == ol.SEQUENCES[0][0] else "+y")
        assert abs(pour.provenance["top_camera_axis_to_down_deg"] - np.degrees(0.35)) < 1e-6
    assert worst < TOL_M, worst
    # resampled by time: 30 fps = every fourth mocap frame
    key = ol.SEQUENCES[0][0]
    prog = json.loads((oi_raw / "program" / "program_info" / f"{oakink2.token(key)}.json").read_text())
    pkey, name = oakink2.primitives(prog, "p")[0][:2]
    c30 = oakink2.load_primitive(oi_raw, key, pkey, name, oi_raw / "body_models", 30.0)
    assert _worst(c30, _gt(oi_raw / "hoibench_gt" / f"{c30.name}.npz"), step=4) < TOL_M


@pytest.mark.parametrize("defect, message", [
    ("up", "up axis undetermined"), ("gap", "lacks frame 1003"), ("global", "refused global (os|posix).system"),
    ("camera", "allocentric_top.* looks 1[0-9]{2} degrees")])
def test_oakink2_refuses_bad_files(oi_raw, tmp_path, defect, message):
    import os
    root = tmp_path / "raw"
    shutil.copytree(oi_raw, root, ignore=shutil.ignore_patterns("body_models", "hoibench_gt"))
    key = ol.SEQUENCES[1][0]
    path = root / "anno_preview" / f"{oakink2.token(key)}.pkl"
    anno = tp.load(path)
    if defect == "up":      # the body's up 45 degrees between +y and +z
        q = np.array([np.cos(np.pi / 8), np.sin(np.pi / 8), 0.0, 0.0])
        anno["raw_smplx"] = {f: {"world_rot": q[None]} for f in anno["mocap_frame_id_list"]}
    elif defect == "gap":
        anno["mocap_frame_id_list"].remove(1003)
    elif defect == "camera":       # the top camera turned to look up
        for E in anno["cam_extr"]["allocentric_top"].values():
            E[:3, :3] = np.diag([1.0, -1.0, -1.0]) @ E[:3, :3]
    else:
        anno["obj_list"] = [os.system]
    path.write_bytes(pickle.dumps(anno) if defect == "global" else tp.dumps(anno))
    prog = json.loads((root / "program" / "program_info" / f"{oakink2.token(key)}.json").read_text())
    pkey, name = oakink2.primitives(prog, "p")[0][:2]
    with pytest.raises(SequenceError, match=message):
        oakink2.load_primitive(root, key, pkey, name, oi_raw / "body_models", 120.0)


# --------------------------------------------------------------------------- the multi-body track
def _protocol(tmp_path, dataset: str, fps: int):
    """The multi-body protocol with this store's dataset and fps (no TACO / OAKINK2 protocol ships)."""
    from hoibench.tracks.protocol import get_protocol
    src = Path(get_protocol("multibody-synthetic").source).read_text().splitlines()
    keep = {"id:": f"id: {dataset}-test", "dataset:": f"dataset: {dataset}", "fps:": f"fps: {fps}",
            "  voxel_m:": "  voxel_m: 0.02"}          # coarse voxels: a fast test, not a reported number
    lines = [next((v for k, v in keep.items() if ln.startswith(k)), ln) for ln in src if not ln.startswith("track:")]
    path = tmp_path / f"{dataset}.yaml"
    path.write_text("\n".join(lines) + "\n")
    return str(path)


def test_the_multibody_track_scores_both_stores(taco_store, oi_store, tmp_path):
    from hoibench.evaluator.recognizer import train_recognizer
    from hoibench.scoring.evaluate import evaluate
    from hoibench.scoring.multibody import write_multibody_submission
    for name, data, fps in (("taco", taco_store, 30), ("oakink2", oi_store, 120)):
        proto = _protocol(tmp_path, name, fps)
        train_recognizer(data, tmp_path / f"rec_{name}", split="all", steps=5)
        sub = write_multibody_submission(data, tmp_path / f"sub_{name}", kind="gt")
        m = {k: v["mean"] for k, v in evaluate(sub, data, tmp_path / f"rec_{name}", protocol=proto)["metrics"].items()}
        assert m["csiou"] == 1.0 and np.isfinite(m["iv_cm3"]) and np.isfinite(m["fid"]), (name, m)
        assert set(m) >= {"csr", "ra"} and "crr" not in m, (name, sorted(m))   # hands only: no CRR
