"""The papers' released evaluation loops for the embedding metrics, replayed on fixed embeddings.

:mod:`hoibench.metrics.embedding` defines each metric once, in float64, with hoibench's own
pools and draws. A paper's table was produced by its own loop: which rows share an
R-precision batch, what is dropped, in which precision, with which random draws. This module
replays those loops exactly on embeddings given as arrays, so that a protocol can select
"the reference's loop" (:func:`run_loop`). Every loop is a pure function of its inputs and a
seed: it seeds private generators (``numpy.random.RandomState(seed)`` for the reference's
global ``np.random``, a ``torch.Generator`` seeded with ``seed`` for the global torch CPU
generator) and replays, in order, every draw the reference's loop makes from those streams.

Inputs: ``text``, ``motion``, ``gt_motion`` (N, D), row i of each is test item i (its
caption, its generated motion, its real motion); ``samples`` (K, N, D), K generated samples per
item, for MultiModality. They are cast to float32, the dtype every reference computes in
(evaluator outputs of torch, ``.cpu().numpy()``); the float32 arithmetic is kept where it
reaches a reported number (distance matrices, matching-score traces, means, norms).

Results (:class:`LoopResult`): per replication, for the generated rows
(``generated``) and the reference's ground-truth row (``real``, where the reference computes
one), ``r_precision_top1..3``, ``mm_dist``, ``fid``, ``diversity``, ``multimodality``; arrays
keep the dtype of the reference's per-replication list (float32 for a Diversity computed by
``np.linalg.norm(...).mean()`` on float32), so :meth:`LoopResult.summary` gives the
reference's ``mean`` and ``1.96 std / sqrt(R)`` (population std) bit for bit.

Loops (sources: the mirrored repositories at the commits named in docs/metrics.md)
---------------------------------------------------------------------------------
``t2m`` -- text-to-motion (Guo et al. 2022) ``final_evaluations.py`` with ``utils/metrics.py``:

* per replication (L155-213): ``CompV6GeneratedDataset`` (``motion_loaders/comp_v6_model_dataset.py``)
  draws the MultiModality items ``np.random.choice(N, 100, replace=False)`` sorted (L64-65)
  and generates in the order of a shuffled batch-1 loader (L58); the generated loader
  (``model_motion_loaders.py`` L66) re-batches that order by 32, unshuffled, ``drop_last``;
  the ground-truth loader (``dataset_motion_loader.py`` L21-22: 32, shuffled, ``drop_last``)
  is iterated once for R-precision (L168) and once more for FID's real statistics (L87);
* R-precision / Matching Score (L42-61): per batch, ``euclidean_distance_matrix`` (float32,
  ``sqrt(-2ab + |a|^2 + |b|^2)``, NaN kept), ``argsort`` rows, top-3 hits, trace summed;
  totals over ``all_size`` = rows in full batches;
* rows inside a batch: ``collate_fn`` sorts by caption length, longest first (stable,
  ``data/dataset.py`` L15-17), then ``get_co_embeddings`` by motion length,
  ``np.argsort(m_lens)[::-1]`` (``networks/evaluator_wrapper.py`` L65, L76); activations for
  FID and Diversity keep that order. Pass ``sent_lens`` / ``lengths`` / ``gt_lengths`` to
  replay it; without them rows keep loader order (changes only which rows Diversity pairs);
* FID (L95-101): ``calculate_frechet_distance(gt_mu, gt_cov, mu, cov)``, float32 means,
  float64 ``np.cov``, ``scipy.linalg.sqrtm`` with the 1e-6 retry and the 1e-3 imaginary check;
* Diversity (L112): 300 pairs, real rows first then generated (two ``choice`` each);
* MultiModality (L119-138): 100 items x 30 samples x 10 pairs; a sample set is ordered by
  ``np.argsort(lengths)[::-1]`` twice (``MMGeneratedDataset`` L37-44, then
  ``get_motion_embeddings`` L84; pass ``sample_lengths``); mm loader iterated (one torch draw);
* 20 replications, CI ``1.96 std / sqrt(20)`` (L141-145, L297-305).

``mdm`` -- MDM (Tevet et al. 2023) ``eval/eval_humanml.py``: the same functions (L20-136),
with ``CompMDMGeneratedDataset`` (``data_loaders/humanml/motion_loaders/comp_v6_model_dataset.py``):
generation in batches of 32 of a shuffled ``drop_last`` loader (``data_loaders/get_data.py``
L54-57) stopping once 1000 motions exist (L187-188: 32 batches, 1024 rows); MultiModality on
``np.random.choice(min(1000 // 32 + 1, batches), 100 // 32 + 1)`` whole batches (L167-176:
128 items, not 100), 30 samples, 10 pairs. ``mode="wo_mm"``: 20 replications, no
MultiModality; ``"mm_short"``: 5 (L262-287).

``chois`` -- CHOIS (Li et al. 2024) ``t2m_eval/final_evaluations.py``: text-to-motion's
functions, the generated rows in listing order (no generation pass, no shuffle), batches of
32 ``drop_last``, the ground-truth loader shuffled twice (R-precision, FID), Diversity 300,
no MultiModality, one replication (:func:`chois_loop`).

``chainhoi`` -- ChainHOI (2025) ``src/models/metrics/tm2t.py`` ``TM2TMetrics.compute``
(L80-161) with ``src/models/metrics/utils.py``: the whole test set is collected unshuffled
with no drop (``src/data/behave_omomo.py`` L117-128; that pass draws the loader's base seed),
then permuted once with ``torch.randperm(N)`` (L91); R-precision in consecutive groups of
32, the incomplete tail left out of R-precision and Matching Score only (L104-121); distances in torch float32
with ``nan_to_num`` (L113), counts and the Matching Score accumulated in float32 tensors;
FID (real first) and Diversity (100 pairs on BEHAVE/OMOMO, ``chainhoi_behave.py`` L182,
``chainhoi_omomo.py`` L188; generated first, then real) over all N permuted rows; Diversity
is the sentinel -1 when ``N <= 100`` (L153-160: reported here as NaN with a note). One
replication (``src/eval.py`` L153), CI 0. MultiModality: not computed -- the released
``on_test_epoch_end`` reads ``self.t2m_mm_metric``, which is never created
(``chainhoi_behave.py`` L177-186, L325-327); NaN with a note.

``interact`` -- InterAct (2025) ``text2interaction/eval/eval_marker_representation.py``
``eval_t2hoi`` (L42-231) with ``text2interaction/utils/eval_t2m_utils.py``: test loader in
dataset order, batches of 64 (``scripts/eval.sh``), ``drop_last`` (``data_loaders/get_data.py``
L80-84); per batch R-precision top-3 and the trace (L149-156), float32 numpy; the real row
uses the same text embeddings (``et_pred = et``, L140); MultiModality (L44-47, L159-202):
2 extra samples for each item of the first 2 batches, ONE pair draw
(``choice(2, 1)`` twice: with probability 1/2 both pick the same sample and MultiModality is
0), and the list receives the last computed block after every batch (L197 sits outside the
``if``), so batch 1 is counted once more for each later batch; Diversity 300 pairs when more
than 300 rows are scored, else 50 (L214-215: real first); FID real first (L224); 2 repeats
(L291), CI ``1.96 std / sqrt(2)`` (L316-320).

Seeds, and what cannot be replayed
----------------------------------
``seed`` stands for the generator states at the start of the reference's loop: each loop
equals the reference's loop run right after ``np.random.seed(seed); torch.manual_seed(seed)``
(``t2m``/``mdm``: before ``evaluation()``; ``chainhoi``: before ``trainer.test``, whose
test-loader pass precedes ``compute()``; ``interact``: before the repeat loop), with motion
generation drawing nothing from those streams (the references generate on CUDA, whose
generator is separate). The authors' own states are not recoverable: text-to-motion never
seeds; MDM and InterAct seed (``fixseed``) before building networks whose initialisation
consumes the torch stream; ChainHOI's ``seed: null``
(``configs/eval.yaml`` L22) leaves torch at its default seed before model construction; and
InterAct's ``bps_torch()`` (eval script L250) calls ``np.random.seed(None)``
(``bps_torch/tools.py`` ``sample_sphere_uniform``), so its numpy draws come from OS entropy.
Text-to-motion also rebuilds its networks inside every replication
(``comp_v6_model_dataset.py`` L59), so from the second replication on even a seeded run of
its script differs from any replay; and it redraws captions and motion crops in its data
workers (Python ``random``), which fixed embeddings stand in for.

Shuffled DataLoaders (``t2m``, ``mdm``) replay torch's draws: one int64 for the worker base
seed (``_BaseDataLoaderIter``), then, shuffled, one int64 for ``RandomSampler``'s seed and
``randperm(N)``. ``torch_sampler="torch<1.9"`` (default; text-to-motion pins torch 1.6,
MDM 1.7.1) takes the permutation from the global generator and discards the drawn seed, as
torch 1.6-1.8 did (pytorch#52568); ``"torch>=1.9"`` from a generator seeded with it (what the
reference scripts do under today's torch). The permutations come from the installed torch's
CPU ``randperm`` and mt19937 generator; that torch 1.6/1.7 permuted identically is assumed,
not checked (no such build runs here). ChainHOI's distance matrices ran on GPU with
``torch.set_float32_matmul_precision('high')`` (``src/eval.py`` L90: TF32 on Ampere GPUs);
here they are exact float32 on CPU, so a near-tie in a ranking can resolve differently. Ties
in lengths are ordered by numpy's default ``argsort`` as in the references (version and CPU
dependent), FID's ``sqrtm`` by the installed scipy. Matching-score sums follow numpy < 2,
which the references run on: float32 traces summed into a float64 (numpy >= 2 would keep
float32).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

__all__ = ["METRIC_NAMES", "TORCH_SAMPLERS", "LoopResult", "LoopSpec", "LOOPS", "reference_ci", "run_loop",
           "t2m_loop", "mdm_loop", "chainhoi_loop", "interact_loop",
           "interact_released_loop", "LoopRefused", "chois_loop"]

from .catalog import metric_names

#: what the loops report: the catalogue's embedding metrics
METRIC_NAMES = metric_names("embedding")
TORCH_SAMPLERS = ("torch<1.9", "torch>=1.9")


# ===================================================================== inputs
@dataclass(frozen=True)
class _Inputs:
    text: np.ndarray          # (N, D) float32
    motion: np.ndarray
    gt_motion: np.ndarray
    samples: np.ndarray | None  # (K, N, D) float32


def _f32(x, name: str, ndim: int) -> np.ndarray:
    a = np.asarray(x)
    if a.ndim != ndim or not np.issubdtype(a.dtype, np.number):
        raise ValueError(f"{name}: expected a numeric {ndim}-D array, got shape {a.shape} dtype {a.dtype}")
    a = np.ascontiguousarray(a, dtype=np.float32)
    if not np.isfinite(a).all():
        raise ValueError(f"{name}: contains non-finite values (after the cast to float32)")
    return a


def _inputs(text, motion, gt_motion, samples) -> _Inputs:
    t, m, g = _f32(text, "text", 2), _f32(motion, "motion", 2), _f32(gt_motion, "gt_motion", 2)
    if not t.shape == m.shape == g.shape:
        raise ValueError(f"text, motion, gt_motion: shapes differ: {t.shape}, {m.shape}, {g.shape}")
    s = None
    if samples is not None:
        s = _f32(samples, "samples", 3)
        if s.shape[1:] != m.shape:
            raise ValueError(f"samples: expected (K, {m.shape[0]}, {m.shape[1]}), got {s.shape}")
    return _Inputs(t, m, g, s)


def _keys(n: int, **keys) -> dict[str, np.ndarray | None]:
    out = {}
    for name, v in keys.items():
        if v is not None:
            v = np.asarray(v, dtype=np.int64)
            if v.shape[-1] != n:
                raise ValueError(f"{name}: expected a last axis of {n} items, got shape {v.shape}")
        out[name] = v
    return out


# ===================================================================== reference numerics
def _distance_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``sqrt((-2 a b^T + |a|^2) + |b|^2)`` in the inputs' dtype (float32); negative rounding
    gives NaN, as in the references."""
    with np.errstate(invalid="ignore"):
        return np.sqrt(-2 * np.dot(a, b.T) + np.sum(np.square(a), axis=1, keepdims=True)
                       + np.sum(np.square(b), axis=1))


def _hits(dist: np.ndarray, top_k: int) -> np.ndarray:
    """Rows whose own column is among the first k of ``argsort(dist[i])``, k = 1..top_k."""
    own = np.argsort(dist, axis=1)[:, :top_k] == np.arange(len(dist))[:, None]
    return np.logical_or.accumulate(own, axis=1).sum(axis=0)


def _matching(text: np.ndarray, motion: np.ndarray, batches: list[np.ndarray], top_k: int) -> dict:
    """R-precision and Matching Score over ``batches`` (numpy float32, per-batch traces summed
    into a float64: numpy < 2 promotion of ``0 + float32``); activations in batch order."""
    hits, total, size = np.zeros(top_k, np.int64), np.float64(0.0), 0
    for b in batches:
        d = _distance_matrix(text[b], motion[b])
        total = total + np.trace(d)
        hits += _hits(d, top_k)
        size += len(b)
    if size == 0:
        raise ValueError("no full batch: fewer rows than the batch size")
    act = motion[np.concatenate(batches)]
    out = {f"r_precision_top{k + 1}": hits[k] / size for k in range(top_k)}
    out["mm_dist"] = total / size
    return {"values": out, "activations": act}


def _statistics(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.mean`` (float32 for float32 rows) and ``np.cov(rowvar=False)`` (float64)."""
    return np.mean(x, axis=0), np.cov(x, rowvar=False)


def _frechet(mu1, sigma1, mu2, sigma2, eps: float = 1e-6) -> np.float64:
    """The references' Frechet distance, dtypes kept: ``|mu1 - mu2|^2`` (float32 for float32
    means) ``+ tr S1 + tr S2 - 2 tr sqrtm(S1 S2)``; ``sqrtm`` retried with ``eps`` on both
    diagonals when not finite; an imaginary part dropped when the diagonal's is within 1e-3
    of 0, else ``ValueError``."""
    from scipy import linalg
    diff = mu1 - mu2
    covmean = linalg.sqrtm(sigma1.dot(sigma2))
    if not np.isfinite(covmean).all():
        offset = np.eye(sigma1.shape[0]) * eps
        covmean = linalg.sqrtm((sigma1 + offset).dot(sigma2 + offset))
    if np.iscomplexobj(covmean):
        if not np.allclose(np.diagonal(covmean).imag, 0, atol=1e-3):
            raise ValueError(f"FID: sqrtm has an imaginary component {np.max(np.abs(covmean.imag)):.3g}")
        covmean = covmean.real
    return diff.dot(diff) + np.trace(sigma1) + np.trace(sigma2) - 2 * np.trace(covmean)


def _fid(real_stats, rows: np.ndarray) -> np.float64:
    return _frechet(*real_stats, *_statistics(rows))


def _diversity(x: np.ndarray, times: int, rs: np.random.RandomState) -> np.float32:
    """Mean ``|x_a - x_b|`` over ``a, b = choice(N, times, replace=False)`` drawn in turn."""
    first = rs.choice(len(x), times, replace=False)
    second = rs.choice(len(x), times, replace=False)
    return np.linalg.norm(x[first] - x[second], axis=1).mean()


def _multimodality(x: np.ndarray, times: int, rs: np.random.RandomState) -> np.float32:
    """(items, S, D): the same ``choice(S, times)`` pairs for every item, mean distance."""
    first = rs.choice(x.shape[1], times, replace=False)
    second = rs.choice(x.shape[1], times, replace=False)
    return np.linalg.norm(x[:, first] - x[:, second], axis=2).mean()


def _nan32() -> np.float32:
    return np.float32(np.nan)


# ===================================================================== random streams
class _TorchStream:
    """The reference's global torch CPU generator, replayed from ``seed``."""

    def __init__(self, seed: int, sampler: str = "torch<1.9"):
        import torch
        if sampler not in TORCH_SAMPLERS:
            raise ValueError(f"torch_sampler: expected one of {TORCH_SAMPLERS}, got {sampler!r}")
        self.torch, self.sampler = torch, sampler
        self.gen = torch.Generator()
        self.gen.manual_seed(int(seed))

    def draw(self) -> int:
        """``torch.empty((), dtype=torch.int64).random_()``."""
        return int(self.torch.empty((), dtype=self.torch.int64).random_(generator=self.gen).item())

    def randperm(self, n: int, generator=None) -> np.ndarray:
        return self.torch.randperm(n, generator=self.gen if generator is None else generator).numpy()

    def loader(self, n: int, shuffle: bool) -> np.ndarray:
        """Index order of one pass over a DataLoader of ``n`` items (``generator=None``)."""
        self.draw()                                   # the workers' base seed
        if not shuffle:
            return np.arange(n)
        seed = self.draw()                            # RandomSampler's seed
        if self.sampler == "torch<1.9":
            return self.randperm(n)                   # 1.6-1.8: the seed is unused
        g = self.torch.Generator()
        g.manual_seed(seed)
        return self.randperm(n, g)


def _chunks(order: np.ndarray, size: int, drop_last: bool) -> list[np.ndarray]:
    stop = len(order) - len(order) % size if drop_last else len(order)
    return [order[s:s + size] for s in range(0, stop, size)]


def _evaluator_order(batch: np.ndarray, sent_lens, lengths) -> np.ndarray:
    """Rows of one batch as text-to-motion's evaluator returns them: caption length, longest
    first, stable (``collate_fn``); then ``np.argsort(motion lengths)[::-1]``."""
    b = batch
    if sent_lens is not None:
        b = np.array(sorted(b.tolist(), key=lambda i: sent_lens[i], reverse=True), dtype=np.int64)
    if lengths is not None:
        b = b[np.argsort(lengths[b].tolist())[::-1]]
    return b


def _sample_order(lengths) -> np.ndarray | slice:
    """Order of one item's samples: ``argsort(lengths)[::-1]`` (``MMGeneratedDataset``) and
    again on the sorted lengths (``get_motion_embeddings``)."""
    if lengths is None:
        return slice(None)
    o1 = np.argsort(lengths)[::-1]
    o2 = np.argsort(lengths[o1].tolist())[::-1]
    return o1[o2]


# ===================================================================== results
def reference_ci(values: np.ndarray) -> tuple[float, float]:
    """``(mean, 1.96 std / sqrt(R))`` with the population std, in the values' dtype
    (text-to-motion ``get_metric_statistics``, ChainHOI ``src/eval.py`` L60-64, InterAct L316)."""
    v = np.asarray(values)
    std = np.float64(np.std(v, axis=0))        # numpy < 2: ``1.96 * float32`` is a float64
    return float(np.mean(v, axis=0)), float(1.96 * std / np.sqrt(len(v)))


@dataclass
class LoopResult:
    """Per-replication values of one loop.

    ``generated[name]`` / ``real[name]``: arrays (R,) in the dtype of the reference's list
    (``real``: the reference's ground-truth row, absent where it computes none);
    ``batches[r][role]``: the row indices of each R-precision batch (``"generated"``,
    ``"real"``), of FID's real set (``"fid_real"``) and of the MultiModality items
    (``"multimodality"``), in the order the reference sees them; ``notes``: what is undefined.
    """

    loop: str
    generated: dict[str, np.ndarray]
    real: dict[str, np.ndarray]
    batches: list[dict[str, list[np.ndarray]]]
    notes: list[str] = field(default_factory=list)

    def rows(self) -> list[dict[str, float]]:
        """The generated values as one dict per replication."""
        n = len(next(iter(self.generated.values())))
        return [{k: float(v[r]) for k, v in self.generated.items()} for r in range(n)]

    def summary(self, real: bool = False) -> dict[str, tuple[float, float]]:
        """``{metric: (mean, CI)}`` by the reference's rule (:func:`reference_ci`)."""
        return {k: reference_ci(v) for k, v in (self.real if real else self.generated).items()}


def _collect(loop: str, reps: list[tuple[dict, dict, dict]], notes: list[str]) -> LoopResult:
    def stack(values: list[dict]) -> dict[str, np.ndarray]:
        names = [n for n in METRIC_NAMES if values and n in values[0]]
        return {n: np.array([v[n] for v in values]) for n in names}
    return LoopResult(loop, stack([g for g, _, _ in reps]), stack([r for _, r, _ in reps]),
                      [b for _, _, b in reps], sorted(set(notes)))


# ===================================================================== text-to-motion / MDM
@dataclass(frozen=True)
class _GuoConfig:
    variant: str          # "t2m" | "mdm" | "chois"
    batch_size: int
    top_k: int
    diversity_times: int
    mm_texts: int         # t2m: items; mdm: mm_num_samples (-> mm_texts // batch + 1 batches)
    mm_repeats: int
    mm_times: int
    run_mm: bool
    limit: int            # mdm: num_samples_limit


def _guo_generated(n: int, torch_rng: _TorchStream, rs, cfg: _GuoConfig) -> tuple[np.ndarray, np.ndarray]:
    """Rows of the generated set in generation order, and the MultiModality items."""
    bs = cfg.batch_size
    if cfg.variant == "chois":                                             # saved windows, listed once
        return np.arange(n), np.array([], np.int64)
    if cfg.variant == "t2m":
        if not cfg.mm_texts < n:
            raise LoopRefused(f"t2m: needs more items than MultiModality items ({cfg.mm_texts}), got {n}")
        mm_pos = np.sort(rs.choice(n, cfg.mm_texts, replace=False))        # L64-65
        order = torch_rng.loader(n, shuffle=True)                          # batch 1, no drop
        return order, order[mm_pos]
    batches = n // bs
    real_batches = min(cfg.limit // bs + 1, batches)
    mm_batches = np.array([], np.int64)
    if cfg.mm_texts > 0:
        mm_batches = np.sort(rs.choice(real_batches, cfg.mm_texts // bs + 1, replace=False))
    order = torch_rng.loader(n, shuffle=True)[:batches * bs]               # drop_last
    made = min(batches, -(-cfg.limit // bs))                              # stops once >= limit
    gen = order[:made * bs]
    mm = [gen[b * bs:(b + 1) * bs] for b in mm_batches if b < made]
    return gen, (np.concatenate(mm) if mm else np.array([], np.int64))


def _guo_multimodality(x: _Inputs, items: np.ndarray, cfg: _GuoConfig, keys: dict, rs, notes: list) -> np.float32:
    if len(items) == 0:
        return np.float32(0.0)                       # final_evaluations.py L130-131: no draws
    if x.samples is None or len(x.samples) < cfg.mm_repeats:
        rs.choice(cfg.mm_repeats, cfg.mm_times, replace=False)   # keep the stream aligned
        rs.choice(cfg.mm_repeats, cfg.mm_times, replace=False)
        notes.append(f"multimodality: needs samples with at least {cfg.mm_repeats} samples per item")
        return _nan32()
    lens = keys["sample_lengths"]
    emb = np.stack([x.samples[:cfg.mm_repeats, i][_sample_order(None if lens is None else lens[:cfg.mm_repeats, i])]
                    for i in items])
    return _multimodality(emb, cfg.mm_times, rs)


def _guo_replication(x: _Inputs, torch_rng: _TorchStream, rs, cfg: _GuoConfig, keys: dict,
                     notes: list) -> tuple[dict, dict, dict]:
    """One replication of ``evaluation()`` (final_evaluations.py L155-213)."""
    n, bs, sl = len(x.text), cfg.batch_size, keys["sent_lens"]
    gen_rows, mm_items = _guo_generated(n, torch_rng, rs, cfg)
    gt_batches = [_evaluator_order(b, sl, keys["gt_lengths"])
                  for b in _chunks(torch_rng.loader(n, shuffle=True), bs, True)]
    torch_rng.loader(len(gen_rows), shuffle=False)                    # the generated loader
    gen_batches = [_evaluator_order(gen_rows[b], sl, keys["lengths"])
                   for b in _chunks(np.arange(len(gen_rows)), bs, True)]
    fid_batches = [_evaluator_order(b, sl, keys["gt_lengths"])
                   for b in _chunks(torch_rng.loader(n, shuffle=True), bs, True)]
    real = _matching(x.text, x.gt_motion, gt_batches, cfg.top_k)
    gen = _matching(x.text, x.motion, gen_batches, cfg.top_k)
    stats = _statistics(x.gt_motion[np.concatenate(fid_batches)])
    real["values"]["fid"] = _fid(stats, real["activations"])
    gen["values"]["fid"] = _fid(stats, gen["activations"])
    for side in (real, gen):                                          # "ground truth" first
        if len(side["activations"]) > cfg.diversity_times:
            side["values"]["diversity"] = _diversity(side["activations"], cfg.diversity_times, rs)
        else:
            side["values"]["diversity"] = _nan32()
            notes.append(f"diversity: needs more than {cfg.diversity_times} scored rows (the reference asserts)")
    if cfg.run_mm:
        torch_rng.loader(len(mm_items), shuffle=False)                # the MultiModality loader
        gen["values"]["multimodality"] = _guo_multimodality(x, mm_items, cfg, keys, rs, notes)
    batches = {"generated": gen_batches, "real": gt_batches, "fid_real": fid_batches,
               "multimodality": [mm_items]}
    return gen["values"], real["values"], batches


def _guo_loop(name: str, x: _Inputs, cfg: _GuoConfig, seed: int, replications: int, torch_sampler: str,
              keys: dict) -> LoopResult:
    torch_rng, rs = _TorchStream(seed, torch_sampler), np.random.RandomState(int(seed))
    notes: list[str] = []
    reps = [_guo_replication(x, torch_rng, rs, cfg, keys, notes) for _ in range(int(replications))]
    if not cfg.run_mm:
        notes.append("multimodality: not computed by this loop's mode")
    return _collect(name, reps, notes)


def t2m_loop(text, motion, gt_motion, samples=None, *, seed: int = 0, replications: int = 20,
             batch_size: int = 32, top_k: int = 3, diversity_times: int = 300, mm_texts: int = 100,
             mm_repeats: int = 30, mm_times: int = 10, sent_lens=None, lengths=None, gt_lengths=None,
             sample_lengths=None, torch_sampler: str = "torch<1.9") -> LoopResult:
    """text-to-motion's ``final_evaluations.py`` (module docstring): 20 replications of
    shuffled, ``drop_last`` batches of 32 (R-precision top-3, Matching Score), FID against a
    second shuffled pass of the real set, Diversity 300, MultiModality 100 x 30 x 10.

    ``sent_lens`` (N,), ``lengths`` / ``gt_lengths`` (N,) and ``sample_lengths`` (K, N)
    (caption token counts, generated / real / per-sample motion lengths) replay the
    evaluator's row order inside batches and sample sets; omitted, rows keep loader order.
    """
    x = _inputs(text, motion, gt_motion, samples)
    keys = _keys(len(x.text), sent_lens=sent_lens, lengths=lengths, gt_lengths=gt_lengths,
                 sample_lengths=sample_lengths)
    cfg = _GuoConfig("t2m", batch_size, top_k, diversity_times, mm_texts, mm_repeats, mm_times, True, 0)
    return _guo_loop("t2m", x, cfg, seed, replications, torch_sampler, keys)


def chois_loop(text, motion, gt_motion, samples=None, *, seed: int = 0, replications: int = 1,
               batch_size: int = 32, top_k: int = 3, diversity_times: int = 300, sent_lens=None, lengths=None,
               gt_lengths=None, torch_sampler: str = "torch<1.9") -> LoopResult:
    """CHOIS's ``t2m_eval/final_evaluations.py`` (lijiaman/chois_release @ 9cd4cf6): text-to-motion's
    functions on CHOIS's saved windows. The generated loader
    (``motion_loaders/model_motion_loaders.py`` ``get_motion_loader_for_chois_eval`` L74-85)
    batches the result files in listing order by 32, unshuffled, ``drop_last``: the rows are
    taken in the order given (hoibench passes its test ids sorted; CHOIS's ``os.listdir`` order
    depends on the file system). The ground-truth loader (``dataset_motion_loader.py`` L21-22:
    shuffled, ``drop_last``) is iterated for R-precision then again for FID's real statistics;
    Diversity 300 (real rows first); no MultiModality; one replication (L172-176)."""
    x = _inputs(text, motion, gt_motion, samples)
    if len(x.text) < batch_size:
        raise LoopRefused(f"chois: {len(x.text)} clips, fewer than one batch of {batch_size} (its loaders drop the "
                          f"incomplete batch)")
    keys = _keys(len(x.text), sent_lens=sent_lens, lengths=lengths, gt_lengths=gt_lengths, sample_lengths=None)
    cfg = _GuoConfig("chois", batch_size, top_k, diversity_times, 0, 0, 0, False, 0)
    return _guo_loop("chois", x, cfg, seed, replications, torch_sampler, keys)


def mdm_loop(text, motion, gt_motion, samples=None, *, seed: int = 0, mode: str = "wo_mm",
             replications: int | None = None, batch_size: int = 32, top_k: int = 3, diversity_times: int = 300,
             num_samples_limit: int = 1000, mm_num_samples: int = 100, mm_repeats: int = 30, mm_times: int = 10,
             sent_lens=None, lengths=None, gt_lengths=None, sample_lengths=None,
             torch_sampler: str = "torch<1.9") -> LoopResult:
    """MDM's ``eval/eval_humanml.py``: ``t2m``'s metric loop on the first
    ``ceil(num_samples_limit / 32)`` batches of a shuffled ``drop_last`` loader;
    ``mode="wo_mm"`` 20 replications without MultiModality, ``"mm_short"`` 5 with
    MultiModality on ``mm_num_samples // 32 + 1`` whole batches x 30 samples x 10 pairs."""
    modes = {"wo_mm": (20, False), "mm_short": (5, True), "debug": (5, False)}
    if mode not in modes:
        raise ValueError(f"mode: expected one of {sorted(modes)}, got {mode!r}")
    reps, run_mm = modes[mode]
    x = _inputs(text, motion, gt_motion, samples)
    keys = _keys(len(x.text), sent_lens=sent_lens, lengths=lengths, gt_lengths=gt_lengths,
                 sample_lengths=sample_lengths)
    cfg = _GuoConfig("mdm", batch_size, top_k, diversity_times, mm_num_samples if run_mm else 0, mm_repeats,
                     mm_times, run_mm, num_samples_limit)
    return _guo_loop("mdm", x, cfg, seed, reps if replications is None else replications, torch_sampler, keys)


# ===================================================================== ChainHOI
def _torch_groups(text, motion, r_size: int, top_k: int) -> tuple:
    """``TM2TMetrics.compute`` L104-121: float32 torch distances per group of ``r_size``,
    ``nan_to_num``; hits and Matching Score accumulated in float32 tensors."""
    import torch
    top, score = torch.zeros((top_k,)), torch.tensor(0.0)
    groups = len(text) // r_size
    for i in range(groups):
        t, m = text[i * r_size:(i + 1) * r_size], motion[i * r_size:(i + 1) * r_size]
        d = torch.sqrt(-2 * torch.mm(t, m.T) + torch.sum(torch.square(t), dim=1, keepdim=True)
                       + torch.sum(torch.square(m), dim=1)).nan_to_num()
        score += d.trace()
        own = torch.argsort(d, dim=1)[:, :top_k] == torch.arange(r_size)[:, None]
        hit, counts = torch.zeros(r_size, dtype=torch.bool), []
        for k in range(top_k):
            hit = hit | own[:, k]
            counts.append(hit.sum())
        top += torch.stack(counts)
    count = groups * r_size
    out = {f"r_precision_top{k + 1}": (top[k] / count).item() for k in range(top_k)}
    out["mm_dist"] = (score / count).item()
    return out, [np.arange(i * r_size, (i + 1) * r_size) for i in range(groups)]


def chainhoi_loop(text, motion, gt_motion, samples=None, *, seed: int = 0, replications: int = 1,
                  r_size: int = 32, top_k: int = 3, diversity_times: int = 100) -> LoopResult:
    """ChainHOI's ``TM2TMetrics.compute`` (module docstring): one ``torch.randperm(N)`` per
    replication, R-precision in groups of 32 of the permuted rows (tail left out), FID and
    Diversity (100) over all rows; one replication as ``src/eval.py``; no MultiModality."""
    import torch
    x = _inputs(text, motion, gt_motion, samples)
    n = len(x.text)
    if not n > r_size:
        raise LoopRefused(f"chainhoi: needs more than {r_size} items, got {n} (TM2TMetrics asserts)")
    torch_rng, rs = _TorchStream(seed), np.random.RandomState(int(seed))
    notes = ["multimodality: the released ChainHOI test loop never creates its MultiModality metric"]
    reps = []
    for _ in range(int(replications)):
        torch_rng.loader(n, shuffle=False)          # the test DataLoader's pass (base seed)
        perm = torch_rng.randperm(n)                # TM2TMetrics.compute L91
        t, m, g = (torch.from_numpy(a[perm]) for a in (x.text, x.motion, x.gt_motion))
        gen, groups = _torch_groups(t, m, r_size, top_k)
        real, _ = _torch_groups(t, g, r_size, top_k)
        gen_np, gt_np = m.numpy(), g.numpy()
        gen["fid"] = float(_frechet(*_statistics(gt_np), *_statistics(gen_np)))
        if n > diversity_times:
            gen["diversity"] = float(_diversity(gen_np, diversity_times, rs))
            real["diversity"] = float(_diversity(gt_np, diversity_times, rs))
        else:
            gen["diversity"] = real["diversity"] = float("nan")
            notes.append(f"diversity: the reference reports -1 when N <= {diversity_times} (here NaN)")
        gen["multimodality"] = float("nan")
        reps.append((gen, real, {"generated": [perm[b] for b in groups], "real": [perm[b] for b in groups],
                                 "fid_real": [perm]}))
    return _collect("chainhoi", reps, notes)


# ===================================================================== InterAct
def _interact_multimodality(x: _Inputs, batches: list[np.ndarray], mm_batches: int, mm_repeats: int,
                            mm_times: int, rs, notes: list) -> tuple[np.float32, list[np.ndarray]]:
    """L159-202: blocks (64, repeats, D) of the first ``mm_batches`` batches; after every batch
    the last block is appended again (L197); ``choice(repeats, times)`` twice."""
    if x.samples is None or len(x.samples) < mm_repeats:
        rs.choice(mm_repeats, mm_times, replace=False)            # keep the stream aligned
        rs.choice(mm_repeats, mm_times, replace=False)
        notes.append(f"multimodality: needs samples with at least {mm_repeats} samples per item")
        return _nan32(), []
    blocks, items, block, rows = [], [], None, None
    for j, b in enumerate(batches):
        if j < mm_batches:
            block, rows = x.samples[:mm_repeats, b].transpose(1, 0, 2), b
        blocks.append(block)
        items.append(rows)
    return _multimodality(np.concatenate(blocks), mm_times, rs), items


def interact_loop(text, motion, gt_motion, samples=None, *, seed: int = 0, replications: int = 2,
                  batch_size: int = 64, top_k: int = 3, mm_batches: int = 2, mm_repeats: int = 2,
                  mm_times: int = 1) -> LoopResult:
    """InterAct's ``eval_t2hoi`` (module docstring): dataset-order ``drop_last`` batches of 64,
    MultiModality from 2 samples of the first 2 batches with one pair (and batch 1 repeated),
    Diversity 300 (50 when at most 300 rows), 2 repeats."""
    x = _inputs(text, motion, gt_motion, samples)
    batches = _chunks(np.arange(len(x.text)), batch_size, True)
    rs, notes, reps = np.random.RandomState(int(seed)), [], []
    for _ in range(int(replications)):
        real = _matching(x.text, x.gt_motion, batches, top_k)
        gen = _matching(x.text, x.motion, batches, top_k)
        gen["values"]["multimodality"], mm_items = _interact_multimodality(x, batches, mm_batches, mm_repeats,
                                                                           mm_times, rs, notes)
        times = 300 if len(gen["activations"]) > 300 else 50
        for side in (real, gen):                                  # L214-215: real first
            if len(side["activations"]) > times:
                side["values"]["diversity"] = _diversity(side["activations"], times, rs)
            else:
                side["values"]["diversity"] = _nan32()
                notes.append(f"diversity: needs more than {times} scored rows (the reference asserts)")
        gen["values"]["fid"] = _fid(_statistics(real["activations"]), gen["activations"])
        reps.append((gen["values"], real["values"], {"generated": batches, "real": batches,
                                                     "fid_real": batches, "multimodality": mm_items}))
    return _collect("interact", reps, notes)


class LoopRefused(ValueError):
    """A loop's own clip selection leaves too little to score (the scorer refuses the
    evaluation with this message)."""


def interact_released_loop(text, motion, gt_motion, samples=None, *, ids=None, lengths=None, seed: int = 0,
                           replications: int = 2, batch_size: int = 64, top_k: int = 3, mm_batches: int = 2,
                           mm_repeats: int = 2, mm_times: int = 1, diversity_times: int | None = None) -> LoopResult:
    """InterAct's released evaluation as its script runs it: its test loader
    (:func:`hoibench.metrics.interact_loop.loader_rows`: clips of 40-300 frames, by length)
    then :func:`interact_loop` on those rows. ``ids`` (hoibench's InterAct clip ids) and
    ``lengths`` (frames) select and order the rows; without them the rows are taken as given
    and a note says so. ``batches`` index the inputs' rows. ``diversity_times`` is accepted
    and not used: the loop fixes its own pairs (300, or 50 when at most 300 rows)."""
    from .interact_loop import loader_rows
    x = _inputs(text, motion, gt_motion, samples)
    notes = []
    if ids is None or lengths is None:
        order = np.arange(len(x.text))
        notes.append("InterAct's loader (40-300 frames, length order) not applied: no clip ids and lengths given; "
                     "rows scored as given")
    else:
        if len(ids) != len(x.text):
            raise ValueError(f"ids: expected {len(x.text)} clip ids, got {len(ids)}")
        rows = loader_rows(ids, lengths)
        order = rows.order
        if rows.dropped:
            notes.append(f"InterAct's loader skips {len(rows.dropped)} of {len(ids)} clips outside 40-300 frames")
        if len(order) < batch_size:
            raise LoopRefused(f"interact-released: {len(order)} clips of 40-300 frames, fewer than one batch of "
                             f"{batch_size} (InterAct's loader drops the incomplete batch)")
    sub = None if x.samples is None else x.samples[:, order]
    res = interact_loop(x.text[order], x.motion[order], x.gt_motion[order], sub, seed=seed,
                        replications=replications, batch_size=batch_size, top_k=top_k, mm_batches=mm_batches,
                        mm_repeats=mm_repeats, mm_times=mm_times)
    res.batches = [{role: [order[b] for b in bs if b is not None] for role, bs in rep.items()}
                   for rep in res.batches]
    return LoopResult("interact-released", res.generated, res.real, res.batches, sorted(set(res.notes + notes)))


# ===================================================================== registry
@dataclass(frozen=True)
class LoopSpec:
    """One reference loop: its function and the rules docs/metrics.md tabulates."""

    name: str
    function: Callable[..., LoopResult]
    batch_size: int
    batches: str          # how R-precision batches are formed
    distance: str
    top_k: int
    diversity: str
    multimodality: str    # items x samples x pair draws
    replications: int
    ci: str
    source: str
    #: whether the loop selects and orders clips itself from their ids and ground-truth lengths
    #: (``ids``, ``lengths`` keywords)
    clip_ids: bool = False


_CI = "1.96 std / sqrt(R), population std"
LOOPS: dict[str, LoopSpec] = {s.name: s for s in (
    LoopSpec("t2m", t2m_loop, 32, "shuffled DataLoader, drop_last", "Euclidean, numpy float32", 3,
             "300 pairs", "100 x 30 x 10", 20, _CI,
             "EricGuo5513/text-to-motion final_evaluations.py L28-145, utils/metrics.py L6-146"),
    LoopSpec("mdm", mdm_loop, 32, "shuffled DataLoader, drop_last, first 32 batches (>= 1000 rows)",
             "Euclidean, numpy float32", 3, "300 pairs", "mm_short: 4 batches (128) x 30 x 10; wo_mm: none",
             20, _CI, "GuyTevet/motion-diffusion-model eval/eval_humanml.py L20-239"),
    LoopSpec("chois", chois_loop, 32, "listing order (test ids sorted), unshuffled, drop_last",
             "Euclidean, numpy float32", 3, "300 pairs", "not computed", 1, _CI + " (R = 1: 0)",
             "lijiaman/chois_release t2m_eval/final_evaluations.py L28-213, "
             "motion_loaders/model_motion_loaders.py L74-85"),
    LoopSpec("chainhoi", chainhoi_loop, 32, "one torch.randperm of all rows, groups of 32, tail left out",
             "Euclidean, torch float32, nan_to_num", 3, "100 pairs (-1 when N <= 100)", "not computed", 1,
             _CI + " (R = 1: 0)", "Huanggh531/ChainHOI src/models/metrics/tm2t.py L80-161"),
    LoopSpec("interact", interact_loop, 64, "dataset order, drop_last", "Euclidean, numpy float32", 3,
             "300 pairs (50 when <= 300 rows)", "first 2 batches (128, batch 1 re-counted) x 2 x 1", 2, _CI,
             "wzyabcas/InterAct text2interaction/eval/eval_marker_representation.py L42-231"),
    LoopSpec("interact-released", interact_released_loop, 64,
             "InterAct's test loader: clips of 40-300 frames by length, drop_last", "Euclidean, numpy float32", 3,
             "300 pairs (50 when <= 300 rows)", "first 2 batches (128, batch 1 re-counted) x 2 x 1", 2, _CI,
             "wzyabcas/InterAct text2interaction/eval/eval_marker_representation.py L42-320, "
             "data_loaders/behave/data/dataset.py L28-167", clip_ids=True),
)}


def run_loop(name: str, text, motion, gt_motion, samples=None, *, seed: int = 0, **options) -> LoopResult:
    """Run the reference loop ``name`` (:data:`LOOPS`) on fixed embeddings; ``options`` go to
    its function (``replications``, length keys, ``torch_sampler``, ...)."""
    if name not in LOOPS:
        raise ValueError(f"loop: expected one of {sorted(LOOPS)}, got {name!r}")
    return LOOPS[name].function(text, motion, gt_motion, samples, seed=seed, **options)
