"""The embedding API of a trained (or freshly built) evaluator.

``Evaluator.embed_motion(features, lengths) -> (N, 512)`` and
``Evaluator.embed_text(texts, tokens=None) -> (N, 512)``: float32 numpy arrays, rows L2-normalised.
Both run batched, in eval mode, under ``torch.inference_mode`` and
``torch.use_deterministic_algorithms(True, warn_only=True)``, with torch's CPU thread
count set to ``threads`` for the duration of a call (default :data:`EMBED_THREADS` = 1).
Why fixed: on CPU the float32 results of the same batch differ by ~1e-7 between thread
counts (measured: 4.5e-8 between 1 and 2 threads on 6 clips), far below any metric's
resolution but enough to break bitwise reproducibility; with the default, the same inputs
give the same bytes on every machine. Pass ``threads=0`` to keep the caller's setting
(faster on many cores) or ``device="cuda"`` for a GPU. Motion features are the *raw* rows (hml263, or hoi269 for the
``hoi`` variant; a ``human`` evaluator also accepts hoi269 rows and uses their first 263
columns): the evaluator normalises them with the statistics named in its card. Rows past
``max_frames`` (196 by default) are dropped (the first ``max_frames`` rows are embedded).
"""
from __future__ import annotations

import contextlib
from typing import Callable, Sequence

import numpy as np
import torch

from .config import EvaluatorConfig
from .features import FeatureStats, motion_inputs
from .model import TextMotionModel

#: CPU threads used while embedding unless the Evaluator is given another count (0 = caller's).
EMBED_THREADS = 1


@contextlib.contextmanager
def deterministic(threads: int | None):
    """Deterministic torch algorithms and a fixed CPU thread count, restored on exit."""
    prev_det = torch.are_deterministic_algorithms_enabled()
    prev_warn = torch.is_deterministic_algorithms_warn_only_enabled()
    prev_threads = torch.get_num_threads()
    torch.use_deterministic_algorithms(True, warn_only=True)
    if threads:
        torch.set_num_threads(int(threads))
    try:
        yield
    finally:
        torch.use_deterministic_algorithms(prev_det, warn_only=prev_warn)
        if threads:
            torch.set_num_threads(prev_threads)


def embed_captions(texts: Sequence[str], width: int, threads: int | None, batch_size: int,
                   encode: Callable[[list[str]], torch.Tensor]) -> np.ndarray:
    """(N, width) float32 rows of ``encode`` (captions to a torch tensor of embeddings) over
    ``texts`` in batches of ``batch_size``, under :func:`deterministic` and inference mode;
    a ValueError for a single string."""
    if isinstance(texts, str):
        raise ValueError("texts: expected a list of strings, got one string")
    texts = list(texts)
    out = np.zeros((len(texts), width), np.float32)
    with deterministic(threads), torch.inference_mode():
        for s in range(0, len(texts), batch_size):
            chunk = texts[s:s + batch_size]
            out[s:s + len(chunk)] = encode(chunk).float().cpu().numpy()
    return out


def as_clip_list(features, lengths=None) -> list[np.ndarray]:
    """A list of (T_i, D) arrays from a padded (N, T, D) batch with ``lengths`` or a list."""
    if isinstance(features, torch.Tensor):
        features = features.detach().cpu().numpy()
    if isinstance(features, np.ndarray):
        if features.ndim == 2:
            features = features[None]
        if features.ndim != 3:
            raise ValueError(f"features: expected (N, T, D) or a list of (T, D), got shape {features.shape}")
        if lengths is None:
            lengths = [features.shape[1]] * len(features)
        lengths = np.asarray(lengths.detach().cpu() if isinstance(lengths, torch.Tensor) else lengths).reshape(-1)
        if len(lengths) != len(features):
            raise ValueError(f"lengths: expected {len(features)} values, got {len(lengths)}")
        out = []
        for i, n in enumerate(lengths):
            n = int(n)
            if not 1 <= n <= features.shape[1]:
                raise ValueError(f"lengths[{i}]: expected 1..{features.shape[1]}, got {n}")
            out.append(features[i, :n])
        return out
    clips = [np.asarray(f) for f in features]
    if lengths is not None:
        lengths = list(np.asarray(lengths).reshape(-1))
        if len(lengths) != len(clips):
            raise ValueError(f"lengths: expected {len(clips)} values, got {len(lengths)}")
        clips = [c[: int(n)] for c, n in zip(clips, lengths)]
    for i, c in enumerate(clips):
        if c.ndim != 2 or len(c) < 1:
            raise ValueError(f"features[{i}]: expected (T, D) rows with T >= 1, got shape {c.shape}")
    return clips


class CardBacked:
    """What every loaded evaluator reads from its card: ``id``, the ``dataset`` block and the
    ``representation`` version its motion rows must have (None: the card names none)."""

    card: dict

    @property
    def id(self) -> str | None:
        return self.card.get("evaluator_id")

    @property
    def dataset(self) -> dict:
        """The card's ``dataset`` block (name, manifest sha256, representation, splits, ...)."""
        return self.card.get("dataset", {})

    @property
    def representation(self) -> str | None:
        """Representation version the evaluator was trained on (e.g. ``hml263-clean-1.0``):
        embed features of that version only."""
        return self.dataset.get("representation")


class Evaluator(CardBacked):
    """A text-motion evaluator: model, normalisation statistics and tokenizer.

    Build one with :func:`hoibench.evaluator.load_evaluator` (from a verified folder) or
    :func:`hoibench.evaluator.build_untrained` (random weights: tests and the sanity gate).

    A loaded evaluator builds its text branch (the pretrained transformer and its tokenizer:
    importing ``transformers`` and reading the encoder's weights, seconds on a CPU) on first
    text use: ``model=None`` with ``motion`` (the loaded motion branch, used by
    :meth:`embed_motion`) and ``load_text() -> (model, tokenizer)``, whose model shares that
    motion branch. An evaluation whose ground-truth statistics are cached embeds no text.
    """

    def __init__(self, config: EvaluatorConfig, model: TextMotionModel | None, tokenizer, stats: FeatureStats,
                 card: dict | None = None, threads: int | None = None, device: str | torch.device = "cpu",
                 motion: torch.nn.Module | None = None,
                 load_text: Callable[[], tuple[TextMotionModel, object]] | None = None):
        if model is None and (motion is None or load_text is None):
            raise ValueError("Evaluator: give the model, or the motion branch and load_text")
        self.config = config
        self.device = torch.device(device)
        self._model = None if model is None else model.to(self.device).eval()
        self._motion = (model.motion if motion is None else motion).to(self.device).eval()
        self._tokenizer = tokenizer
        self._load_text = load_text
        self.stats = stats
        self.card = card or {}
        self.threads = EMBED_THREADS if threads is None else threads

    @property
    def model(self) -> TextMotionModel:
        """The whole model (motion and text branches); built here on first use when the
        evaluator was loaded with a deferred text branch."""
        if self._model is None:
            model, self._tokenizer = self._load_text()
            self._model = model.to(self.device).eval()
        return self._model

    @property
    def tokenizer(self):
        if self._model is None:
            self.model                     # builds the text branch and its tokenizer
        return self._tokenizer

    @property
    def variant(self) -> str:
        return self.config.model.variant

    @property
    def embed_dim(self) -> int:
        return self.config.model.embed_dim

    # ------------------------------------------------------------------ motion
    def prepare_motion(self, clips: Sequence[np.ndarray],
                       crop: bool = True) -> list[tuple[np.ndarray, np.ndarray | None]]:
        """Normalised (body, object) rows of raw clips (the first ``max_frames`` rows when ``crop``)."""
        m = self.config.model.max_frames if crop else None
        return [motion_inputs(c[:m], self.variant, self.stats) for c in clips]

    def _motion_batch(self, prepared, crops=None):
        """Padded tensors from prepared (body, obj) pairs; ``crops`` (start offsets) or first rows."""
        m = self.config.model.max_frames
        rows = []
        for i, (body, obj) in enumerate(prepared):
            a = 0 if crops is None else int(crops[i])
            rows.append((body[a:a + m], None if obj is None else obj[a:a + m]))
        T = max(len(b) for b, _ in rows)
        B = len(rows)
        body = np.zeros((B, T, rows[0][0].shape[1]), np.float32)
        obj = np.zeros((B, T, rows[0][1].shape[1]), np.float32) if rows[0][1] is not None else None
        lengths = np.zeros(B, np.int64)
        for i, (b, o) in enumerate(rows):
            body[i, :len(b)] = b
            lengths[i] = len(b)
            if obj is not None:
                obj[i, :len(o)] = o
        dev = self.device
        return (torch.from_numpy(body).to(dev), torch.from_numpy(lengths).to(dev),
                None if obj is None else torch.from_numpy(obj).to(dev))

    def embed(self, features, lengths=None, batch_size: int = 64) -> np.ndarray:
        """The evaluator's motion embedding (:meth:`embed_motion`)."""
        return self.embed_motion(features, lengths, batch_size)

    def embed_motion(self, features, lengths=None, batch_size: int = 64) -> np.ndarray:
        """(N, 512) float32 embeddings of raw feature rows: a padded (N, T, D) array with
        ``lengths`` (N,), or a list of (T_i, D) arrays."""
        clips = as_clip_list(features, lengths)
        out = np.zeros((len(clips), self.embed_dim), np.float32)
        with deterministic(self.threads), torch.inference_mode():
            self._motion.eval()
            for s in range(0, len(clips), batch_size):
                prepared = self.prepare_motion(clips[s:s + batch_size])
                body, lens, obj = self._motion_batch(prepared)
                out[s:s + len(prepared)] = self._motion(body, lens, obj).float().cpu().numpy()
        return out

    # ------------------------------------------------------------------ text
    def tokenize(self, texts: Sequence[str]) -> dict:
        b = self.tokenizer(list(texts), padding=True, truncation=True,
                           max_length=self.config.model.text_max_tokens, return_tensors="pt")
        return {k: v.to(self.device) for k, v in b.items() if k in ("input_ids", "attention_mask", "token_type_ids")}

    def embed_text(self, texts: Sequence[str], tokens=None, batch_size: int = 128) -> np.ndarray:
        """(N, 512) float32 embeddings of captions. ``tokens`` (HumanML3D ``word/POS`` lists,
        read by the published ``t2m`` evaluator) is accepted for a uniform call and ignored:
        this evaluator reads the caption text."""
        self.model.eval()
        return embed_captions(texts, self.embed_dim, self.threads, batch_size,
                              lambda chunk: self.model.text.project(self.model.text.pooled(self.tokenize(chunk))))
