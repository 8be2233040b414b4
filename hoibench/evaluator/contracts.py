"""What an evaluator backend's loaded object provides (:func:`hoibench.evaluator.backends.
load_evaluator` returns one): the written contracts the scorers rely on.

* :class:`TextMotionEvaluator` (kinds ``contrastive`` and the imported ``t2m``, ``chainhoi``,
  ``chois``, ``interact``): embeds motions and captions into one space, for R-precision, FID,
  MM-Dist, Diversity and MultiModality;
* :class:`ActionRecognizer` (kind ``recognizer``): recognises the action of multi-body clips
  and gives their features, for RA and FID.

``tests/test_contracts.py`` checks every registered backend's class against its contract."""
from __future__ import annotations

from typing import Any, Protocol, Sequence, runtime_checkable

import numpy as np


@runtime_checkable
class TextMotionEvaluator(Protocol):
    """``embed_motion(features) -> (N, embed_dim)`` and ``embed_text(captions, tokens) ->
    (M, embed_dim)`` in one space; ``id`` (content hash), ``card`` (its metadata),
    ``embed_dim``."""

    card: dict

    @property
    def id(self) -> str: ...

    @property
    def embed_dim(self) -> int: ...

    def embed_motion(self, features, lengths=None, batch_size: int = ...) -> np.ndarray: ...

    def embed_text(self, captions: Sequence[str], tokens=None, batch_size: int = ...) -> np.ndarray: ...


@runtime_checkable
class ActionRecognizer(Protocol):
    """``run(clips) -> (features (N, D), predicted actions)`` on multi-body clips; ``id`` and
    ``card`` (``trained_on_split``, ``store_manifest_sha256``)."""

    id: str
    card: dict

    def run(self, clips: list) -> tuple[np.ndarray, list[str]]: ...


#: the contract of each evaluator kind (a backend's ``kind``)
CONTRACTS: dict[str, Any] = {"contrastive": TextMotionEvaluator, "interact": TextMotionEvaluator,
                             "recognizer": ActionRecognizer}

__all__ = ["TextMotionEvaluator", "ActionRecognizer", "CONTRACTS"]
