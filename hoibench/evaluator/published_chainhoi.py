"""The ``chainhoi`` evaluator backend: ChainHOI's published MotionCLIP evaluator.

``hoibench evaluator import chainhoi --checkpoint EPOCH.ckpt --text-model ROBERTA_DIR
--stats DATA_ROOT --out EV`` (:func:`import_chainhoi`) reads

* the Lightning checkpoint ChainHOI's evaluator loads (``checkpoint/behave_t2m/
  epoch=24-step=325.ckpt`` for BEHAVE, ``checkpoint/omomo/epoch=273-step=9590.ckpt`` for
  OMOMO in its code): ``state_dict`` with every key under ``motion_clip.`` -- the motion
  branch, both projections, ``logit_scale`` and the whole RoBERTa (``text_encoder.*``,
  pooler included: the reference loads the state dict strictly, so these weights, not the
  RoBERTa folder's, are the ones that score);
* a local RoBERTa folder (``roberta-base``): ``config.json`` (the text model's
  architecture) and the tokenizer files (``vocab.json``, ``merges.txt``; nothing else
  of the folder is used and nothing is downloaded);
* the dataset folder of ChainHOI's data (``dataset/behave_t2m`` or ``dataset/omomo``)
  holding ``Mean_local.npy`` and ``Std_local.npy``, the statistics the evaluation
  datamodule normalises motions with (their first 263 entries are used).

Checks, each a one-line refusal naming the file and key: the checkpoint is missing,
truncated or not a torch file (:mod:`hoibench.evaluator.safe_checkpoint`: read with
``weights_only``), has no ``state_dict``, a key outside ``motion_clip.``, a missing or
unexpected key, or a tensor whose shape differs from the one the architecture implies
(sizes are read from the checkpoint: width from ``motion_encoder.conv.weight``, layers from
the numbered transformer layers, positions from ``pos_embedding``, output width from
``motion_proj``; the text side from the RoBERTa ``config.json``); a statistics file that is
missing, not a float vector of at least 263 entries, or has a non-finite value or a
non-positive standard deviation; a RoBERTa folder without ``config.json`` of
``model_type: roberta`` or without its tokenizer files.

The folder written is an ordinary evaluator folder (``load_evaluator(EV)`` and ``hoibench
evaluate --evaluator EV`` use it): ``weights.safetensors`` (every checkpoint tensor but
``logit_scale``, names without the ``motion_clip.`` prefix, float32), ``card.json``
(``backend: chainhoi``; sizes, statistics, the checkpoint's and statistics files' sha256,
the dataset and representation the evaluator was trained for) and ``text_model/`` (copies
of the RoBERTa folder's ``config.json`` and tokenizer files, each sha256 recorded in the
card and checked on load). Its evaluator id covers the weights and the card.

Which data it fits. The evaluator was trained on HOI-Diff's processing of BEHAVE (or
OMOMO) at 20 fps: the 269 ``new_joint_vecs_local`` columns, of which it reads the 263 body
columns. In hoibench these are the ``hoi269-legacy-1.0`` rows of a store prepared in a
legacy mode (their body part is ``hml263-legacy-hoidiff-1.0``), which is what the scorer
embeds for object stores. The card says so (``dataset``: name, ``features: hoi269``,
``representation: hoi269-legacy-1.0``, ``fps: 20``, and for reading
``body_representation``), so :func:`hoibench.evaluator.card.store_mismatches` refuses it on
another dataset or a clean store. Its normalisation is its own (no store statistics hash
is compared) and its training split is unknown to hoibench (not compared either). The
dataset is read from the architecture (384 wide, 8 layers: BEHAVE; 512 wide, 6 layers:
OMOMO); other sizes take it from the statistics folder's name (``behave...`` /
``omomo...``), and a disagreement between the two is refused.
"""
from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path

import numpy as np

from .chainhoi_model import HEADS, MAX_FRAMES, MOTION_DIM, RELEASED_SIZES, TEXT_MAX_TOKENS
from .errors import CorruptEvaluatorFile, EvaluatorError, EvaluatorIntegrityError

BACKEND = "chainhoi"
PREFIX = "motion_clip."
STATS_FILES = ("Mean_local.npy", "Std_local.npy")
#: files copied from the RoBERTa folder: required, then used when present
TEXT_FILES_REQUIRED = ("config.json", "vocab.json", "merges.txt")
TEXT_FILES_OPTIONAL = ("tokenizer_config.json", "special_tokens_map.json", "added_tokens.json", "tokenizer.json")
TEXT_DIR = "text_model"
#: state-dict entries that are buffers in some transformers versions (saved by older ones)
_TEXT_BUFFERS = ("text_encoder.embeddings.position_ids", "text_encoder.embeddings.token_type_ids")
#: the code this backend reproduces
SOURCE = {"paper": "ChainHOI (Zeng et al., CVPR 2025)", "code": "https://github.com/Huanggh531/ChainHOI",
          "commit": "4990160", "module": "src/models/evaluator/MotionCLIP (MotionCLIP: BEHAVE, MotionCLIP2: OMOMO)",
          "normalisation": "src/data/behave_omomo.py + src/data/humanml/hoidataset.py (Mean_local/Std_local)"}
#: the data the released evaluators were trained on (HOI-Diff's BEHAVE / OMOMO processing)
TRAINED_ON = {"features": "hoi269", "representation": "hoi269-legacy-1.0", "fps": 20,
              "body_representation": "hml263-legacy-hoidiff-1.0"}

__all__ = ["BACKEND", "ChainHOIImportError", "import_chainhoi", "load_chainhoi", "verify_chainhoi_folder",
           "verify_folder",
           "read_stats", "architecture", "summary"]


class ChainHOIImportError(EvaluatorError):
    """A file given to ``hoibench evaluator import chainhoi`` that cannot be used (names it)."""


def _sha256_file(path: Path) -> str:
    from ..core.io import sha256_regular_file
    return sha256_regular_file(path, what="ChainHOI file").hexdigest()


# --------------------------------------------------------------------------- inputs
def read_stats(folder: Path) -> dict:
    """``Mean_local.npy``/``Std_local.npy`` of ``folder``: their first 263 entries (as
    float64 lists, exact for float32 files), dtype, length and sha256."""
    out: dict = {"source": "ChainHOI " + "/".join(STATS_FILES), "folder": folder.name}
    arrays = {}
    for key, name in zip(("mean", "std"), STATS_FILES):
        path = folder / name
        if not path.is_file():
            raise ChainHOIImportError(f"--stats {folder}: {name} is missing (ChainHOI's dataset folder, e.g. "
                                      f"dataset/behave_t2m, holds Mean_local.npy and Std_local.npy)")
        try:
            from ..core.io import load_npy_file
            a = load_npy_file(path, 64 << 20, "ChainHOI statistics file")
        except Exception as exc:
            raise ChainHOIImportError(f"{path}: not a readable .npy array ({' '.join(str(exc).split())[:160]})") \
                from None
        if a.ndim != 1 or a.shape[0] < MOTION_DIM or a.dtype.kind != "f":
            raise ChainHOIImportError(f"{path}: expected a float vector of at least {MOTION_DIM} entries, got "
                                      f"{a.dtype} of shape {a.shape}")
        v = a[:MOTION_DIM]
        if not np.isfinite(v).all():
            raise ChainHOIImportError(f"{path}: entry {int(np.flatnonzero(~np.isfinite(v))[0])} is not finite")
        if key == "std" and (v <= 0).any():
            raise ChainHOIImportError(f"{path}: entry {int(np.flatnonzero(v <= 0)[0])} is {v[v <= 0][0]}: a "
                                      f"standard deviation must be positive")
        arrays[key] = a
        out[key] = [float(x) for x in v]
        out[f"{key}_sha256"] = _sha256_file(path)
    if arrays["mean"].dtype != arrays["std"].dtype or arrays["mean"].shape != arrays["std"].shape:
        raise ChainHOIImportError(f"--stats {folder}: Mean_local.npy ({arrays['mean'].dtype}, "
                                  f"{arrays['mean'].shape}) and Std_local.npy ({arrays['std'].dtype}, "
                                  f"{arrays['std'].shape}) do not match")
    out["dtype"] = str(arrays["mean"].dtype)
    out["file_entries"] = int(arrays["mean"].shape[0])
    return out


def _text_model(folder: Path):
    """(config, {file: path}) of a local RoBERTa folder; nothing is downloaded."""
    for name in TEXT_FILES_REQUIRED:
        if not (folder / name).is_file():
            raise ChainHOIImportError(f"--text-model {folder}: {name} is missing (a local roberta-base folder "
                                      f"holds config.json, vocab.json and merges.txt; hoibench never downloads it)")
    from transformers import AutoConfig
    try:
        config = AutoConfig.from_pretrained(str(folder), local_files_only=True)
    except Exception as exc:
        raise ChainHOIImportError(f"{folder / 'config.json'}: not a readable model config "
                                  f"({' '.join(str(exc).split())[:160]})") from None
    if getattr(config, "model_type", None) != "roberta":
        raise ChainHOIImportError(f"{folder / 'config.json'}: field model_type: {config.model_type!r}, ChainHOI's "
                                  f"evaluator uses RoBERTa ('roberta')")
    files = {n: folder / n for n in TEXT_FILES_REQUIRED + TEXT_FILES_OPTIONAL if (folder / n).is_file()}
    _check_tokenizer(folder, files)
    return config, files


def _check_tokenizer(folder: Path, files: dict[str, Path]) -> None:
    """The copied files alone must give the ``RobertaTokenizer`` the loader builds, and it must
    pad a batch: checked in a scratch folder at import, not when text is first embedded."""
    import shutil
    import tempfile
    from .text import load_tokenizer
    with tempfile.TemporaryDirectory(prefix="hoibench-tokenizer-") as scratch:
        for n, p in files.items():
            shutil.copyfile(p, Path(scratch) / n)
        try:
            load_tokenizer(Path(scratch), "RobertaTokenizer", named=folder)
        except ValueError as exc:
            raise ChainHOIImportError(f"--text-model {exc}") from None


def _roberta_shapes(config) -> dict[str, tuple[int, ...]]:
    """Parameter shapes of ``RobertaModel(config)`` (built on the meta device: no memory)."""
    import torch
    from transformers import AutoModel
    with torch.device("meta"):
        model = AutoModel.from_config(config)
    return {f"text_encoder.{k}": tuple(v.shape) for k, v in model.state_dict().items()
            if f"text_encoder.{k}" not in _TEXT_BUFFERS}


def architecture(sd: dict, path) -> dict:
    """Sizes read from a ChainHOI evaluator state dict (keys without ``motion_clip.``)."""
    for key in ("motion_encoder.conv.weight", "motion_encoder.pos_embedding", "motion_proj", "text_proj"):
        if key not in sd:
            raise ChainHOIImportError(f"{path}: state_dict has no {PREFIX}{key} (not ChainHOI's MotionCLIP "
                                      f"evaluator?)")
    conv = tuple(sd["motion_encoder.conv.weight"].shape)
    if len(conv) != 3 or conv[1:] != (MOTION_DIM, 1):
        raise ChainHOIImportError(f"{path}: {PREFIX}motion_encoder.conv.weight has shape {conv}, expected "
                                  f"(width, {MOTION_DIM}, 1)")
    layer_ids = {int(m.group(1)) for k in sd if (m := re.match(r"motion_encoder\.transformer\.layers\.(\d+)\.", k))}
    layers = max(layer_ids) + 1 if layer_ids else 0
    if layers == 0:
        raise ChainHOIImportError(f"{path}: state_dict has no {PREFIX}motion_encoder.transformer.layers.*")
    pos = tuple(sd["motion_encoder.pos_embedding"].shape)
    proj = tuple(sd["motion_proj"].shape)
    tproj = tuple(sd["text_proj"].shape)
    if len(pos) != 2 or len(proj) != 2 or len(tproj) != 2:
        raise ChainHOIImportError(f"{path}: pos_embedding {pos}, motion_proj {proj}, text_proj {tproj}: expected "
                                  f"matrices")
    return {"motion_dim": MOTION_DIM, "width": conv[0], "layers": layers, "heads": HEADS, "ff": 4 * conv[0],
            "max_positions": pos[0], "output_dim": proj[1], "text_dim": tproj[0],
            "text_max_tokens": TEXT_MAX_TOKENS, "max_frames": MAX_FRAMES}


def expected_shapes(arch: dict, text_shapes: dict) -> dict[str, tuple[int, ...]]:
    """Every tensor the reference's strict ``load_state_dict`` wants, with its shape."""
    d, ff = arch["width"], arch["ff"]
    out = {"motion_encoder.conv.weight": (d, MOTION_DIM, 1), "motion_encoder.class_token": (d,),
           "motion_encoder.pos_embedding": (arch["max_positions"], d),
           "motion_proj": (d, arch["output_dim"]), "text_proj": (arch["text_dim"], arch["output_dim"]),
           "logit_scale": ()}
    for ln in ("ln_pre", "ln_post"):
        out[f"motion_encoder.{ln}.weight"] = out[f"motion_encoder.{ln}.bias"] = (d,)
    for i in range(arch["layers"]):
        p = f"motion_encoder.transformer.layers.{i}."
        out.update({p + "self_attn.in_proj_weight": (3 * d, d), p + "self_attn.in_proj_bias": (3 * d,),
                    p + "self_attn.out_proj.weight": (d, d), p + "self_attn.out_proj.bias": (d,),
                    p + "linear1.weight": (ff, d), p + "linear1.bias": (ff,),
                    p + "linear2.weight": (d, ff), p + "linear2.bias": (d,)})
        for n in ("norm1", "norm2"):
            out[p + n + ".weight"] = out[p + n + ".bias"] = (d,)
    out.update(text_shapes)
    return out


def _state_dict(ckpt: dict, path: Path) -> dict:
    """The checkpoint's ``state_dict`` with the ``motion_clip.`` prefix removed (tensors only)."""
    import torch
    sd = ckpt.get("state_dict")
    if not isinstance(sd, dict):
        raise ChainHOIImportError(f"{path}: no 'state_dict' (keys: {', '.join(map(str, list(ckpt)[:6]))}); "
                                  f"expected the Lightning checkpoint of ChainHOI's evaluator")
    out = {}
    for k, v in sd.items():
        if not (isinstance(k, str) and k.startswith(PREFIX)):
            raise ChainHOIImportError(f"{path}: state_dict key {k!r} is not under {PREFIX!r} (the reference loads "
                                      f"every key into MotionCLIP, strictly)")
        if not isinstance(v, torch.Tensor):
            raise ChainHOIImportError(f"{path}: state_dict[{k!r}] is a {type(v).__name__}, not a tensor")
        out[k[len(PREFIX):]] = v
    return out


def check_shapes(sd: dict, want: dict, path) -> None:
    """One-line refusal for the first missing, unexpected or wrongly shaped key."""
    for k in sorted(want):
        if k not in sd:
            raise ChainHOIImportError(f"{path}: state_dict has no {PREFIX}{k} (expected shape {want[k]})")
        if tuple(sd[k].shape) != want[k]:
            raise ChainHOIImportError(f"{path}: {PREFIX}{k} has shape {tuple(sd[k].shape)}, the architecture "
                                      f"needs {want[k]}")
    extra = sorted(k for k in sd if k not in want and k not in _TEXT_BUFFERS)
    if extra:
        raise ChainHOIImportError(f"{path}: unexpected state_dict key {PREFIX}{extra[0]} (shape "
                                  f"{tuple(sd[extra[0]].shape)}; {len(extra)} unexpected in all)")


def _check_buffers(sd: dict, path) -> None:
    """Saved ``position_ids`` (older transformers) must be the positions 0, 1, ... the model uses."""
    import torch
    pid = sd.get(_TEXT_BUFFERS[0])
    if pid is not None and not torch.equal(pid.reshape(-1).long(), torch.arange(pid.numel())):
        raise ChainHOIImportError(f"{path}: {PREFIX}{_TEXT_BUFFERS[0]} is not 0, 1, 2, ... (a modified text model)")


def _dataset(arch: dict, stats_dir: Path) -> str:
    """The dataset the evaluator was trained on: from its sizes, else the statistics folder name."""
    by_size = next((n for n, s in RELEASED_SIZES.items() if s == (arch["width"], arch["layers"])), None)
    name = stats_dir.resolve().name.lower()
    by_folder = next((n for n in RELEASED_SIZES if n in name), None)
    if by_size and by_folder and by_size != by_folder:
        raise ChainHOIImportError(f"--stats {stats_dir}: the folder is {by_folder.upper()}'s but the checkpoint is "
                                  f"the {by_size.upper()} evaluator (width {arch['width']}, {arch['layers']} layers); "
                                  f"give the statistics of the dataset the evaluator was trained on")
    if not (by_size or by_folder):
        raise ChainHOIImportError(f"--stats {stats_dir}: cannot tell whether the evaluator is BEHAVE's or OMOMO's: "
                                  f"width {arch['width']} with {arch['layers']} layers is neither release's, and "
                                  f"the folder name names neither (ChainHOI's are dataset/behave_t2m, dataset/omomo)")
    return by_size or by_folder


# --------------------------------------------------------------------------- import
def import_chainhoi(out: Path, checkpoint: Path, text_model: Path, stats: Path) -> str:
    """Write the evaluator folder ``out`` from ChainHOI's evaluator files; return its id
    (see the module docstring for the inputs and every check)."""
    import torch

    from .. import __version__
    from ..core.io import atomic_write_bytes
    from .card import write_folder
    from .safe_checkpoint import load_checkpoint
    from .text import package_versions

    checkpoint, text_model, stats = Path(checkpoint), Path(text_model), Path(stats)
    if not stats.is_dir():
        raise ChainHOIImportError(f"--stats {stats}: no such folder (ChainHOI's dataset folder with "
                                  f"Mean_local.npy and Std_local.npy)")
    if not text_model.is_dir():
        raise ChainHOIImportError(f"--text-model {text_model}: no such folder (a local roberta-base download)")
    norm = read_stats(stats)
    config, text_files = _text_model(text_model)
    sd = _state_dict(load_checkpoint(checkpoint, "--checkpoint"), checkpoint)
    arch = architecture(sd, checkpoint)
    if arch["text_dim"] != config.hidden_size:
        raise ChainHOIImportError(f"{checkpoint}: {PREFIX}text_proj has shape {tuple(sd['text_proj'].shape)}, the "
                                  f"RoBERTa of {text_model} gives {config.hidden_size}-wide pooled outputs")
    check_shapes(sd, expected_shapes(arch, _roberta_shapes(config)), checkpoint)
    _check_buffers(sd, checkpoint)
    dataset = _dataset(arch, stats)
    tensors = {k: v.detach().to(torch.float32).contiguous() for k, v in sorted(sd.items())
               if k != "logit_scale" and k not in _TEXT_BUFFERS}
    copied = {}
    for name, path in sorted(text_files.items()):
        from ..core.io import read_regular_file
        data = read_regular_file(path, 64 << 20, "RoBERTa tokenizer/config file")
        atomic_write_bytes(Path(out) / TEXT_DIR / name, data)
        copied[name] = hashlib.sha256(data).hexdigest()
    card = {
        "backend": BACKEND, "source": SOURCE, "config": arch,
        "dataset": {"name": dataset, **TRAINED_ON},
        "normalization": norm,
        "text_encoder": {"name": text_model.resolve().name, "model_type": "roberta", "pooling": "pooler_output",
                         "weights": "from the checkpoint (text_encoder.*)", "files_sha256": copied,
                         "hidden_size": int(config.hidden_size), "layers": int(config.num_hidden_layers),
                         "vocab_size": int(config.vocab_size)},
        "checkpoint": {"file": checkpoint.name, "sha256": _sha256_file(checkpoint), "tensors": len(sd),
                       "logit_scale": float(sd["logit_scale"])},
        "toolkit_version": __version__, "libraries": package_versions(),
    }
    return write_folder(out, tensors, card)


# --------------------------------------------------------------------------- verify, load
_CARD_FIELDS = (("config", dict), ("dataset", dict), ("normalization", dict), ("text_encoder", dict),
                ("evaluator_id", str))
_CONFIG_INTS = ("width", "layers", "heads", "ff", "max_positions", "output_dim", "text_dim", "text_max_tokens",
                "max_frames")


def verify_chainhoi_folder(folder: str | Path) -> tuple[dict, bytes]:
    """(card, weights bytes) of a ``chainhoi`` folder whose id, card fields and copied
    tokenizer files check out; one-line :class:`EvaluatorIntegrityError` otherwise."""
    from ..core.io import read_json_object, read_regular_file
    from .card import CARD, FORMAT, MAX_WEIGHTS_BYTES, WEIGHTS, changed_parts, check_safetensors, compute_id
    folder = Path(folder)
    cpath = folder / CARD
    try:
        card = read_json_object(cpath, 64 * 1024 ** 2, "evaluator card", _CARD_FIELDS)
    except ValueError as exc:
        raise CorruptEvaluatorFile(str(exc)) from None
    if card.get("format") != FORMAT or card.get("backend") != BACKEND:
        raise EvaluatorIntegrityError(f"{cpath}: fields format/backend: {card.get('format')!r}/"
                                      f"{card.get('backend')!r}, expected {FORMAT!r}/{BACKEND!r}")
    try:
        data = read_regular_file(folder / WEIGHTS, MAX_WEIGHTS_BYTES, "evaluator weights")
    except ValueError as exc:
        raise EvaluatorIntegrityError(f"{folder}: {WEIGHTS} cannot be read ({exc})") from None
    check_safetensors(data, folder / WEIGHTS)
    if compute_id(data, card) != card["evaluator_id"]:
        detail = "; ".join(changed_parts(card, data, WEIGHTS, CARD)) or f"{CARD} field evaluator_id was modified"
        raise EvaluatorIntegrityError(f"{folder}: evaluator id mismatch: {detail}; import it again")
    cfg, norm = card["config"], card["normalization"]
    for k in _CONFIG_INTS:
        if not isinstance(cfg.get(k), int) or isinstance(cfg.get(k), bool) or cfg[k] < 1:
            raise CorruptEvaluatorFile(f"{cpath}: field config.{k}: expected a positive integer")
    if cfg["max_frames"] + 1 > cfg["max_positions"]:
        raise CorruptEvaluatorFile(f"{cpath}: field config.max_frames: {cfg['max_frames']} frames need "
                                   f"{cfg['max_frames'] + 1} positions, the model has {cfg['max_positions']}")
    for k in ("mean", "std"):
        v = norm.get(k)
        if not (isinstance(v, list) and len(v) == MOTION_DIM and all(isinstance(x, (int, float)) for x in v)):
            raise CorruptEvaluatorFile(f"{cpath}: field normalization.{k}: expected {MOTION_DIM} numbers")
    files = card["text_encoder"].get("files_sha256")
    if not isinstance(files, dict) or not all(n in files for n in TEXT_FILES_REQUIRED):
        raise CorruptEvaluatorFile(f"{cpath}: field text_encoder.files_sha256: expected the sha256 of "
                                   f"{', '.join(TEXT_FILES_REQUIRED)}")
    for name, sha in sorted(files.items()):
        path = folder / TEXT_DIR / name
        if not path.is_file():
            raise EvaluatorIntegrityError(f"{folder}: {TEXT_DIR}/{name} is missing (incomplete copy?)")
        if _sha256_file(path) != sha:
            raise EvaluatorIntegrityError(f"{path}: sha256 differs from the card's text_encoder.files_sha256 "
                                          f"(modified after import); import the evaluator again")
    return card, data


#: the name ``hoibench evaluator show`` looks for in a backend's loader module
verify_folder = verify_chainhoi_folder


def _load_text(folder: Path):
    """(tokenizer, RoBERTa model) from the folder's ``text_model/`` copy, offline, quietly."""
    from transformers import AutoConfig, AutoModel, RobertaTokenizer
    from transformers.utils import logging as hf_logging
    verbosity = hf_logging.get_verbosity()
    hf_logging.set_verbosity_error()
    try:
        tok = RobertaTokenizer.from_pretrained(str(folder), local_files_only=True)
        model = AutoModel.from_config(AutoConfig.from_pretrained(str(folder), local_files_only=True))
    finally:
        hf_logging.set_verbosity(verbosity)
    return tok, model


def load_chainhoi(folder: str | Path, *, allow_failed_gate: bool = False, text_encoder: str | None = None,
                  threads: int | None = None, device: str = "cpu"):
    """A :class:`~hoibench.evaluator.chainhoi_model.ChainHOIEvaluator` from a verified
    folder. ``allow_failed_gate`` and ``text_encoder`` are accepted for the common loader
    signature: a published evaluator carries no training-time gate (the scorer measures the
    gate on the store it scores) and its text model is the folder's own."""
    import torch

    from .card import WEIGHTS, _load_tensors
    from .chainhoi_model import ChainHOIEvaluator, ChainHOINet, MotionTransformer

    folder = Path(folder)
    card, data = verify_chainhoi_folder(folder)
    cfg, norm = card["config"], card["normalization"]
    tok, text_model = _load_text(folder / TEXT_DIR)
    motion = MotionTransformer(cfg["width"], cfg["layers"], cfg["heads"], cfg["ff"], cfg["max_positions"])
    net = ChainHOINet(motion, text_model, cfg["output_dim"], cfg["text_dim"])
    tensors = _load_tensors(data, folder / WEIGHTS)
    want = {k: tuple(v.shape) for k, v in net.state_dict().items() if k not in _TEXT_BUFFERS}
    try:
        check_shapes(tensors, want, folder / WEIGHTS)
    except ChainHOIImportError as exc:
        raise EvaluatorIntegrityError(str(exc).replace(PREFIX, "")) from None
    with torch.no_grad():
        net.load_state_dict(tensors, strict=False)
    dtype = np.dtype(norm.get("dtype", "float32"))
    mean, std = np.asarray(norm["mean"], dtype), np.asarray(norm["std"], dtype)
    return ChainHOIEvaluator(net, tok, mean, std, card, max_frames=cfg["max_frames"],
                             text_max_tokens=cfg["text_max_tokens"], threads=threads, device=device)


def summary(card: dict, verified: bool | None = None) -> str:
    """What ``hoibench evaluator show EV`` prints for a ``chainhoi`` folder."""
    cfg, ds, te, ck = (card.get(k) if isinstance(card.get(k), dict) else {}
                       for k in ("config", "dataset", "text_encoder", "checkpoint"))
    mark = "" if verified is None else ("  (id verified)" if verified else "  (ID MISMATCH)")
    return "\n".join([
        f"evaluator {card.get('evaluator_id', '?')}{mark}",
        f"  backend chainhoi: ChainHOI's MotionCLIP evaluator ({SOURCE['code']} @ {SOURCE['commit']})",
        f"  motion: width {cfg.get('width')}, {cfg.get('layers')} layers, {cfg.get('heads')} heads, "
        f"{cfg.get('max_positions')} positions, first {cfg.get('max_frames')} frames; output {cfg.get('output_dim')}",
        f"  text: {te.get('name')} ({te.get('layers')} layers, {te.get('hidden_size')} wide, weights from the "
        f"checkpoint), {cfg.get('text_max_tokens')} tokens, pooler_output",
        f"  trained for: {ds.get('name')} {ds.get('representation')} (body columns: "
        f"{ds.get('body_representation')}) at {ds.get('fps')} fps",
        f"  checkpoint: {ck.get('file')} sha256 {str(ck.get('sha256', ''))[:12]}",
        f"  normalisation: {json.dumps((card.get('normalization') or {}).get('source'))} "
        f"({(card.get('normalization') or {}).get('folder')})"])
