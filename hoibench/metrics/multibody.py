"""Contact, penetration and diversity metrics of multi-body interaction (N hands or humans
with M rigid objects), as SyncDiff reports them: CSR, CRR, CSIoU, IV, ID, SD and OD.

Reference: SyncDiff (He et al., ICCV 2025, arXiv 2412.20104), section 4.2 and appendix C.5;
IV, ID, SD and OD follow DiffH2O (Christen et al., 2024), whose evaluation code fixes what
the SyncDiff text leaves out (``docs/multibody_metrics.md`` has the formulas, the sources of
every default and what the paper's text copy lost).

Conventions: metres, y-up (no metric here depends on the up axis), one clip of T frames.
A body is a posed mesh: vertices (T, V, 3) float, one per frame, and faces (F, 3) int shared
by all frames (:class:`PosedMesh`, or a ``(vertices, faces)`` pair). Hands/roots and objects
of one clip must have the same T; a generated clip and its ground truth must too (trim
explicitly; nothing here truncates silently).

Geometry is open3d's ``RaycastingScene`` (imported lazily), built per frame from the posed
vertices, in float32 after moving the frame's origin to the bodies' centre:

* distances (CSR, CRR): ``compute_distance``, the exact unsigned distance from a point to the
  nearest triangle, so meshes need not be closed (``distance="vertex"``: to the nearest
  object vertex instead, the reading of appendix C.5's vertex-only inputs);
* inside tests (IV, ID): ``compute_occupancy`` / ``compute_signed_distance`` (ray parity,
  ``nsamples`` rays, majority), exact only for closed, consistently oriented meshes without
  self-intersections -- :func:`check_closed` enforces the first two (a MANO hand must have
  its wrist sealed).

Two layers, as in :mod:`hoibench.metrics`: array-level functions (one clip or one frame),
then :class:`~hoibench.metrics.state.Metric` classes that accumulate per-clip values keyed by
clip id and reduce them in sorted key order, so serial and sharded runs are bit-identical.
Every input is validated; a bad one raises ``ValueError`` naming the argument.

The code lives in four parts; this module re-exports them (import from here):

* :mod:`~hoibench.metrics.multibody_common` -- units and defaults, input validation,
  open3d helpers and the per-clip-mean metric base;
* :mod:`~hoibench.metrics.multibody_contact` -- CSR, CRR, CSIoU;
* :mod:`~hoibench.metrics.multibody_penetration` -- IV, ID;
* :mod:`~hoibench.metrics.multibody_diversity` -- SD, OD.
"""
from __future__ import annotations

from .multibody_common import (CRR_THRESHOLD_M, CSR_THRESHOLD_M, DIFFH2O_FRAMES, DISTANCES, DIVERSITY_MODES, IV_VOXEL_M,
                               M3_TO_CM3, M_TO_MM, NSAMPLES, PAIR_REDUCTIONS, PosedMesh, check_closed,
                               recognition_accuracy)
from .multibody_contact import (CRR, CSR, CSIoU, contact_frames_hand, contact_frames_human_roots, contact_ratio,
                                contact_root_ratio, contact_surface_iou, contact_surface_ratio, frame_iou,
                                hand_object_distance, root_object_distances)
from .multibody_penetration import (InterpenetrationDepth, InterpenetrationVolume, PairwisePenetration,
                                    clip_interpenetration_depth, clip_interpenetration_volume, interpenetration_depth,
                                    interpenetration_volume, pairwise_penetration, reduce_pairs)
from .multibody_diversity import (OverallDiversity, SampleDiversity, downsample_indices, mean_pairwise_distance,
                                  overall_diversity, sample_diversity, wrist_trajectory)

__all__ = [
    "CSR_THRESHOLD_M", "CRR_THRESHOLD_M", "IV_VOXEL_M", "DIFFH2O_FRAMES", "NSAMPLES", "DISTANCES",
    "PosedMesh", "check_closed", "recognition_accuracy", "hand_object_distance", "contact_frames_hand", "root_object_distances",
    "contact_frames_human_roots", "contact_ratio", "contact_surface_ratio", "contact_root_ratio", "frame_iou",
    "contact_surface_iou", "interpenetration_volume", "interpenetration_depth", "PairwisePenetration",
    "pairwise_penetration", "reduce_pairs", "clip_interpenetration_volume", "clip_interpenetration_depth",
    "downsample_indices", "wrist_trajectory", "mean_pairwise_distance", "sample_diversity", "overall_diversity",
    "CSR", "CRR", "CSIoU", "InterpenetrationVolume", "InterpenetrationDepth", "SampleDiversity", "OverallDiversity",
]
