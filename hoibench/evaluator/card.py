"""Evaluator folders: write, verify, load, show.

Layout::

    EVAL/weights.safetensors   model tensors; of the pretrained text transformer only the
                               fine-tuned parameters (the rest is named by hash in the card)
    EVAL/card.json             config, dataset (manifest sha256, splits, texts sha256),
                               normalisation statistics and their sha256, text encoder
                               (name, weights sha256, pooling, fine-tuned or not), training
                               curve and its summary, GT retrieval scores, sanity gate,
                               toolkit and library versions, seed, evaluator_id
    EVAL/curve.png             training curve plot       (not covered by the id)
    EVAL/train_log.json        wall-clock times, resumes (not covered by the id)

Evaluator id = ``sha256(bytes of weights.safetensors || canonical card)``, where the
canonical card is ``json.dumps(card without "evaluator_id" and the provenance fields
(toolkit_version, libraries, torch_version), sort_keys=True, separators=(",", ":"),
ensure_ascii=True)``. Nothing time-, path- or machine-dependent enters it (the card records
the store by its content manifest's sha256), so the same data, config and seed give the
same id in any folder and under any toolkit version whose output bytes are the same. :func:`verify_folder` recomputes
it; :func:`load_evaluator` additionally checks the normalisation statistics against their
hash, the local text encoder against the card's hash, the tensor names and shapes against
the config, and the sanity gate.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import fields
from pathlib import Path

from ..core.io import atomic_write_bytes, atomic_write_text, load_json_bytes, read_regular_file
from .errors import CorruptEvaluatorFile, EvaluatorIntegrityError, StoreMismatchError, read_evaluator_file

FORMAT = "hoibench-evaluator-1"
WEIGHTS = "weights.safetensors"
CARD = "card.json"
#: a text encoder folder an evaluator may ship beside its weights (used when the card names
#: an encoder other than the packaged MiniLM and no ``text_encoder`` is passed)
SHIPPED_TEXT_ENCODER = "text_encoder"
CURVE_PNG = "curve.png"
TRAIN_LOG = "train_log.json"
#: size limits when reading a folder (a card is ~100 KB; paper-size weights with a fine-tuned
#: RoBERTa-base ~600 MB)
MAX_CARD_BYTES = 64 * 1024 ** 2
MAX_WEIGHTS_BYTES = 8 * 1024 ** 3

__all__ = ["EvaluatorIntegrityError", "CorruptEvaluatorFile", "canonical_card_bytes", "compute_id", "write_folder",
           "read_card", "validate_card", "verify_folder", "load_evaluator", "store_fingerprint", "store_mismatches",
           "check_store_match", "summary", "show"]


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _canonical(obj) -> bytes:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False).encode()


#: top-level card fields that say which software wrote a folder, not what it holds: kept in
#: the card, left out of the id and of the integrity block
PROVENANCE_KEYS = ("toolkit_version", "libraries", "torch_version")


def canonical_card_bytes(card: dict, id_key: str = "evaluator_id") -> bytes:
    return _canonical({k: v for k, v in card.items() if k != id_key and k not in PROVENANCE_KEYS})


def compute_id(weights: bytes, card: dict, id_key: str = "evaluator_id") -> str:
    """``sha256(weights || canonical card without its id and provenance fields)``
    (``id_key``: the field that holds the id: ``evaluator_id`` here, ``checkpoint_id`` for
    baseline runs)."""
    h = hashlib.sha256()
    h.update(weights)
    h.update(canonical_card_bytes(card, id_key))
    return h.hexdigest()


def legacy_id(weights: bytes, card: dict, id_key: str = "evaluator_id") -> str:
    """The id of folders written before the provenance fields were left out (the whole card
    without its id): such folders still verify."""
    return hashlib.sha256(weights + _canonical({k: v for k, v in card.items() if k != id_key})).hexdigest()


def id_matches(weights: bytes, card: dict, id_key: str = "evaluator_id") -> tuple[bool, str]:
    """(whether ``card[id_key]`` is the folder's id under the current or the legacy rule,
    the current rule's id)."""
    actual = compute_id(weights, card, id_key)
    return card.get(id_key) in (actual, legacy_id(weights, card, id_key)), actual


def integrity_block(weights: bytes, card: dict, id_key: str = "evaluator_id") -> dict:
    """Per-part hashes stored in the card (and covered by the id) so that a modified folder
    is reported by file and field: ``weights_sha256`` and ``sections_sha256[key]`` =
    sha256 of the canonical JSON of ``card[key]`` for every top-level key."""
    return {"weights_sha256": _sha256(weights),
            "sections_sha256": {k: _sha256(_canonical(v)) for k, v in sorted(card.items())
                                if k not in (id_key, "integrity") and k not in PROVENANCE_KEYS}}


def changed_parts(card: dict, data: bytes, weights_name: str = "weights.safetensors", card_name: str = "card.json",
                  id_key: str = "evaluator_id") -> list[str]:
    """What differs from the card's ``integrity`` block: the weights file, card fields."""
    integ = card.get("integrity")
    if not isinstance(integ, dict) or not isinstance(integ.get("sections_sha256"), dict):
        return []
    parts = []
    if integ.get("weights_sha256") != _sha256(data):
        parts.append(f"{weights_name} was modified (sha256 {_sha256(data)[:12]}..., the card records "
                     f"{str(integ.get('weights_sha256'))[:12]}...)")
    now = integrity_block(data, card, id_key)["sections_sha256"]
    rec = {k: v for k, v in integ["sections_sha256"].items() if k not in PROVENANCE_KEYS}
    fields_changed = sorted(k for k in set(now) | set(rec) if now.get(k) != rec.get(k))
    if fields_changed:
        parts.append(f"{card_name} field(s) {', '.join(fields_changed)} were modified")
    return parts


def weights_bytes(state_dict: dict) -> bytes:
    """safetensors bytes. One metadata key only: safetensors serialises its metadata map in
    hash order, so several keys would make the bytes (and the id) vary between runs."""
    from safetensors.torch import save
    return save(state_dict, metadata={"format": "pt"})


def write_folder(out: str | Path, state_dict: dict, card: dict) -> str:
    """Write weights and card (card last: its presence marks a complete folder); return the id."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    data = weights_bytes(state_dict)
    card = {k: v for k, v in card.items() if k not in ("evaluator_id", "integrity")}
    card["format"] = FORMAT
    card["integrity"] = integrity_block(data, card)
    eid = compute_id(data, card)
    card["evaluator_id"] = eid
    atomic_write_bytes(out / WEIGHTS, data)
    atomic_write_text(out / CARD, json.dumps(card, indent=1, sort_keys=True, allow_nan=False) + "\n")
    return eid


# --------------------------------------------------------------------------- reading, schema
_JSON_NAMES = {float: "number", dict: "object", list: "array", str: "string", bool: "boolean", int: "integer"}


def _type_name(t) -> str:
    return _JSON_NAMES.get(t, str(t))


def _is(value, t) -> bool:
    if t is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if t is int:
        return isinstance(value, int) and not isinstance(value, bool)
    return isinstance(value, t)


#: fields load_evaluator and the gate rely on, with their JSON types
_SCHEMA: tuple[tuple[str, type], ...] = (
    ("format", str), ("evaluator_id", str), ("config", dict), ("config.size", str), ("config.model", dict),
    ("config.train", dict), ("dataset", dict), ("normalization", dict), ("normalization.mean", list),
    ("normalization.std", list), ("normalization.sha256", str), ("text_encoder", dict), ("text_encoder.name", str),
    ("text_encoder.weights_sha256", str), ("text_encoder.pooling", str), ("text_encoder.fine_tuned", bool),
    ("gt_retrieval", dict), ("gt_retrieval.top1", dict), ("gt_retrieval.top1.mean", float),
    ("gt_retrieval.pool_size", int), ("gt_retrieval.pools_per_replication", int), ("gt_retrieval.items", int))


def _get(card: dict, dotted: str):
    v = card
    for k in dotted.split("."):
        if not isinstance(v, dict) or k not in v:
            raise KeyError(dotted)
        v = v[k]
    return v


def _dataclass_type_errors(d: dict, cls, prefix: str) -> list[str]:
    out = []
    for f in fields(cls):
        if f.name in d and isinstance(f.default, (bool, int, float, str)):
            t = type(f.default)
            if not _is(d[f.name], t):
                out.append(f"{prefix}.{f.name}: expected {_type_name(t)}, got {type(d[f.name]).__name__}")
    return out


def validate_card(card, path: str | Path) -> dict:
    """``card`` when it has every field :func:`load_evaluator` needs with the right JSON type;
    :class:`CorruptEvaluatorFile` naming the file and the first bad field otherwise."""
    from .config import ModelConfig, TrainConfig
    if not isinstance(card, dict):
        raise CorruptEvaluatorFile(f"{path}: expected a JSON object, got a JSON {type(card).__name__}")
    for dotted, t in _SCHEMA:
        try:
            v = _get(card, dotted)
        except KeyError:
            raise CorruptEvaluatorFile(f"{path}: field {dotted} is missing") from None
        if not _is(v, t):
            raise CorruptEvaluatorFile(f"{path}: field {dotted}: expected {_type_name(t)}, got {type(v).__name__}")
    bad = (_dataclass_type_errors(card["config"]["model"], ModelConfig, "config.model")
           + _dataclass_type_errors(card["config"]["train"], TrainConfig, "config.train"))
    if bad:
        raise CorruptEvaluatorFile(f"{path}: field {bad[0]}")
    for key in ("mean", "std"):
        if not all(_is(x, float) for x in card["normalization"][key]):
            raise CorruptEvaluatorFile(f"{path}: field normalization.{key}: expected an array of numbers")
    return card


def read_card(folder: str | Path) -> dict:
    """The validated card of ``folder`` (:func:`validate_card`); one-line errors naming the file."""
    path = Path(folder) / CARD
    if not Path(folder).exists():
        raise EvaluatorIntegrityError(f"{folder}: does not exist (expected an evaluator folder)")
    if Path(folder).is_file():
        raise EvaluatorIntegrityError(f"{folder}: is a file, not an evaluator folder (a folder with {CARD})")
    if not path.exists():
        raise EvaluatorIntegrityError(f"{folder}: not an evaluator folder (no {CARD}); "
                                      f"train one with `hoibench train-evaluator`")
    try:
        card = load_json_bytes(read_regular_file(path, MAX_CARD_BYTES, "evaluator card"), path)
    except ValueError as exc:
        raise CorruptEvaluatorFile(str(exc)) from None
    return validate_card(card, path)


def check_safetensors(data: bytes, path: str | Path) -> None:
    """:class:`CorruptEvaluatorFile` unless ``data`` is a complete safetensors file: an 8-byte
    little-endian header length, a JSON header of tensors with ``dtype``, ``shape`` and
    ``data_offsets``, and exactly the data those offsets cover."""
    if len(data) < 8:
        raise CorruptEvaluatorFile(f"{path}: {len(data)} bytes: truncated, not a safetensors file")
    n = int.from_bytes(data[:8], "little")
    if n > len(data) - 8:
        raise CorruptEvaluatorFile(f"{path}: header length {n} exceeds the file ({len(data)} bytes): truncated or "
                                   f"not a safetensors file")
    try:
        header = load_json_bytes(data[8:8 + n], f"{path} header")
    except ValueError as exc:
        raise CorruptEvaluatorFile(f"{exc} (not a safetensors file)") from None
    if not isinstance(header, dict):
        raise CorruptEvaluatorFile(f"{path}: safetensors header is not a JSON object: not a safetensors file")
    end = 0
    for name, info in header.items():
        if name == "__metadata__":
            continue
        off = info.get("data_offsets") if isinstance(info, dict) else None
        if not (isinstance(off, list) and len(off) == 2 and all(_is(o, int) for o in off) and 0 <= off[0] <= off[1]):
            raise CorruptEvaluatorFile(f"{path}: tensor {name!r} has no valid data_offsets: not a safetensors file")
        end = max(end, off[1])
    if 8 + n + end != len(data):
        raise CorruptEvaluatorFile(f"{path}: the tensors end at byte {8 + n + end} but the file has {len(data)} "
                                   f"bytes: truncated or corrupt")


def _mismatch_detail(folder: Path, card: dict, data: bytes, actual: str) -> str:
    """Which file and card fields changed, from the card's ``integrity`` block."""
    integ = card.get("integrity")
    if not isinstance(integ, dict) or not isinstance(integ.get("sections_sha256"), dict):
        return "the folder was modified after training or mixes files of different evaluators"
    parts = changed_parts(card, data, WEIGHTS, CARD)
    if not parts:
        parts.append(f"{CARD} field evaluator_id or integrity was modified")
    return "; ".join(parts) + " after training"


def verify_folder(folder: str | Path) -> tuple[dict, bytes]:
    """(card, weights bytes) of a folder whose id checks out; raises
    :class:`EvaluatorIntegrityError` naming the file (and field) that is wrong otherwise
    (:class:`CorruptEvaluatorFile` for a file that cannot be parsed at all)."""
    folder = Path(folder)
    card = read_card(folder)
    wpath = folder / WEIGHTS
    if not wpath.exists():
        raise EvaluatorIntegrityError(f"{folder}: {WEIGHTS} is missing (incomplete copy?)")
    if card.get("format") != FORMAT:
        raise EvaluatorIntegrityError(f"{folder / CARD}: field format: {card.get('format')!r} is not {FORMAT!r} "
                                      f"(written by another hoibench version?)")
    data = read_evaluator_file(wpath, MAX_WEIGHTS_BYTES, "evaluator weights", CorruptEvaluatorFile)
    check_safetensors(data, wpath)
    recorded = card["evaluator_id"]
    ok, actual = id_matches(data, card)
    if not ok:
        raise EvaluatorIntegrityError(
            f"{folder}: evaluator id mismatch: {CARD} says {recorded[:12]}... but {WEIGHTS} + {CARD} hash to "
            f"{actual[:12]}...: {_mismatch_detail(folder, card, data, actual)}. Restore the original folder (or "
            f"retrain); scores computed with it would not be comparable")
    return card, data


def load_evaluator(folder: str | Path, *, allow_failed_gate: bool = False, text_encoder: str | None = None,
                   threads: int | None = None, device: str = "cpu"):
    """A verified :class:`~hoibench.evaluator.embed.Evaluator` from ``folder``.

    Checks, each refusing with a one-line error naming the file and field: the card's
    schema, the safetensors file, the evaluator id (weights + card), the normalisation
    statistics against their sha256, the local text encoder against the card's hash, the
    tensors against the config (the text branch's when it is built: on first text use, see
    :class:`~hoibench.evaluator.embed.Evaluator`), and the sanity gate -- re-derived from the
    card's GT scores with this version's rule (:func:`~hoibench.evaluator.gate.card_gate`),
    never read from the card's ``gate`` block. ``allow_failed_gate=True`` loads a failing evaluator for
    inspection. To measure the gate from the weights on data, use
    :func:`~hoibench.evaluator.gate.recompute_gate`.

    ``text_encoder``: where the pretrained sentence encoder is when it is not the packaged
    all-MiniLM-L6-v2 (a local folder); its weights must hash to the card's value. Without
    it, a card naming another encoder uses ``folder/text_encoder/`` when that folder exists
    (an evaluator that ships its own text encoder), else the card's name as a path.
    ``threads``/``device``: see :class:`~hoibench.evaluator.embed.Evaluator`.
    """
    import torch

    from . import text as text_mod
    from .config import EvaluatorConfig
    from .embed import Evaluator
    from .features import FeatureStats
    from .gate import card_gate, check_card_gate
    from .model import MotionEncoder, TextMotionModel

    card, data = verify_folder(folder)
    cpath = Path(folder) / CARD
    if allow_failed_gate:
        card_gate(card)                      # still refuses malformed GT scores
    else:
        check_card_gate(card)
    try:
        config = EvaluatorConfig.from_dict(card["config"])
    except (KeyError, TypeError, ValueError) as exc:
        raise CorruptEvaluatorFile(f"{cpath}: field config: {exc}") from None
    try:
        stats = FeatureStats.from_card(card["normalization"])
    except (KeyError, TypeError, ValueError) as exc:
        raise CorruptEvaluatorFile(f"{cpath}: field normalization: {exc}") from None
    te = card["text_encoder"]
    shipped = Path(folder) / SHIPPED_TEXT_ENCODER
    if text_encoder is None and te["name"] != text_mod.DEFAULT_TEXT_ENCODER and (shipped / "config.json").is_file():
        text_encoder = str(shipped)          # a text encoder shipped inside the evaluator folder
    name, path = text_mod.resolve_text_encoder(text_encoder or te["name"])
    sha = text_mod.weights_sha256(path)
    if sha != te["weights_sha256"]:
        raise EvaluatorIntegrityError(
            f"{folder}: text encoder mismatch: the card names {te['name']} with weights sha256 "
            f"{te['weights_sha256'][:12]}..., but {path} hashes to {sha[:12]}...; pass text_encoder=<folder of "
            f"the same pretrained model>")
    tensors = _load_tensors(data, Path(folder) / WEIGHTS)
    motion = MotionEncoder(config.model)
    _check_tensors(folder, {f"motion.{k}": v for k, v in motion.state_dict().items()},
                   {k: v for k, v in tensors.items() if k.startswith("motion.")})
    with torch.no_grad():
        motion.load_state_dict({k[len("motion."):]: v for k, v in tensors.items() if k.startswith("motion.")})

    def load_text():
        """The whole model and its tokenizer, on first text use (the motion branch shared)."""
        tok, transformer = text_mod.load_pretrained(path)
        model = TextMotionModel(config.model, transformer, te["pooling"])
        _check_tensors(folder, model.own_state_dict(config.train.text_finetune_layers if te["fine_tuned"] else None),
                       tensors)
        with torch.no_grad():
            model.load_state_dict(tensors, strict=False)
        model.motion = motion
        return model, tok

    return Evaluator(config, None, None, stats, card, threads=threads, device=device, motion=motion,
                     load_text=load_text)


def _check_tensors(folder, expected: dict, tensors: dict) -> None:
    """``EvaluatorIntegrityError`` unless ``tensors`` has exactly the names and shapes of ``expected``."""
    missing = sorted(set(expected) - set(tensors))
    extra = sorted(set(tensors) - set(expected))
    bad = sorted(k for k in set(expected) & set(tensors) if tuple(expected[k].shape) != tuple(tensors[k].shape))
    if missing or extra or bad:
        raise EvaluatorIntegrityError(
            f"{folder}: weights do not match the card's config (missing {missing[:3]}, unexpected {extra[:3]}, "
            f"wrong shape {bad[:3]})")


def _load_tensors(data: bytes, path: Path) -> dict:
    from safetensors.torch import load as load_tensors
    try:
        return load_tensors(data)
    except Exception as exc:                 # SafetensorError, dtype errors
        raise CorruptEvaluatorFile(f"{path}: not a readable safetensors file ({' '.join(str(exc).split())[:200]})") \
            from None


# --------------------------------------------------------------------------- store match
def _ids_sha256(ids) -> str:
    return _sha256("\n".join(sorted(ids)).encode())


def store_fingerprint(manifest: dict) -> dict:
    """What a card records about its store beyond the manifest hash, so that a store can be
    matched without the identical manifest: fps, mode, store config sha256, sha256 of the
    sorted train and test clip ids."""
    clips = manifest.get("clips", [])
    cfg = manifest.get("config", {})
    return {"fps": cfg.get("fps"), "mode": cfg.get("mode"), "store_config_sha256": manifest.get("config_sha256"),
            "train_ids_sha256": _ids_sha256(c["id"] for c in clips if c.get("split") == "train"),
            "test_ids_sha256": _ids_sha256(c["id"] for c in clips if c.get("split") == "test")}


def store_mismatches(evaluator, store_manifest: dict) -> list[str]:
    """Reasons why ``evaluator`` (an :class:`Evaluator` or a card dict) should not score the
    store with ``store_manifest``; empty when it fits.

    Compared with the evaluator's card: dataset name; representation version of the
    evaluator's features (or, for a published evaluator, the versions it accepts:
    ``dataset.representations``); normalisation statistics sha256 (the store's train-split
    ``stats/hml263``); and, for cards that record them, fps, mode and the train split's clip
    ids (another train split may contain the clips being scored). The manifest hash itself
    is not compared: the same data prepared into another folder differs only in paths.
    An imported published evaluator's card names the dataset, features, representation
    and fps it was trained for, and no store statistics hash (it normalises with its own
    statistics), so only those are compared."""
    card = evaluator if isinstance(evaluator, dict) else getattr(evaluator, "card", {}) or {}
    eid = str(card.get("evaluator_id", "?"))[:12]
    ds = card.get("dataset") or {}
    out = []

    def differ(what: str, ours, theirs) -> None:
        if ours is not None and ours != theirs:
            out.append(f"evaluator {eid} was trained on {what} {ours!r}, the store has {theirs!r}")

    differ("dataset", ds.get("name"), store_manifest.get("dataset"))
    feats = ds.get("features", "hml263")
    differ(f"{feats} representation", ds.get("representation"), store_manifest.get("representations", {}).get(feats))
    accepted = ds.get("representations")
    theirs = store_manifest.get("representations", {}).get(feats)
    if isinstance(accepted, list) and accepted and theirs not in accepted:   # [] : rows made from joints
        out.append(f"evaluator {eid} reads {feats} rows computed as {', '.join(map(str, accepted))}, the store has "
                   f"{theirs!r}")
    norm = (card.get("normalization") or {}).get("sha256")
    differ("normalisation statistics (train-split stats/hml263) sha256", norm,
           store_manifest.get("stats", {}).get("hml263", {}).get("sha256"))
    fp = store_fingerprint(store_manifest)
    differ("fps", ds.get("fps"), fp["fps"])
    differ("mode", ds.get("mode"), fp["mode"])
    if ds.get("train_ids_sha256") is not None and ds["train_ids_sha256"] != fp["train_ids_sha256"]:
        out.append(f"evaluator {eid} was trained on another train split (sha256 of its clip ids "
                   f"{ds['train_ids_sha256'][:12]}..., the store's {fp['train_ids_sha256'][:12]}...): clips scored "
                   f"here may have been in its training data")
    return out


def check_store_match(evaluator, store_manifest: dict) -> None:
    """:class:`StoreMismatchError` listing :func:`store_mismatches` when there are any."""
    reasons = store_mismatches(evaluator, store_manifest)
    if reasons:
        raise StoreMismatchError("; ".join(reasons))


def dict_diff(a, b, prefix: str) -> list[str]:
    """Dotted paths where two JSON values differ."""
    if isinstance(a, dict) and isinstance(b, dict):
        return [d for k in sorted(set(a) | set(b)) for d in dict_diff(a.get(k), b.get(k), f"{prefix}.{k}")]
    return [] if a == b else [prefix]


# --------------------------------------------------------------------------- show
def _n(d, *keys) -> float:
    """A number inside nested dicts, NaN when absent or not a number (summary never raises)."""
    for k in keys:
        d = d.get(k) if isinstance(d, dict) else None
    return float(d) if isinstance(d, (int, float)) and not isinstance(d, bool) else float("nan")


def _d(d, key) -> dict:
    v = d.get(key) if isinstance(d, dict) else None
    return v if isinstance(v, dict) else {}


def summary(card: dict, verified: bool | None = None) -> str:
    """Human-readable card summary (what ``hoibench evaluator show EVAL`` prints). The sanity
    gate line is re-derived from the GT scores (:func:`~hoibench.evaluator.gate.card_gate`)."""
    from .errors import EvaluatorError
    from .gate import card_gate
    cfg = _d(card, "config")
    m, t = _d(cfg, "model"), _d(cfg, "train")
    ds, te, g, norm = _d(card, "dataset"), _d(card, "text_encoder"), _d(card, "gt_retrieval"), _d(card, "normalization")
    curve = _d(_d(card, "curve"), "summary")
    lines = [f"evaluator {card.get('evaluator_id', '?')}" + ("" if verified is None else
                                                            ("  (id verified)" if verified else "  (ID MISMATCH)")),
             f"  hoibench {card.get('toolkit_version', '?')}, format {card.get('format', '?')}, "
             f"seed {card.get('seed')}",
             f"  model: size {cfg.get('size')}, variant {m.get('variant')}, width {m.get('width')}, layers "
             f"{m.get('layers')}, heads {m.get('heads')}, dropout {m.get('dropout')}, output {m.get('embed_dim')}",
             f"  training: {t.get('epochs')} epochs, batch {t.get('batch_size')}, lr {t.get('lr')}, text frozen "
             f"until epoch {t.get('text_unfreeze_epoch')}, control {t.get('control')}",
             f"  dataset: {ds.get('name')} manifest {str(ds.get('manifest_sha256', ''))[:12]}, train "
             f"{ds.get('train_items')} items / test {ds.get('test_items')} items, {ds.get('representation')}",
             f"  normalisation: {norm.get('source')} sha256 {str(norm.get('sha256', ''))[:12]}",
             f"  text encoder: {te.get('name')} sha256 {str(te.get('weights_sha256', ''))[:12]}, "
             f"{'fine-tuned' if te.get('fine_tuned') else 'frozen'}"]
    if curve:
        lines.append(f"  curve: loss {_n(curve, 'first_loss'):.3f} -> {_n(curve, 'final_loss'):.3f}, "
                     f"in-batch top-1 {_n(curve, 'final_batch_top1'):.3f}, "
                     f"temperature {_n(curve, 'final_temperature'):.4f}")
    if g:
        lines.append(f"  GT retrieval ({g.get('split')}, {g.get('items')} items, pool {g.get('pool_size')}, "
                     f"{g.get('replications')} replications): top-1 {_n(g, 'top1', 'mean'):.3f} "
                     f"+- {_n(g, 'top1', 'ci95'):.3f}, top-2 {_n(g, 'top2', 'mean'):.3f}, "
                     f"top-3 {_n(g, 'top3', 'mean'):.3f}, MM-Dist {_n(g, 'mm_dist', 'mean'):.3f}, "
                     f"chance {_n(g, 'chance_top1'):.3f}")
        lines.append(f"  GT-vs-GT FID (halves of {g.get('half_size')}): {_n(g, 'fid_gt_halves'):.4f} "
                     f"(relative {_n(g, 'fid_gt_relative'):.3f}; mean over {g.get('fid_gt_splits', 1)} splits "
                     f"{_n(g, 'fid_gt_relative_mean'):.3f}; structureless noise {_n(g, 'fid_noise_relative'):.3f})")
        if g.get("pool_size") != g.get("requested_pool_size"):
            lines.append(f"  note: {g.get('pool_rule')}")
    try:
        gate = card_gate(card)
        lines.append(f"  {gate.diagnostic()} (re-derived from the GT scores)")
    except EvaluatorError as exc:
        lines.append(f"  sanity gate: cannot be derived ({exc})")
    return "\n".join(lines)


def show(folder: str | Path) -> str:
    card = read_card(folder)
    try:
        verify_folder(folder)
        ok = True
    except CorruptEvaluatorFile:
        raise
    except EvaluatorIntegrityError:
        ok = False
    return summary(card, ok)
