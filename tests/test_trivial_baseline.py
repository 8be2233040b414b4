"""The "mean pose + static object" baseline (hoibench.scoring.mean_pose) against independent
computations on the session's synthetic store."""
from __future__ import annotations

import shutil

import numpy as np
import pytest

from hoibench.scoring import mean_pose
from hoibench.representations import hml263
from hoibench.datasets.store import Store
from hoibench.scoring.submission import Submission, validation_report


def _expected(data) -> tuple[np.ndarray, np.ndarray]:
    """Mean pose and object offset over the train frames, computed here from hml263 rows and
    the raw hoi269 translation columns (not via the module under test)."""
    st = Store(data)
    rel_poses, rel_objs = [], []
    for cid in st.clip_ids("train"):
        clip = st.load(cid)
        J = hml263.decode(clip["hml263"]).astype(np.float64)            # (T-1, 22, 3) canonical
        pelvis = J[:, 0].copy()
        rel = J.copy()
        rel[..., 0] -= pelvis[:, None, 0]
        rel[..., 2] -= pelvis[:, None, 2]
        rel_poses.append(rel)
        if "hoi269" in clip:
            t = clip["hoi269"][:, 266:269].astype(np.float64)
            rel_objs.append(np.stack([t[:, 0] - pelvis[:, 0], t[:, 1], t[:, 2] - pelvis[:, 2]], axis=-1))
    return np.concatenate(rel_poses).mean(0), np.concatenate(rel_objs).mean(0)


@pytest.fixture(scope="module")
def store(synthetic_store):
    _, data, _ = synthetic_store
    return data


@pytest.fixture(scope="module")
def samples(store):
    return dict(mean_pose.mean_pose_samples(store))


def test_samples_cover_test_ids_with_gt_lengths_and_shapes(store, samples):
    st = Store(store)
    assert list(samples) == st.clip_ids("test") and samples
    for sid, arrays in samples.items():
        gt = st.load(sid)
        T = gt["joints"].shape[0]
        assert arrays["joints"].shape == (1, T, 22, 3) and arrays["joints"].dtype == np.float32
        assert ("obj_rot" in arrays) == ("obj_rot" in gt) == ("obj_trans" in arrays)
        if "obj_rot" in gt:
            assert arrays["obj_rot"].shape == (1, T, 3, 3) and arrays["obj_rot"].dtype == np.float32
            assert arrays["obj_trans"].shape == (1, T, 3) and arrays["obj_trans"].dtype == np.float32
            np.testing.assert_array_equal(arrays["obj_rot"], np.broadcast_to(np.eye(3, dtype=np.float32), (1, T, 3, 3)))


def test_static_pose_equals_independent_train_mean(store, samples):
    pose, obj = _expected(store)
    assert abs(pose[0, 0]) < 1e-9 and abs(pose[0, 2]) < 1e-9
    for arrays in samples.values():
        J = arrays["joints"][0]
        assert (J == J[0]).all()                                # the same pose every frame
        assert J[0, 0, 0] == 0 and J[0, 0, 2] == 0              # pelvis at x = z = 0
        np.testing.assert_allclose(J[0], pose, atol=1e-5)
        if "obj_trans" in arrays:
            tr = arrays["obj_trans"][0]
            assert (tr == tr[0]).all()
            np.testing.assert_allclose(tr[0], obj, atol=1e-5)
    # plausible: standing above the floor, the object within reach
    assert pose[:, 1].min() > -0.05 and pose[0, 1] > 0.5
    assert np.linalg.norm(obj[[0, 2]]) < 3.0


def test_pose_ignores_test_clips(store, samples, tmp_path):
    data = tmp_path / "data"
    shutil.copytree(store, data)
    st = Store(data)

    def perturb(cid: str) -> None:
        clip = st.load(cid)
        for k in ("joints", "hml263", "hoi269"):
            if k in clip:
                clip[k] = (clip[k] * 1.3 + 0.2).astype(clip[k].dtype)
        np.savez(data / "clips" / f"{cid}.npz", **clip)

    for cid in st.clip_ids("test"):
        perturb(cid)
    again = dict(mean_pose.mean_pose_samples(data))
    assert list(again) == list(samples)
    for sid in samples:
        for k in samples[sid]:
            np.testing.assert_array_equal(again[sid][k], samples[sid][k])
    # the check is sensitive: the same change to a train clip moves the pose
    perturb(st.clip_ids("train")[0])
    moved = next(mean_pose.mean_pose_samples(data))[1]
    assert not np.allclose(moved["joints"][0, 0], samples[next(iter(samples))]["joints"][0, 0], atol=1e-4)


@pytest.mark.parametrize("as_zip", [False, True])
def test_submission_validates_and_matches_samples(store, samples, tmp_path, as_zip):
    out = mean_pose.write_mean_pose_submission(store, tmp_path / ("sub.zip" if as_zip else "sub"), as_zip=as_zip)
    rep = validation_report(out, store)
    assert rep.complete and not rep.errors, [str(p) for p in rep.problems]
    test_ids = Store(store).clip_ids("test")
    assert sorted(rep.valid_ids) == sorted(test_ids) and not rep.missing_ids
    assert rep.samples_per_prompt == 1
    with Submission(out) as sub:
        assert sorted(sub.ids) == sorted(test_ids)
        assert sub.meta["method"] == "mean pose + static object"
        assert sub.meta["flags"] == {"uses_gt_length": True, "samples_per_prompt": 1, "checkpoint_selection": "n/a"}
        assert sub.meta["fps"] == float(Store(store).manifest["config"]["fps"])
        for sid in test_ids:
            got = sub.load(sid)
            assert set(got) == set(samples[sid])
            for k, a in samples[sid].items():
                np.testing.assert_array_equal(got[k], a)


def test_cli_writes_the_mean_pose_submission_and_refuses_a_run_folder(store, tmp_path):
    import subprocess
    import sys
    exe = [sys.executable, "-m", "hoibench.cli", "baseline", "sample", "mean-pose"]
    r = subprocess.run(exe + ["--data", str(store), "--out", str(tmp_path / "sub")], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    assert validation_report(tmp_path / "sub", store).complete
    r = subprocess.run(exe + [str(tmp_path), "--data", str(store), "--out", str(tmp_path / "x")], capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 2 and r.stderr.strip().startswith("hoibench baseline: error: mean-pose takes no RUN")
