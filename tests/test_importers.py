"""Importers: fixtures written here in each generator's real format give the submission that
writing the same samples directly gives (repetition order, padding by lengths, text and id
matching, z-up and 30 fps conversions, normalised features), pickles only when trusted, and
missing samples reported."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from hoibench.scoring.importers import ImportProblem, import_results, resample, z_up_to_y_up


@pytest.fixture(scope="module")
def gt(template_store):
    from hoibench.evaluator.text import read_captions
    from hoibench.datasets.store import Store
    st = Store(template_store)
    ids = st.clip_ids("test")
    clips = {c: st.load(c) for c in ids}
    caps = {c: read_captions(st.root, c)[0].text for c in ids}
    return st, ids, clips, caps


def mdm_dict(ids, clips, caps, reps: int, with_obj: bool) -> tuple[dict, dict]:
    """An MDM/HOI-Diff results dict (repetition-major, padded to the longest) and the samples
    it encodes, per id: (K, T, 22, 3) joints (+ object)."""
    n = len(ids)
    Tmax = max(len(clips[c]["joints"]) for c in ids) + 5
    rng = np.random.default_rng(0)
    motion = np.zeros((n * reps, 22, 3, Tmax), np.float32)
    mobj = np.zeros((n * reps, 1, 6, Tmax), np.float32)
    expect = {}
    from hoibench.core.geometry import matrix_to_axis_angle
    for i, c in enumerate(ids):
        T = len(clips[c]["joints"])
        js, os_ = [], []
        for r in range(reps):
            j = clips[c]["joints"] + rng.normal(scale=0.01 * r, size=clips[c]["joints"].shape)
            motion[r * n + i, :, :, :T] = j.transpose(1, 2, 0)
            motion[r * n + i, :, :, T:] = 99.0                       # padding must be cut by `lengths`
            o = np.concatenate([matrix_to_axis_angle(clips[c]["obj_rot"]), clips[c]["obj_trans"] + 0.01 * r], -1)
            mobj[r * n + i, 0, :, :T] = o.T
            js.append(j)
            os_.append(o)
        expect[c] = {"joints": np.stack(js).astype(np.float32)}
        if with_obj:
            o = np.stack(os_).astype(np.float32)
            expect[c].update(obj_rotvec=o[..., :3], obj_trans=o[..., 3:])
    d = {"motion": motion, "text": [caps[c] for _ in range(reps) for c in ids],
         "lengths": np.array([len(clips[c]["joints"]) for _ in range(reps) for c in ids]),
         "num_samples": n, "num_repetitions": reps}
    if with_obj:
        d.update(motion_obj=mobj, obj_name=[str(clips[c]["object_name"]) for _ in range(reps) for c in ids])
    return d, expect


def direct(tmp_path, samples: dict, name: str):
    from hoibench.scoring.submission import write_submission
    return write_submission(tmp_path / name, {"method": "direct"}, sorted(samples.items()))


def same_samples(a, b, ids, atol=1e-6):
    for c in ids:
        with np.load(a / "samples" / f"{c}.npz") as x, np.load(b / "samples" / f"{c}.npz") as y:
            assert sorted(x.files) == sorted(y.files), c
            for k in x.files:
                np.testing.assert_allclose(x[k], y[k], atol=atol, err_msg=f"{c}.{k}")


@pytest.mark.parametrize("fmt", ["mdm", "hoidiff"])
def test_mdm_and_hoidiff_results_equal_the_direct_submission(gt, template_store, tmp_path, fmt):
    st, ids, clips, caps = gt
    d, expect = mdm_dict(ids, clips, caps, reps=3, with_obj=fmt == "hoidiff")
    path = tmp_path / "results.npy"
    np.save(path, d, allow_pickle=True)
    with pytest.raises(ImportProblem, match="--trust-pickle"):
        import_results(fmt, path, template_store, tmp_path / "nope")
    sub, rep = import_results(fmt, path, template_store, tmp_path / "sub", trust_pickle=True)
    assert rep["matched"] == len(ids) and not rep["missing_ids"] and rep["samples_per_prompt"] == [3]
    if fmt == "mdm":
        for c in ids:                                            # an MDM sample has no object: joints only
            expect[c] = {"joints": expect[c]["joints"]}
    same_samples(sub, direct(tmp_path, expect, "direct"), ids, atol=1e-5)
    meta = json.loads((sub / "submission.json").read_text())
    assert meta["source"]["import"]["match"] == "text" and meta["flags"]["uses_gt_length"] is True
    # MDM generates no object: on this human-object store the submission says so, and validates
    assert rep["human_only"] is (fmt == "mdm") and meta["flags"].get("human_only", False) is (fmt == "mdm")
    from hoibench.scoring.submission import validation_report
    assert validation_report(sub, template_store).complete


def test_missing_prompts_are_reported_and_a_mapping_file_maps_entries(gt, template_store, tmp_path):
    st, ids, clips, caps = gt
    d, expect = mdm_dict(ids[:3], clips, caps, reps=1, with_obj=False)
    d["text"] = ["a text nobody wrote", *d["text"][1:]]
    path = tmp_path / "results.npy"
    np.save(path, d, allow_pickle=True)
    sub, rep = import_results("mdm", path, template_store, tmp_path / "sub", trust_pickle=True)
    assert rep["matched"] == 2 and rep["unmatched_entries"] == ["a text nobody wrote"]
    assert len(rep["missing_ids"]) == len(ids) - 2 and ids[0] in rep["missing_ids"]
    mp = tmp_path / "map.json"
    mp.write_text(json.dumps({"0": ids[0], "1": ids[1], "2": ids[2]}))
    sub2, rep2 = import_results("mdm", path, template_store, tmp_path / "sub2", trust_pickle=True, mapping=mp)
    assert rep2["matched"] == 3 and rep2["conversions"]["match"] == "map"
    from hoibench.scoring.submission import validation_report
    assert not validation_report(sub, template_store).complete


def test_joint_files_with_z_up_and_30_fps_are_converted(gt, template_store, tmp_path):
    st, ids, clips, caps = gt
    folder = tmp_path / "t2m"
    folder.mkdir()
    expect = {}
    for c in ids[:4]:
        j = clips[c]["joints"].astype(np.float64)
        j30 = resample(j, 20.0, 30.0)                           # the source: 30 fps, z up, two repeats
        zup = np.stack([j30[..., 0], -j30[..., 2], j30[..., 1]], -1)
        np.testing.assert_allclose(z_up_to_y_up(zup), j30, atol=1e-12)
        for r in range(2):
            np.save(folder / f"{c}_{r}.npy", zup)
        back = resample(j30, 30.0, 20.0)
        expect[c] = {"joints": np.stack([back, back]).astype(np.float32)}
    sub, rep = import_results("joints", folder, template_store, tmp_path / "sub", fps=30, up="z")
    assert rep["matched"] == 4 and rep["conversions"]["resampled"] and rep["conversions"]["up_axis"] == "z -> y"
    same_samples(sub, direct(tmp_path, expect, "direct"), ids[:4], atol=1e-5)
    for c in ids[:4]:                                          # and that is the ground truth, to interpolation error
        with np.load(sub / "samples" / f"{c}.npz") as z:
            n = min(len(z["joints"][0]), len(clips[c]["joints"]))
            assert np.abs(z["joints"][0, :n] - clips[c]["joints"][:n]).max() < 0.02


def test_chois_npz_and_normalised_feature_folders(gt, template_store, tmp_path):
    from hoibench.metrics.chois_inputs import canonical_window
    from hoibench.representations import hoi269
    st, ids, clips, caps = gt
    chois, feats = tmp_path / "chois", tmp_path / "feats"
    chois.mkdir()
    feats.mkdir()
    stats = st.stats("hoi269")
    expect_c, expect_f = {}, {}
    for c in ids[:3]:
        j = clips[c]["joints"].astype(np.float64)
        j30 = resample(j, 20.0, 30.0)
        rot, shift = canonical_window(j)                                # CHOIS saves its window frame
        window = np.stack([j30[..., 0], -j30[..., 2], j30[..., 1]], -1) @ rot.T + shift
        g = np.concatenate([window, np.zeros((len(j30), 2, 3))], 1)
        np.savez(chois / f"{c}.npz", global_jpos=g)
        expect_c[c] = {"joints": resample(j30, 30.0, 20.0)[None].astype(np.float32)}
        f = clips[c]["hoi269"].astype(np.float64)
        np.save(feats / f"{c}.npy", (f - stats.mean) / stats.std)
        jj, rot, tr = hoi269.decode(f[None])
        from hoibench.core.geometry import matrix_to_axis_angle
        expect_f[c] = {"joints": jj.astype(np.float32), "obj_rotvec": matrix_to_axis_angle(rot).astype(np.float32),
                       "obj_trans": tr.astype(np.float32)}
    sub, _ = import_results("chois", chois, template_store, tmp_path / "sc")
    same_samples(sub, direct(tmp_path, expect_c, "dc"), ids[:3], atol=1e-5)
    stray = tmp_path / "chois_stray"                  # no test id names the file: no clip gives its frame
    stray.mkdir()
    np.savez(stray / "my_prompt_7.npz", global_jpos=g)
    with pytest.raises(ImportProblem, match=r"my_prompt\[_<r>\]\.npz: not named by a test id"):
        import_results("chois", stray, template_store, tmp_path / "sx")
    sub, _ = import_results("features", feats, template_store, tmp_path / "sf", normalized=True)
    same_samples(sub, direct(tmp_path, expect_f, "df"), ids[:3], atol=2e-4)


def test_cli_import_reports_and_one_line_errors(gt, template_store, tmp_path):
    st, ids, clips, caps = gt
    d, _ = mdm_dict(ids, clips, caps, reps=1, with_obj=False)
    path = tmp_path / "results.npy"
    np.save(path, d, allow_pickle=True)
    exe = [sys.executable, "-m", "hoibench.cli", "import", "mdm", str(path), "--data", str(template_store)]
    r = subprocess.run(exe + ["--out", str(tmp_path / "a")], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "--trust-pickle" in r.stderr
    r = subprocess.run(exe + ["--out", str(tmp_path / "b"), "--trust-pickle"], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0 and f"{len(ids)}/{len(ids)} test ids" in r.stdout, r.stderr
    bad = tmp_path / "bad.npy"
    np.save(bad, {"motion": np.zeros((2, 21, 3, 5))}, allow_pickle=True)
    r = subprocess.run(exe[:5] + [str(bad), "--data", str(template_store), "--out", str(tmp_path / "c"),
                                  "--trust-pickle"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "field text missing" in r.stderr, r.stderr
