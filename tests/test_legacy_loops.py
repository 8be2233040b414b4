"""Reference evaluation loops (hoibench.metrics.legacy_loops): the claims.

* Each loop's per-replication values equal those of the reference's own evaluation code run
  on the same fixed embeddings (numbers recorded below).
* The batch composition (which rows share an R-precision batch, in which order) equals what
  torch's DataLoader gives under the same seed.
* drop_last, top-3 and the quirks kept (InterAct's re-counted MultiModality batch, ChainHOI's
  missing MultiModality) show in constructed cases.

How the expected numbers were made (a scratch harness outside the repository, not committed):
the embeddings of :func:`_embeddings` were fed to
  - t2m: text-to-motion ``final_evaluations.py`` (EricGuo5513/text-to-motion @ 72df96ec) --
    ``evaluate_matching_score``, ``evaluate_fid``, ``evaluate_diversity``,
    ``evaluate_multimodality`` and ``evaluation`` exec'd from the file, with
    ``utils/metrics.py``; real torch DataLoaders with the file's ``collate_fn``; stand-ins for
    ``CompV6GeneratedDataset``'s loop, ``MMGeneratedDataset`` and the evaluator wrapper's row
    reordering; ``matching_score_sum = 0`` made a float64 as under numpy < 2;
    ``torch<1.9``: torch 1.6-1.8's ``RandomSampler.__iter__`` patched in;
  - mdm: MDM ``eval/eval_humanml.py`` (GuyTevet/motion-diffusion-model @ d4fd88c8), the same
    way, with a stand-in for ``CompMDMGeneratedDataset``'s loop;
  - chainhoi: ``TM2TMetrics`` of ChainHOI ``src/models/metrics/tm2t.py`` + ``utils.py``
    (Huanggh531/ChainHOI @ 49901600) itself (torchmetrics.Metric stubbed), updated in
    unshuffled batches of 32 from a DataLoader, ``compute`` then ``reset`` per replication;
  - interact: InterAct ``eval_t2hoi``'s metric lines
    (``text2interaction/eval/eval_marker_representation.py`` L49-231, wzyabcas/InterAct @
    daa79451) with ``text2interaction/utils/eval_t2m_utils.py``;
each after ``np.random.seed(seed); torch.manual_seed(seed)`` (numpy 2.4.6, scipy 1.17.1,
torch 2.13.0 CPU). The library matched every number exactly (0 difference); the tests allow
1e-6 relative for other BLAS builds.
"""
from __future__ import annotations

import numpy as np
import pytest

from hoibench.metrics import legacy_loops as LL

torch = pytest.importorskip("torch")
from torch.utils.data import DataLoader  # noqa: E402

REL = 1e-6


def _embeddings(N=330, D=16, K=30, seed=2024) -> dict:
    """Fixed embeddings: N test items, D features, K samples per item, and length keys."""
    rng = np.random.default_rng(seed)
    text = rng.normal(size=(N, D)).astype(np.float32)
    motion = (text + 1.5 * rng.normal(size=(N, D))).astype(np.float32)
    gt = (text + rng.normal(size=(N, D))).astype(np.float32)
    samples = (motion[None] + 0.5 * rng.normal(size=(K, N, D))).astype(np.float32)
    keys = dict(sent_lens=rng.integers(5, 15, N), lengths=rng.integers(10, 50, N) * 4,
                gt_lengths=rng.integers(10, 50, N) * 4, sample_lengths=rng.integers(10, 50, (K, N)) * 4)
    return dict(text=text, motion=motion, gt=gt, samples=samples, keys=keys)


@pytest.fixture(scope="module")
def emb():
    return _embeddings()


def _args(e):
    return e["text"], e["motion"], e["gt"], e["samples"]


def _check(got: dict, expected: dict) -> None:
    assert set(expected) <= set(got)
    for name, values in expected.items():
        np.testing.assert_allclose(np.asarray(got[name], np.float64), values, rtol=REL, atol=1e-12, err_msg=name)


# ====================================================================== values = the references'
# final_evaluations.py (text-to-motion @ 72df96ec), seed 0, replication_times 3, torch 1.6-1.8 sampler
T2M_GENERATED = {
    "r_precision_top1": [0.38125, 0.328125, 0.33125], "r_precision_top2": [0.540625, 0.521875, 0.525],
    "r_precision_top3": [0.659375, 0.640625, 0.65625],
    "mm_dist": [5.836221218109131, 5.859166383743286, 5.848993539810181],
    "fid": [3.250154508304121, 3.185808063904034, 3.2686479332417946],
    "diversity": [9.98981761932373, 9.976609230041504, 9.910888671875],
    "multimodality": [2.762153148651123, 2.4930708408355713, 2.7743923664093018]}
T2M_REAL = {
    "r_precision_top1": [0.7625, 0.78125, 0.76875], "r_precision_top2": [0.884375, 0.875, 0.89375],
    "r_precision_top3": [0.94375, 0.953125, 0.940625],
    "mm_dist": [3.928022027015686, 3.9313246488571165, 3.925342082977295],
    "fid": [0.03518467870521391, 0.03257093319280102, 0.034109316707571224],
    "diversity": [7.9295783042907715, 7.944920063018799, 7.915421485900879]}
# the same, today's torch sampler (torch >= 1.9)
T2M_GENERATED_NEW = {
    "r_precision_top1": [0.315625, 0.334375, 0.353125], "r_precision_top2": [0.515625, 0.496875, 0.5375],
    "r_precision_top3": [0.621875, 0.634375, 0.640625],
    "mm_dist": [5.845091533660889, 5.823848009109497, 5.843540143966675],
    "fid": [3.0940687744565025, 3.160394916290329, 3.1482817280173947],
    "diversity": [9.80985164642334, 9.769301414489746, 9.800758361816406],
    "multimodality": [2.787759780883789, 2.5016820430755615, 2.766514778137207]}
# eval/eval_humanml.py (motion-diffusion-model @ d4fd88c8): mm_short, seed 0, 2 replications
MDM_MM_SHORT = {
    "r_precision_top1": [0.38125, 0.328125], "r_precision_top2": [0.540625, 0.521875],
    "r_precision_top3": [0.659375, 0.640625], "mm_dist": [5.836221218109131, 5.859166383743286],
    "fid": [3.250154508304121, 3.185808063904034], "diversity": [9.751872062683105, 9.921082496643066],
    "multimodality": [2.781846523284912, 2.7799465656280518]}
MDM_MM_SHORT_REAL_DIVERSITY = [7.848575115203857, 7.735808849334717]
# the same, wo_mm, seed 1
MDM_WO_MM = {
    "r_precision_top1": [0.33125, 0.353125], "r_precision_top2": [0.525, 0.525], "r_precision_top3": [0.65, 0.65],
    "mm_dist": [5.837361860275268, 5.842070722579956], "fid": [3.131515134255906, 3.2283925073741813],
    "diversity": [9.771269798278809, 9.902724266052246]}
# TM2TMetrics.compute (ChainHOI @ 49901600), seed 0, 2 replications (test loader pass + compute each)
CHAINHOI_GENERATED = {
    "r_precision_top1": [0.34375, 0.34062498807907104], "r_precision_top2": [0.543749988079071, 0.518750011920929],
    "r_precision_top3": [0.6343749761581421, 0.625], "mm_dist": [5.832348346710205, 5.859455108642578],
    "fid": [3.1472770417342844, 3.147277160943503], "diversity": [9.809179306030273, 9.716529846191406]}
CHAINHOI_REAL = {
    "r_precision_top1": [0.7749999761581421, 0.7406250238418579],
    "r_precision_top2": [0.918749988079071, 0.893750011920929],
    "r_precision_top3": [0.9593750238418579, 0.949999988079071], "mm_dist": [3.9295661449432373, 3.933762311935425],
    "diversity": [7.942031383514404, 7.781482696533203]}
# eval_t2hoi (InterAct @ daa79451), seed 0, repeat_time 2
INTERACT_GENERATED = {
    "r_precision_top1": [0.209375, 0.209375], "r_precision_top2": [0.35, 0.35],
    "r_precision_top3": [0.453125, 0.453125],
    "mm_dist": [5.850979518890381, 5.850979518890381], "fid": [3.259412389607249, 3.259412389607249],
    "diversity": [9.884634017944336, 9.944018363952637], "multimodality": [2.6553354263305664, 0.0]}
INTERACT_REAL = {
    "r_precision_top1": [0.665625, 0.665625], "r_precision_top2": [0.8125, 0.8125],
    "r_precision_top3": [0.896875, 0.896875], "mm_dist": [3.9332356452941895, 3.9332356452941895],
    "diversity": [7.831381797790527, 7.809528827667236]}


def test_t2m_equals_final_evaluations(emb):
    res = LL.run_loop("t2m", *_args(emb), seed=0, replications=3, **emb["keys"])
    _check(res.generated, T2M_GENERATED)
    _check(res.real, T2M_REAL)
    # the reference's list dtypes: float32 Diversity / MultiModality, float64 otherwise
    assert res.generated["diversity"].dtype == np.float32 and res.generated["fid"].dtype == np.float64
    assert res.notes == []


def test_t2m_with_todays_torch_sampler(emb):
    res = LL.t2m_loop(*_args(emb), seed=0, replications=3, torch_sampler="torch>=1.9", **emb["keys"])
    _check(res.generated, T2M_GENERATED_NEW)


def test_mdm_equals_eval_humanml(emb):
    res = LL.run_loop("mdm", *_args(emb), seed=0, mode="mm_short", replications=2, **emb["keys"])
    _check(res.generated, MDM_MM_SHORT)
    _check(res.real, {"diversity": MDM_MM_SHORT_REAL_DIVERSITY})
    # MultiModality on whole batches: 100 // 32 + 1 = 4 batches of 32 items
    assert all(len(b["multimodality"][0]) == 128 for b in res.batches)
    wo = LL.run_loop("mdm", *_args(emb), seed=1, replications=2, **emb["keys"])
    _check(wo.generated, MDM_WO_MM)
    assert "multimodality" not in wo.generated and any("multimodality" in n for n in wo.notes)


def test_chainhoi_equals_tm2t_metrics(emb):
    res = LL.run_loop("chainhoi", *_args(emb), seed=0, replications=2)
    _check(res.generated, CHAINHOI_GENERATED)
    _check(res.real, CHAINHOI_REAL)
    assert np.isnan(res.generated["multimodality"]).all()
    assert any("never creates" in n for n in res.notes)
    assert LL.chainhoi_loop(*_args(emb)).summary()["fid"][1] == 0.0       # one replication: CI 0


def test_interact_equals_eval_t2hoi(emb):
    res = LL.run_loop("interact", *_args(emb), seed=0)
    _check(res.generated, INTERACT_GENERATED)
    _check(res.real, INTERACT_REAL)


def test_summary_is_the_references_mean_and_ci(emb):
    res = LL.t2m_loop(*_args(emb), seed=0, replications=3, **emb["keys"])
    for name, values in res.generated.items():
        mean, ci = res.summary()[name]
        assert mean == float(np.mean(values))
        assert ci == pytest.approx(1.96 * float(np.std(values.astype(np.float64))) / np.sqrt(3), rel=1e-6)


# ====================================================================== batch composition
def _chunks(order, size):
    return [list(order[s:s + size]) for s in range(0, len(order) - len(order) % size, size)]


def test_t2m_batches_equal_torch_dataloaders(emb):
    """No length keys: the batches are exactly the DataLoaders' (today's torch) under the seed."""
    n = len(emb["text"])
    with torch.random.fork_rng():
        torch.manual_seed(7)
        generated = [int(b) for b in DataLoader(range(n), batch_size=1, shuffle=True)]     # generation order
        real = [b.tolist() for b in DataLoader(range(n), batch_size=32, shuffle=True, drop_last=True)]
        list(DataLoader(range(n), batch_size=32, drop_last=True))                          # generated loader
        fid = [b.tolist() for b in DataLoader(range(n), batch_size=32, shuffle=True, drop_last=True)]
    res = LL.t2m_loop(*_args(emb), seed=7, replications=1, torch_sampler="torch>=1.9")
    b = res.batches[0]
    assert [x.tolist() for x in b["real"]] == real
    assert [x.tolist() for x in b["generated"]] == _chunks(generated, 32)
    assert [x.tolist() for x in b["fid_real"]] == fid


def test_t2m_batches_with_torch_1_6_sampler_and_length_keys(emb):
    # the first 'ground truth' and generated batches of replication 0 (seed 0) as the harness's
    # evaluator stand-in received them: DataLoader with torch 1.6-1.8's RandomSampler, rows
    # sorted by caption length (collate_fn) then by motion length (evaluator_wrapper.py L65)
    res = LL.t2m_loop(*_args(emb), seed=0, replications=1, **emb["keys"])
    assert res.batches[0]["real"][0].tolist() == [
        290, 169, 171, 42, 49, 75, 102, 131, 209, 108, 29, 74, 95, 230, 118, 289, 31, 94, 272, 195, 302, 98, 271,
        126, 188, 76, 215, 304, 303, 135, 12, 133]
    assert res.batches[0]["generated"][0].tolist() == [
        311, 21, 108, 29, 153, 180, 294, 303, 87, 275, 210, 273, 255, 17, 325, 281, 286, 312, 157, 212, 113, 209,
        163, 70, 324, 283, 191, 246, 49, 48, 195, 208]


def test_chainhoi_permutation_follows_the_test_loader_pass(emb):
    n = len(emb["text"])
    with torch.random.fork_rng():
        torch.manual_seed(3)
        list(DataLoader(range(n), batch_size=32))            # the test loader: one base-seed draw
        perm = torch.randperm(n).numpy()
    res = LL.chainhoi_loop(*_args(emb), seed=3)
    groups = res.batches[0]["generated"]
    assert len(groups) == n // 32 and all(len(g) == 32 for g in groups)
    assert np.array_equal(np.concatenate(groups), perm[:n // 32 * 32])      # the tail of 10 left out


# ====================================================================== drop_last, top-k, quirks
def _triangles(n_batches=3, extra=8, bs=64, D=4):
    """Per batch of 64: 21 triangles whose texts sit opposite their own vertex (own motion 3rd
    nearest) and one row matched at rank 1; then ``extra`` rows, each matched at rank 1."""
    h = np.sqrt(3) / 2
    text, motion = [], []
    for _ in range(n_batches):
        for c in range(21):
            a, b, cc = np.array([10. * c, 0]), np.array([10. * c + 1, 0]), np.array([10. * c + .5, h])
            motion += [a, b, cc]
            text += [b + cc - a, a + cc - b, a + b - cc]
        motion.append(np.array([0., 50.]))
        text.append(np.array([0.1, 50.]))
    for i in range(extra):
        motion.append(np.array([20. * i, -50.]))
        text.append(np.array([20. * i + .1, -50.]))
    pad = lambda x: np.pad(np.array(x), ((0, 0), (0, D - 2)))  # noqa: E731
    return pad(text).astype(np.float32), pad(motion).astype(np.float32)


@pytest.mark.filterwarnings("ignore:Matrix is singular")         # FID of the padded 2-D layout
def test_interact_top3_and_drop_last():
    text, motion = _triangles()                          # 200 rows: 3 batches of 64, 8 left over
    assert len(text) == 200
    res = LL.interact_loop(text, motion, motion, seed=0, replications=1)
    g = res.generated
    assert g["r_precision_top1"][0] == g["r_precision_top2"][0] == 3 / 192    # the 8 perfect rows dropped
    assert g["r_precision_top3"][0] == 1.0
    assert res.real["r_precision_top3"][0] == 1.0
    assert np.isnan(g["multimodality"][0])               # no samples given
    # 192 scored rows (<= 300): Diversity with 50 pairs, so it is defined
    assert np.isfinite(g["diversity"][0])


def test_shuffled_loops_drop_the_incomplete_batch(emb):
    n = len(emb["text"])                                 # 330 = 10 x 32 + 10
    for res in (LL.t2m_loop(*_args(emb), seed=2, replications=2), LL.mdm_loop(*_args(emb), seed=2, replications=2)):
        for b in res.batches:
            for role in ("real", "generated", "fid_real"):
                assert [len(x) for x in b[role]] == [32] * (n // 32)
                assert len(np.unique(np.concatenate(b[role]))) == n // 32 * 32


def test_interact_multimodality_recounts_batch_one():
    """L197: after each batch past the first two, batch 1's block is appended again."""
    rng = np.random.default_rng(0)
    N, D = 192, 8
    x = rng.normal(size=(N, D)).astype(np.float32)
    step = np.zeros((2, N, D), np.float32)
    step[1, :64, 0], step[1, 64:128, 0], step[1, 128:, 0] = 1.0, 2.0, 100.0   # sample 1 - sample 0
    samples = x[None] + step
    res = LL.interact_loop(x, x, x, samples, seed=0, replications=4)
    mm = res.generated["multimodality"]
    # one pair per replication: the same sample twice (0) or the two samples: (64*1 + 64*2 + 64*2) / 192
    assert all(v == 0 or v == pytest.approx(5 / 3, rel=1e-6) for v in mm) and (mm > 0).any() and (mm == 0).any()
    assert [len(r) for r in res.batches[0]["multimodality"]] == [64, 64, 64]


def test_small_sets_are_reported_not_crashed(emb):
    e = _embeddings(N=80)
    res = LL.chainhoi_loop(e["text"], e["motion"], e["gt"], seed=0)
    assert np.isnan(res.generated["diversity"][0]) and any("-1" in n for n in res.notes)
    with pytest.raises(ValueError, match="more than 32"):
        LL.chainhoi_loop(e["text"][:32], e["motion"][:32], e["gt"][:32])
    with pytest.raises(ValueError, match="no full batch"):
        LL.interact_loop(e["text"][:63], e["motion"][:63], e["gt"][:63])
    t2m = LL.t2m_loop(e["text"], e["motion"], e["gt"], seed=0, replications=1, mm_texts=10, diversity_times=300)
    assert np.isnan(t2m.generated["diversity"][0]) and np.isnan(t2m.generated["multimodality"][0])


def test_registry():
    assert set(LL.LOOPS) == {"t2m", "mdm", "chainhoi", "interact", "interact-released", "chois"}
    got = {k: (s.batch_size, s.top_k, s.replications) for k, s in LL.LOOPS.items()}
    assert got == {"t2m": (32, 3, 20), "mdm": (32, 3, 20), "chainhoi": (32, 3, 1), "interact": (64, 3, 2),
                   "interact-released": (64, 3, 2), "chois": (32, 3, 1)}
    with pytest.raises(ValueError, match="loop"):
        LL.run_loop("nope", np.zeros((40, 2)), np.zeros((40, 2)), np.zeros((40, 2)))
    with pytest.raises(ValueError, match="torch_sampler"):
        LL.t2m_loop(np.zeros((200, 2)), np.zeros((200, 2)), np.zeros((200, 2)), torch_sampler="1.7")
