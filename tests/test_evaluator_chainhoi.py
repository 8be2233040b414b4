"""The ``chainhoi`` evaluator backend: ChainHOI's published MotionCLIP evaluator.

Fixtures are written in the real file layouts, with random weights at tiny sizes (no
download, no licensed data): a Lightning checkpoint (``state_dict`` under ``motion_clip.``,
plus the ``epoch``/``global_step``/``hyper_parameters`` entries Lightning writes, one of
them a ``functools.partial`` as the lightning-hydra template stores optimisers), a RoBERTa
folder (``config.json`` of a 1-layer, 768-wide RoBERTa -- 768 because ChainHOI's class
fixes ``text_dim = 768`` -- with a byte-level BPE ``vocab.json``/``merges.txt`` built
here) and ``Mean_local.npy``/``Std_local.npy`` (269 entries, as ChainHOI's) in a folder
named ``behave_t2m``. Every random value comes from ``numpy.random.default_rng`` so the
same fixture can be rebuilt anywhere.

Reference values (``tests/data/chainhoi_evaluator_reference.npz``, README there): ChainHOI's
own evaluator code run outside the project on this fixture (repository
``Huanggh531/ChainHOI``, commit ``4990160``, ``src/models/evaluator/MotionCLIP/
{evaluator,motion_clip}.py`` unmodified; ``MotionCLIPEvaluator`` with ``MotionCLIP``
bound to ``model_dim=32, num_layers=2`` and the tokenizer/model paths pointed at the
fixture folder; motions normalised as ``hoidataset.py`` does, ``(motion[:199] - mean) /
std`` over all 269 columns then ``[..., :263]``, length floored to a multiple of 4
("single" crop), zero-padded as ``collate_tensors`` does), torch 2.13.0 CPU,
transformers 5.24.0.
"""
from __future__ import annotations

import functools
import json
import shutil
from collections import OrderedDict
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("transformers")

from hoibench.evaluator.backends import backend_of, import_evaluator, load_evaluator, peek_card  # noqa: E402
from hoibench.evaluator.card import store_mismatches  # noqa: E402

REF = Path(__file__).parent / "data" / "chainhoi_evaluator_reference.npz"
WIDTH, LAYERS = 32, 2
#: merges of the tiny BPE vocabulary (after the 256 byte symbols)
MERGES = [("Ġ", "a"), ("Ġ", "p"), ("e", "r"), ("Ġp", "er"), ("o", "n"), ("Ġ", "t"), ("h", "e"), ("Ġt", "he"),
          ("Ġ", "b"), ("o", "x"), ("Ġb", "ox"), ("Ġ", "s"), ("i", "t"), ("Ġs", "it"), ("Ġ", "c"), ("a", "i")]
CAPTIONS = ["a person picks up the box", "someone sits on the chair and then stands up again",
            "the person lifts the box over the head, turns around, walks forward, puts it down on the table, "
            "and sits on the chair while waving both arms"]


def _bytes_to_unicode() -> list[str]:
    """GPT-2's byte -> printable character table (the byte-level BPE alphabet)."""
    bs = (list(range(ord("!"), ord("~") + 1)) + list(range(ord("¡"), ord("¬") + 1))
          + list(range(ord("®"), ord("ÿ") + 1)))
    cs, n = bs[:], 0
    for b in range(256):
        if b not in bs:
            bs.append(b)
            cs.append(256 + n)
            n += 1
    return [chr(c) for _, c in sorted(zip(bs, cs))]


def write_roberta_folder(folder: Path) -> Path:
    """config.json of a tiny 768-wide RoBERTa + a byte-level BPE tokenizer (vocab.json, merges.txt)."""
    from transformers import RobertaConfig
    folder.mkdir(parents=True, exist_ok=True)
    vocab = {"<s>": 0, "<pad>": 1, "</s>": 2, "<unk>": 3}
    for ch in _bytes_to_unicode():
        vocab[ch] = len(vocab)
    for a, b in MERGES:
        vocab.setdefault(a + b, len(vocab))
    vocab["<mask>"] = len(vocab)
    (folder / "vocab.json").write_text(json.dumps(vocab))
    (folder / "merges.txt").write_text("#version: 0.2\n" + "".join(f"{a} {b}\n" for a, b in MERGES))
    RobertaConfig(vocab_size=len(vocab), hidden_size=768, num_hidden_layers=1, num_attention_heads=12,
                  intermediate_size=64, max_position_embeddings=40, type_vocab_size=1, pad_token_id=1,
                  bos_token_id=0, eos_token_id=2).save_pretrained(folder)
    return folder


def _random(shape, name: str, rng) -> np.ndarray:
    """A float32 draw for parameter ``name``: LayerNorm gains near 1, biases small, matrices
    scaled by their fan-in."""
    if name.endswith("bias"):
        return (0.02 * rng.standard_normal(shape)).astype(np.float32)
    if len(shape) == 1 and ("norm" in name.lower() or "ln_" in name):
        return (1 + 0.1 * rng.standard_normal(shape)).astype(np.float32)
    fan = int(np.prod(shape[1:])) if len(shape) > 1 else shape[0]
    return (rng.standard_normal(shape) / np.sqrt(fan)).astype(np.float32)


def lightning_state_dict(roberta: Path, width: int = WIDTH, layers: int = LAYERS, seed: int = 0) -> OrderedDict:
    """ChainHOI's evaluator state dict (``motion_clip.`` keys) with seeded random values."""
    from transformers import AutoConfig

    from hoibench.evaluator.published_chainhoi import _roberta_shapes, expected_shapes
    arch = {"width": width, "layers": layers, "ff": 4 * width, "max_positions": 256, "output_dim": 512,
            "text_dim": 768}
    shapes = expected_shapes(arch, _roberta_shapes(AutoConfig.from_pretrained(str(roberta))))
    rng = np.random.default_rng(seed)
    sd = OrderedDict()
    for k in sorted(shapes):
        if k == "logit_scale":
            sd["motion_clip." + k] = torch.tensor(float(np.log(1 / 0.07)))
        else:
            sd["motion_clip." + k] = torch.from_numpy(_random(shapes[k], k, rng))
    return sd


def write_checkpoint(path: Path, sd: OrderedDict, extras: bool = True) -> Path:
    """A Lightning-style checkpoint around ``sd``."""
    ckpt = {"epoch": 24, "global_step": 325, "pytorch-lightning_version": "2.1.0", "state_dict": sd,
            "loops": {}, "callbacks": {}, "optimizer_states": [], "lr_schedulers": []}
    if extras:
        ckpt["hyper_parameters"] = {"optimizer": functools.partial(torch.optim.AdamW, lr=1e-4), "dropout": 0.3}
    path.parent.mkdir(parents=True, exist_ok=True)
    torch.save(ckpt, path)
    return path


def write_stats(folder: Path, seed: int = 1, dims: int = 269) -> Path:
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True, exist_ok=True)
    np.save(folder / "Mean_local.npy", (0.5 * rng.standard_normal(dims)).astype(np.float32))
    np.save(folder / "Std_local.npy", rng.uniform(0.5, 1.5, dims).astype(np.float32))
    return folder


def motions(seed: int = 2) -> list[np.ndarray]:
    """Raw hoi269 rows of four clips: 40, 24 and 8 frames, and 210 (cropped to 196)."""
    rng = np.random.default_rng(seed)
    return [rng.standard_normal((t, 269)).astype(np.float32) for t in (40, 24, 8, 210)]


def build(root: Path, extras: bool = True) -> dict:
    """Every input file of an import under ``root``."""
    roberta = write_roberta_folder(root / "roberta-base")
    sd = lightning_state_dict(roberta)
    return {"checkpoint": write_checkpoint(root / "checkpoint" / "behave_t2m" / "epoch=24-step=325.ckpt", sd, extras),
            "text_model": roberta, "stats": write_stats(root / "dataset" / "behave_t2m"), "state_dict": sd}


# --------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def imported(tmp_path_factory):
    """(inputs, evaluator folder, evaluator id) of one import of the fixture."""
    root = tmp_path_factory.mktemp("chainhoi")
    files = build(root)
    eid = import_evaluator("chainhoi", root / "ev", checkpoint=files["checkpoint"], text_model=files["text_model"],
                           stats=files["stats"])
    return files, root / "ev", eid


def _import(tmp_path: Path, files: dict, **override) -> str:
    args = {k: files[k] for k in ("checkpoint", "text_model", "stats")}
    args.update(override)
    return import_evaluator("chainhoi", tmp_path / "ev", **args)


def _one_line(exc) -> str:
    msg = str(exc.value)
    assert "\n" not in msg
    return msg


# --------------------------------------------------------------------------- reference values
def test_embeddings_match_chainhois_own_evaluator_code(imported):
    """Motion and text embeddings equal those of ChainHOI's evaluator code on the same
    weights and inputs (module docstring; measured max |diff|: 0 for both on this
    machine, allowed 1e-5)."""
    files, ev_dir, eid = imported
    ref = np.load(REF)
    ev = load_evaluator(ev_dir, kind="contrastive")
    assert ev.id == eid and type(ev).__name__ == "ChainHOIEvaluator"
    clips = motions()
    # the reference floors lengths to multiples of 4 and cuts at 196; these lengths are already
    # multiples of 4 except the 210-frame clip, which the evaluator cuts to its first 196 rows
    assert [min(len(c), 196) for c in clips] == ref["motion_lengths"].tolist()
    m = ev.embed_motion(clips)
    t = ev.embed_text(list(ref["captions"]), tokens=[["unused/X"]] * 3)
    assert m.dtype == np.float32 and m.shape == (4, 512) and t.shape == (3, 512)
    assert np.abs(m - ref["motion_embeddings"]).max() <= 1e-5
    assert np.abs(t - ref["text_embeddings"]).max() <= 1e-5
    assert np.array_equal(ev.tokenize(list(ref["captions"]))["input_ids"].numpy(), ref["text_input_ids"])
    assert np.allclose(np.linalg.norm(m, axis=1), 1, atol=1e-6) and np.allclose(np.linalg.norm(t, axis=1), 1,
                                                                                   atol=1e-6)


def test_embeddings_do_not_depend_on_batching_or_on_the_object_columns(imported):
    _, ev_dir, _ = imported
    ev = load_evaluator(ev_dir)
    clips = motions()
    together = ev.embed_motion(clips)
    alone = np.concatenate([ev.embed_motion([c]) for c in clips])
    human = ev.embed_motion([c[:, :263] for c in clips], batch_size=2)
    assert np.abs(together - alone).max() < 1e-5 and np.abs(together - human).max() < 1e-5
    # a padded (N, T, D) batch with lengths is read like the list
    padded = np.zeros((2, 40, 269), np.float32)
    padded[0], padded[1, :24] = clips[0], clips[1]
    assert np.abs(ev.embed_motion(padded, [40, 24]) - together[:2]).max() < 1e-5
    # the text of one caption is the same alone and in a batch padded to 32 tokens
    assert np.abs(ev.embed_text(CAPTIONS[:1]) - ev.embed_text(CAPTIONS)[:1]).max() < 1e-5


# --------------------------------------------------------------------------- the folder
def test_the_folder_is_an_ordinary_evaluator_folder_of_backend_chainhoi(imported):
    files, ev_dir, eid = imported
    assert backend_of(ev_dir).name == "chainhoi"
    card = peek_card(ev_dir, "contrastive")
    assert card["backend"] == "chainhoi" and card["evaluator_id"] == eid
    assert card["config"]["width"] == WIDTH and card["config"]["layers"] == LAYERS
    assert card["config"]["heads"] == 8 and card["config"]["max_positions"] == 256
    assert card["dataset"]["name"] == "behave" and card["dataset"]["representation"] == "hoi269-legacy-1.0"
    assert card["dataset"]["features"] == "hoi269" and card["dataset"]["fps"] == 20
    mean = np.load(files["stats"] / "Mean_local.npy")
    assert card["normalization"]["mean"] == [float(x) for x in mean[:263]]
    assert card["normalization"]["file_entries"] == 269
    # the RoBERTa weights come from the checkpoint, not the folder (which has none here)
    from safetensors.numpy import load_file
    w = load_file(str(ev_dir / "weights.safetensors"))
    key = "text_encoder.pooler.dense.weight"
    assert np.array_equal(w[key], files["state_dict"]["motion_clip." + key].numpy())
    assert "logit_scale" not in w and not any(k.startswith("motion_clip.") for k in w)


def test_import_is_deterministic_and_reads_checkpoints_without_their_pickled_objects(imported, tmp_path):
    """Same files, same id; a checkpoint without the Lightning extras (so loadable by plain
    weights_only) holds the same weights."""
    files, ev_dir, eid = imported
    assert _import(tmp_path / "a", files) == eid
    plain = write_checkpoint(tmp_path / "plain.ckpt", files["state_dict"], extras=False)
    _import(tmp_path / "b", files, checkpoint=plain)
    assert (tmp_path / "b" / "ev" / "weights.safetensors").read_bytes() == (ev_dir / "weights.safetensors").read_bytes()


def test_store_mismatches_judge_the_dataset_and_representation_it_was_trained_for(imported):
    _, ev_dir, _ = imported
    card = peek_card(ev_dir)
    behave = {"dataset": "behave", "config": {"fps": 20, "mode": "legacy-hoidiff"},
              "representations": {"hml263": "hml263-legacy-hoidiff-1.0", "hoi269": "hoi269-legacy-1.0"},
              "stats": {"hml263": {"sha256": "0" * 64}}, "clips": [{"id": "a", "split": "train"}]}
    assert store_mismatches(card, behave) == []      # its own statistics: the store's are not compared
    # a store prepared in mode legacy holds the same hoi269 rows (body part: HOI-Diff's)
    legacy = {**behave, "config": {"fps": 20, "mode": "legacy"},
              "representations": {"hml263": "hml263-legacy-1.0", "hoi269": "hoi269-legacy-1.0"}}
    assert store_mismatches(card, legacy) == []
    omomo = {**behave, "dataset": "omomo"}
    assert any("dataset 'behave'" in r for r in store_mismatches(card, omomo))
    clean = {**behave, "config": {"fps": 20, "mode": "clean"},
             "representations": {"hml263": "hml263-clean-1.0", "hoi269": "hoi269-clean-1.0"}}
    assert any("hoi269-legacy-1.0" in r and "hoi269-clean-1.0" in r for r in store_mismatches(card, clean))
    assert any("fps" in r for r in store_mismatches(card, {**behave, "config": {"fps": 30, "mode": "legacy"}}))


def test_a_result_scored_with_it_is_comparable_with_chainhois_paper_rows(imported):
    """What ``hoibench evaluate`` records as the backend (``backend_of(EV).name``) makes a
    behave-legacy row comparable with ChainHOI's checked-in rows; another backend does not."""
    from hoibench.publish.leaderboard import comparable, entry_from_result, read_entry
    _, ev_dir, eid = imported
    paper = read_entry(Path(__file__).parent.parent / "leaderboards" / "behave" / "entries"
                       / "reported-chainhoi-chainhoi.json")
    result = {"protocol": "behave-legacy", "evaluator_id": eid, "evaluator_backend": backend_of(ev_dir).name,
              "metrics": {"fid": {"mean": 1.0, "ci95": 0.0}}, "complete": True}
    assert comparable(entry_from_result(result, method="m", track="behave"), paper)
    assert not comparable(entry_from_result({**result, "evaluator_backend": "contrastive"}, method="m",
                                            track="behave"), paper)


# --------------------------------------------------------------------------- refusals
def test_missing_and_truncated_checkpoints_are_refused_in_one_line(imported, tmp_path):
    files, _, _ = imported
    with pytest.raises(ValueError) as e:
        _import(tmp_path, files, checkpoint=tmp_path / "none.ckpt")
    assert "none.ckpt" in _one_line(e) and "no such file" in str(e.value)
    data = files["checkpoint"].read_bytes()
    cut = tmp_path / "cut.ckpt"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(ValueError) as e:
        _import(tmp_path, files, checkpoint=cut)
    assert "cut.ckpt" in _one_line(e) and "truncated" in str(e.value)
    assert not (tmp_path / "ev" / "card.json").exists()


def test_a_checkpoint_that_would_run_code_is_refused_and_runs_nothing(imported, tmp_path):
    import os

    files, _, _ = imported
    marker = tmp_path / "ran"

    class Payload:
        def __reduce__(self):
            return (os.system, (f"touch {marker}",))

    bad = tmp_path / "bad.ckpt"
    torch.save({"state_dict": files["state_dict"], "callbacks": Payload()}, bad)
    with pytest.raises(ValueError) as e:
        _import(tmp_path, files, checkpoint=bad)
    assert "bad.ckpt" in _one_line(e) and "blocked" in str(e.value)
    assert not marker.exists()


@pytest.mark.parametrize("edit, needles", [
    ("shape", ("motion_clip.motion_encoder.transformer.layers.1.linear1.weight", "(100, 32)", "(128, 32)")),
    ("missing", ("motion_clip.motion_encoder.ln_post.bias", "no ")),
    ("extra", ("unexpected", "motion_clip.motion_encoder.extra")),
    ("prefix", ("'model.head'", "motion_clip.")),
    ("text", ("motion_clip.text_encoder.pooler.dense.weight", "(768, 10)", "(768, 768)")),
])
def test_checkpoint_keys_and_shapes_are_checked_before_loading(imported, tmp_path, edit, needles):
    files, _, _ = imported
    sd = OrderedDict(files["state_dict"])
    if edit == "shape":
        sd["motion_clip.motion_encoder.transformer.layers.1.linear1.weight"] = torch.zeros(100, 32)
    elif edit == "missing":
        del sd["motion_clip.motion_encoder.ln_post.bias"]
    elif edit == "extra":
        sd["motion_clip.motion_encoder.extra"] = torch.zeros(3)
    elif edit == "prefix":
        sd["model.head"] = torch.zeros(3)
    else:
        sd["motion_clip.text_encoder.pooler.dense.weight"] = torch.zeros(768, 10)
    with pytest.raises(ValueError) as e:
        _import(tmp_path, files, checkpoint=write_checkpoint(tmp_path / "edited.ckpt", sd))
    msg = _one_line(e)
    assert "edited.ckpt" in msg and all(n in msg for n in needles), msg


@pytest.mark.parametrize("option, folder, name", [("stats", "behave_t2m", "Std_local.npy"),
                                                  ("text_model", "roberta", "merges.txt")])
def test_a_missing_statistics_or_text_file_is_named(imported, tmp_path, option, folder, name):
    files, _, _ = imported
    copy = tmp_path / folder
    shutil.copytree(files[option], copy)
    (copy / name).unlink()
    with pytest.raises(ValueError) as e:
        _import(tmp_path, files, **{option: copy})
    assert f"{name} is missing" in _one_line(e)


def test_unusable_statistics_are_named(imported, tmp_path):
    files, _, _ = imported
    stats = tmp_path / "behave_t2m"
    shutil.copytree(files["stats"], stats)
    np.save(stats / "Std_local.npy", np.zeros(269, np.float32))
    with pytest.raises(ValueError) as e:
        _import(tmp_path, files, stats=stats)
    assert "Std_local.npy" in _one_line(e) and "positive" in str(e.value)
    unnamed = tmp_path / "stats"
    shutil.copytree(files["stats"], unnamed)
    with pytest.raises(ValueError) as e:         # a tiny evaluator: the dataset comes from the folder name
        _import(tmp_path, files, stats=unnamed)
    assert "BEHAVE's or OMOMO's" in _one_line(e)


def test_a_modified_folder_is_refused_on_load(imported, tmp_path):
    _, ev_dir, _ = imported
    copy = tmp_path / "ev"
    shutil.copytree(ev_dir, copy)
    vocab = copy / "text_model" / "vocab.json"
    vocab.write_text(vocab.read_text().replace('"<unk>": 3', '"<unk>": 4'))
    with pytest.raises(ValueError) as e:
        load_evaluator(copy)
    assert "vocab.json" in _one_line(e)
    shutil.rmtree(copy)
    shutil.copytree(ev_dir, copy)
    card = json.loads((copy / "card.json").read_text())
    card["dataset"]["name"] = "omomo"
    (copy / "card.json").write_text(json.dumps(card))
    with pytest.raises(ValueError) as e:
        load_evaluator(copy)
    assert "dataset" in _one_line(e) and "id mismatch" in str(e.value)


def test_the_command_line_imports_and_shows_it(imported, tmp_path, capsys):
    from hoibench.cli import main
    files, _, eid = imported
    out = tmp_path / "ev-cli"
    assert main(["evaluator", "import", "chainhoi", "--checkpoint", str(files["checkpoint"]), "--text-model",
                 str(files["text_model"]), "--stats", str(files["stats"]), "--out", str(out)]) == 0
    assert eid in capsys.readouterr().out
    assert main(["evaluator", "show", str(out)]) == 0
    shown = capsys.readouterr().out
    assert "chainhoi" in shown and "id verified" in shown and "behave" in shown
    assert main(["evaluator", "import", "chainhoi", "--checkpoint", str(tmp_path / "x.ckpt"), "--text-model",
                 str(files["text_model"]), "--stats", str(files["stats"]), "--out", str(tmp_path / "ev2")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "x.ckpt" in err[0]


def test_a_checkpoint_without_a_lightning_state_dict_is_refused(imported, tmp_path):
    files, _, _ = imported
    plain = tmp_path / "plain.pt"
    torch.save({"model": files["state_dict"]}, plain)
    with pytest.raises(ValueError) as e:
        _import(tmp_path, files, checkpoint=plain)
    assert "plain.pt" in _one_line(e) and "no 'state_dict'" in str(e.value)
    listed = tmp_path / "list.pt"
    torch.save([1, 2], listed)
    with pytest.raises(ValueError) as e:
        _import(tmp_path, files, checkpoint=listed)
    assert "list.pt" in _one_line(e) and "holds a list" in str(e.value)


def test_position_ids_saved_by_older_transformers_are_accepted_only_when_they_are_positions(imported, tmp_path):
    files, ev_dir, _ = imported
    sd = OrderedDict(files["state_dict"])
    sd["motion_clip.text_encoder.embeddings.position_ids"] = torch.arange(40)[None]
    _import(tmp_path / "a", files, checkpoint=write_checkpoint(tmp_path / "old.ckpt", sd))
    assert (tmp_path / "a" / "ev" / "weights.safetensors").read_bytes() == (ev_dir / "weights.safetensors").read_bytes()
    sd["motion_clip.text_encoder.embeddings.position_ids"] = torch.arange(40)[None].flip(1)
    with pytest.raises(ValueError) as e:
        _import(tmp_path / "b", files, checkpoint=write_checkpoint(tmp_path / "odd.ckpt", sd))
    assert "odd.ckpt" in _one_line(e) and "position_ids" in str(e.value)


def test_the_dataset_comes_from_the_released_sizes_and_must_agree_with_the_statistics_folder(tmp_path):
    from hoibench.evaluator.published_chainhoi import _dataset
    assert _dataset({"width": 384, "layers": 8}, tmp_path / "stats") == "behave"
    assert _dataset({"width": 512, "layers": 6}, tmp_path / "omomo") == "omomo"
    assert _dataset({"width": 32, "layers": 2}, tmp_path / "OMOMO_data") == "omomo"
    with pytest.raises(ValueError, match="OMOMO's but the checkpoint is the BEHAVE evaluator"):
        _dataset({"width": 384, "layers": 8}, tmp_path / "omomo")
    with pytest.raises(ValueError, match="BEHAVE's but the checkpoint is the OMOMO evaluator"):
        _dataset({"width": 512, "layers": 6}, tmp_path / "behave_t2m")
