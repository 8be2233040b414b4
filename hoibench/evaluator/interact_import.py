"""``hoibench evaluator import interact``: InterAct's evaluator files -> an evaluator folder.

Inputs (nothing is downloaded):

* ``--checkpoint markersbps.ckpt``: the Lightning checkpoint of InterAct's evaluator, read
  with ``torch.load(weights_only=True)``; its ``state_dict`` holds ``textencoder.*``
  (including the DistilBERT ``textencoder.text_model.*``) and ``motionencoder.*``; other
  prefixes are ignored.
* ``--distilbert DIR``: a local ``distilbert-base-uncased`` folder (``config.json`` and the
  tokenizer files: ``vocab.txt`` or ``tokenizer.json``, with ``tokenizer_config.json`` and
  ``special_tokens_map.json`` when present); its weights are not read, the checkpoint carries
  them. The tokenizer class is ``tokenizer_config.json``'s ``tokenizer_class`` or, as in the
  hub's folder which names none, the one ``config.json``'s ``model_type`` maps to (what
  ``AutoTokenizer`` does); it is recorded in the card (so in the evaluator id) and the copied
  files must load with it and pad a batch at import.
* ``--mean`` / ``--std``: ``mean_train_markersbps.npy`` / ``std_train_markersbps.npy`` (615,).
* ``--bps-basis``: ``bps_basis_set_128_1.npy`` (128, 3).

Every tensor is checked against the architecture (InterAct's sizes: latent 256, feed-forward
1024, 4 layers, 4 heads, 615 motion inputs; the DistilBERT sizes from ``config.json``) before
anything is written; a missing key or a shape mismatch is a one-line error naming the key and
both shapes.
"""
from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import torch

from .errors import EvaluatorError
from .interact import BACKEND, REPRESENTATION, TOKENIZER_DIR, build_motion_encoder, build_text_encoder
from .interact_features import BPS_POINTS, ROW_WIDTH
from .interact_model import FF_SIZE, HEADS, LATENT, LAYERS

#: tokenizer files copied when present (at least vocab.txt or tokenizer.json is needed)
TOKENIZER_FILES = ("vocab.txt", "tokenizer.json", "tokenizer_config.json", "special_tokens_map.json")
#: buffers older transformers versions saved with DistilBERT; not parameters, dropped on import
_DROPPED = ("text_model.embeddings.position_ids",)


def _sha(path: Path) -> str:
    from ..core.io import sha256_regular_file
    return sha256_regular_file(path, what="InterAct file").hexdigest()


def read_checkpoint(path: Path) -> dict:
    """The checkpoint's ``state_dict`` (tensors), read with ``weights_only=True``."""
    if not path.is_file():
        raise EvaluatorError(f"{path}: checkpoint not found")
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=True)  # read-ok: weights-only unpickler (tensors, plain containers)
    except Exception as exc:      # truncated zip, not a torch file, non-allow-listed objects
        msg = " ".join(str(exc).split())[:240]
        raise EvaluatorError(f"{path}: not a readable torch checkpoint with weights_only=True ({msg})") from None
    sd = ckpt.get("state_dict") if isinstance(ckpt, dict) else None
    if not isinstance(sd, dict):
        raise EvaluatorError(f"{path}: no 'state_dict' dict in the checkpoint (a Lightning checkpoint of "
                             f"InterAct's evaluator has one)")
    return sd


def _slice(sd: dict, prefix: str, expected: dict, path: Path, flexible: tuple[str, ...] = ()) -> dict:
    """``sd``'s ``prefix`` tensors renamed, checked key by key against ``expected`` shapes."""
    got = {k[len(prefix):]: v for k, v in sd.items() if k.startswith(prefix)}
    for k in _DROPPED:
        got.pop(k, None)
    if not got:
        raise EvaluatorError(f"{path}: no '{prefix}*' tensors in state_dict (not InterAct's evaluator checkpoint?)")
    for k, ref in expected.items():
        if k not in got:
            raise EvaluatorError(f"{path}: state_dict key {prefix}{k} is missing")
        v = got[k]
        if not isinstance(v, torch.Tensor):
            raise EvaluatorError(f"{path}: state_dict key {prefix}{k} is not a tensor")
        shape, want = tuple(v.shape), tuple(ref.shape)
        if k in flexible:
            ok = len(shape) == len(want) and shape[1:] == want[1:] and shape[0] >= 3
        else:
            ok = shape == want
        if not ok:
            raise EvaluatorError(f"{path}: state_dict key {prefix}{k} has shape {list(shape)}, the architecture "
                                 f"expects {list(want)}")
    extra = sorted(set(got) - set(expected))
    if extra:
        raise EvaluatorError(f"{path}: state_dict key {prefix}{extra[0]} is not part of the architecture")
    return {k: got[k].detach().to(torch.float32).contiguous() for k in expected}


def _array(path: Path, shape: tuple, what: str) -> np.ndarray:
    from ..core.io import read_regular_file
    if not path.is_file():
        raise EvaluatorError(f"{path}: {what} not found")
    import io
    try:
        a = np.load(io.BytesIO(read_regular_file(path, 64 << 20, what)), allow_pickle=False)
    except ValueError as exc:
        raise EvaluatorError(f"{path}: not a numeric .npy array ({' '.join(str(exc).split())[:160]})") from None
    if not isinstance(a, np.ndarray) or a.shape != shape or not np.issubdtype(a.dtype, np.floating):
        raise EvaluatorError(f"{path}: {what} must be a float array of shape {list(shape)}, got "
                             f"{getattr(a, 'dtype', '?')} {list(getattr(a, 'shape', ()))}")
    if not np.all(np.isfinite(a)):
        raise EvaluatorError(f"{path}: {what} has non-finite values")
    return a.astype(np.float64)


def _distilbert(folder: Path) -> tuple[dict, dict[str, Path], str]:
    """(config, tokenizer files, tokenizer class) of a local DistilBERT folder whose tokenizer
    loads from the copied files alone and pads a batch (checked in a scratch folder)."""
    import tempfile
    from ..core.io import read_json_file
    from .text import load_tokenizer, tokenizer_class
    if not folder.is_dir():
        raise EvaluatorError(f"{folder}: DistilBERT folder not found (a local distilbert-base-uncased download)")
    cfg_path = folder / "config.json"
    if not cfg_path.is_file():
        raise EvaluatorError(f"{cfg_path}: missing (the DistilBERT folder needs its config.json)")
    config = read_json_file(cfg_path, 1 << 20, "DistilBERT config")
    if not isinstance(config, dict) or config.get("model_type", "distilbert") != "distilbert":
        raise EvaluatorError(f"{cfg_path}: field model_type: expected 'distilbert', got "
                             f"{config.get('model_type') if isinstance(config, dict) else config!r}")
    files = {n: folder / n for n in TOKENIZER_FILES if (folder / n).is_file()}
    if "vocab.txt" not in files and "tokenizer.json" not in files:
        raise EvaluatorError(f"{folder}: vocab.txt is missing (the DistilBERT tokenizer reads vocab.txt or "
                             f"tokenizer.json)")
    try:
        name = tokenizer_class(folder, config.get("model_type", "distilbert"))
        with tempfile.TemporaryDirectory(prefix="hoibench-tokenizer-") as scratch:
            for n, p in files.items():
                shutil.copyfile(p, Path(scratch) / n)
            load_tokenizer(Path(scratch), name, named=folder)
    except ValueError as exc:
        raise EvaluatorError(str(exc)) from None
    return config, files, name


def import_interact(out: Path, checkpoint: Path, distilbert: Path, mean: Path, std: Path, bps_basis: Path) -> str:
    """Write an ``interact`` evaluator folder at ``out``; return its evaluator id."""
    from .card import write_folder
    from .errors import EvaluatorFolderExists
    out = Path(out)
    if out.exists() and any(out.iterdir()):
        raise EvaluatorFolderExists(f"{out}: exists and is not empty; choose a new --out folder")
    config, tok_files, tok_class = _distilbert(Path(distilbert))
    m = _array(Path(mean), (ROW_WIDTH,), "mean")
    s = _array(Path(std), (ROW_WIDTH,), "std")
    if np.any(s <= 0):
        raise EvaluatorError(f"{std}: std has values <= 0 (column {int(np.argmax(s <= 0))})")
    basis = _array(Path(bps_basis), (BPS_POINTS, 3), "BPS basis")
    sd = read_checkpoint(Path(checkpoint))
    pe_key = "sequence_pos_encoding.pe"
    pe = sd.get("motionencoder." + pe_key)
    pos_len = int(pe.shape[0]) if isinstance(pe, torch.Tensor) and pe.ndim == 3 else 5000   # else _slice names it
    text_ref = build_text_encoder(config, pos_len).state_dict()
    motion_ref = build_motion_encoder(pos_len).state_dict()
    text = _slice(sd, "textencoder.", text_ref, Path(checkpoint), (pe_key,))
    motion = _slice(sd, "motionencoder.", motion_ref, Path(checkpoint), (pe_key,))
    if text[pe_key].shape != motion[pe_key].shape:
        raise EvaluatorError(f"{checkpoint}: textencoder.{pe_key} {list(text[pe_key].shape)} and motionencoder."
                             f"{pe_key} {list(motion[pe_key].shape)} differ")
    tensors = {**{"textencoder." + k: v for k, v in text.items()},
               **{"motionencoder." + k: v for k, v in motion.items()},
               "normalization.mean": torch.from_numpy(m), "normalization.std": torch.from_numpy(s),
               "bps.basis": torch.from_numpy(basis)}
    card = {"backend": BACKEND, "kind": "interact",
            "source": {"checkpoint": Path(checkpoint).name, "checkpoint_sha256": _sha(Path(checkpoint)),
                       "mean_sha256": _sha(Path(mean)), "std_sha256": _sha(Path(std)),
                       "bps_basis_sha256": _sha(Path(bps_basis))},
            "text_model": {"config": config, "tokenizer_class": tok_class,
                           "tokenizer_files": {n: _sha(p) for n, p in sorted(tok_files.items())}},
            "motion": {"nfeats": ROW_WIDTH, "markers": 77, "bps_points": BPS_POINTS, "latent": LATENT,
                       "ff_size": FF_SIZE, "layers": LAYERS, "heads": HEADS, "pos_len": pos_len,
                       "embedding": "loc"},
            "dataset": {"name": "interact", "fps": 30.0, "rows": REPRESENTATION}}
    (out / TOKENIZER_DIR).mkdir(parents=True, exist_ok=True)
    for n, p in tok_files.items():
        shutil.copyfile(p, out / TOKENIZER_DIR / n)
    return write_folder(out, tensors, json.loads(json.dumps(card)))  # read-ok: a deep copy of our own card


__all__ = ["import_interact", "read_checkpoint", "TOKENIZER_FILES"]
