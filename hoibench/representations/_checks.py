"""Input validation shared by the representations: clear ``ValueError`` messages that name
the argument and what was expected."""
from __future__ import annotations

import numpy as np


def as_float_array(x, name: str, trailing: tuple[int, ...], *, min_frames: int = 1,
                   batch_ok: bool = True) -> tuple[np.ndarray, bool]:
    """Validate ``x`` as (T, *trailing) or, when ``batch_ok``, (B, T, *trailing) floats.

    Returns the array (float32 or float64, unchanged dtype) in batched form (B, T, ...) and
    whether the input was batched. Raises ``ValueError`` naming ``name`` on a wrong shape,
    a non-float dtype, too few frames or a non-finite value.
    """
    if hasattr(x, "detach") and hasattr(x, "cpu"):  # torch tensor
        x = x.detach().cpu().numpy()
    if not isinstance(x, np.ndarray):
        raise ValueError(f"{name}: expected a numpy array of floats, got {type(x).__name__}")
    shape_txt = "(T, " + ", ".join(map(str, trailing)) + ")"
    if batch_ok:
        shape_txt += " or (B, T, " + ", ".join(map(str, trailing)) + ")"
    n = len(trailing)
    if x.ndim not in ((n + 1, n + 2) if batch_ok else (n + 1,)) or tuple(x.shape[-n:]) != trailing:
        raise ValueError(f"{name}: expected shape {shape_txt}, got {tuple(x.shape)}")
    if x.dtype not in (np.float32, np.float64):
        raise ValueError(f"{name}: expected float32 or float64 values, got dtype {x.dtype}")
    batched = x.ndim == n + 2
    xb = x if batched else x[None]
    if xb.shape[1] < min_frames:
        raise ValueError(f"{name}: expected at least {min_frames} frames, got {xb.shape[1]}")
    if not np.isfinite(xb).all():
        bad = np.argwhere(~np.isfinite(xb))[0]
        where = f"clip {bad[0]}, frame {bad[1]}" if batched else f"frame {bad[1]}"
        raise ValueError(f"{name}: non-finite value (NaN or inf) at {where}")
    return xb, batched
