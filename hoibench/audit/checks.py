"""Input checks and small shared helpers of the audit corruptions: every check raises
``ValueError`` naming the argument it refuses."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from ..core.skeleton import NUM_JOINTS

#: the arrays a corruption reads and writes; other arrays of a clip (hml263, hoi269, markers,
#: contacts, ...) are derived from them and are dropped from a corrupted clip
MOTION_KEYS = ("joints", "obj_rot", "obj_trans", "object_name")


@dataclass(frozen=True)
class Context:
    """What a corruption needs besides the arrays or captions.

    ``fps``: frames per second (the protocol's; 20 on the synthetic track). ``objects``: the
    object names of the split (the pool swaps draw from). ``clip_objects``: clip id -> its
    object name. ``object_nouns``: object name -> noun phrases, each a tuple of HumanML3D
    ``word/POS`` tokens (``("small/ADJ", "box/NOUN")``); an object without an entry is
    named by its name. ``object_categories``: object name -> category (a noun swap picks an
    object of another category when it can). ``verbs``: main-verb lemmas of the split.
    """

    fps: float = 20.0
    objects: tuple[str, ...] = ()
    clip_objects: Mapping[str, str] = field(default_factory=dict)
    object_nouns: Mapping[str, tuple[tuple[str, ...], ...]] = field(default_factory=dict)
    object_categories: Mapping[str, str] = field(default_factory=dict)
    verbs: tuple[str, ...] = ()

    def nouns(self, name: str) -> tuple[tuple[str, ...], ...]:
        """Noun phrases of object ``name`` (its name as one noun when it has none listed)."""
        return tuple(self.object_nouns.get(name) or ((f"{name.lower()}/NOUN",),))


def check_context(ctx) -> Context:
    if not isinstance(ctx, Context):
        raise ValueError(f"ctx: expected an audit Context, got {type(ctx).__name__}")
    if not (isinstance(ctx.fps, (int, float)) and math.isfinite(ctx.fps) and ctx.fps > 0):
        raise ValueError(f"ctx: fps must be a positive number of frames per second, got {ctx.fps!r}")
    return ctx


def check_rng(rng) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng: expected a numpy Generator (np.random.default_rng), got {type(rng).__name__}")
    return rng


def check_severity(severity, lo: float = 0.0, hi: float = math.inf, what: str = "") -> float:
    """``severity`` as a float in ``[lo, hi]`` (ValueError naming ``severity`` otherwise)."""
    if isinstance(severity, bool) or not isinstance(severity, (int, float, np.integer, np.floating)):
        raise ValueError(f"severity: expected a number{what}, got {severity!r}")
    s = float(severity)
    if not (math.isfinite(s) and lo <= s <= hi):
        raise ValueError(f"severity: expected a finite value in [{lo:g}, {hi:g}]{what}, got {severity!r}")
    return s


def check_arrays(arrays, need_object: bool = False) -> tuple[int, bool]:
    """Check a clip's or sample's arrays: ``joints`` (..., T, 22, 3); ``obj_rot`` (..., T, 3, 3)
    and ``obj_trans`` (..., T, 3) together or neither, with the same leading shape; finite
    values. Returns ``(T, has_object)``."""
    if not isinstance(arrays, Mapping):
        raise ValueError(f"arrays: expected a mapping of array name -> array, got {type(arrays).__name__}")
    if "joints" not in arrays:
        raise ValueError("arrays: no 'joints' array")
    J = arrays["joints"]
    if not isinstance(J, np.ndarray) or J.ndim < 3 or J.shape[-2:] != (NUM_JOINTS, 3) or J.shape[-3] < 1:
        raise ValueError(f"arrays['joints']: expected an array of shape (..., T, 22, 3), got "
                         f"{getattr(J, 'shape', type(J).__name__)}")
    lead = J.shape[:-2]
    has = [k in arrays for k in ("obj_rot", "obj_trans")]
    if has[0] != has[1]:
        raise ValueError("arrays: 'obj_rot' and 'obj_trans' come together (one of them is missing)")
    if need_object and not has[0]:
        raise ValueError("arrays: no object ('obj_rot', 'obj_trans'): this corruption moves the object")
    for k, tail in (("obj_rot", (3, 3)), ("obj_trans", (3,))):
        a = arrays.get(k)
        if a is not None and (not isinstance(a, np.ndarray) or a.shape != lead + tail):
            raise ValueError(f"arrays[{k!r}]: expected shape {lead + tail} (the joints' leading shape), got "
                             f"{getattr(a, 'shape', type(a).__name__)}")
    for k in ("joints", "obj_rot", "obj_trans"):
        if k in arrays and (arrays[k].dtype.kind != "f" or not np.isfinite(arrays[k]).all()):
            raise ValueError(f"arrays[{k!r}]: expected finite floating-point values")
    return int(J.shape[-3]), bool(has[0])


def unchanged(arrays: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """A copy of every array of ``arrays`` (what severity 0 returns)."""
    return {k: np.array(v, copy=True) for k, v in arrays.items()}


def motion_only(arrays: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Copies of the :data:`MOTION_KEYS` arrays of ``arrays`` (the derived ones dropped)."""
    return {k: np.array(arrays[k], copy=True) for k in MOTION_KEYS if k in arrays}


def held_from(a: np.ndarray, t0: int, time_axis: int) -> np.ndarray:
    """``a`` with every frame ``t >= t0`` along ``time_axis`` replaced by frame ``t0``."""
    out = np.array(a, copy=True)
    index = [slice(None)] * a.ndim
    index[time_axis] = slice(t0, None)
    frame = [slice(None)] * a.ndim
    frame[time_axis] = slice(t0, t0 + 1)
    out[tuple(index)] = a[tuple(frame)]
    return out


def frame_from_fraction(fraction: float, frames: int) -> int:
    """``t0 = floor((1 - fraction) * (T - 1))``: the frame a fraction of the clip is held from
    (fraction 0: the last frame, nothing changes; fraction 1: frame 0)."""
    return int(math.floor((1.0 - fraction) * (frames - 1) + 1e-9))


def check_clips(clips) -> None:
    """Check every clip of a split (``clips``: clip id -> arrays); the message names the clip."""
    if not isinstance(clips, Mapping):
        raise ValueError(f"clips: expected a mapping of clip id -> arrays, got {type(clips).__name__}")
    for cid, arrays in clips.items():
        if not isinstance(cid, str):
            raise ValueError(f"clips: clip ids must be strings, got {cid!r}")
        try:
            check_arrays(arrays)
        except ValueError as e:
            raise ValueError(f"clips[{cid!r}]: {e}") from None
