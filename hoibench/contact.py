"""Contacts between the body and the object: distances, per-joint labels, timelines.

Timelines turn per-joint, per-frame labels (T, 22) into segments per body part; the
annotator describes the segments, and ignores *transitions* (segments shorter than
``min_frames``, 5 by default), which are kept so nothing is lost but are never described.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Mapping, Sequence

import numpy as np

from . import skeleton as sk


@dataclass(frozen=True)
class ContactSegment:
    """Frames ``[start, end)`` during which ``part`` touches the object."""

    part: str
    start: int
    end: int
    transition: bool          # shorter than the timeline's min_frames: kept, not described

    @property
    def num_frames(self) -> int:
        return self.end - self.start

    def seconds(self, fps: float) -> tuple[float, float]:
        return self.start / fps, self.end / fps

    def to_dict(self) -> dict:
        return asdict(self)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) runs of True in a 1-D boolean array."""
    padded = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]])
    edges = np.flatnonzero(np.diff(padded.astype(np.int8)))
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2])]


def contact_timeline(labels: np.ndarray, parts: Mapping[str, Sequence[int]] | None = None,
                     min_frames: int = 5) -> list[ContactSegment]:
    """Segments per body part from per-joint contact labels.

    Args:
        labels: (T, 22) bool, joint j of frame t touches the object.
        parts: part name -> joints; a part is in contact on a frame when any of its joints
            is. Default: :data:`hoibench.skeleton.BODY_PARTS`.
        min_frames: segments shorter than this are marked ``transition``.

    Returns:
        Segments sorted by (start, part).
    """
    lab = np.asarray(labels)
    if lab.ndim != 2 or lab.shape[1] != sk.NUM_JOINTS:
        raise ValueError(f"labels: expected shape (T, 22), got {lab.shape}")
    if lab.dtype != bool:
        raise ValueError(f"labels: expected bool, got {lab.dtype}")
    parts = sk.BODY_PARTS if parts is None else parts
    segs = []
    for name, joints in parts.items():
        for a, b in _runs(lab[:, list(joints)].any(axis=1)):
            segs.append(ContactSegment(name, a, b, (b - a) < min_frames))
    return sorted(segs, key=lambda s: (s.start, s.part))
