"""The "mean pose + static object" baseline (the text-blind floor). It is also a reference
row, so it lives with them in :mod:`hoibench.scoring.mean_pose`; this module gives it its
place among the baselines (``hoibench baseline sample mean-pose``)."""
from __future__ import annotations

from ..scoring.mean_pose import METHOD, TRAIN_SPLIT, mean_pose_samples, write_mean_pose_submission  # noqa: F401

__all__ = ["METHOD", "TRAIN_SPLIT", "mean_pose_samples", "write_mean_pose_submission"]
