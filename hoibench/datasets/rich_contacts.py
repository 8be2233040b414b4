"""RICH's per-vertex contact labels -> per-joint contacts (step 5 of :mod:`hoibench.datasets.rich`).

RICH labels SMPL's 6890 vertices. Every vertex goes to the joint of its largest skinning
weight (:func:`vertex_joint_map`; hands and fingers to their wrist, SMPL-X face joints to the
head) and a joint touches when any of its vertices does (:func:`joint_contacts`, OR). The
weights come from SMPL-topology model files under ``body_models`` or from SMPL-X's weights
carried to SMPL topology by SMPL-X's deformation transfer setup, ``W = M W_x``
(:func:`contact_joint_map`).
"""
from __future__ import annotations

import pickle
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..core.skeleton import NUM_JOINTS
from .behave import SequenceError

__all__ = ["SMPL_NUM_VERTICES", "SMPLX_NUM_VERTICES", "DEFTRAFO_PATHS", "ContactMapUnavailable", "vertex_joint_map",
           "joint_contacts", "read_deftrafo", "contact_joint_map"]

SMPL_NUM_VERTICES = 6890


def vertex_joint_map(weights) -> np.ndarray:
    """(V, J) skinning weights -> (V,) index in 0..21 of the joint each vertex moves with most.

    J = 24 (SMPL: hands 22/23 -> wrists 20/21), 52 (SMPL-H: fingers 22-36 -> 20, 37-51 -> 21),
    55 (SMPL-X: jaw/eyes 22-24 -> head 15, fingers 25-39 -> 20, 40-54 -> 21) or 22.
    Ties go to the lower joint index (``argmax``).
    """
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim != 2 or w.shape[1] not in (22, 24, 52, 55):
        raise ValueError(f"weights: expected (V, J) with J in 22, 24, 52, 55, got {w.shape}")
    j = w.argmax(1)
    fold = np.arange(w.shape[1])
    if w.shape[1] == 24:
        fold[22], fold[23] = 20, 21
    elif w.shape[1] == 52:
        fold[22:37], fold[37:52] = 20, 21
    elif w.shape[1] == 55:
        fold[22:25], fold[25:40], fold[40:55] = 15, 20, 21
    return fold[j]


def joint_contacts(vertex_labels, vmap) -> np.ndarray:
    """(T, V) per-vertex contact labels + (V,) vertex->joint map -> (T, 22) bool: a joint is
    in contact when any of its vertices is (OR)."""
    lab = np.asarray(vertex_labels) > 0
    vmap = np.asarray(vmap)
    if lab.shape[-1] != len(vmap):
        raise ValueError(f"vertex_labels: {lab.shape[-1]} vertices, the map has {len(vmap)}")
    onehot = np.zeros((len(vmap), NUM_JOINTS), dtype=np.float32)
    onehot[np.arange(len(vmap)), vmap] = 1.0
    return (lab.astype(np.float32) @ onehot) > 0


#: Where SMPL-X's deformation-transfer setup (SMPL-X vertices -> SMPL vertices; smplx's
#: ``transfer_model``, a download from the SMPL-X site) is looked for, under ``body_models``.
DEFTRAFO_PATHS = ("transfer_data/smplx2smpl_deftrafo_setup.pkl", "model_transfer/smplx2smpl_deftrafo_setup.pkl",
                  "smplx2smpl_deftrafo_setup.pkl", "smplx/smplx2smpl_deftrafo_setup.pkl")
SMPLX_NUM_VERTICES = 10475


class ContactMapUnavailable(SequenceError):
    """No model files under ``body_models`` give RICH's SMPL-topology labels a joint."""


def _npz_weights(root: Path, model_type: str, shape: tuple) -> tuple[np.ndarray, str] | None:
    """Skinning weights of the first ``<model_type>/<PREFIX>_<GENDER>.npz`` under ``root``
    whose ``weights`` start with ``shape`` (read without pickles), and the file's name."""
    from ..bodies.smpl import MODEL_FILE_PREFIX
    for g in ("NEUTRAL", "MALE", "FEMALE"):
        p = root / model_type / f"{MODEL_FILE_PREFIX[model_type]}_{g}.npz"
        if p.is_file():
            try:
                with np.load(p, allow_pickle=False) as z:  # read-ok: the user's body model file (is_file checked)
                    w = np.asarray(z["weights"], dtype=np.float64)
                if w.shape[:len(shape)] == shape:
                    return w, f"{model_type}/{p.name}"
            except Exception:
                pass
    return None


def _smpl_topology_weights(root: Path) -> tuple[np.ndarray, str] | None:
    """(6890, J) skinning weights of an SMPL-H ``.npz`` (read without pickles) or, through
    ``smplx``, of SMPL-H / SMPL model files under ``root``; None when there are none."""
    found = _npz_weights(root, "smplh", (SMPL_NUM_VERTICES,))
    if found is not None:
        return found
    from ..bodies.smpl import load_body_model
    for mt in ("smplh", "smpl"):
        for g in ("neutral", "male", "female"):
            try:
                model = load_body_model(root, mt, g)
            except Exception:
                continue
            w = model.lbs_weights.detach().cpu().numpy().astype(np.float64)
            if w.shape[0] == SMPL_NUM_VERTICES:
                return w, f"{mt} {g}"
    return None


def read_deftrafo(path: str | Path) -> np.ndarray:
    """SMPL-X -> SMPL deformation transfer (``smplx2smpl_deftrafo_setup.pkl``) as a dense
    (6890, 10475) matrix: SMPL vertex ``i`` = ``M[i] @`` SMPL-X vertices. The file is a
    pickle (the user's own download from the SMPL-X site) holding ``mtx`` (sparse, vertex
    columns then normal columns, of which the first half is kept) or ``matrix``."""
    from ..core.io import check_regular_file
    path = Path(path)
    check_regular_file(path, "deformation transfer setup")
    try:
        with open(path, "rb") as fh:  # read-ok: SMPL-X's own pickle, own download (docs/security.md)
            setup = pickle.load(fh, encoding="latin1")  # read-ok: SMPL-X's own pickle, own download
        mat = setup["mtx"] if "mtx" in setup else setup["matrix"]
        mat = np.asarray(mat.todense() if hasattr(mat, "todense") else mat, dtype=np.float64)
    except Exception as exc:
        raise ValueError(f"{path}: expected smplx's deformation transfer setup (a pickled dict with 'mtx' "
                         f"or 'matrix'): {type(exc).__name__}: {exc}") from None
    if mat.ndim == 2 and mat.shape == (SMPL_NUM_VERTICES, 2 * SMPLX_NUM_VERTICES):
        mat = mat[:, :SMPLX_NUM_VERTICES]
    if mat.shape != (SMPL_NUM_VERTICES, SMPLX_NUM_VERTICES) or not np.isfinite(mat).all():
        raise ValueError(f"{path}: expected a finite ({SMPL_NUM_VERTICES}, {SMPLX_NUM_VERTICES}) matrix "
                         f"(SMPL-X -> SMPL), got {mat.shape}")
    return mat


def _smplx_weights(root: Path) -> tuple[np.ndarray, str] | None:
    """(10475, 55) SMPL-X skinning weights from the first SMPL-X file under ``root/smplx``
    (``.npz`` read without pickles, else through ``smplx``), or None."""
    found = _npz_weights(root, "smplx", (SMPLX_NUM_VERTICES, 55))
    if found is not None:
        return found
    from ..bodies.smpl import load_body_model
    for g in ("neutral", "male", "female"):
        try:
            w = load_body_model(root, "smplx", g).lbs_weights.detach().cpu().numpy().astype(np.float64)
        except Exception:
            continue
        if w.shape == (SMPLX_NUM_VERTICES, 55):
            return w, f"smplx {g}"
    return None


@lru_cache(maxsize=4)
def contact_joint_map(body_models: str) -> tuple[np.ndarray, str]:
    """(6890,) joint 0..21 of every SMPL vertex (:func:`vertex_joint_map`) and where it came
    from, for RICH's SMPL-topology contact labels. In order:

    1. SMPL-H or SMPL model files under ``body_models`` (``smplh/``, ``smpl/``): their own
       skinning weights;
    2. SMPL-X files (``smplx/``) and SMPL-X's deformation transfer setup
       (:data:`DEFTRAFO_PATHS`): SMPL-X's weights carried to SMPL topology, ``W = M W_x``
       (each SMPL vertex takes the weights of the SMPL-X surface point it corresponds to);
    3. neither: :class:`ContactMapUnavailable`, naming the files to add.
    """
    root = Path(body_models)
    found = _smpl_topology_weights(root)
    if found is not None:
        return vertex_joint_map(found[0]), f"skinning weights of {found[1]}"
    xw = _smplx_weights(root)
    trafo = next((root / p for p in DEFTRAFO_PATHS if (root / p).is_file()), None)
    if xw is not None and trafo is not None:
        try:
            M = read_deftrafo(trafo)
        except ValueError as exc:
            raise ContactMapUnavailable(str(exc)) from None
        return (vertex_joint_map(M @ xw[0]),
                f"skinning weights of {xw[1]} carried to SMPL topology by {trafo.relative_to(root)}")
    raise ContactMapUnavailable(
        f"RICH's contact labels are on SMPL's 6890 vertices; to give them a joint, put under {root} either "
        f"SMPL-H or SMPL model files (smplh/SMPLH_<GENDER>.npz or smpl/SMPL_<GENDER>.pkl) or SMPL-X's "
        f"deformation transfer setup (transfer_data/smplx2smpl_deftrafo_setup.pkl, from the SMPL-X "
        f"site's model transfer download) next to smplx/")
