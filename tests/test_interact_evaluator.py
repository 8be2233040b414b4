"""The ``interact`` evaluator backend against InterAct's own code on the same weights.

Reference values: ``tests/data/interact_evaluator_reference.npz``, produced by running
InterAct's public encoders and its evaluation script's feature step on the files and inputs of
``tests/interact_fixture.py`` (how: tests/data/README.md). Tolerance 1e-5 (measured: rows
1.8e-7, motion embeddings 2.6e-6, text embeddings 0 batched / 2.4e-6 vs one-caption batches).
"""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from interact_fixture import CAPTIONS, clip_inputs, write_interact_files

REF = Path(__file__).parent / "data" / "interact_evaluator_reference.npz"


@pytest.fixture(scope="module")
def interact(tmp_path_factory):
    pytest.importorskip("transformers")
    from hoibench.evaluator.backends import import_evaluator, load_evaluator
    root = tmp_path_factory.mktemp("interact")
    files = write_interact_files(root / "src")
    eid = import_evaluator("interact", root / "ev", **files)
    return {"files": files, "root": root, "ev_dir": root / "ev", "id": eid,
            "ev": load_evaluator(root / "ev", kind="interact")}


def test_fixture_is_the_one_the_reference_ran_on(interact):
    import torch
    sd = torch.load(interact["files"]["checkpoint"], weights_only=True)["state_dict"]
    total = sum(float(v.double().sum()) for v in sd.values())
    assert total == pytest.approx(float(np.load(REF)["state_sum"]), rel=1e-12)


def test_rows_and_embeddings_match_interact_code(interact):
    from hoibench.evaluator.interact_features import interact_rows
    ev, ref = interact["ev"], np.load(REF)
    assert ev.id == interact["id"] and ev.card["backend"] == "interact"
    rows = [interact_rows(c["markers"], c["points"], c["rot"], c["trans"], ev.basis) for c in clip_inputs()]
    assert [len(r) for r in rows] == list(ref["lengths"])
    assert np.abs(np.concatenate(rows) - ref["rows"]).max() <= 1e-5
    motion = ev.embed_motion(rows)
    assert motion.shape == (3, 256)
    assert np.abs(motion - ref["motion"]).max() <= 1e-5
    # a padded batch with lengths gives the same embeddings (padding is masked)
    T = max(len(r) for r in rows)
    padded = np.stack([np.concatenate([r, np.full((T - len(r), 615), 7.0, np.float32)]) for r in rows])
    assert np.abs(ev.embed_motion(padded, [len(r) for r in rows]) - ref["motion"]).max() <= 1e-5
    text = ev.embed_text(CAPTIONS)
    assert np.abs(text - ref["text"]).max() <= 1e-5
    assert np.abs(ev.embed_text(CAPTIONS, batch_size=1) - ref["text_single"]).max() <= 1e-5


def test_bps_deltas_nearest_point_analytic():
    from hoibench.evaluator.interact_features import bps_deltas
    pts = np.array([[[0.0, 0, 0], [1.0, 0, 0], [0, 2.0, 0]]])
    basis = np.array([[0.9, 0.1, 0], [0.1, 1.5, 0]])
    d = bps_deltas(pts + [1.0, 1.0, 1.0], basis, np.array([[1.0, 1.0, 1.0]]))
    np.testing.assert_allclose(d[0], [[0.1, -0.1, 0], [-0.1, 0.5, 0]], atol=1e-12)


def test_markers_pick_vertex_ids():
    import hashlib
    from hoibench.bodies.markers import MARKERS_SMPLH, MARKERS_SMPLX, markers_from_vertices
    assert len(set(MARKERS_SMPLH)) == len(set(MARKERS_SMPLX)) == 77
    # sha256 of ",".join(ids) of markerset_smplh / markerset_smplx in InterAct's
    # text2interaction/utils/markerset.py (wzyabcas/InterAct, commit daa7945), imported and hashed
    digest = lambda ids: hashlib.sha256(",".join(map(str, ids)).encode()).hexdigest()   # noqa: E731
    assert digest(MARKERS_SMPLH) == "0bd58e4e73cf2c29410985c72a19123d5ff72071cfd58c6b49d7844b676b00a4"
    assert digest(MARKERS_SMPLX) == "f030ab3dc02b6ce43eccfdce7fd0fd7ec3ac4fcd1c48a154ea74e167e0ca0398"
    v = np.arange(2 * 6890 * 3, dtype=float).reshape(2, 6890, 3)
    np.testing.assert_array_equal(markers_from_vertices(v), v[:, list(MARKERS_SMPLH)])
    vx = np.random.default_rng(0).normal(size=(10475, 3))
    np.testing.assert_array_equal(markers_from_vertices(vx)[5], vx[MARKERS_SMPLX[5]])
    with pytest.raises(ValueError, match="1000 vertices has no InterAct marker set"):
        markers_from_vertices(np.zeros((1000, 3)))


def test_markers_of_the_posed_proxy_body(tmp_path):
    """Markers are vertices of the posed body: they move rigidly with the root."""
    pytest.importorskip("smplx")
    from hoibench.bodies.markers import markers_from_vertices
    from hoibench.bodies.proxy import write_proxy_model
    from hoibench.bodies.smpl import body_forward, load_body_model
    write_proxy_model(tmp_path, "smplh")
    model = load_body_model(tmp_path, "smplh")
    poses = np.zeros((2, 156))
    poses[1, 1] = np.pi / 2                             # root yaw 90 degrees about y
    _, verts = body_forward(model, poses, trans=np.array([[0, 0, 0], [0.5, 0, 0]]))
    m0, m1 = markers_from_vertices(verts)
    R = np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0]], float)
    j0 = body_forward(model, poses[:1])[0][0, 0]         # root joint: the centre of global_orient
    np.testing.assert_allclose(m1, (m0 - j0) @ R.T + j0 + [0.5, 0, 0], atol=1e-5)


def _import(tmp_path, files, **change):
    from hoibench.evaluator.backends import import_evaluator
    return import_evaluator("interact", tmp_path / "ev", **{**files, **change})


def test_import_errors_are_one_line(interact, tmp_path):
    import torch
    files = interact["files"]
    bad = tmp_path / "trunc.ckpt"
    bad.write_bytes(files["checkpoint"].read_bytes()[:5000])
    with pytest.raises(ValueError, match="trunc.ckpt: not a readable torch checkpoint") as e:
        _import(tmp_path, files, checkpoint=bad)
    assert "\n" not in str(e.value)
    sd = torch.load(files["checkpoint"], weights_only=True)["state_dict"]
    wrong = dict(sd)
    wrong["motionencoder.skel_embedding.weight"] = torch.zeros(256, 263)
    torch.save({"state_dict": wrong}, tmp_path / "shape.ckpt")
    with pytest.raises(ValueError, match=r"motionencoder.skel_embedding.weight has shape \[256, 263\], the "
                                         r"architecture expects \[256, 615\]"):
        _import(tmp_path, files, checkpoint=tmp_path / "shape.ckpt")
    missing = {k: v for k, v in sd.items() if k != "textencoder.projection.1.bias"}
    torch.save({"state_dict": missing}, tmp_path / "missing.ckpt")
    with pytest.raises(ValueError, match="key textencoder.projection.1.bias is missing"):
        _import(tmp_path, files, checkpoint=tmp_path / "missing.ckpt")
    torch.save({"weights": sd}, tmp_path / "nosd.ckpt")
    with pytest.raises(ValueError, match="no 'state_dict'"):
        _import(tmp_path, files, checkpoint=tmp_path / "nosd.ckpt")
    np.save(tmp_path / "mean.npy", np.zeros(263))
    with pytest.raises(ValueError, match=r"mean.npy: mean must be a float array of shape \[615\]"):
        _import(tmp_path, files, mean=tmp_path / "mean.npy")
    (tmp_path / "bert").mkdir()
    with pytest.raises(ValueError, match="config.json: missing"):
        _import(tmp_path, files, distilbert=tmp_path / "bert")
    from hoibench.evaluator.backends import import_evaluator
    with pytest.raises(ValueError, match="--bps-basis is required"):
        import_evaluator("interact", tmp_path / "ev2", **{k: v for k, v in files.items() if k != "bps_basis"})


def test_folder_tamper_and_wrong_inputs_are_refused(interact, tmp_path):
    from hoibench.evaluator.backends import load_evaluator
    ev_dir = tmp_path / "ev"
    shutil.copytree(interact["ev_dir"], ev_dir)
    with pytest.raises(ValueError, match="615"):
        interact["ev"].embed_motion([np.zeros((4, 263), np.float32)])
    with pytest.raises(ValueError, match="a interact evaluator|this track needs a contrastive"):
        load_evaluator(ev_dir, kind="contrastive")
    (tmp_path / "rec").mkdir()
    (tmp_path / "rec" / "recognizer.json").write_text("{}")
    with pytest.raises(ValueError, match=r"needs a interact one \(make it with `hoibench evaluator import interact"):
        load_evaluator(tmp_path / "rec", kind="interact")
    vocab = ev_dir / "tokenizer" / "vocab.txt"
    vocab.write_text(vocab.read_text() + "extra\n")
    with pytest.raises(ValueError, match="vocab.txt: sha256 differs from card field"):
        load_evaluator(ev_dir, kind="interact")


def test_cli_import(interact, tmp_path, capsys):
    from hoibench.cli import main
    f = interact["files"]
    rc = main(["evaluator", "import", "interact", "--checkpoint", str(f["checkpoint"]), "--distilbert",
               str(f["distilbert"]), "--mean", str(f["mean"]), "--std", str(f["std"]), "--bps-basis",
               str(f["bps_basis"]), "--out", str(tmp_path / "ev")])
    assert rc == 0
    assert interact["id"] in capsys.readouterr().out      # the same files give the same id
    assert main(["evaluator", "show", str(tmp_path / "ev")]) == 0
    out = capsys.readouterr().out
    assert f"interact evaluator {interact['id']} (verified)" in out and "615 inputs" in out
