"""Motion near-duplicates between two sets of clips (what ``hoibench datasets leak-check`` runs).

Every clip's joints (T, 22, 3) are resampled by time to :data:`ANALYSIS_FPS` and compared
root-aligned: the index's short windows are **canonicalised** (:func:`canonicalise`: the first
frame's pelvis moved to x = z = 0, height kept, and the first frame turned about the vertical
(y) axis to face +z; facing = ``across x up``, ``across`` = (left hip - right hip) + (left
shoulder - right shoulder), as HumanML3D's canonicalisation); the exact distance aligns whole
overlaps by least squares (below), which a heading estimated from one frame would not match
over several metres of walking.

**Distance** between a query clip ``a`` and a reference clip ``b`` at frame offset ``o``
(query frame ``t`` against reference frame ``t + o``), variant ``v`` in {``same``,
``mirror``} (``mirror``: ``a`` reflected x -> -x with left and right joints swapped)::

    D_o(a, b) = mean over the overlap frames t and joints j of |A_t,j - B_t+o,j|   (metres)

with ``A`` the overlapping segment of ``a`` turned about the vertical axis and moved on the
floor (one rotation and one xz translation for the whole segment, the least-squares fit to
``B``: :func:`align_about_y`; heights are kept): the mean per-joint position error (MPJPE)
of the best-aligned overlap, invariant to where and facing which way a copy was placed. A
fractional offset interpolates ``b`` linearly: an offset from the index that is within
``REFINE_BELOW_M`` is refined (the frames before and after, then quarter frames around the
best). A clip's distance to a reference clip is the ``min`` over variants and offsets whose
overlap covers at least :data:`MIN_COVERAGE` of the shorter clip and :data:`WINDOW` frames
(a short shared stretch, such as standing still at the start, is no duplicate); a pair is a
duplicate when it is at most ``threshold_m`` (:data:`THRESHOLD_M`). A renamed copy is at 0,
a mirrored copy at 0 under ``mirror``, a shifted crop at 0 at its offset (a shift by a
fraction of a frame: the residual of the quarter-frame grid and of linear interpolation).

**Index** (the candidates the exact distance re-ranks): windows of :data:`WINDOW` frames,
each canonicalised at its own first frame, every :data:`SUBSAMPLE`-th frame kept, scaled so
that the Euclidean distance of two descriptors is their RMS joint error (m), projected on the
first :data:`PCA_DIMS` principal axes of the reference windows (an orthogonal projection:
never farther than the full distance, so a radius search loses no pair). Windows start at
every frame of ``[0, STRIDE)`` and at every multiple of :data:`STRIDE`; the query's first
starts meet the reference's multiples and the reference's first starts the query's
multiples, so one aligned window pair exists for every offset (the query inside the
reference or the reference inside the query) as long as the inner clip has ``STRIDE``
window starts (``WINDOW + STRIDE - 1`` frames). Search is by blocked matrix products: every
pair within ``window_radius_m`` and each query window's nearest. Deterministic: clips in
the given order, ties broken by index.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from ..core.geometry import resample_frames
from ..core.skeleton import JOINT_INDEX, MIRROR_JOINTS
from .leak_settings import (ANALYSIS_FPS, BLOCK, MIN_COVERAGE, OFFSETS_PER_PAIR, PCA_DIMS, REFINE_BELOW_M,
                            RERANK_PER_CLIP, STRIDE, SUBFRAME_OFFSETS, SUBSAMPLE, THRESHOLD_M, WINDOW, WINDOW_RADIUS_M)

__all__ = ["ANALYSIS_FPS", "THRESHOLD_M", "WINDOW", "STRIDE", "MIN_COVERAGE", "Match", "match_sets",
           "overlap_distance", "align_about_y", "canonicalise", "mirror", "resample", "windows", "search"]

_LH, _RH, _LS, _RS = (JOINT_INDEX[n] for n in ("left_hip", "right_hip", "left_shoulder", "right_shoulder"))


def resample(joints: np.ndarray, fps: float, target_fps: float = ANALYSIS_FPS) -> np.ndarray:
    """(T, 22, 3) at ``fps`` -> (T', 22, 3) float32 at ``target_fps`` by linear interpolation in
    time (frame k at k / target_fps s, T' = floor((T - 1) target_fps / fps) + 1)."""
    return resample_frames(np.asarray(joints, dtype=np.float64), fps, target_fps).astype(np.float32)


def mirror(joints: np.ndarray) -> np.ndarray:
    """Left-right reflection: ``J'[j] = M J[m(j)]``, ``M = diag(-1, 1, 1)``, ``m`` swapping sides."""
    out = np.asarray(joints)[..., list(MIRROR_JOINTS), :].copy()
    out[..., 0] *= -1
    return out


def canonicalise(seg: np.ndarray) -> np.ndarray:
    """(..., T, 22, 3) segments -> the same, each with its first frame's pelvis at x = z = 0 and
    its first frame facing +z (rotation about y)."""
    seg = np.asarray(seg, dtype=np.float32)
    f0 = seg[..., 0, :, :]
    across = (f0[..., _LH, :] - f0[..., _RH, :]) + (f0[..., _LS, :] - f0[..., _RS, :])
    fx, fz = -across[..., 2], across[..., 0]              # across x up (y-up frame)
    theta = np.arctan2(fx, fz)                            # 0 when facing +z
    c, s = np.cos(theta)[..., None, None], np.sin(theta)[..., None, None]
    x = seg[..., 0] - f0[..., None, 0:1, 0]
    z = seg[..., 2] - f0[..., None, 0:1, 2]
    return np.stack([c * x - s * z, seg[..., 1], s * x + c * z], axis=-1).astype(np.float32)


def align_about_y(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a`` (..., 3) moved by the rotation about y and the xz translation that bring it closest to
    ``b`` in least squares (heights unchanged): with both xz centred,
    ``theta = atan2(sum(a_z b_x - a_x b_z), sum(a_x b_x + a_z b_z))``,
    ``x' = cos(theta) x + sin(theta) z``, ``z' = -sin(theta) x + cos(theta) z``."""
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    ax, az, bx, bz = a[..., 0], a[..., 2], b[..., 0], b[..., 2]
    max_, maz, mbx, mbz = ax.mean(), az.mean(), bx.mean(), bz.mean()
    ax, az, bx, bz = ax - max_, az - maz, bx - mbx, bz - mbz
    theta = np.arctan2(np.vdot(az, bx) - np.vdot(ax, bz), np.vdot(ax, bx) + np.vdot(az, bz))
    c, s = np.cos(theta), np.sin(theta)
    out = np.empty_like(a)
    out[..., 0] = c * ax + s * az + mbx
    out[..., 1] = a[..., 1]
    out[..., 2] = -s * ax + c * az + mbz
    return out


def overlap_distance(a: np.ndarray, b: np.ndarray, offset: float) -> tuple[float, int]:
    """(MPJPE in metres, overlap frames) of query ``a`` against reference ``b`` with query frame
    t on reference time t + ``offset`` frames (a fractional offset interpolates ``b`` linearly
    between frames), after :func:`align_about_y` of the overlapping segments; (inf, 0) when
    they do not overlap."""
    k = int(np.floor(offset))
    f = float(offset - k)
    t0 = max(0, -k)
    n = min(len(a), len(b) - k - (1 if f > 0 else 0)) - t0
    if n <= 0:
        return float("inf"), 0
    B = b[t0 + k:t0 + k + n].astype(np.float64)
    if f > 0:
        B = (1 - f) * B + f * b[t0 + k + 1:t0 + k + 1 + n]
    A = align_about_y(a[t0:t0 + n], B)
    return float(np.linalg.norm(A - B, axis=-1).mean()), int(n)


@dataclass(frozen=True)
class Windows:
    """Window descriptors of a set of clips: ``desc`` (N, D) float32, ``clip`` (N,) index of the
    clip, ``start`` (N,) first frame, ``variant`` (N,) 0 same / 1 mirror."""
    desc: np.ndarray
    clip: np.ndarray
    start: np.ndarray
    variant: np.ndarray


def _starts(T: int, which: str) -> np.ndarray:
    """Window starts of a T-frame clip: ``head`` = [0, STRIDE), ``grid`` = multiples of STRIDE."""
    last = max(T - WINDOW, 0)
    if which == "head":
        return np.arange(min(STRIDE, last + 1))
    return np.arange(0, last + 1, STRIDE)


def windows(clips: Sequence[np.ndarray], which: str, variants: Sequence[int] = (0,),
            basis: tuple[np.ndarray, np.ndarray] | None = None) -> Windows:
    """Descriptors of every clip's ``which`` windows, for each variant (full dimension, or
    projected on ``basis`` = (mean, axes), about 16k windows at a time); a clip shorter than
    WINDOW is padded with its last frame."""
    keep = np.arange(0, WINDOW, SUBSAMPLE)
    scale = np.float32(1.0 / np.sqrt(len(keep) * 22))
    out, pending, cl, st, va = [], [], [], [], []

    def flush() -> None:
        if pending:
            d = np.concatenate(pending)
            out.append(d if basis is None else (d - basis[0]) @ basis[1])
            pending.clear()
    rows = 0
    for v in variants:
        for i, j in enumerate(clips):
            if len(j) < WINDOW:
                j = np.concatenate([j, np.repeat(j[-1:], WINDOW - len(j), 0)])
            if v:
                j = mirror(j)
            s = _starts(len(j), which)
            pending.append(canonicalise(j[s[:, None] + keep[None, :]]).reshape(len(s), -1) * scale)
            cl.append(np.full(len(s), i)), st.append(s), va.append(np.full(len(s), v))
            rows += len(s)
            if rows >= 16384:
                flush()
                rows = 0
    flush()
    if not out:
        dim = len(keep) * 66 if basis is None else basis[1].shape[1]
        return Windows(np.zeros((0, dim), np.float32), *(np.zeros(0, int),) * 3)
    return Windows(np.concatenate(out).astype(np.float32), np.concatenate(cl), np.concatenate(st),
                   np.concatenate(va))


def pca_basis(desc: np.ndarray, dims: int = PCA_DIMS) -> tuple[np.ndarray, np.ndarray]:
    """(mean (D,), axes (D, d)): the first ``dims`` principal axes of the rows of ``desc``
    (orthonormal columns, each signed so that its largest entry is positive)."""
    rows = desc.astype(np.float64)
    mean = rows.mean(0) if len(rows) else np.zeros(desc.shape[1])
    x = rows - mean
    _, v = np.linalg.eigh(x.T @ x)                       # ascending eigenvalues
    axes = v[:, ::-1][:, :dims]
    axes = axes * np.where(axes[np.abs(axes).argmax(0), np.arange(axes.shape[1])] < 0, -1.0, 1.0)
    return mean.astype(np.float32), np.ascontiguousarray(axes, dtype=np.float32)


def fit_basis(ref: Sequence[np.ndarray], sample: int = 20000) -> tuple[np.ndarray, np.ndarray]:
    """:func:`pca_basis` of the grid windows of every n-th reference clip (n such that about
    ``sample`` windows are used; all of them for a small set)."""
    per = max(1.0, float(np.mean([len(j) for j in ref])) / STRIDE) if len(ref) else 1.0
    step = max(1, int(len(ref) * per // sample))
    return pca_basis(windows(list(ref)[::step], "grid").desc)


def search(q: np.ndarray, r: np.ndarray, radius: float,
           progress: Callable[[int], None] | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(query rows, reference rows, distances) of every pair within ``radius`` plus each query
    row's nearest reference row, by blocked products ``|q|^2 + |r|^2 - 2 q.r``."""
    qi, ri, dd = [], [], []
    if len(q) == 0 or len(r) == 0:
        return np.zeros(0, int), np.zeros(0, int), np.zeros(0, np.float32)
    rn = (r * r).sum(1)
    qn = (q * q).sum(1)
    block = max(16, min(BLOCK, (1 << 24) // len(r)))            # at most 16M distances at once
    for b0 in range(0, len(q), block):
        m = (-2.0 * q[b0:b0 + block]) @ r.T                     # |q - r|^2 - |q|^2, row by row
        m += rn[None, :]
        near = np.argmin(m, axis=1)
        hit = m <= (radius * radius - qn[b0:b0 + block])[:, None]
        hit[np.arange(len(m)), near] = True
        a, b = np.nonzero(hit)
        qi.append(a + b0), ri.append(b), dd.append(np.sqrt(np.maximum(m[a, b] + qn[a + b0], 0)))
        if progress is not None:
            progress(len(m))
    return np.concatenate(qi), np.concatenate(ri), np.concatenate(dd).astype(np.float32)


@dataclass(frozen=True)
class Match:
    """The closest alignment found between query clip ``query`` and reference clip ``ref``:
    ``offset`` frames at ANALYSIS_FPS (query t on reference t + offset), ``distance_m`` MPJPE."""
    query: int
    ref: int
    variant: str
    offset: float
    overlap: int
    distance_m: float


def _candidates(qw: Windows, rw: Windows, radius: float, swapped: bool, progress) -> np.ndarray:
    """Rows (query clip, ref clip, variant, offset, window distance) of every window pair found;
    with ``swapped`` the rows of ``qw`` are reference windows and those of ``rw`` query windows."""
    a, b, d = search(qw.desc, rw.desc, radius, progress)
    if swapped:
        a, b, qw, rw = b, a, rw, qw
    return np.stack([qw.clip[a], rw.clip[b], qw.variant[a], rw.start[b] - qw.start[a], d], 1).astype(np.float64)


def _rank_within(rows: np.ndarray, group: np.ndarray) -> np.ndarray:
    """The rank of each row within its run of equal ``group`` values (rows sorted by group)."""
    begins = np.r_[0, np.nonzero(np.diff(group))[0] + 1]
    return np.arange(len(rows)) - np.repeat(begins, np.diff(np.r_[begins, len(rows)]))


def _best_per_clip(rows: np.ndarray, n_ref: int) -> np.ndarray:
    """Of ``rows`` (query, ref, variant, offset, distance): the closest row of each (query, ref,
    variant, offset); of those the OFFSETS_PER_PAIR closest offsets of each (query, ref, variant);
    and those of at most RERANK_PER_CLIP reference clips per (query, variant), closest first."""
    if len(rows) == 0:
        return rows
    q, r, v, o = (rows[:, i].astype(np.int64) for i in range(4))
    order = np.lexsort((o, r, v, q, rows[:, 4]))               # by distance, ties by index
    _, first = np.unique(np.stack([q, r, v, o], 1)[order], axis=0, return_index=True)
    rows = rows[order[np.sort(first)]]                         # still by distance
    pair = (rows[:, 0].astype(np.int64) * n_ref + rows[:, 1].astype(np.int64)) * 2 + rows[:, 2].astype(np.int64)
    by_pair = np.argsort(pair, kind="stable")
    rows = rows[by_pair][_rank_within(by_pair, pair[by_pair]) < OFFSETS_PER_PAIR]
    pair = (rows[:, 0].astype(np.int64) * n_ref + rows[:, 1].astype(np.int64)) * 2 + rows[:, 2].astype(np.int64)
    _, at = np.unique(pair, return_index=True)                 # each pair's closest row
    heads = rows[at]
    heads = heads[np.lexsort((heads[:, 1], heads[:, 4], heads[:, 2], heads[:, 0]))]
    keep = heads[_rank_within(heads, heads[:, 0] * 2 + heads[:, 2]) < RERANK_PER_CLIP]
    chosen = set(((keep[:, 0] * n_ref + keep[:, 1]) * 2 + keep[:, 2]).astype(np.int64).tolist())
    rows = rows[np.isin(pair, list(chosen))]
    return rows[np.lexsort((rows[:, 3], rows[:, 2], rows[:, 1], rows[:, 0]))]


def match_sets(query: Sequence[np.ndarray], ref: Sequence[np.ndarray], *, radius: float = WINDOW_RADIUS_M,
               exclude: Sequence[tuple[int, int]] = (),
               progress: Callable[[str, int], Callable[[int], None] | None] | None = None) -> list[Match]:
    """For every query clip (joints at ANALYSIS_FPS), its best exact match per candidate reference
    clip (at most RERANK_PER_CLIP per variant), sorted by (query, distance, ref): the alignment of
    least distance among those whose overlap covers MIN_COVERAGE of the shorter clip (and at
    least WINDOW frames). ``exclude``: (query, ref) pairs never matched (one clip on both sides);
    ``progress(name, total)`` makes a bar."""
    with _blas_threads():
        return _match_sets(query, ref, radius, exclude, progress or (lambda name, n: None))


def _blas_threads():
    """BLAS on one thread while matching (threadpoolctl, when installed): the report is then
    the same whatever the machine's load (float32 sums can depend on the thread count), and on
    a busy machine two BLAS threads made the index many times slower than one."""
    from contextlib import nullcontext
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return nullcontext()
    return threadpool_limits(limits=1, user_api="blas")


def _match_sets(query, ref, radius, exclude, bar) -> list[Match]:
    basis = fit_basis(ref)
    qh, rg = windows(query, "head", (0, 1), basis), windows(ref, "grid", (0,), basis)
    rh, qg = windows(ref, "head", (0,), basis), windows(query, "grid", (0, 1), basis)
    rows = np.concatenate([_candidates(qh, rg, radius, False, bar("leak-check index", len(qh.desc))),
                           _candidates(rh, qg, radius, True, bar("leak-check index (reverse)", len(rh.desc)))])
    if len(exclude) and len(rows):
        n = max(len(ref), 1)
        drop = np.array([q * n + r for q, r in exclude], np.int64)
        rows = rows[~np.isin(rows[:, 0].astype(np.int64) * n + rows[:, 1].astype(np.int64), drop)]
    rows = _best_per_clip(rows, max(len(ref), 1))
    tick = bar("leak-check re-rank", len(rows))
    best: dict = {}
    for qc, rc, v, off, _ in rows:
        qc, rc, v, off = int(qc), int(rc), int(v), float(off)
        a, b = (mirror(query[qc]) if v else query[qc]), ref[rc]
        need = max(min(WINDOW, len(a), len(b)), int(np.ceil(MIN_COVERAGE * min(len(a), len(b)))))
        tries = [t for t in [overlap_distance(a, b, off) + (off,)] if t[1] >= need]
        if tries and tries[0][0] < REFINE_BELOW_M:          # near: the next frames, then sub-frame steps
            tries += [t for t in (overlap_distance(a, b, off + d) + (off + d,) for d in (-1.0, 1.0)) if t[1] >= need]
            whole = min(tries)[2]
            tries += [t for t in (overlap_distance(a, b, whole + d) + (whole + d,) for d in SUBFRAME_OFFSETS)
                      if t[1] >= need]
        if tries:
            dist, n, o = min(tries)
            m = Match(qc, rc, "mirror" if v else "same", o, n, dist)
            k = (qc, rc)
            if k not in best or (m.distance_m, m.variant, m.offset) < (best[k].distance_m, best[k].variant,
                                                                        best[k].offset):
                best[k] = m
        if tick is not None:
            tick(1)
    return sorted(best.values(), key=lambda m: (m.query, m.distance_m, m.ref))
