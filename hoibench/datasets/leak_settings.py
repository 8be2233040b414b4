"""The leak check's settings (no imports: the command line's help reads them while it builds).

Motion: joints resampled to ``ANALYSIS_FPS``; index windows of ``WINDOW`` frames starting
every ``STRIDE`` frames (and at each of the first ``STRIDE`` frames), every ``SUBSAMPLE``-th
frame kept, projected on ``PCA_DIMS`` principal axes, searched within ``WINDOW_RADIUS_M`` (RMS
joint error) plus each window's nearest; ``RERANK_PER_CLIP`` reference clips per query clip
and variant and ``OFFSETS_PER_PAIR`` offsets per pair re-ranked exactly; an offset within
``REFINE_BELOW_M`` is refined (the frames before and after, then ``SUBFRAME_OFFSETS`` around
the best); a duplicate overlaps at least ``MIN_COVERAGE`` of the shorter clip with an MPJPE
of at most ``THRESHOLD_M``. Text: word ``NGRAM``-grams, duplicate at Jaccard >=
``JACCARD_THRESHOLD``.
"""
from __future__ import annotations

ANALYSIS_FPS = 20.0
WINDOW = 16                 # frames at ANALYSIS_FPS: 0.8 s
STRIDE = 4                  # frames: 0.2 s
SUBSAMPLE = 2               # descriptor keeps every 2nd window frame (8 frames)
PCA_DIMS = 48
THRESHOLD_M = 0.01          # MPJPE of a duplicate (calibrated in docs/datasets.md, "Leak check")
WINDOW_RADIUS_M = 0.05      # index radius (RMS joint error of a window pair)
RERANK_PER_CLIP = 4         # reference clips re-ranked exactly per query clip and variant
#: offsets (frames) tried around each candidate's window offset: sub-frame steps catch a clip
#: resampled at another phase (a time shift that is no whole number of frames)
SUBFRAME_OFFSETS = (-0.75, -0.5, -0.25, 0.25, 0.5, 0.75)
REFINE_BELOW_M = 0.1        # an offset this close is refined (a duplicate is within half a frame's motion)
OFFSETS_PER_PAIR = 3        # offsets re-ranked per (query, reference, variant)
MIN_COVERAGE = 0.5          # an overlap shorter than this fraction of the shorter clip is no duplicate
BLOCK = 512                 # query windows per matrix-product block
NGRAM = 3
JACCARD_THRESHOLD = 0.6
