"""Contrastive text-motion evaluator (docs/evaluator.md).

Modules, one job each:

``config``     sizes (``paper``, ``tiny``), variants (``human``, ``hoi``), training recipe
``text``       caption files (``DATA/texts/<id>.txt``), the offline sentence encoder, its hash
``features``   motion-branch inputs: normalised hml263 rows, object-relative rows (``hoi``)
``data``       text-motion items of a store split, the store's default protocol (``store_protocol``)
``model``      motion encoder, text branch, learned temperature, symmetric InfoNCE loss
``embed``      :class:`Evaluator`: ``embed_motion`` / ``embed_text``
``retrieval``  GT retrieval scores: R-precision top-1/2/3 in pools of 32, MM-Dist, GT-vs-GT FID
``gate``       the sanity gate: rule, re-derivation from a card, re-measurement on a store
``card``       evaluator folders: weights + card, evaluator id, verification, loading, show,
               store match (``store_mismatches``)
``errors``     one-line ``ValueError`` subclasses naming the file and field
``train``      training with checkpoints and exact resume
``commands``   ``main_train_evaluator`` / ``main_show`` for the CLI
``backends``   the registry of evaluator kinds; ``load_evaluator`` dispatches on it
``published_chainhoi``, ``chainhoi_model``  the ``chainhoi`` backend: ChainHOI's published
               MotionCLIP evaluator (import, checks, folder, loader; network, embedding API)
``safe_checkpoint``  reading published torch checkpoints with ``weights_only``
``published_t2m``  the published ``t2m`` backend (Guo et al.'s evaluator): import, load, embeddings
``t2m_text``   its GloVe vocabulary (restricted unpickler) and ``word/POS`` inputs

Typical use::

    from hoibench.evaluator import load_evaluator
    ev = load_evaluator("EVAL")                  # verifies the files, the id and the sanity gate
    m = ev.embed_motion(feats, lengths)          # (N, 512), raw hml263 rows in
    t = ev.embed_text(["a person lifts a box"])  # (N, 512)

Heavy imports (torch, transformers) happen when these names are first used.
"""
from __future__ import annotations

from importlib import import_module

_EXPORTS = {
    "EvaluatorConfig": "config", "ModelConfig": "config", "TrainConfig": "config", "preset": "config",
    "EMBED_DIM": "config",
    "Evaluator": "embed",
    "load_evaluator": "backends", "backend_of": "backends",
    "get_backend": "backends", "list_backends": "backends", "verify_folder": "card", "read_card": "card", "show": "card",
    "compute_id": "card", "store_mismatches": "card", "check_store_match": "card",
    "EvaluatorError": "errors", "EvaluatorIntegrityError": "errors", "CorruptEvaluatorFile": "errors",
    "CheckpointError": "errors", "EvaluatorFolderExists": "errors", "StoreMismatchError": "errors",
    "SanityGateError": "errors", "sanity_gate": "gate", "GateResult": "gate", "card_gate": "gate",
    "gate_from_embeddings": "gate", "recompute_gate": "gate",
    "train_evaluator": "train", "build_untrained": "train", "TrainResult": "train",
    "gt_scores": "retrieval", "retrieval_scores": "retrieval", "gt_fid_halves": "retrieval",
    "load_items": "data",
    "main_train_evaluator": "commands", "main_show": "commands",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    mod = _EXPORTS.get(name)
    if mod is None:
        raise AttributeError(f"module 'hoibench.evaluator' has no attribute {name!r}")
    value = getattr(import_module(f".{mod}", __name__), name)
    globals()[name] = value
    return value
