"""Hostile raw input to ``prepare`` (BEHAVE, OMOMO, RICH loaders and the store): unsafe ids,
implausible values and units, broken meshes, duplicate ids, wrong-field messages, NaN in
provenance, and their siblings. Inputs are the synthetic raw layouts, damaged on purpose."""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import os

import numpy as np
import pytest

pytest.importorskip("smplx")
trimesh = pytest.importorskip("trimesh")

from test_omomo_rich import _editable_omomo_copy, _read_pickle, _write_pickle, omomo_raw, rich_raw  # noqa: E402,F401

from hoibench.core import plausibility as pl  # noqa: E402
from hoibench.datasets import behave, omomo, rich  # noqa: E402
from hoibench.datasets.synthetic import write_behave_layout  # noqa: E402
from hoibench.datasets.export import export  # noqa: E402
from hoibench.core.ids import InvalidIdError  # noqa: E402
from hoibench.core.skeleton import SMPL_REST_JOINTS  # noqa: E402
from hoibench.datasets.splits import SplitFileError, split_assignment  # noqa: E402
from hoibench.datasets.store import PrepareConfig, clip_arrays, prepare, refuse_duplicates, run_unit  # noqa: E402

TRAIN_PKL, TEST_PKL = omomo.PICKLES["train"], omomo.PICKLES["test"]


# --------------------------------------------------------------------------- helpers
@pytest.fixture(scope="module")
def behave_raw(tmp_path_factory):
    """Three synthetic BEHAVE sequences: two train (yogamat, chairwood), one test (stool)."""
    root = tmp_path_factory.mktemp("behave") / "raw"
    manifest = write_behave_layout(root, 3, seed=0, progress=False)
    return root, [c["name"] for c in manifest["clips"]]


def _behave_copy(behave_raw, base: Path) -> tuple[Path, list[str]]:
    root = base / "raw"
    shutil.copytree(behave_raw[0], root)
    return root, behave_raw[1]


def _edit_npz(path: Path, key: str, fn) -> None:
    z = dict(np.load(path))
    z[key] = fn(z[key])
    np.savez(path, **z)


def _trim(seq: dict, frames: int) -> dict:
    T = len(seq["trans"])
    return {k: (v[:frames] if isinstance(v, np.ndarray) and v.ndim and len(v) == T else v) for k, v in seq.items()}


def _small_omomo(omomo_raw, base: Path, frames: int = 40):
    """An OMOMO copy with one short sequence per pickle (no ground-truth sidecars):
    (root, train sequence, test sequence)."""
    root, pkl, data = _editable_omomo_copy(omomo_raw, base)
    shutil.rmtree(root / "hoibench_gt")
    train = _trim(data[0], frames)
    test = _trim(next(iter(_read_pickle(root / TEST_PKL).values())), frames)
    _write_pickle(pkl, {0: train})
    _write_pickle(root / TEST_PKL, {0: test})
    return root, train, test


def _load_omomo(root: Path, seq: dict, fps: float = 30.0, text_file=None):
    return omomo.load_sequence(seq, str(root / "captured_objects"), str(root / "body_models"), fps,
                               text_file, None, TRAIN_PKL, None)


def _run(module, root: Path, out: Path, name: str, split_file=None, jobs_filter=None):
    """prepare ``root`` with ``module``'s jobs (optionally filtered): (manifest, {id: error})."""
    cfg = PrepareConfig(name, fps=20.0, body_model_type="smplh" if module is behave else "smplx")
    jobs = module.prepare_jobs(root, root / "body_models", out, cfg, split_file=split_file)
    if jobs_filter is not None:
        jobs = [j for j in jobs if jobs_filter(j)]
    manifest = prepare(jobs, out, cfg)
    lines = (out / "errors.jsonl").read_text().splitlines()
    return manifest, {e["sequence"]: e["error"] for e in map(json.loads, lines)}


def _tree(base: Path) -> set[Path]:
    return {p for p in base.rglob("*")}


# --------------------------------------------------------------------------- 1. ids / paths
def test_unsafe_ids_are_refused_and_nothing_is_written_outside_out(omomo_raw, behave_raw, rich_raw, tmp_path):
    base = tmp_path / "a" / "b" / "c"
    # OMOMO: a seq_name that would write out/clips/../../../../PWNED.npz
    oroot, train, _ = _small_omomo(omomo_raw, base / "omomo")
    evil = dict(train, seq_name="sub1_x/../../../../PWNED")
    _write_pickle(oroot / TRAIN_PKL, {0: train, 1: evil})
    # BEHAVE: an object name ("cat") that would write objects/../../../PWNED.npz, a folder name with a space
    broot, names = _behave_copy(behave_raw, base / "behave")
    info = broot / "sequences" / names[1] / "info.json"
    info.write_text(json.dumps({"gender": "male", "cat": "../../../PWNED"}))
    shutil.move(broot / "sequences" / names[0], broot / "sequences" / "Date01_Sub01_yogamat_carry now")
    shutil.rmtree(broot / "sequences" / names[2])
    before = _tree(tmp_path)
    m_o, err_o = _run(omomo, oroot, base / "out_o", "omomo")
    m_b, err_b = _run(behave, broot, base / "out_b", "behave")
    new = _tree(tmp_path) - before
    outs = (base / "out_o", base / "out_b")
    assert new and all(p in outs or any(o in p.parents for o in outs) for p in new), sorted(map(str, new))
    assert not list(tmp_path.rglob("PWNED*"))
    bad = [e for e in err_o.values() if "PWNED" in e]
    assert len(bad) == 1 and "sub1_x/../../../../PWNED" in bad[0] and TRAIN_PKL in bad[0] and "not a valid id" in bad[0]
    assert m_o["counts"]["clips"] == 2 and all("PWNED" not in c["id"] for c in m_o["clips"])
    assert "info.json: cat" in err_b[names[1]] and "../../../PWNED" in err_b[names[1]]
    spaced = [e for e in err_b.values() if "yogamat_carry now" in e]
    assert len(spaced) == 1 and "sequences" in spaced[0] and "not a valid id" in spaced[0]
    assert m_b["counts"]["clips"] == 0
    # RICH: a sequence folder whose name is not an id
    rroot = base / "rich"
    shutil.copytree(rich_raw[0], rroot, ignore=shutil.ignore_patterns("body_models", "human_scene_contact"))
    seq = next(p for p in (rroot / "bodies" / "train").iterdir())
    seq.rename(seq.parent / f"{seq.name} (copy)")
    _, err_r = _run(rich, rroot, base / "out_r", "rich-cat", jobs_filter=lambda j: j[0].startswith("invalid-id-"))
    assert len(err_r) == 1 and all(f"'{seq.name} (copy)'" in e and "bodies/train" in e for e in err_r.values())
    # a split file entry is an id too: refused naming the file and the entry
    split = base / "split.json"
    split.write_text(json.dumps({"train": ["../../../PWNED"], "test": []}))
    with pytest.raises(SplitFileError, match=r"train\[0\] '\.\./\.\./\.\./PWNED' \(from .*split\.json\)"):
        behave.prepare_jobs(broot, broot / "body_models", base / "out_s", PrepareConfig("behave"), split_file=split)
    # export: ids from a tampered manifest never become paths
    store = base / "out_o"
    manifest = json.loads((store / "manifest.json").read_text())
    manifest["clips"].append({"id": "../../PWNED", "split": "train", "frames": 2, "object": "", "contact_frames": 0})
    (store / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(InvalidIdError, match=r"clip id '\.\./\.\./PWNED' \(from .*manifest\.json\)"):
        export(store, base / "exported", "humanml3d")
    assert not list(tmp_path.rglob("PWNED*"))


# --------------------------------------------------------------------------- 2. plausibility / units
def test_corrupt_values_and_millimetre_units_are_refused_per_clip(behave_raw, omomo_raw, tmp_path):
    root, names = _behave_copy(behave_raw, tmp_path / "b")
    seqs = root / "sequences"
    _edit_npz(seqs / names[0] / "smpl_fit_all.npz", "trans",
              lambda t: np.where(np.arange(len(t))[:, None] == 7, 1e30, t))          # one corrupt frame
    _edit_npz(seqs / names[1] / "object_fit_all.npz", "trans", lambda t: t * 1000.0)       # millimetres
    ply = root / "objects" / "stool" / "stool_f1000.ply"
    mesh = trimesh.load(ply, process=False, force="mesh")
    mesh.vertices = mesh.vertices * 100.0                                                   # centimetres
    mesh.export(ply)
    manifest, errors = _run(behave, root, tmp_path / "out", "behave")
    assert set(errors) == set(names) and manifest["counts"]["clips"] == 0 and manifest["stats"] == {}
    assert "smpl_fit_all.npz: trans" in errors[names[0]] and "1e+30 at index (7," in errors[names[0]]
    assert "object_fit_all.npz: trans" in errors[names[1]] and "millimetres?" in errors[names[1]]
    assert all(s in errors[names[2]] for s in ("'stool'", "stool_f1000.ply", "centimetres?"))
    # OMOMO: complex poses are refused (not cast), trans in millimetres is named
    oroot, train, _ = _small_omomo(omomo_raw, tmp_path / "o")
    with pytest.raises(ValueError, match=r"pose_body: complex values \(complex\d+\) refused"):
        _load_omomo(oroot, dict(train, pose_body=train["pose_body"] + 1e-3j))
    with pytest.raises(ValueError, match=rf"{train['seq_name']}: {TRAIN_PKL}: trans: .*millimetres\?"):
        _load_omomo(oroot, dict(train, trans=train["trans"] * 1000.0))
    # a speed no body reaches: one frame 3 m away
    jump = train["trans"].copy()
    jump[10, 0] += 3.0
    with pytest.raises(ValueError, match=r"trans: speed .* between frames 9 and 10 exceeds 50 m/s"):
        _load_omomo(oroot, dict(train, trans=jump))
    # per clip body height and object extent, with the unit they fit
    for factor, unit in ((1000.0, "millimetres"), (100.0, "centimetres")):
        with pytest.raises(pl.ImplausibleDataError, match=rf"body height .* {unit}\?"):
            pl.check_body_height(np.repeat(SMPL_REST_JOINTS[None] * factor, 3, 0), "clip")
    box = trimesh.creation.box(extents=(0.4, 0.3, 0.2))
    with pytest.raises(pl.ImplausibleDataError, match=r"millimetres\?"):
        pl.check_extent(box.vertices * 1000.0, "box")
    assert 1.4 < pl.skeletal_height(SMPL_REST_JOINTS[None])[0] < 1.8


def test_rich_world_scale_in_millimetres_fails_the_clip(rich_raw, tmp_path):
    src, _ = rich_raw
    root = tmp_path / "raw"
    shutil.copytree(src, root, ignore=shutil.ignore_patterns("body_models", "human_scene_contact"))
    cfg = PrepareConfig("rich-cat", fps=20.0, body_model_type="smplx")
    job = next(j for j in rich.prepare_jobs(root, src / "body_models", tmp_path / "out", cfg) if j[4] is rich.load_clip)
    tfile = Path(job[5][11])
    t = json.loads(tfile.read_text())
    tfile.write_text(json.dumps(dict(t, c=1000.0 * t["c"])))
    res = run_unit(job)
    assert res.status == "failed" and res.error.startswith(job[0])
    assert "millimetres?" in res.error and tfile.name in res.error
    assert not (tmp_path / "out" / "clips" / f"{job[0]}.npz").exists()


# --------------------------------------------------------------------------- 3. meshes
def test_broken_object_meshes_are_refused_naming_object_and_file(behave_raw, omomo_raw, tmp_path):
    root, names = _behave_copy(behave_raw, tmp_path / "b")
    ply = root / "objects" / "yogamat" / "yogamat_f1000.ply"
    mesh = trimesh.load(ply, process=False, force="mesh")
    mesh.vertices[3] = np.nan
    mesh.export(ply)
    with pytest.raises(ValueError, match=rf"{names[0]}: object 'yogamat' template: yogamat_f1000.ply: vertices: "
                                         r"non-finite value nan at index \(3, 0\)"):
        behave.load_sequence(root / "sequences" / names[0], root / "objects", root / "body_models", 20.0)
    oroot, train, _ = _small_omomo(omomo_raw, tmp_path / "o")
    obj = omomo.parse_name(train["seq_name"])[1]
    path = oroot / "captured_objects" / f"{obj}_cleaned_simplified.obj"
    path.write_text(path.read_text() + "f 1 2 999999\n")
    with pytest.raises(ValueError, match=rf"object '{obj}' template: {path.name}: unreadable mesh"):
        _load_omomo(oroot, train)
    v = np.eye(4)[:, :3]
    f = np.array([[0, 1, 2], [0, 1, 3]])
    assert pl.check_mesh(v, f, "ok")[1].dtype == np.int64
    for verts, faces, msg in ((v[:3], f[:1], "3 vertices"), (v, f.astype(float), "integer vertex indices"),
                              (v, np.array([[0, 1, 4]]), r"face 0 = \[0, 1, 4\]"),
                              (v, np.array([[0, 0, 1]]), "zero area"), (v, np.zeros((0, 3), int), "point cloud")):
        with pytest.raises(pl.ImplausibleDataError, match=msg):
            pl.check_mesh(verts, faces, "object 'x' (x.obj)")


# --------------------------------------------------------------------------- 4. store integrity
def test_duplicate_ids_and_ids_in_two_splits_are_refused(rich_raw, omomo_raw, behave_raw, tmp_path):
    src, manifest = rich_raw
    root = tmp_path / "rich"
    shutil.copytree(src, root, ignore=shutil.ignore_patterns("body_models"))
    e = next(e for e in manifest["sequences"] if e["split"] == "train" and len(e["runs"]) == 1)
    seq = e["sequence"]
    shutil.copytree(root / "bodies" / "train" / seq, root / "bodies" / "test" / seq)
    cfg = PrepareConfig("rich-cat", fps=30.0, body_model_type="smplx")
    jobs = rich.prepare_jobs(root, src / "body_models", tmp_path / "out", cfg)
    dup = [j for j in jobs if j[5][0].startswith(f"{seq}_")]
    assert len(dup) == 2 and {j[1] for j in dup} == {"train", "test"} and all(j[4] is not rich.load_clip for j in dup)
    out = prepare(dup, tmp_path / "out", cfg)
    assert out["counts"]["clips"] == 0 and out["counts"]["failed"] == 2
    for line in (tmp_path / "out" / "errors.jsonl").read_text().splitlines():
        err = json.loads(line)["error"]
        assert "duplicate clip id" in err and f"bodies/train/{seq}/" in err and f"bodies/test/{seq}/" in err
    # OMOMO: one seq_name in both pickles fails both copies, naming both files
    oroot, train, test = _small_omomo(omomo_raw, tmp_path / "o")
    _write_pickle(oroot / TEST_PKL, {0: test, 5: train})
    ojobs = omomo.prepare_jobs(oroot, oroot / "body_models", tmp_path / "oo", PrepareConfig("omomo"))
    copies = [j for j in ojobs if j[0] == train["seq_name"]]
    assert len(copies) == 2 and all(TRAIN_PKL in j[5][0] and TEST_PKL in j[5][0] for j in copies)
    # case-folded ids collide on some file systems; an id in two splits of a split file is a leak
    a = ("Abc", "train", "", "o", behave.load_sequence, (), "clean")
    b = ("abc", "test", "", "o", behave.load_sequence, (), "clean")
    assert all("duplicate clip id" in j[5][0] for j in refuse_duplicates([a, b], ["x/Abc", "y/abc"]))
    with pytest.raises(SplitFileError, match=r"'Date01_x' is listed in both 'train' and 'test'"):
        split_assignment({"train": ["Date01_x"], "test": ["Date01_x"]}, "split.json")
    # a stale object template of an earlier run is rewritten, never kept
    broot, names = _behave_copy(behave_raw, tmp_path / "b")
    shutil.rmtree(broot / "sequences" / names[1])
    shutil.rmtree(broot / "sequences" / names[2])
    store = tmp_path / "store"
    _run(behave, broot, store, "behave")
    good = (store / "objects" / "yogamat.npz").read_bytes()
    (store / "objects" / "yogamat.npz").write_bytes(b"stale")
    (store / "clips" / f"{names[0]}.npz").unlink()
    _run(behave, broot, store, "behave")
    assert (store / "objects" / "yogamat.npz").read_bytes() == good


# --------------------------------------------------------------------------- 5. messages
def test_messages_name_the_real_field_and_file(omomo_raw, behave_raw, tmp_path):
    oroot, train, test = _small_omomo(omomo_raw, tmp_path / "o")
    name = train["seq_name"]
    with pytest.raises(ValueError, match=rf"{name}: {TRAIN_PKL}: trans has 30 frames, the other per-frame fields "
                                         r"\(root_orient, pose_body, obj_rot, obj_trans, obj_scale\) have 40"):
        _load_omomo(oroot, dict(train, trans=train["trans"][:30]))
    with pytest.raises(ValueError, match=r"zero frames: trans, root_orient, .* are empty"):
        _load_omomo(oroot, _trim(train, 0))
    root, names = _behave_copy(behave_raw, tmp_path / "b")
    seq = root / "sequences" / names[0]
    load = lambda: behave.load_sequence(seq, root / "objects", root / "body_models", 20.0)  # noqa: E731
    (seq / "info.json").write_text(json.dumps(["male", "yogamat"]))
    with pytest.raises(ValueError, match=rf"{names[0]}: info.json: expected a JSON object, got list"):
        load()
    (seq / "info.json").write_text(json.dumps({"gender": 1, "cat": "yogamat"}))
    with pytest.raises(ValueError, match=rf"{names[0]}: info.json: gender: .* got 1"):
        load()
    (seq / "info.json").write_text(json.dumps({"gender": "male", "cat": "yogamat"}))
    for f, key in (("smpl_fit_all.npz", "poses"), ("smpl_fit_all.npz", "betas"), ("smpl_fit_all.npz", "trans"),
                   ("object_fit_all.npz", "angles"), ("object_fit_all.npz", "trans")):
        _edit_npz(seq / f, key, lambda a: a[:0])
    _edit_npz(seq / "smpl_fit_all.npz", "frame_times", lambda a: a[:0])
    with pytest.raises(ValueError, match=rf"{names[0]}: zero frames: smpl_fit_all.npz: poses"):
        load()
    # one corrupt pickle fails as a source, the other's sequences are prepared; a missing one is reported
    (oroot / TEST_PKL).write_bytes(b"\x80\x04 not a joblib file")
    manifest, errors = _run(omomo, oroot, tmp_path / "out", "omomo")
    assert manifest["counts"]["clips"] == 1 and "unreadable OMOMO pickle" in errors[TEST_PKL]
    assert manifest["incomplete"] == [errors[TEST_PKL]]
    (oroot / TEST_PKL).unlink()
    manifest, errors = _run(omomo, oroot, tmp_path / "out2", "omomo")
    assert manifest["counts"]["clips"] == 1 and manifest["counts"]["by_split"] == {"train": 1}
    assert "missing" in errors[TEST_PKL] and "no test split" in errors[TEST_PKL]
    assert manifest["incomplete"] == [errors[TEST_PKL]]


# --------------------------------------------------------------------------- 6. strict JSON
def test_nan_never_reaches_provenance_or_texts(omomo_raw, behave_raw, tmp_path):
    root, names = _behave_copy(behave_raw, tmp_path / "b")
    seq = root / "sequences" / names[0]
    _edit_npz(seq / "smpl_fit_all.npz", "frame_times", lambda a: np.array(["tnan"] + list(a[1:])))
    with pytest.raises(ValueError, match=r"smpl_fit_all.npz: frame_times: non-finite time 'tnan' at frame 0"):
        behave.load_sequence(seq, root / "objects", root / "body_models", 20.0)
    oroot, train, _ = _small_omomo(omomo_raw, tmp_path / "o")
    offsets = train["rest_offsets"].copy()
    offsets[3, 1] = np.nan
    with pytest.raises(ValueError, match=r"rest_offsets: non-finite value nan at index \(3, 1\)"):
        _load_omomo(oroot, dict(train, rest_offsets=offsets))
    text = tmp_path / "t.json"
    text.write_text('{"%s": NaN}' % train["seq_name"])
    with pytest.raises(ValueError, match=r"t.json: .*(expected a sentence|the token NaN is not JSON)"):
        _load_omomo(oroot, train, text_file=str(text))
    good = _load_omomo(oroot, train)
    good.provenance["floor_shift_m"] = float("nan")
    with pytest.raises(ValueError, match=r"provenance: not strict JSON .*floor_shift_m = nan"):
        pl.check_sequence(good, TRAIN_PKL)
    with pytest.raises(ValueError, match="non-finite"):
        clip_arrays(good, "clean", "train", "sha")


# --------------------------------------------------------------------------- 7. siblings
def test_fps_frames_betas_and_gender_are_checked(omomo_raw, tmp_path):
    for fps in (float("nan"), 0.0, -20.0, float("inf")):
        with pytest.raises(ValueError, match="--fps"):
            PrepareConfig("behave", fps=fps)
    oroot, train, _ = _small_omomo(omomo_raw, tmp_path / "o")
    with pytest.raises(ValueError, match="fps"):
        _load_omomo(oroot, train, fps=float("nan"))
    with pytest.raises(ValueError, match=r"only 1 frame\(s\)"):
        _load_omomo(oroot, _trim(train, 1))
    for betas in (np.zeros((1, 0)), np.zeros((1, 301))):
        with pytest.raises(ValueError, match=r"betas: expected 1\.\.300"):
            _load_omomo(oroot, dict(train, betas=betas))
    with pytest.raises(ValueError, match=r"gender: expected male/female/neutral, got '\.\./\.\./male'"):
        _load_omomo(oroot, dict(train, gender="../../male"))
    seq = _load_omomo(oroot, train)
    pl.check_sequence(seq, TRAIN_PKL)
    seq.body.gender = "../male"
    with pytest.raises(ValueError, match=r"gender '\.\./male'"):
        pl.check_sequence(seq, TRAIN_PKL)


def test_raw_special_files_and_deflate_bombs_are_refused_not_read(tmp_path):
    """A raw .npz that is a FIFO, a link to /dev/zero, or a few MB inflating to GBs fails its
    sequence (no hang, no memory blow-up); the other sequences are prepared."""
    import io as _io
    import zipfile as _zip

    from hoibench.datasets import behave
    from hoibench.datasets.synthetic import write_behave_layout
    from hoibench.datasets.store import PrepareConfig, prepare
    raw = tmp_path / "raw"
    write_behave_layout(raw, 4, seed=0, progress=False)
    seqs = sorted((raw / "sequences").iterdir())
    (seqs[0] / "smpl_fit_all.npz").unlink()
    os.mkfifo(seqs[0] / "smpl_fit_all.npz")
    (seqs[1] / "smpl_fit_all.npz").unlink()
    (seqs[1] / "smpl_fit_all.npz").symlink_to("/dev/zero")
    buf = _io.BytesIO()
    hdr = _io.BytesIO()
    np.lib.format.write_array_header_1_0(hdr, {"descr": "<f4", "fortran_order": False, "shape": (1_000_000, 156)})
    with _zip.ZipFile(buf, "w", _zip.ZIP_DEFLATED) as zf:
        with zf.open("poses.npy", "w", force_zip64=True) as f:
            f.write(hdr.getvalue())
            for _ in range(38):
                f.write(bytes(16 * 1024 ** 2))           # 608 MiB of zeros, < 1 MiB deflated
    (seqs[2] / "smpl_fit_all.npz").write_bytes(buf.getvalue())
    cfg = PrepareConfig("synthetic", fps=20.0)
    out = tmp_path / "data"
    m = prepare(behave.prepare_jobs(raw, raw / "body_models", out, cfg, split_file=raw / "split.json"), out, cfg)
    errors = (out / "errors.jsonl").read_text()
    assert m["counts"]["clips"] == 1 and m["counts"]["failed"] == 3
    assert "FIFO" in errors and "not a regular file" in errors and "limit" in errors
