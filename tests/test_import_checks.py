"""What ``hoibench import`` checks before writing a submission: pickled (object-dtype) members
refused naming file and member, feature rows of the other kind than ``--normalized`` says
refused, and joints in centimetres or z up warned about with the fix."""
from __future__ import annotations

import numpy as np
import pytest

from hoibench.scoring.importers import ImportProblem, import_results


@pytest.fixture(scope="module")
def gt(template_store):
    from hoibench.datasets.store import Store
    st = Store(template_store)
    ids = st.clip_ids("test")
    return st, ids, {c: st.load(c) for c in ids}


def _z_up(j: np.ndarray) -> np.ndarray:
    """y-up -> z-up, the inverse of the importer's ``(x, y, z) -> (x, z, -y)``."""
    return np.stack([j[..., 0], -j[..., 2], j[..., 1]], -1)


def test_a_pickled_member_is_refused_naming_file_and_member(gt, template_store, tmp_path):
    st, ids, clips = gt
    folder = tmp_path / "chois"
    folder.mkdir()
    for c in ids[:2]:
        g = np.concatenate([_z_up(clips[c]["joints"].astype(np.float64)), np.zeros((len(clips[c]["joints"]), 2, 3))], 1)
        np.savez(folder / f"{c}.npz", global_jpos=g, seq_name=np.array([c, 1], dtype=object))
    sub, rep = import_results("chois", folder, template_store, tmp_path / "ok")    # an unread object member is fine
    assert rep["matched"] == 2
    bad = folder / f"{ids[0]}.npz"
    np.savez(bad, global_jpos=np.array([clips[ids[0]]["joints"]], dtype=object))
    with pytest.raises(ImportProblem) as exc:
        import_results("chois", folder, template_store, tmp_path / "bad")
    msg = str(exc.value)
    assert str(bad) in msg and "'global_jpos'" in msg and "run code" in msg and "dtype=np.float32" in msg, msg
    assert "\n" not in msg and "allow_pickle" not in msg
    joints = tmp_path / "joints"
    joints.mkdir()
    np.save(joints / f"{ids[0]}.npy", np.array([clips[ids[0]]["joints"]], dtype=object), allow_pickle=True)
    with pytest.raises(ImportProblem, match="holds Python objects .*run code"):
        import_results("joints", joints, template_store, tmp_path / "bad2")


def _features(folder, st, ids, clips, normalized: bool, noise: float = 0.0) -> None:
    stats = st.stats("hoi269")
    rng = np.random.default_rng(1)
    folder.mkdir()
    for c in ids:
        f = clips[c]["hoi269"].astype(np.float64)
        f = f + noise * stats.std * rng.normal(size=f.shape)
        np.save(folder / f"{c}.npy", (f - stats.mean) / stats.std if normalized else f)


def test_feature_rows_of_the_other_kind_are_refused(gt, template_store, tmp_path):
    st, ids, clips = gt
    _features(tmp_path / "raw", st, ids, clips, normalized=False)
    _features(tmp_path / "norm", st, ids, clips, normalized=True)
    with pytest.raises(ImportProblem, match="look raw.*drop --normalized"):
        import_results("features", tmp_path / "raw", template_store, tmp_path / "a", normalized=True)
    with pytest.raises(ImportProblem, match="look normalised.*pass --normalized"):
        import_results("features", tmp_path / "norm", template_store, tmp_path / "b")
    _, rep = import_results("features", tmp_path / "raw", template_store, tmp_path / "c")
    _, rep_n = import_results("features", tmp_path / "norm", template_store, tmp_path / "d", normalized=True)
    assert rep["matched"] == rep_n["matched"] == len(ids)
    _features(tmp_path / "noisy", st, ids, clips, normalized=False, noise=3.0)   # a poor generator is not refused
    _, rep = import_results("features", tmp_path / "noisy", template_store, tmp_path / "e")
    assert rep["matched"] == len(ids)


def _joint_folder(folder, ids, clips, transform) -> None:
    folder.mkdir()
    for c in ids:
        np.save(folder / f"{c}.npy", transform(clips[c]["joints"].astype(np.float64)))


def test_joints_in_centimetres_or_z_up_are_warned_about_with_the_fix(gt, template_store, tmp_path, capsys):
    st, ids, clips = gt
    _joint_folder(tmp_path / "m", ids, clips, lambda j: j)
    _, rep = import_results("joints", tmp_path / "m", template_store, tmp_path / "a")
    assert rep["warnings"] == []
    _joint_folder(tmp_path / "cm", ids, clips, lambda j: 100.0 * j)
    _, rep = import_results("joints", tmp_path / "cm", template_store, tmp_path / "b")
    assert len(rep["warnings"]) == 1 and "centimetres" in rep["warnings"][0] and "0.01" in rep["warnings"][0]
    assert "centimetres" in capsys.readouterr().err
    _joint_folder(tmp_path / "z", ids, clips, _z_up)
    _, rep = import_results("joints", tmp_path / "z", template_store, tmp_path / "c")
    assert len(rep["warnings"]) == 1 and "+z" in rep["warnings"][0] and "pass --up z" in rep["warnings"][0]
    _, rep = import_results("joints", tmp_path / "z", template_store, tmp_path / "d", up="z")
    assert rep["warnings"] == []
    _, rep = import_results("joints", tmp_path / "m", template_store, tmp_path / "e", up="z")
    assert len(rep["warnings"]) == 1 and "do not pass --up z" in rep["warnings"][0]
