"""Text side of the published ``t2m`` evaluator: GloVe vocabulary and ``word/POS`` inputs.

Guo et al.'s text encoder (text-to-motion, ``utils/word_vectorizer.py`` and
``data/dataset.py``) reads a caption as HumanML3D ``word/POS`` tokens and turns each into a
300-d GloVe vector plus a 15-slot part-of-speech one-hot:

* slots 0-8: ``VERB NOUN DET ADP NUM AUX PRON ADJ ADV``; 9-13: five lists of "very important"
  words (location, body part, object, action, description) whose membership overrides the
  tagged POS (the first list holding the word wins, in that order); 14: ``OTHER`` (any other
  tag, and every word not in the vocabulary);
* a word not in the vocabulary gets the ``unk`` vector and the ``OTHER`` slot;
* the sequence is ``sos/OTHER`` + the first :data:`MAX_TOKENS` (20) tokens + ``eos/OTHER``
  (``length`` = its number of tokens, at most 22), padded with ``unk/OTHER`` to 22 rows (the
  padding never reaches the encoder: sequences are packed by length).

The published vocabulary is three files of ``glove/``: ``our_vab_data.npy`` (V x 300
vectors), ``our_vab_words.pkl`` (list of words) and ``our_vab_idx.pkl`` (dict word -> row).
The pickles are read with :func:`read_plain_pickle`, which admits only lists, dicts,
strings and integers: a pickle that names any class or function (the way pickles run code)
is refused before anything is built. The importer stores the vocabulary as plain data
(vectors in safetensors, words in the card), so loading an evaluator never unpickles.
"""
from __future__ import annotations

import io
import pickle
from pathlib import Path
from typing import Sequence

import numpy as np

from ..core.io import read_regular_file
from .errors import EvaluatorError, read_evaluator_file

#: part-of-speech slots of the one-hot, in order (text-to-motion's ``POS_enumerator``)
POS_SLOTS = ("VERB", "NOUN", "DET", "ADP", "NUM", "AUX", "PRON", "ADJ", "ADV",
             "Loc_VIP", "Body_VIP", "Obj_VIP", "Act_VIP", "Desc_VIP", "OTHER")
#: words whose slot is fixed whatever their tag (checked in this order; first match wins)
VIP_WORDS: tuple[tuple[str, frozenset[str]], ...] = (
    ("Loc_VIP", frozenset("left right clockwise counterclockwise anticlockwise forward back backward up down "
                          "straight curve".split())),
    ("Body_VIP", frozenset("arm chin foot feet face hand mouth leg waist eye knee shoulder thigh".split())),
    ("Obj_VIP", frozenset("stair dumbbell chair window floor car ball handrail baseball basketball".split())),
    ("Act_VIP", frozenset("walk run swing pick bring kick put squat throw hop dance jump turn stumble stop sit "
                          "lift lower raise wash stand kneel stroll rub bend balance flap jog shuffle lean rotate "
                          "spin spread climb".split())),
    ("Desc_VIP", frozenset("slowly carefully fast careful slow quickly happy angry sad happily angrily "
                           "sadly".split())),
)
#: tokens kept from a caption (longer ones are cropped), and the padded sequence length
MAX_TOKENS = 20
SEQ_LEN = MAX_TOKENS + 2
SPECIAL_WORDS = ("sos", "eos", "unk")
GLOVE_FILES = ("our_vab_data.npy", "our_vab_words.pkl", "our_vab_idx.pkl")
WORD_DIM = 300
#: size limits of the vocabulary files (the published ones: 0.4 MB data, 80 KB pickles)
MAX_PICKLE_BYTES = 64 * 1024 ** 2
MAX_VECTORS_BYTES = 2 * 1024 ** 3


class _PlainUnpickler(pickle.Unpickler):
    """An unpickler that resolves no global: classes and functions (what ``__reduce__``
    payloads call) are refused, so only built-in containers and scalars can come out."""

    def find_class(self, module: str, name: str):
        raise pickle.UnpicklingError(f"refers to {module}.{name}; only lists, dicts, strings and integers are "
                                     f"accepted")

    def persistent_load(self, pid):
        raise pickle.UnpicklingError("holds a persistent reference; only plain data is accepted")


def _check_plain(obj, path: Path, depth: int = 0) -> None:
    if depth > 4:
        raise EvaluatorError(f"{path}: nested deeper than a vocabulary file is")
    if isinstance(obj, bool) or not isinstance(obj, (list, dict, str, int)):
        raise EvaluatorError(f"{path}: holds a {type(obj).__name__}; only lists, dicts, strings and integers "
                             f"are accepted")
    items = [x for kv in obj.items() for x in kv] if isinstance(obj, dict) else obj if isinstance(obj, list) else ()
    for item in items:
        _check_plain(item, path, depth + 1)


def read_plain_pickle(path: str | Path):
    """The lists/dicts/strings/integers pickled in ``path``; :class:`EvaluatorError` (one
    line, naming the file) for anything else, raised before any object of another type is
    created or any code runs."""
    path = Path(path)
    if not path.is_file():
        raise EvaluatorError(f"{path}: is missing")
    raw = read_evaluator_file(path, MAX_PICKLE_BYTES, "vocabulary pickle")
    try:
        obj = _PlainUnpickler(io.BytesIO(raw)).load()
    except pickle.UnpicklingError as exc:
        raise EvaluatorError(f"{path}: refused: {exc}") from None
    except Exception as exc:                        # truncated or not a pickle at all
        raise EvaluatorError(f"{path}: not a readable pickle ({type(exc).__name__}: "
                             f"{' '.join(str(exc).split())[:120]})") from None
    _check_plain(obj, path)
    return obj


def read_glove(folder: str | Path) -> tuple[list[str], np.ndarray]:
    """(words, vectors) of a published ``glove/`` folder: ``vectors[i]`` is the vector of
    ``words[i]`` (``our_vab_data.npy`` rows picked by ``our_vab_idx.pkl``), words in the order
    of ``our_vab_words.pkl`` without repeats, float dtype as stored. One-line errors name the
    missing or malformed file."""
    folder = Path(folder)
    if not folder.is_dir():
        raise EvaluatorError(f"--glove {folder}: not a folder (expected text-to-motion's glove/ with "
                             f"{', '.join(GLOVE_FILES)})")
    for name in GLOVE_FILES:
        if not (folder / name).is_file():
            raise EvaluatorError(f"--glove {folder}: {name} is missing (text-to-motion's glove/ holds "
                                 f"{', '.join(GLOVE_FILES)})")
    vpath = folder / GLOVE_FILES[0]
    try:
        vectors = np.load(io.BytesIO(read_regular_file(vpath, MAX_VECTORS_BYTES, "GloVe vectors")),
                          allow_pickle=False)
    except ValueError as exc:
        raise EvaluatorError(f"{vpath}: not a readable .npy of vectors ({' '.join(str(exc).split())[:120]})") \
            from None
    if vectors.ndim != 2 or vectors.shape[1] != WORD_DIM or vectors.dtype not in (np.float32, np.float64):
        raise EvaluatorError(f"{vpath}: expected a (V, {WORD_DIM}) float array, got shape {vectors.shape} "
                             f"dtype {vectors.dtype}")
    if not np.isfinite(vectors).all():
        raise EvaluatorError(f"{vpath}: holds non-finite values")
    words = read_plain_pickle(folder / GLOVE_FILES[1])
    index = read_plain_pickle(folder / GLOVE_FILES[2])
    if not isinstance(words, list) or not all(isinstance(w, str) for w in words):
        raise EvaluatorError(f"{folder / GLOVE_FILES[1]}: expected a list of words")
    if not isinstance(index, dict) or not all(isinstance(k, str) and isinstance(v, int) and not isinstance(v, bool)
                                              for k, v in index.items()):
        raise EvaluatorError(f"{folder / GLOVE_FILES[2]}: expected a dict word -> row number")
    unique = list(dict.fromkeys(words))
    for w in unique:
        row = index.get(w)
        if row is None:
            raise EvaluatorError(f"{folder / GLOVE_FILES[2]}: has no row for the word {w!r} of "
                                 f"{GLOVE_FILES[1]}")
        if not 0 <= row < len(vectors):
            raise EvaluatorError(f"{folder / GLOVE_FILES[2]}: row {row} of {w!r} is outside {GLOVE_FILES[0]}'s "
                                 f"{len(vectors)} rows")
    missing = [w for w in SPECIAL_WORDS if w not in index or w not in unique]
    if missing:
        raise EvaluatorError(f"{folder / GLOVE_FILES[1]}: the vocabulary lacks {missing[0]!r} (sos, eos and unk "
                             f"are needed)")
    return unique, np.ascontiguousarray(vectors[[index[w] for w in unique]])


def pos_slot(word: str, pos: str) -> int:
    """The one-hot slot of a vocabulary word tagged ``pos`` (VIP lists first)."""
    for slot, words in VIP_WORDS:
        if word in words:
            return POS_SLOTS.index(slot)
    return POS_SLOTS.index(pos) if pos in POS_SLOTS else POS_SLOTS.index("OTHER")


def sequence(tokens: Sequence[str], max_tokens: int = MAX_TOKENS) -> tuple[list[str], int]:
    """The padded token sequence of a caption's ``word/POS`` tokens and its length:
    ``sos`` + the first ``max_tokens`` (20; CHOIS's evaluator: 30) + ``eos``, then ``unk``
    up to ``max_tokens + 2``."""
    kept = list(tokens[:max_tokens])
    seq = ["sos/OTHER", *kept, "eos/OTHER"]
    return seq + ["unk/OTHER"] * (max_tokens + 2 - len(seq)), len(seq)


class Vocabulary:
    """Word -> row of ``vectors``; :meth:`encode` gives the text encoder's inputs."""

    def __init__(self, words: Sequence[str], vectors: np.ndarray):
        if len(words) != len(vectors):
            raise EvaluatorError(f"vocabulary: {len(words)} words but {len(vectors)} vectors")
        self.row = {w: i for i, w in enumerate(words)}
        self.vectors = np.asarray(vectors)
        self.unk = self.row["unk"]

    def encode(self, tokens: Sequence[str], where: str = "tokens",
               max_tokens: int = MAX_TOKENS) -> tuple[np.ndarray, np.ndarray, int]:
        """(word vectors (L, 300), POS one-hot (L, 15), length) of one caption's tokens,
        ``L = max_tokens + 2`` (22 by default)."""
        seq, length = sequence(tokens, max_tokens)
        words = np.zeros((len(seq), self.vectors.shape[1]), self.vectors.dtype)
        onehot = np.zeros((len(seq), len(POS_SLOTS)))
        for j, token in enumerate(seq):
            parts = str(token).split("/")
            if len(parts) != 2:
                raise ValueError(f"{where}: token {token!r} is not 'word/POS'")
            word, pos = parts
            row = self.row.get(word)
            if row is None:
                words[j], onehot[j, POS_SLOTS.index("OTHER")] = self.vectors[self.unk], 1.0
            else:
                words[j], onehot[j, pos_slot(word, pos)] = self.vectors[row], 1.0
        return words, onehot, length


__all__ = ["POS_SLOTS", "VIP_WORDS", "MAX_TOKENS", "SEQ_LEN", "GLOVE_FILES", "read_plain_pickle", "read_glove",
           "pos_slot", "sequence", "Vocabulary"]
