"""Export to the HumanML3D and HOI-Diff layouts, and the HumanML3D round trip."""
from __future__ import annotations

import json

import numpy as np

from hoibench.datasets.export import export, read_humanml3d
from hoibench.representations import hml263
from hoibench.datasets.store import Store


def _write_texts(data, ids):
    for i, cid in enumerate(ids):
        (data / "texts").mkdir(exist_ok=True)
        (data / "texts" / f"{cid}.txt").write_text(
            f"a person lifts the box#a/DET person/NOUN lift/VERB the/DET box/NOUN#0.0#0.0\n"
            f"someone picks it up {i}#someone/PRON pick/VERB it/PRON up/ADP {i}/NUM#0.5#1.5\n")


def test_humanml3d_export_reimports_to_the_same_features_and_texts(synthetic_store, tmp_path):
    _, data, manifest = synthetic_store
    store = Store(data)
    ids = store.clip_ids()
    _write_texts(data, ids[:-1])        # the last clip has no text: reported, not fatal
    report = export(data, tmp_path / "hml", "humanml3d")
    assert report["missing_texts"] == ids[-1:]
    back = read_humanml3d(tmp_path / "hml")
    assert set(back) == set(ids)
    for cid in ids:
        clip = store.load(cid)
        np.testing.assert_array_equal(back[cid]["features"], clip["hml263"])
        np.testing.assert_allclose(back[cid]["joints"], hml263.decode(clip["hml263"]), atol=1e-6)
        assert back[cid]["split"] == str(clip["split"])
    assert back[ids[0]]["texts"][1][0] == "someone picks it up 0"
    assert back[ids[0]]["texts"][0][1][:2] == ["a/DET", "person/NOUN"]
    mean = np.load(tmp_path / "hml" / "Mean.npy")
    np.testing.assert_array_equal(mean, store.stats("hml263").mean)
    assert (tmp_path / "hml" / "test.txt").read_text().split() == store.clip_ids("test")


def test_hoidiff_export_layout(synthetic_store, tmp_path):
    _, data, manifest = synthetic_store
    store = Store(data)
    export(data, tmp_path / "hd", "hoidiff")
    split = json.loads((tmp_path / "hd" / "dataset_split.json").read_text())["synthetic"]
    assert sorted(split["train"] + split["test"]) == sorted(store.clip_ids())
    cid = store.clip_ids()[0]
    root = tmp_path / "hd" / "synthetic_t2m"
    motion = np.load(root / "sequences_263_rep" / cid / "hoi_motion.npy")
    np.testing.assert_array_equal(motion, store.load(cid)["hoi269"])
    with np.load(root / "sequences" / cid / "object_motion.npz") as z:
        obj = str(z["name"])
        assert z["angles"].shape == (len(store.load(cid)["joints"]), 3)
    pts = np.load(root / "object_mesh" / obj / "sample_points.npy")
    assert pts.shape == (1024, 3) and (root / "object_mesh" / obj / f"{obj}.obj").exists()
    assert np.load(root / "Std_local.npy").shape == (269,)
