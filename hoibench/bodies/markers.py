"""InterAct's 77 body-surface markers: fixed vertex ids on the SMPL-H and SMPL-X meshes.

InterAct (Xu et al., CVPR 2025) represents the human of every sequence by 77 vertices of the
posed body mesh (a marker set in the style of MoSh/GRAB: head, torso, arms, hands, legs and
feet), taken from the SMPL-H mesh (6890 vertices) for BEHAVE, NeuralDome and IMHD and from
the SMPL-X mesh (10475 vertices) for GRAB, InterCap, CHAIRS and OMOMO. The two id lists
below mark the same 77 anatomical places on the two topologies, in the same order, so a
marker array ``(T, 77, 3)`` means the same thing whichever model posed the body.

The ids are the ``markerset_smplh`` / ``markerset_smplx`` lists of InterAct's public code
(``process/markerset.py``, repeated in ``text2interaction/utils/markerset.py``; GitHub
``wzyabcas/InterAct``, commit ``daa7945``): mesh-topology facts (vertex indices), copied as
numbers. ``tests/test_interact_evaluator.py`` compares their hash with the lists of that
file; ``tests/test_interact_prepare.py`` checks that prepared clips carry the vertices at
these ids of the independently posed meshes.
"""
from __future__ import annotations

import numpy as np

#: marker vertex ids on the SMPL-H mesh (6890 vertices)
MARKERS_SMPLH: tuple[int, ...] = (
    3470, 3171, 3327, 857, 1812, 628, 182, 3116, 3040, 239, 1666, 1725, 0, 2174, 1568, 1368, 3387, 2112,
    1053, 1058, 3336, 3346, 1323, 2108, 3122, 3314, 1252, 1082, 1861, 1454, 850, 2224, 3233, 1769, 6728,
    4343, 5273, 4116, 3694, 6399, 6540, 6488, 3749, 5135, 5194, 3512, 5635, 5210, 4360, 4841, 6786, 5573,
    4538, 4544, 6736, 6747, 4804, 5568, 6544, 6682, 5322, 4927, 5686, 4598, 6633, 3506, 3508, 6191, 5782,
    5905, 6016, 6133, 2746, 2319, 2445, 2556, 2673)

#: marker vertex ids on the SMPL-X mesh (10475 vertices), same places and order
MARKERS_SMPLX: tuple[int, ...] = (
    5920, 5621, 5882, 3486, 4430, 3258, 2029, 5694, 5645, 9117, 4302, 4319, 707, 4788, 4198, 3998, 8846,
    4726, 3682, 3688, 5890, 5901, 3961, 4722, 5698, 5868, 3892, 3712, 4479, 4088, 3477, 4839, 5787, 4291,
    8576, 6248, 7166, 6021, 3067, 8250, 8388, 8339, 3116, 7040, 7099, 2198, 7524, 7115, 6265, 6746, 8634,
    7462, 6443, 6449, 8584, 8595, 6709, 7458, 8392, 8527, 7215, 6832, 7575, 6503, 8481, 5945, 5947, 8079,
    7669, 7794, 7905, 8022, 5361, 4933, 5058, 5169, 5286)

NUM_MARKERS = 77

#: vertex count -> marker ids (the topology is recognised by its vertex count)
MARKER_IDS = {6890: MARKERS_SMPLH, 10475: MARKERS_SMPLX}


def marker_ids(num_vertices: int) -> np.ndarray:
    """The 77 marker vertex ids for a mesh of ``num_vertices`` (6890: SMPL-H, 10475: SMPL-X)."""
    ids = MARKER_IDS.get(int(num_vertices))
    if ids is None:
        raise ValueError(f"markers: a body mesh with {num_vertices} vertices has no InterAct marker set "
                         f"(SMPL-H has 6890, SMPL-X 10475)")
    return np.asarray(ids, dtype=np.int64)


def markers_from_vertices(vertices: np.ndarray) -> np.ndarray:
    """``(..., 77, 3)`` marker positions (metres, the vertices' frame) from posed vertices
    ``(..., V, 3)`` of an SMPL-H or SMPL-X mesh (the proxy body's meshes have the same counts)."""
    v = np.asarray(vertices)
    if v.ndim < 2 or v.shape[-1] != 3:
        raise ValueError(f"markers: expected vertices (..., V, 3), got shape {v.shape}")
    return v[..., marker_ids(v.shape[-2]), :]


__all__ = ["MARKERS_SMPLH", "MARKERS_SMPLX", "NUM_MARKERS", "MARKER_IDS", "marker_ids", "markers_from_vertices"]
