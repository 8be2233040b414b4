"""InterAct's test loader: which clips its released evaluation scores, and in which order.

InterAct (Xu et al., CVPR 2025) evaluates text-to-interaction generation with
``text2interaction/eval/eval_marker_representation.py`` over the test loader built by
``text2interaction/data_loaders/get_data.py`` and ``data_loaders/behave/data/dataset.py``
(GitHub ``wzyabcas/InterAct`` @ ``daa7945``). What reaches the metric loop
(:func:`hoibench.metrics.legacy_loops.interact_loop`) is decided there:

* **sources** (``Behave.__init__``, ``dataset == 'interact'``): the sub-datasets are read in the
  order ``neuraldome, chairs, omomo, imhd, grab, behave, intercap`` (:data:`SOURCES`);
* **split**: a sequence is a test item when its folder name is in ``test_seq.txt`` (the
  sequence split; ``test.txt`` with ``--obj_split``, which ``scripts/eval.sh`` does not pass);
* **length cut** (``TextOnlyDataset.__init__``): a sequence of fewer than 40 frames or more
  than 300 (``len(motion) < 40 or len(motion) > 300``) is skipped, never cropped
  (:data:`MIN_FRAMES`, :data:`MAX_FRAMES`; frames at InterAct's 30 fps);
* **order**: the kept sequences, in ``os.listdir`` order per source, are sorted by length,
  ascending (Python's stable ``sorted`` on the length alone); the loader iterates them in that
  order (``shuffle=False``), batches of 64 with ``drop_last`` (``scripts/eval.sh``,
  ``get_data.py`` L80-84) and the collate function (``t2m_behave_bps_collate``) keeps it.

``os.listdir`` order depends on the filesystem; :func:`loader_rows` breaks length ties by
source order, then sequence name, which is the loader's order on a filesystem that lists
names sorted (and the order the scratch reference run used, its ``os.listdir`` sorted).
Clip ids are hoibench's InterAct ids, ``<source>-<sequence>`` (:mod:`hoibench.datasets.interact`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

__all__ = ["SOURCES", "MIN_FRAMES", "MAX_FRAMES", "LoaderRows", "loader_rows", "split_id"]

#: InterAct's sub-datasets in the order its loader reads them (``dataset.py``, ``dataset == 'interact'``)
SOURCES: tuple[str, ...] = ("neuraldome", "chairs", "omomo", "imhd", "grab", "behave", "intercap")
#: the loader keeps sequences of MIN_FRAMES..MAX_FRAMES frames, inclusive (``TextOnlyDataset``)
MIN_FRAMES = 40
MAX_FRAMES = 300


@dataclass(frozen=True)
class LoaderRows:
    """The rows InterAct's test loader scores: ``order`` (indices into the inputs, in loader
    order) and ``dropped`` (``{clip id: reason}`` for every row it skips)."""

    order: np.ndarray
    dropped: dict[str, str] = field(default_factory=dict)


def split_id(clip_id: str) -> tuple[str, str]:
    """``"<source>-<sequence>"`` -> ``(source, sequence)``; ValueError naming the id when the
    source is not one of :data:`SOURCES`."""
    source, sep, name = str(clip_id).partition("-")
    if not sep or source not in SOURCES or not name:
        raise ValueError(f"clip id {clip_id!r}: expected '<source>-<sequence>' with a source of "
                         f"{', '.join(SOURCES)} (hoibench's InterAct ids)")
    return source, name


def loader_rows(ids: Sequence[str], lengths: Sequence[int], *, min_frames: int = MIN_FRAMES,
                max_frames: int = MAX_FRAMES) -> LoaderRows:
    """The rows InterAct's test loader keeps and their order (module docstring): rows with
    ``min_frames <= length <= max_frames``, sorted by (length, source rank, sequence name)."""
    ids = [str(i) for i in ids]
    lengths = np.asarray(lengths)
    if lengths.shape != (len(ids),) or not np.issubdtype(lengths.dtype, np.integer):
        raise ValueError(f"lengths: expected {len(ids)} integer frame counts, got shape {lengths.shape} "
                         f"dtype {lengths.dtype}")
    if not 0 < min_frames <= max_frames:
        raise ValueError(f"min_frames, max_frames: expected 0 < min <= max, got {min_frames}, {max_frames}")
    keys, dropped = [], {}
    for i, (cid, n) in enumerate(zip(ids, lengths.tolist())):
        source, name = split_id(cid)
        if n < min_frames:
            dropped[cid] = f"{n} frames < {min_frames}"
        elif n > max_frames:
            dropped[cid] = f"{n} frames > {max_frames}"
        else:
            keys.append((n, SOURCES.index(source), name, i))
    order = np.array([k[-1] for k in sorted(keys)], dtype=np.int64)
    return LoaderRows(order, dropped)
