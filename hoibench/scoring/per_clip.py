"""The per-test-clip table of a result (``result["per_clip"]``): one row per scored test id,
for finding a submission's failure cases (``hoibench render RESULT --worst K --by COLUMN``).

Each row describes the submission's sample ``s`` (the one replication 0 scores: sample 0)
of one test id:

- ``mm_dist``: mean Euclidean distance (evaluator embedding units) between the sample's
  motion embedding and the embeddings of the clip's captions; ``gt_mm_dist`` the same for
  the real motion (a clip whose text is hard for the evaluator has a large one too);
- ``text_rank``: 1 + the number of other scored clips whose captions are nearer (same mean
  distance) to the sample than its own: 1 = retrieved first among all scored texts;
- the physical metrics of that sample alone (:meth:`hoibench.metrics.physical.
  PhysicalMetrics.per_clip`): ``cd`` and ``ocd`` (m^2), ``ps``, ``fsr``, ``fsr_gmd``,
  ``jitter_mps3`` (m/s^3), ``penetration_depth_max_m`` and ``penetration_depth_mean_m`` (m),
  ``contact_iou``, ``hand_contact_ratio``, ``object_floating_ratio``; ``null`` where undefined
  (no contact frames, no object).
"""
from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from ..metrics.catalog import METRICS


def physical_columns(present: set[str] = frozenset()) -> tuple[str, ...]:
    """The physical per-clip columns of the catalogue (``per_clip``): every built-in one, and
    those computed by a per-clip function (``clip_fn``) when ``present``."""
    return tuple(n for n, i in METRICS.items() if i.per_clip and i.kind == "physical"
                 and (not i.clip_fn or n in present))


def sortable_columns() -> dict[str, bool]:
    """``{column: worse when high}`` for the per-clip columns with a failure end."""
    return {n: i.failure_end == "high" for n, i in METRICS.items() if i.per_clip and i.failure_end}


def _clean(v) -> float | None:
    v = float(v)
    return None if math.isnan(v) or math.isinf(v) else v


def caption_distances(motions: np.ndarray, text_sets: Sequence[np.ndarray]) -> np.ndarray:
    """``D[i, j]`` = mean over clip j's captions c of ``||motions[i] - c||`` (N x N)."""
    caps = np.concatenate([np.asarray(t, np.float64) for t in text_sets])
    m = np.asarray(motions, np.float64)
    sq = (m ** 2).sum(1)[:, None] + (caps ** 2).sum(1)[None, :] - 2.0 * m @ caps.T
    dist = np.sqrt(np.maximum(sq, 0.0))
    bounds = np.cumsum([0] + [len(t) for t in text_sets])
    return np.stack([dist[:, a:b].mean(1) for a, b in zip(bounds[:-1], bounds[1:])], axis=1)


def per_clip_table(ids: Sequence[str], motions: np.ndarray, real: np.ndarray, text_sets: Sequence[np.ndarray],
                   physical: Mapping[str, Mapping[str, float]], sample: int) -> dict:
    """The ``per_clip`` block: ``{"sample", "rows": [{"id", "mm_dist", "gt_mm_dist",
    "text_rank", <physical columns>}, ...]}`` in ``ids`` order (``motions``, ``real``,
    ``text_sets``: aligned with ``ids``; ``physical``: per-clip physical values by id)."""
    d = caption_distances(motions, text_sets)
    d_gt = caption_distances(real, text_sets)
    own = np.diag(d)
    ranks = 1 + (d < own[:, None]).sum(1)
    rows = []
    columns = physical_columns({c for row in physical.values() for c in row})
    for i, cid in enumerate(ids):
        row = {"id": cid, "mm_dist": _clean(own[i]), "gt_mm_dist": _clean(d_gt[i, i]), "text_rank": int(ranks[i])}
        phys = physical.get(cid, {})
        row.update({c: (_clean(phys[c]) if c in phys else None) for c in columns})
        rows.append(row)
    return {"sample": int(sample), "clips": len(rows), "rows": rows}


def check_worst_args(k: int, by: str) -> None:
    """ValueError for a ``--by`` that is no per-clip column or a ``--worst`` below 1."""
    if by not in sortable_columns():
        raise ValueError(f"--by {by!r}: expected one of {', '.join(sorted(sortable_columns()))}")
    if k < 1:
        raise ValueError(f"--worst {k}: expected a positive number of clips")


def worst(result: dict, k: int, by: str = "mm_dist", where: str = "result") -> list[dict]:
    """The ``k`` rows of ``result["per_clip"]`` at the failure end of column ``by`` (ties by
    id); rows where ``by`` is undefined are left out. ValueError naming what is missing."""
    check_worst_args(k, by)
    table = result.get("per_clip")
    if not isinstance(table, dict) or not isinstance(table.get("rows"), list):
        raise ValueError(f"{where}: field per_clip: absent (a result written before per-clip tables, or by "
                         f"another scorer); evaluate the submission again to get one")
    rows = [r for r in table["rows"] if isinstance(r, dict) and isinstance(r.get(by), (int, float))]
    sign = -1.0 if sortable_columns()[by] else 1.0
    return sorted(rows, key=lambda r: (sign * float(r[by]), str(r.get("id"))))[:k]


__all__ = ["physical_columns", "sortable_columns", "caption_distances", "per_clip_table", "check_worst_args", "worst"]
