"""InterAct's released evaluation replayed (protocol ``interact-legacy``, loop ``interact-released``).

* InterAct's test loader (:func:`hoibench.metrics.interact_loop.loader_rows`): which clips it
  keeps (40-300 frames) and in which order (length, then source order, then name).
* The loop's per-repeat values equal those of InterAct's own code on the same embeddings.
* The protocol loads, belongs to the interact track and scores a synthetic InterAct-layout
  store end to end.

How the recorded numbers were made (a scratch harness outside the repository, not committed):
the sequences of :func:`_items` were written as a fake InterAct ``data/`` folder
(``<source>/sequences_canonical/<name>/motion.npy`` of the item's length, ``object.npz``,
``text.txt``; ``test_seq.txt``) and read by InterAct's own ``TextOnlyDataset``
(``text2interaction/data_loaders/behave/data/dataset.py``) through a ``DataLoader(batch_size=64,
shuffle=False, drop_last=True, collate_fn=t2m_behave_bps_collate)`` (``data_loaders/tensors.py``);
``eval_t2hoi`` (``text2interaction/eval/eval_marker_representation.py``) ran on that loader
with ``text2interaction/utils/eval_t2m_utils.py``, twice after ``np.random.seed(seed);
torch.manual_seed(seed)`` (its ``repeat_time = 2``), with stand-ins returning the fixed
embeddings for the text encoder, the motion encoder, the diffusion sampler (the generated
motion, then the 2 MultiModality samples of the first 2 batches) and BPS. Source:
wzyabcas/InterAct @ daa7945178e4b2fa0e14bddc3661f723ade50597. Two edits for this machine:
``os.listdir`` returned sorted names (the loader's tie order is the filesystem's listing), and
the matching-score accumulators started as ``np.float64(0)`` (numpy < 2's promotion of
``0 + float32``, which InterAct's environment has; numpy 2.4.6, scipy 1.17.1, torch 2.13.0
CPU here). The library matched every number exactly (0 difference); the tests allow 1e-6
relative for other BLAS builds.
"""
from __future__ import annotations

import hashlib

import numpy as np
import pytest

from hoibench.metrics import legacy_loops as LL
from hoibench.metrics.interact_loop import SOURCES, loader_rows, split_id

REL = 1e-6


def _items(n: int, d: int = 16, seed: int = 2025) -> dict:
    """n sequences over InterAct's 7 sources: names, lengths 30-340 frames, test flags (85%),
    and fixed embeddings (text, generated, real, 2 MultiModality samples)."""
    rng = np.random.default_rng(seed)
    src = [SOURCES[i] for i in rng.integers(0, len(SOURCES), n)]
    names = [f"sub{int(rng.integers(1, 9)):02d}_obj{int(rng.integers(0, 5))}_{i:03d}" for i in range(n)]
    lengths = rng.integers(30, 341, n)
    test = rng.uniform(size=n) < 0.85
    text = rng.normal(size=(n, d)).astype(np.float32)
    motion = (text + 1.5 * rng.normal(size=(n, d))).astype(np.float32)
    gt = (text + rng.normal(size=(n, d))).astype(np.float32)
    samples = (motion[None] + 0.5 * rng.normal(size=(2, n, d))).astype(np.float32)
    return dict(source=src, name=names, lengths=lengths, test=test, text=text, motion=motion, gt=gt,
                samples=samples)


def _test_rows(n: int) -> dict:
    """The test items in the scorer's order (sorted clip ids ``<source>-<name>``)."""
    it = _items(n)
    t = np.flatnonzero(it["test"])
    ids = [f"{it['source'][i]}-{it['name'][i]}" for i in t]
    perm = np.argsort(ids)
    t = t[perm]
    return dict(ids=[ids[i] for i in perm], lengths=it["lengths"][t], text=it["text"][t], motion=it["motion"][t],
                gt=it["gt"][t], samples=it["samples"][:, t])


# ====================================================================== InterAct's numbers
# eval_t2hoi on InterAct's loader, 420 sequences (370 test, 313 of 40-300 frames: 4 batches,
# 256 rows <= 300, so 50 Diversity pairs), seed 0
R420_ORDER = (313, "01a6c4df35497762ea54ec4fb4e4a434b146101a1e199a47112ca0dcc8979b93",
              ["sub01_obj3_189", "sub04_obj0_178", "sub07_obj4_137"], ["sub01_obj0_268", "sub06_obj1_083"])
R420_GENERATED = {
    "r_precision_top1": [0.26953125, 0.26953125], "r_precision_top2": [0.41796875, 0.41796875],
    "r_precision_top3": [0.4921875, 0.4921875], "mm_dist": [5.8928927183151245, 5.8928927183151245],
    "fid": [3.956674719342516, 3.956674719342516], "diversity": [10.074291229248047, 10.066286087036133],
    "multimodality": [2.7864956855773926, 0.0]}
R420_REAL = {
    "r_precision_top1": [0.6953125, 0.6953125], "r_precision_top2": [0.8359375, 0.8359375],
    "r_precision_top3": [0.89453125, 0.89453125], "mm_dist": [3.970771014690399, 3.970771014690399],
    "diversity": [7.932063579559326, 8.103161811828613]}
# 520 sequences (443 test, 371 kept: 5 batches, 320 rows > 300, so 300 pairs), seed 7
R520_ORDER = (371, "9101ecc3615e4631ca733a30ef53bac3b792c0d021dd086246a10e6ab0cfaf46",
              ["sub03_obj2_226", "sub05_obj0_322", "sub05_obj4_023"], ["sub01_obj1_370", "sub07_obj3_416"])
R520_GENERATED = {
    "r_precision_top1": [0.228125, 0.228125], "r_precision_top2": [0.378125, 0.378125],
    "r_precision_top3": [0.44375, 0.44375], "mm_dist": [5.827266120910645, 5.827266120910645],
    "fid": [2.9300587097517905, 2.9300587097517905], "diversity": [9.949748039245605, 9.735846519470215],
    "multimodality": [2.8141517639160156, 2.8141517639160156]}
R520_REAL = {
    "r_precision_top1": [0.6875, 0.6875], "r_precision_top2": [0.803125, 0.803125], "r_precision_top3": [0.875, 0.875],
    "mm_dist": [3.9320324420928956, 3.9320324420928956], "diversity": [7.932569980621338, 7.885038375854492]}


def _check(got: dict, expected: dict) -> None:
    for name, values in expected.items():
        np.testing.assert_allclose(np.asarray(got[name], np.float64), values, rtol=REL, atol=1e-12, err_msg=name)


@pytest.mark.parametrize("n, seed, order, generated, real", [
    (420, 0, R420_ORDER, R420_GENERATED, R420_REAL), (520, 7, R520_ORDER, R520_GENERATED, R520_REAL)])
def test_released_loop_equals_interact_code(n, seed, order, generated, real):
    x = _test_rows(n)
    rows = loader_rows(x["ids"], x["lengths"])
    names = [split_id(x["ids"][i])[1] for i in rows.order]
    count, digest, head, tail = order
    assert len(names) == count and names[:3] == head and names[-2:] == tail
    assert hashlib.sha256("\n".join(names).encode()).hexdigest() == digest
    res = LL.run_loop("interact-released", x["text"], x["motion"], x["gt"], x["samples"], ids=x["ids"],
                      lengths=x["lengths"], seed=seed)
    _check(res.generated, generated)
    _check(res.real, real)
    assert res.loop == "interact-released" and len(res.batches) == 2
    # the batches are InterAct's: consecutive 64-row slices of the loader order, indexed in the inputs
    full = (count // 64) * 64
    np.testing.assert_array_equal(np.concatenate(res.batches[0]["generated"]), rows.order[:full])
    assert len(rows.dropped) == len(x["ids"]) - count
    assert any("skips" in note for note in res.notes)


# ====================================================================== the loader, constructed cases
def test_loader_cut_is_inclusive_and_ties_follow_source_order_then_name():
    ids = ["behave-b", "grab-z", "neuraldome-k", "behave-a", "omomo-x", "chairs-c", "intercap-q", "imhd-m"]
    lengths = [40, 300, 120, 120, 39, 301, 120, 41]
    rows = loader_rows(ids, lengths)
    # kept: 40 (behave-b), 300, the three 120s, 41; 39 and 301 dropped
    assert rows.dropped == {"omomo-x": "39 frames < 40", "chairs-c": "301 frames > 300"}
    got = [ids[i] for i in rows.order]
    # 120-frame ties: neuraldome (rank 0) < behave (rank 5) < intercap (rank 6)
    assert got == ["behave-b", "imhd-m", "neuraldome-k", "behave-a", "intercap-q", "grab-z"]


def test_loader_bad_input_is_one_line():
    with pytest.raises(ValueError, match="clip id 'arctic-s1'.*source"):
        loader_rows(["arctic-s1"], [50])
    with pytest.raises(ValueError, match="lengths: expected 2 integer frame counts"):
        loader_rows(["behave-a", "grab-b"], [50.0, 60.0])


def test_without_ids_the_rows_are_scored_as_given_and_noted():
    x = _test_rows(420)
    sl = slice(0, 200)
    res = LL.run_loop("interact-released", x["text"][sl], x["motion"][sl], x["gt"][sl], x["samples"][:, sl], seed=3)
    plain = LL.interact_loop(x["text"][sl], x["motion"][sl], x["gt"][sl], x["samples"][:, sl], seed=3)
    for k in plain.generated:
        np.testing.assert_array_equal(res.generated[k], plain.generated[k])
    assert any("not applied" in n for n in res.notes)


def test_fewer_kept_clips_than_one_batch_is_refused():
    x = _test_rows(420)
    lengths = np.full(len(x["ids"]), 36)            # the synthetic store's 36-frame clips: all under 40
    with pytest.raises(ValueError, match="0 clips of 40-300 frames, fewer than one batch of 64"):
        LL.run_loop("interact-released", x["text"], x["motion"], x["gt"], ids=x["ids"], lengths=lengths)


# ====================================================================== protocol and scoring
def test_protocol_loads_and_belongs_to_the_interact_track():
    from hoibench.tracks.protocol import get_protocol
    from hoibench.tracks.registry import get_track
    p = get_protocol("interact-legacy")
    assert (p.track, p.embedding_loop, p.replications, p.r_precision_pool_size, p.r_precision_top_k) == \
        ("interact", "interact-released", 2, 64, 3)
    assert (p.mm_texts, p.mm_samples, p.mm_pairs, p.fps, p.seed) == (128, 2, 1, 30.0, 11)
    assert set(p.metrics) == {"r_precision_top1", "r_precision_top2", "r_precision_top3", "fid", "mm_dist",
                              "diversity", "multimodality"}
    assert "interact-legacy" in get_track("interact").protocols
    assert p.sha256 != get_protocol("interact-clean").sha256


@pytest.fixture(scope="module")
def scored(tmp_path_factory):
    """A 12-sequence synthetic InterAct store (4 test clips), InterAct's evaluator files with
    random weights (tests/interact_fixture.py, seeded), the ground truth scored under
    interact-legacy with batches of 4 (a copy of the YAML: the store is smaller than 64 clips)."""
    pytest.importorskip("transformers")
    from interact_fixture import prepare_interact_store, write_interact_files
    from hoibench.evaluator.backends import import_evaluator
    from hoibench.scoring.evaluate import evaluate
    from hoibench.scoring.submission_write import from_store
    from hoibench.tracks.protocol import get_protocol
    root = tmp_path_factory.mktemp("interact_legacy")
    prepare_interact_store(root / "raw", root / "data")
    import_evaluator("interact", root / "ev", **write_interact_files(root / "src"))
    from_store(root / "data", root / "gt")
    text = open(get_protocol("interact-legacy").source).read().replace("pool_size: 64 ", "pool_size: 4 ")
    (root / "small.yaml").write_text(text)
    # the synthetic clips have 36 frames: InterAct's loader (40-300) would keep none of them,
    # so the end-to-end run lowers its floor to 1 frame; the refusal is tested below
    from functools import partial
    from hoibench.metrics import interact_loop
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(interact_loop, "loader_rows", partial(interact_loop.loader_rows, min_frames=1))
        res = evaluate(root / "gt", root / "data", root / "ev", protocol=str(root / "small.yaml"),
                       allow_failed_gate=True)
    return res, root


def test_the_scorer_hands_the_loader_its_clips_and_refuses_a_split_it_cuts_away(scored):
    from hoibench.scoring.evaluate import evaluate
    from hoibench.scoring.pipeline import EvaluationRefused
    res, root = scored
    notes = " ".join(res.get("notes", []))
    assert "not applied" not in notes                      # the loader saw the clip ids and lengths
    with pytest.raises(EvaluationRefused, match="interact-legacy.*40-300 frames"):
        evaluate(root / "gt", root / "data", root / "ev", protocol=str(root / "small.yaml"), allow_failed_gate=True)


def test_protocol_scores_a_synthetic_interact_store_end_to_end(scored):
    res, _ = scored
    assert res["protocol"] == "interact-legacy" and res["replications"] == 2
    assert res["metric_variants"]["embedding_loop"] == "interact-released"
    m = res["metrics"]
    # the ground truth as the submission: generated rows = real rows, so FID 0 and the same
    # R-precision as the reference's real row would give
    # (4 rows in 256 dimensions: sqrtm of a singular covariance product, so 0 to ~1e-5)
    assert m["fid"]["mean"] == pytest.approx(0.0, abs=1e-3)
    for k in ("r_precision_top1", "r_precision_top2", "r_precision_top3"):
        assert 0.0 <= m[k]["mean"] <= 1.0
    assert m["mm_dist"]["mean"] > 0
    notes = " ".join(res.get("notes", []))
    assert "interact-released loop" in notes
    assert len(res["per_replication"]) == 2


def test_the_audit_moves_markers_with_the_corrupted_body(scored, tmp_path):
    """On a marker track the corruptions carry the markers along (``follow_markers``): severity
    0 is the ground truth (FID 0 with InterAct's evaluator at random weights), jitter moves the
    markers and the embeddings (FID > 0 at the top severity), a floating object leaves the
    markers as they were. InterAct's rows place the object's BPS basis at the object's own
    translation, so they do not see the object move away from the body: FID stays 0 under
    ``object_float`` (a blind spot of the evaluator, not of the audit)."""
    from hoibench.audit.corruptions import FAMILIES
    from hoibench.audit.document import run_audit
    from hoibench.audit.runner import corrupted_split, ground_truth, split_context
    from hoibench.datasets.store import Store
    _, root = scored
    doc = run_audit(root / "data", root / "ev", tmp_path / "audit", families=["jitter", "object_float"],
                    allow_failed_gate=True, log=lambda _m: None)
    fid = doc["corruptions"]["jitter"]["values"]["fid"]
    assert fid[0] == pytest.approx(0.0, abs=1e-3) and fid[-1] > fid[0] + 1e-3
    assert max(abs(v) for v in doc["corruptions"]["object_float"]["values"]["fid"]) < 1e-3
    store = Store(root / "data")
    ids = store.clip_ids("test")
    clips, caps = ground_truth(store, ids, ["markers"])
    ctx = split_context(clips, caps)
    top = FAMILIES["jitter"].severities[-1]
    jit = corrupted_split(store, clips, caps, "jitter", top, 0, ctx, {})
    flt = corrupted_split(store, clips, caps, "object_float", FAMILIES["object_float"].severities[-1], 0, ctx, {})
    for cid in ids:
        m = clips[cid]["markers"]
        np.testing.assert_array_equal(flt.samples[cid]["markers"][0], m)
        moved = np.linalg.norm(jit.samples[cid]["markers"][0] - m, axis=-1)
        assert 0.5 * top < np.median(moved) < 3 * top     # jitter of amplitude a moves a marker by ~a
