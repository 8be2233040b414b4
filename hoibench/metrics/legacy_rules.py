"""ChainHOI's released metric rules, quirks included, as switchable settings of the physical
metrics (``legacy`` protocols turn them on; the defaults are hoibench's ``clean`` rules).

Reference: ChainHOI (github.com/Huanggh531/ChainHOI, commit 4990160),
``src/models/metrics/compute.py`` (``ContactMetric`` for BEHAVE, ``ContactMetric2`` for OMOMO)
and ``src/data/humanml/hoidataset.py`` (the evaluated lengths). docs/metrics.md tables each
rule with its file and line. The settings (fields of
:class:`hoibench.metrics.physical.PhysicalConfig`, optional keys of a protocol's
``physical:`` mapping, :data:`PHYSICAL_OPTIONS`):

``ocd_members``
    ``tolerance`` (clean): an OCD group member's map counts when its length is within
    +-8 frames of the generated clip's. ``crop`` (reference): the member is read over the
    generated clip's frames (``label[start:start + L]``), so a longer member is cut to L and
    always counts; a shorter one counts when ``L - T_m <= 8`` (T_m: its frames from
    ``start``). Implemented in :func:`hoibench.metrics.contact_metrics.optimal_contact_distance`.
``contact_joints``
    ``all`` (clean) or ``wrists`` (OMOMO reference: only joints 20, 21 enter the CD and OCD
    masks).
``contact_gt_rule`` and ``contact_gt_threshold_m``
    ground-truth joint labels from the signed joint-object distance d: ``signed`` (clean)
    ``d < tau``; ``unsigned`` (reference) ``|d| <= tau``. ``contact_gt_threshold_m``
    replaces the per-object thresholds for the GT labels (OMOMO reference: 0.5 m).
``fsr_frame`` and ``fsr_feet_to_floor``
    the joints ChainHOI's FSR reads: ``world`` (clean) or ``canonical`` (reference: the
    joints recovered from the hml263 features, HumanML3D's canonical frame: floor at the
    clip's lowest joint, first root at the xz origin, frame 0 facing +z; T - 1 frames);
    ``fsr_feet_to_floor`` (OMOMO reference) lowers both foot joints by their lowest height
    over the clip before the test.
``length_crop``
    the frames the physical metrics see: ``none`` (clean: the whole clip), ``unit4_random``
    (BEHAVE reference) or ``unit4_start`` (OMOMO reference), see :func:`length_window`.
"""
from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

from ..core import skeleton as sk

#: optional keys of a protocol's ``physical:`` mapping -> allowed values (first: the default,
#: hoibench's clean rule); ``contact_gt_threshold_m`` (positive float or null) is apart
PHYSICAL_OPTIONS: dict[str, tuple] = {
    "ocd_members": ("tolerance", "crop"),
    "contact_joints": ("all", "wrists"),
    "contact_gt_rule": ("signed", "unsigned"),
    "fsr_frame": ("world", "canonical"),
    "fsr_feet_to_floor": (False, True),
    "length_crop": ("none", "unit4_random", "unit4_start"),
}
WRISTS: tuple[int, int] = (20, 21)
FEET: tuple[int, int] = (10, 11)
UNIT_LENGTH = 4            # configs/data/{behave_gcn,omomo}.yaml: unit_length: 4
MAX_FRAMES = 199           # hoidataset.py: motion[:199]
#: :mod:`hoibench.representations.hml263` modes a canonical frame can come from; ChainHOI's
#: features are HOI-Diff's (``legacy-hoidiff``, the body part of legacy hoi269)
CANONICAL_MODES: tuple[str, ...] = ("legacy-hoidiff", "legacy", "clean")


def check_option(name: str, value) -> None:
    """``ValueError`` naming ``name`` unless ``value`` is one of its allowed values (type
    included: ``1`` is not ``True``)."""
    allowed = PHYSICAL_OPTIONS[name]
    if not any(type(value) is type(a) and value == a for a in allowed):
        raise ValueError(f"field {name!r} must be one of {list(allowed)}, got {value!r}")


# ===================================================================== contact labels
def gt_labels(distances, thresholds, rule: str = "signed") -> np.ndarray:
    """Ground-truth joint contact labels (T, 22) from signed distances d (T, 22), metres.

    ``signed``: ``d < tau`` (hoibench; penetration counts as contact). ``unsigned``:
    ``|d| <= tau`` (ChainHOI: ``contact <= dis[object]``, hoidataset.py:224, and
    ``contact <= 0.5``, :471, on a stored per-joint distance array that is not released;
    the OMOMO model's commented-out loss, chainhoi_omomo.py:242, compares it with ``|d|``):
    a joint deeper than tau inside the object is *not* in contact. ``thresholds``: float
    or (22,).
    """
    check_option("contact_gt_rule", rule)
    d = np.asarray(distances, dtype=np.float64)
    tau = np.broadcast_to(np.asarray(thresholds, dtype=np.float64), (sk.NUM_JOINTS,))
    return np.abs(d) <= tau if rule == "unsigned" else d < tau


def select_joints(labels, joints: str = "all") -> np.ndarray:
    """Labels (T, 22) with every joint but the chosen ones off: ``all`` unchanged, ``wrists``
    keeps joints 20, 21 (ChainHOI OMOMO: ``contact_mask[:, 0:20] = 0``)."""
    check_option("contact_joints", joints)
    lab = np.asarray(labels, dtype=bool)
    if joints == "all":
        return lab
    out = np.zeros_like(lab)
    out[:, list(WRISTS)] = lab[:, list(WRISTS)]
    return out


# ===================================================================== FSR joints
def fsr_joints(joints, fps: float, frame: str = "world", feet_to_floor: bool = False,
               canonical_mode: str = "legacy-hoidiff") -> np.ndarray:
    """The joints ChainHOI's FSR test reads, (T, 22, 3) or (T - 1, 22, 3) metres.

    ``world``: as given. ``canonical``: ``decode(encode(joints))`` with the hml263 mode
    ``canonical_mode`` -- the joints the evaluated features decode to (HumanML3D's
    ``recover_from_ric``, as ChainHOI's ``human_positions``), one frame fewer.
    ``feet_to_floor``: subtract ``min_{t, f in (10, 11)} y_tf`` from the feet's heights
    (ChainHOI OMOMO, compute.py:955-967; only the feet, which is all FSR reads).
    Clips of one frame are returned as given (their FSR is 0 / 0).
    """
    check_option("fsr_frame", frame)
    J = np.asarray(joints, dtype=np.float64)
    if len(J) < 2:
        return J
    if frame == "canonical":
        from ..representations import hml263
        J = hml263.decode(hml263.encode(J, mode=canonical_mode, fps=fps))
    if feet_to_floor:
        J = J.copy()
        J[:, list(FEET), 1] -= J[:, list(FEET), 1].min()
    return J


# ===================================================================== evaluated lengths
def length_window(frames: int, rule: str, seed: int) -> tuple[int, int]:
    """``(start, length)`` of the frames the physical metrics see, for a ground-truth clip of
    ``frames`` frames (ChainHOI hoidataset.py:299-316 BEHAVE, 543-561 OMOMO).

    ``none``: ``(0, frames)``. Otherwise ``T0 = min(frames, 199)`` (``motion[:199]``); with
    probability 1/3 (``np.random.choice(['single', 'single', 'double'])``) ``L = (T0 // 4 - 1)
    * 4``, else ``L = (T0 // 4) * 4`` (unit_length 4); ``start`` uniform in ``[0, T0 - L]``
    (``random.randint``, both ends) for ``unit4_random``, 0 for ``unit4_start``. Draws come
    from ``numpy.random.default_rng(seed)`` (coin ``integers(3) == 2``, then ``start``); the
    reference's global RNG state cannot be reproduced, its distribution is. A clip too
    short for a unit keeps ``L = T0``.
    """
    check_option("length_crop", rule)
    if rule == "none":
        return 0, int(frames)
    T0 = min(int(frames), MAX_FRAMES)
    rng = np.random.default_rng(int(seed))
    double = int(rng.integers(3)) == 2
    L = (T0 // UNIT_LENGTH - (1 if double else 0)) * UNIT_LENGTH
    if L < 1:
        L = T0
    start = int(rng.integers(0, T0 - L + 1)) if rule == "unit4_random" else 0
    return start, L


def replication_windows(clip_id: str, frames: int, rule: str, replications: Sequence[int],
                        seed_for: Callable[[str, int], int]) -> tuple[tuple[int, int, int], ...]:
    """``((replication, start, length), ...)`` for one test clip: :func:`length_window` with
    ``seed_for(f"length_crop/{clip_id}", replication)`` (a protocol's
    :meth:`~hoibench.tracks.protocol.Protocol.seed_for`), so each clip and replication draws
    its own window, the same on every executor."""
    return tuple((int(r), *length_window(frames, rule, seed_for(f"length_crop/{clip_id}", int(r))))
                 for r in replications)


__all__ = ["PHYSICAL_OPTIONS", "WRISTS", "UNIT_LENGTH", "MAX_FRAMES", "CANONICAL_MODES", "check_option", "gt_labels",
           "select_joints", "fsr_joints", "length_window", "replication_windows"]
