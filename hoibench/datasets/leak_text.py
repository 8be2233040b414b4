"""Caption near-duplicates between two sets of clips (the text part of ``datasets leak-check``).

A caption is **normalised** by lowercasing, replacing every character that is not a letter,
digit or space by a space, and collapsing whitespace (``"A person lifts the box."`` ->
``"a person lifts the box"``). For each query clip, every caption of it is compared with
every caption of the reference clips:

* ``exact``: the stripped caption strings are equal;
* ``normalised``: the normalised captions are equal (case, punctuation, spacing differ);
* ``ngram``: Jaccard similarity of the captions' word 3-gram sets
  ``|G(a) & G(b)| / |G(a) | G(b)|`` is at least :data:`JACCARD_THRESHOLD` (a caption of
  fewer than three words is its single n-gram).

Captions are deduplicated (after normalisation) before comparing, and the n-gram overlap of
all unique pairs is one sparse product (gram incidence matrices), so datasets of templated
captions cost no more than their distinct captions.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .leak_settings import JACCARD_THRESHOLD, NGRAM

_NOT_WORD = re.compile(r"[^\w ]+|_+")
KINDS = ("exact", "normalised", "ngram")


def normalise(caption: str) -> str:
    """Lowercase, punctuation -> space, whitespace collapsed."""
    return " ".join(_NOT_WORD.sub(" ", caption.lower().replace("\t", " ")).split())


def ngrams(norm: str, n: int = NGRAM) -> frozenset[str]:
    """The word n-grams of a normalised caption (the whole caption when it has fewer than n words)."""
    words = norm.split()
    if len(words) < n:
        return frozenset([" ".join(words)]) if words else frozenset()
    return frozenset(" ".join(words[i:i + n]) for i in range(len(words) - n + 1))


@dataclass(frozen=True)
class TextMatch:
    """The closest caption pair of query clip ``query`` and reference clip ``ref``."""
    query: int
    ref: int
    kind: str                  # exact | normalised | ngram
    jaccard: float
    query_caption: str
    ref_caption: str
    shared_by: int             # reference clips holding a caption with this normalised form


def _unique(captions: Sequence[Sequence[str]]) -> tuple[list[str], dict[str, list[tuple[int, str]]]]:
    """Sorted distinct normalised captions, and for each the (clip, raw caption) pairs holding it."""
    where: dict[str, list[tuple[int, str]]] = {}
    for i, caps in enumerate(captions):
        for c in caps:
            n = normalise(c)
            if n:
                where.setdefault(n, []).append((i, c.strip()))
    return sorted(where), where


def _incidence(norms: list[str], vocab: dict[str, int]):
    """Sparse (len(norms), len(vocab)) 0/1 matrix of each caption's n-grams (grams not in
    ``vocab`` are added to it)."""
    from scipy import sparse
    rows, cols = [], []
    for i, n in enumerate(norms):
        for g in sorted(ngrams(n)):
            rows.append(i), cols.append(vocab.setdefault(g, len(vocab)))
    return rows, cols, sparse


def match_captions(query: Sequence[Sequence[str]], ref: Sequence[Sequence[str]],
                   threshold: float = JACCARD_THRESHOLD) -> list[TextMatch]:
    """For every query clip with a caption within ``threshold``: its closest reference clip
    (exact before normalised before n-gram, then higher Jaccard, then lower reference index),
    sorted by query index."""
    qn, qwhere = _unique(query)
    rn, rwhere = _unique(ref)
    if not qn or not rn:
        return []
    vocab: dict[str, int] = {}
    qr, qc, sparse = _incidence(qn, vocab)
    rr, rc, _ = _incidence(rn, vocab)
    Q = sparse.csr_matrix((np.ones(len(qr)), (qr, qc)), shape=(len(qn), len(vocab)))
    R = sparse.csr_matrix((np.ones(len(rr)), (rr, rc)), shape=(len(rn), len(vocab)))
    inter = (Q @ R.T).tocoo()
    qsize, rsize = np.asarray(Q.sum(1)).ravel(), np.asarray(R.sum(1)).ravel()
    jac = inter.data / (qsize[inter.row] + rsize[inter.col] - inter.data)
    keep = jac >= threshold
    first: dict[str, tuple[int, str]] = {n: min(rwhere[n]) for n in rn}        # lowest clip, its caption
    raw_first: dict[str, dict[str, int]] = {}
    for n in rn:
        for ri, raw in sorted(rwhere[n], reverse=True):
            raw_first.setdefault(n, {})[raw] = ri
    shared = {n: len({r for r, _ in rwhere[n]}) for n in rn}
    best: dict[int, tuple] = {}
    for a, b, j in zip(inter.row[keep], inter.col[keep], jac[keep]):
        na, nb = qn[a], rn[b]
        for qi, qraw in qwhere[na]:
            if na == nb and qraw in raw_first[nb]:
                rank = (0, -1.0, raw_first[nb][qraw], qraw, qraw)
            else:
                ri, rraw = first[nb]
                rank = (1 if na == nb else 2, -float(j), ri, qraw, rraw)
            if qi not in best or rank < best[qi][0]:
                best[qi] = (rank, shared[nb])
    return [TextMatch(qi, rank[2], KINDS[rank[0]], round(-rank[1], 6), rank[3], rank[4], n)
            for qi, (rank, n) in sorted(best.items())]


def pair_kind(a: Sequence[str], b: Sequence[str], threshold: float = JACCARD_THRESHOLD) -> str | None:
    """The closest caption relation (``exact`` / ``normalised`` / ``ngram``) between any caption
    of ``a`` and any of ``b``; None when no pair reaches ``threshold``."""
    best = None
    for x in a:
        for y in b:
            nx, ny = normalise(x), normalise(y)
            if not nx or not ny:
                continue
            if x.strip() == y.strip():
                return KINDS[0]
            if nx == ny:
                best = 1
            elif best is None:
                gx, gy = ngrams(nx), ngrams(ny)
                if len(gx & gy) / len(gx | gy) >= threshold:
                    best = 2
    return None if best is None else KINDS[best]
