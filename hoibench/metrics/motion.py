"""Motion-quality metrics on joint positions: foot skating (three definitions) and jitter.

All functions take one clip, joints (T, 22, 3) in the canonical frame (metres, y-up, floor at
y = 0; docs/representations.md) and return counts, so that clips pool exactly (sums of integers):

* :func:`foot_skating_counts` -- ChainHOI's FSR (``legacy``) and hoibench's ``clean``
  variant: the feet are joints 10 (L_foot) and 11 (R_foot); foot-frame ``(t, f)`` for
  ``t = 0 .. T-2`` is a *ground-contact* foot-frame when the foot's height at ``t+1`` is
  below ``height_m`` (0.05 m); it *skates* when, in addition, its displacement from ``t`` to
  ``t+1`` exceeds ``displacement_m`` (0.025 m per frame, i.e. 0.5 m/s at 20 fps).
  ``legacy`` measures ``|dx|`` along the world x axis only (ChainHOI, ``src/models/metrics/
  compute.py``: a foot sliding along z is never counted); ``clean`` measures the horizontal
  (x, z) displacement and scales the threshold to the clip's frame rate
  (``speed_mps / fps`` with ``speed_mps = 0.025 * 20 = 0.5``). FSR = skating foot-frames /
  ground-contact foot-frames, pooled over clips (ChainHOI divides the summed counts).
  Paper column: ChainHOI "FSR"; lower is better.
* :func:`gmd_skating_counts` -- the velocity-based definition of GMD (Karunratanakul et al.,
  ICCV 2023, ``data_loaders/humanml/utils/metrics.py: calculate_skating_ratio``), also used by
  HOI-Diff: feet 10, 11; horizontal (x, z) speed ``v_t = |p_{t+1} - p_t|_xz * fps``; its
  5-frame moving average (``scipy.ndimage.uniform_filter1d``, zero padding); a frame skates
  when, for either foot, the foot is below 0.05 m at both ``t`` and ``t+1`` and both ``v_t``
  and the average exceed 0.5 m/s. Ratio per clip = skating frames / (T - 1), averaged over
  clips. (GMD counts over the padded batch length; hoibench over each clip's own length.)
  Reported as ``fsr_gmd``; lower is better.
* :func:`jitter_sums` -- mean jerk magnitude: third finite difference of every joint,
  ``|p_{t+3} - 3 p_{t+2} + 3 p_{t+1} - p_t| * fps^3`` (m/s^3), pooled over joints, frames
  and clips. Not a paper metric; lower is better (the real motion's value is the floor).
"""
from __future__ import annotations

import numpy as np

from ..core import skeleton as sk

FEET: tuple[int, int] = (10, 11)
FSR_HEIGHT_M = 0.05
FSR_DISPLACEMENT_M = 0.025          # per frame, ChainHOI (20 fps data)
FSR_REFERENCE_FPS = 20.0
GMD_HEIGHT_M = 0.05
GMD_SPEED_MPS = 0.5
GMD_WINDOW_FRAMES = 5
FSR_MODES: tuple[str, ...] = ("legacy", "clean")


def _joints(joints, min_frames: int = 1) -> np.ndarray:
    J = np.asarray(joints, dtype=np.float64)
    if J.ndim != 3 or J.shape[1:] != (sk.NUM_JOINTS, 3):
        raise ValueError(f"joints: expected shape (T, 22, 3), got {J.shape}")
    if len(J) < min_frames:
        raise ValueError(f"joints: expected at least {min_frames} frames, got {len(J)}")
    return J


def foot_skating_counts(joints, fps: float = FSR_REFERENCE_FPS, mode: str = "legacy",
                        height_m: float = FSR_HEIGHT_M,
                        displacement_m: float = FSR_DISPLACEMENT_M) -> tuple[int, int]:
    """(skating foot-frames, ground-contact foot-frames) of one clip; see the module notes.

    ``legacy``: ``|x_{t+1} - x_t| > displacement_m`` (x only, per frame, whatever ``fps``).
    ``clean``: ``|p_{t+1} - p_t|_xz > displacement_m * FSR_REFERENCE_FPS / fps``.
    Ground contact: foot height at ``t+1`` below ``height_m``. Clips of one frame give (0, 0).
    """
    if mode not in FSR_MODES:
        raise ValueError(f"mode: expected one of {FSR_MODES}, got {mode!r}")
    if not fps > 0:
        raise ValueError(f"fps: expected a positive frame rate, got {fps}")
    F = _joints(joints)[:, list(FEET)]                           # (T, 2, 3)
    ground = F[1:, :, 1] < height_m                                # (T-1, 2)
    if mode == "legacy":
        step = np.abs(F[1:, :, 0] - F[:-1, :, 0])
        skate = step > displacement_m
    else:
        step = np.linalg.norm((F[1:] - F[:-1])[..., [0, 2]], axis=-1)
        skate = step > displacement_m * FSR_REFERENCE_FPS / fps
    return int((skate & ground).sum()), int(ground.sum())


def foot_skating_ratio(joints, fps: float = FSR_REFERENCE_FPS, mode: str = "legacy", **kw) -> float:
    """FSR of one clip (``nan`` when no foot touches the ground)."""
    s, g = foot_skating_counts(joints, fps, mode, **kw)
    return s / g if g else float("nan")


def gmd_skating_counts(joints, fps: float = FSR_REFERENCE_FPS, height_m: float = GMD_HEIGHT_M,
                       speed_mps: float = GMD_SPEED_MPS,
                       window_frames: int = GMD_WINDOW_FRAMES) -> tuple[int, int]:
    """(skating frames, T - 1) of one clip under GMD's velocity-based definition."""
    from scipy.ndimage import uniform_filter1d

    if not fps > 0:
        raise ValueError(f"fps: expected a positive frame rate, got {fps}")
    F = _joints(joints)[:, list(FEET)]
    if len(F) < 2:
        return 0, 0
    vel = np.linalg.norm((F[1:] - F[:-1])[..., [0, 2]], axis=-1) * fps          # (T-1, 2)
    avg = uniform_filter1d(vel, size=int(window_frames), axis=0, mode="constant", origin=0)
    low = F[:, :, 1] < height_m
    contact = low[:-1] & low[1:]
    skating = (contact & (vel > speed_mps) & (avg > speed_mps)).any(axis=1)
    return int(skating.sum()), int(len(skating))


def jitter_sums(joints, fps: float) -> tuple[float, int]:
    """(sum of jerk magnitudes in m/s^3, number of joint-frames) of one clip; clips shorter
    than 4 frames give (0.0, 0)."""
    if not fps > 0:
        raise ValueError(f"fps: expected a positive frame rate, got {fps}")
    J = _joints(joints)
    if len(J) < 4:
        return 0.0, 0
    jerk = (J[3:] - 3 * J[2:-1] + 3 * J[1:-2] - J[:-3]) * fps ** 3
    mag = np.linalg.norm(jerk, axis=-1)
    return float(mag.sum()), int(mag.size)


def jitter(joints, fps: float) -> float:
    """Mean jerk magnitude of one clip, m/s^3 (``nan`` below 4 frames)."""
    s, n = jitter_sums(joints, fps)
    return s / n if n else float("nan")
