"""Diversity metrics of multi-body interaction (DiffH2O, as SyncDiff reports them): SD
(within a prompt) and OD (over a split) of wrist trajectories, as functions and as
mergeable metrics.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from .multibody_common import DIFFH2O_FRAMES, _array, _clip_key, _finite, _mode, _num_frames, _PerClipMean, _sequence
from .state import Metric, sorted_items

# ===================================================================== diversity (SD, OD)
def downsample_indices(frames: int, num_frames: int | None = DIFFH2O_FRAMES) -> np.ndarray:
    """DiffH2O's frame subset: ``arange(0, T, T // n)[:n]`` (all frames when ``n`` is None).
    Needs ``T >= n``."""
    num_frames = _num_frames(num_frames)
    if num_frames is None:
        return np.arange(frames)
    if frames < num_frames:
        raise ValueError(f"frames: {frames}, fewer than num_frames={num_frames}")
    return np.arange(0, frames, frames // num_frames)[:num_frames]


def wrist_trajectory(x, num_frames: int | None = DIFFH2O_FRAMES, field: str = "trajectory") -> np.ndarray:
    """A validated wrist trajectory (T', J, 3): input (T, 3) (one wrist) or (T, J, 3) (e.g.
    J = 2 hands), subsampled with :func:`downsample_indices`."""
    a = _array(x, field)
    if a.ndim == 2:
        a = a[:, None, :]
    if a.ndim != 3 or a.shape[-1] != 3:
        raise ValueError(f"{field}: expected shape (T, 3) or (T, J, 3), got {np.shape(x)}")
    _finite(a, field)
    n = _num_frames(num_frames)
    if n is not None and len(a) < n:
        raise ValueError(f"{field}: {len(a)} frames, fewer than num_frames={n}")
    return a[downsample_indices(len(a), n)]


def mean_pairwise_distance(trajectories, mode: str = "diffh2o", field: str = "trajectories") -> float:
    """Mean over all unordered pairs (i < j) of the distance between trajectories
    (N, T, J, 3), N >= 2, all pairs exactly (no sampling):

    * ``diffh2o``: ``|x_i - x_j|_2 / T`` on the flattened (T*J*3) vectors -- DiffH2O's
      ``mean(pdist(x.reshape(N, -1))) / num_downsampled_frames``;
    * ``per_frame``: ``mean_{t, j} |x_i(t, j) - x_j(t, j)|``, the mean Euclidean distance
      between corresponding wrist positions (metres, independent of T).
    """
    mode = _mode(mode)
    x = _array(trajectories, field)
    if x.ndim != 4 or x.shape[-1] != 3:
        raise ValueError(f"{field}: expected shape (N, T, J, 3), got {x.shape}")
    _finite(x, field)
    if len(x) < 2:
        raise ValueError(f"{field}: need at least 2 trajectories, got {len(x)}")
    if mode == "diffh2o":
        from scipy.spatial.distance import pdist

        return float(pdist(x.reshape(len(x), -1), metric="euclidean").mean() / x.shape[1])
    d = np.concatenate([np.linalg.norm(x[i + 1:] - x[i], axis=-1).mean(axis=(1, 2)) for i in range(len(x) - 1)])
    return float(d.mean())


def _stack(trajs: Sequence[np.ndarray], field: str) -> np.ndarray:
    shapes = {t.shape for t in trajs}
    if len(shapes) > 1:
        raise ValueError(f"{field}: trajectories differ in shape {sorted(shapes)} (set num_frames, "
                         "or give equal lengths and wrist counts)")
    return np.stack(trajs)


def sample_diversity(samples_per_prompt, num_frames: int | None = DIFFH2O_FRAMES, mode: str = "diffh2o") -> float:
    """SD: for each prompt, :func:`mean_pairwise_distance` of its S >= 2 generated wrist
    trajectories; the mean over prompts."""
    prompts = _sequence(samples_per_prompt, "samples_per_prompt")
    return float(np.mean([_prompt_diversity(s, num_frames, mode, f"samples_per_prompt[{p}]")
                          for p, s in enumerate(prompts)]))


def _prompt_diversity(samples, num_frames, mode: str, field: str) -> float:
    trajs = [wrist_trajectory(s, num_frames, f"{field}[{i}]") for i, s in enumerate(_sequence(samples, field))]
    return mean_pairwise_distance(_stack(trajs, field), mode, field)


def overall_diversity(trajectories, num_frames: int | None = DIFFH2O_FRAMES, mode: str = "diffh2o") -> float:
    """OD: :func:`mean_pairwise_distance` over every generated wrist trajectory of a split
    (all samples of all prompts)."""
    trajs = [wrist_trajectory(s, num_frames, f"trajectories[{i}]")
             for i, s in enumerate(_sequence(trajectories, "trajectories"))]
    return mean_pairwise_distance(_stack(trajs, "trajectories"), mode)


# ===================================================================== mergeable metrics
class _TrajectorySettings:
    """What SD and OD share: frames sampled per trajectory, the distance mode (metres) and
    their direction (higher is better)."""


    def __init__(self, num_frames: int | None = DIFFH2O_FRAMES, mode: str = "diffh2o"):
        super().__init__()
        self.num_frames, self.mode = _num_frames(num_frames), _mode(mode)

    def config(self) -> dict:
        return {"num_frames": self.num_frames, "mode": self.mode}


class SampleDiversity(_TrajectorySettings, _PerClipMean):
    """SD (DiffH2O, as SyncDiff reports it): keyed by prompt id, each prompt's mean pairwise
    distance between its generated wrist trajectories; the mean over prompts (metres, see
    :func:`mean_pairwise_distance` for ``mode``)."""

    name = "sd"

    def update(self, prompt_id, trajectories) -> None:
        """``trajectories``: the S >= 2 samples of one prompt, each (T, 3) or (T, J, 3)."""
        self._new_key(prompt_id, "prompt_id")
        self._put(prompt_id, _prompt_diversity(trajectories, self.num_frames, self.mode, "trajectories"), "prompt_id")


class OverallDiversity(_TrajectorySettings, Metric):
    """OD (DiffH2O, as SyncDiff reports it): every generated wrist trajectory of a split,
    keyed by id (e.g. ``(prompt id, sample)``); ``compute()`` stacks them in sorted key
    order and returns their mean pairwise distance (metres, see
    :func:`mean_pairwise_distance`)."""

    name = "od"

    def __init__(self, num_frames: int | None = DIFFH2O_FRAMES, mode: str = "diffh2o"):
        super().__init__(num_frames, mode)
        self.add_state("trajectories", {}, "keyed")

    def update(self, clip_id, trajectory) -> None:
        """One generated wrist trajectory (T, 3) or (T, J, 3)."""
        key = _clip_key(clip_id)
        if key in self.trajectories:
            raise ValueError(f"clip_id: trajectory {key!r} was already added")
        self.trajectories[key] = wrist_trajectory(trajectory, self.num_frames)

    def compute(self) -> float:
        items = sorted_items(self.trajectories)
        if len(items) < 2:
            raise ValueError(f"OverallDiversity: need at least 2 trajectories, got {len(items)}")
        return mean_pairwise_distance(_stack([v for _, v in items], "trajectories"), self.mode)
