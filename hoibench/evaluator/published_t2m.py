"""The published ``t2m`` evaluator: Guo et al.'s text-motion matching model (CVPR 2022).

The evaluator of text-to-motion (``networks/modules.py``), which T2M, MDM, T2M-GPT, MoMask
and HOI-Diff scored with, rebuilt here so that its released ``finest.tar`` loads exactly:

* movement encoder: ``main`` = Conv1d(259 -> 512, kernel 4, stride 2, padding 1), Dropout
  0.2, LeakyReLU 0.2, Conv1d(512 -> 512, 4, 2, 1), Dropout, LeakyReLU; ``out_net`` =
  Linear(512 -> 512) per step. Input: the 263 hml263 features minus the last 4 (foot
  contacts), normalised; T frames give T // 4 steps;
* motion encoder: ``input_emb`` Linear(512 -> 1024), bidirectional GRU(1024) from the learned
  initial state ``hidden`` (2, 1, 1024), packed by length (steps = frames // 4);
  ``output_net`` = Linear(2048 -> 1024), LayerNorm, LeakyReLU 0.2, Linear(1024 -> 512) on the
  concatenated last forward and backward states;
* text encoder: word vector (300) + ``pos_emb`` Linear(15 -> 300) of the POS one-hot,
  ``input_emb`` Linear(300 -> 512), bidirectional GRU(512) from ``hidden`` (2, 1, 512), packed
  by length, ``output_net`` 1024 -> 512 -> 512 as above.

Embeddings are the raw 512-d outputs (not normalised), as the published metrics use them.
State-dict names are the reference's, so ``finest.tar`` (``TextMotionMatchTrainer.save``:
keys ``text_encoder``, ``motion_encoder``, ``movement_encoder``, plus optimiser states and
``epoch``) loads with ``torch.load(weights_only=True)`` after every tensor's shape is checked.

Motions (:meth:`T2MEvaluator.embed_motion`): raw hml263 rows (hoibench stores raw features;
hoi269 rows are read by their first 263 columns), cropped to the first 196 rows
(``max_motion_length``) and then to a multiple of 4 (the reference's length crop at offset
0), normalised with the evaluator's own ``mean``/``std`` (text-to-motion's
``Comp_v6_KLD01/meta``), zero-padded *after* normalisation to 196 rows, batched longest
first as ``get_co_embeddings`` does, the input order restored. A clip of fewer than 4 rows
is refused.

Folder: ``weights.safetensors`` (``movement_encoder.*``, ``motion_encoder.*``,
``text_encoder.*``, ``vocab.vectors``, ``meta.mean``, ``meta.std``) and ``card.json``
(``"backend": "t2m"``, sizes, vocabulary words, sources with sha256, evaluator id):
written by :func:`import_t2m`, read by :func:`load_t2m`; nothing is unpickled. The card holds
nothing version- or machine-dependent, so the same files import to the same evaluator id
(what a paper row's ``comparable_with.evaluator_id`` names).
"""
from __future__ import annotations

import io
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Sequence

import numpy as np
import torch
from torch import nn
from torch.nn.utils.rnn import pack_padded_sequence

from .embed import EMBED_THREADS, CardBacked, as_clip_list, deterministic
from .errors import CorruptEvaluatorFile, EvaluatorError, EvaluatorIntegrityError, read_evaluator_file
from .t2m_text import MAX_TOKENS, POS_SLOTS, SEQ_LEN, WORD_DIM, Vocabulary, read_glove

BACKEND = "t2m"
PARTS = ("movement_encoder", "motion_encoder", "text_encoder")
#: hml263 columns the evaluator reads; the last FOOT_CONTACTS of them are left out
POSE_DIM = 263
FOOT_CONTACTS = 4
MAX_FRAMES = 196
UNIT_LENGTH = 4
#: representations whose hml263 rows are computed as HumanML3D's (what the evaluator saw)
LEGACY_REPRESENTATIONS = ("hml263-legacy-1.0", "hml263-legacy-hoidiff-1.0")
MAX_CHECKPOINT_BYTES = 2 * 1024 ** 3
TRAINED_ON = ("not recorded in the files: text-to-motion's release was trained on HumanML3D's train split; "
              "a retrained evaluator in the same layout (e.g. HOI-Diff's for BEHAVE) on its own dataset")


@dataclass(frozen=True)
class T2MDims:
    """Layer sizes (the published evaluator's by default; tests use small ones)."""

    pose: int = POSE_DIM
    word: int = WORD_DIM
    pos: int = len(POS_SLOTS)
    movement_hidden: int = 512
    movement_latent: int = 512
    motion_hidden: int = 1024
    text_hidden: int = 512
    output: int = 512


def _head(width: int, out: int) -> nn.Sequential:
    return nn.Sequential(nn.Linear(2 * width, width), nn.LayerNorm(width), nn.LeakyReLU(0.2), nn.Linear(width, out))


class MovementEncoder(nn.Module):
    """(B, T, pose - 4) -> (B, T // 4, latent): two strided convolutions and a linear map."""

    def __init__(self, d: T2MDims, contacts: int = FOOT_CONTACTS):
        super().__init__()
        self.main = nn.Sequential(nn.Conv1d(d.pose - contacts, d.movement_hidden, 4, 2, 1), nn.Dropout(0.2),
                                  nn.LeakyReLU(0.2), nn.Conv1d(d.movement_hidden, d.movement_latent, 4, 2, 1),
                                  nn.Dropout(0.2), nn.LeakyReLU(0.2))
        self.out_net = nn.Linear(d.movement_latent, d.movement_latent)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.out_net(self.main(x.transpose(1, 2)).transpose(1, 2))


class _BiGRUEncoder(nn.Module):
    """Linear input map, bidirectional GRU from a learned initial state over the packed
    sequences (lengths sorted longest first), head on [last forward, last backward]."""

    def __init__(self, d_in: int, width: int, out: int):
        super().__init__()
        self.input_emb = nn.Linear(d_in, width)
        self.gru = nn.GRU(width, width, batch_first=True, bidirectional=True)
        self.output_net = _head(width, out)
        self.hidden = nn.Parameter(torch.zeros(2, 1, width))

    def encode(self, x: torch.Tensor, lengths: torch.Tensor) -> torch.Tensor:
        packed = pack_padded_sequence(self.input_emb(x), lengths.cpu(), batch_first=True)
        _, last = self.gru(packed, self.hidden.expand(-1, x.shape[0], -1).contiguous())
        return self.output_net(torch.cat([last[0], last[1]], dim=-1))


class MotionEncoder(_BiGRUEncoder):
    def __init__(self, d: T2MDims):
        super().__init__(d.movement_latent, d.motion_hidden, d.output)

    def forward(self, movements: torch.Tensor, steps: torch.Tensor) -> torch.Tensor:
        return self.encode(movements, steps)


class TextEncoder(_BiGRUEncoder):
    def __init__(self, d: T2MDims):
        super().__init__(d.word, d.text_hidden, d.output)
        self.pos_emb = nn.Linear(d.pos, d.word)

    def forward(self, words: torch.Tensor, onehot: torch.Tensor, lengths: torch.Tensor) -> torch.Tensor:
        return self.encode(words + self.pos_emb(onehot), lengths)


def build_parts(dims: T2MDims, contacts: int = FOOT_CONTACTS) -> dict[str, nn.Module]:
    """The three encoders; ``contacts``: trailing pose columns the movement encoder does not
    read (4 foot contacts of hml263; 0 for CHOIS's joints24 evaluator)."""
    return {"movement_encoder": MovementEncoder(dims, contacts), "motion_encoder": MotionEncoder(dims),
            "text_encoder": TextEncoder(dims)}


def expected_shapes(dims: T2MDims, contacts: int = FOOT_CONTACTS) -> dict[str, dict[str, tuple[int, ...]]]:
    """Per part, every state-dict name and its shape (modules built without storage)."""
    with torch.device("meta"):
        parts = build_parts(dims, contacts)
    return {name: {k: tuple(v.shape) for k, v in m.state_dict().items()} for name, m in parts.items()}


def check_part(state, part: str, expected: dict[str, tuple[int, ...]], where: str) -> dict[str, torch.Tensor]:
    """``state`` when it has exactly ``expected``'s names with those shapes (float tensors);
    one-line errors naming the key and both shapes otherwise."""
    if not isinstance(state, dict):
        raise EvaluatorError(f"{where}: {part} is a {type(state).__name__}, expected a state dict")
    for key, shape in expected.items():
        if key not in state:
            raise EvaluatorError(f"{where}: {part}.{key} is missing (not text-to-motion's evaluator?)")
        t = state[key]
        if not isinstance(t, torch.Tensor) or not t.is_floating_point():
            raise EvaluatorError(f"{where}: {part}.{key} is not a float tensor")
        if tuple(t.shape) != shape:
            raise EvaluatorError(f"{where}: {part}.{key} has shape {tuple(t.shape)}, expected {shape}")
    extra = sorted(set(state) - set(expected))
    if extra:
        raise EvaluatorError(f"{where}: {part}.{extra[0]} is not a tensor of the t2m evaluator")
    return {k: state[k].detach().to(torch.float32).contiguous() for k in expected}


# ============================================================================ import
def _sha256_file(path: Path) -> str:
    from ..core.io import sha256_regular_file
    return sha256_regular_file(path, what="t2m evaluator file").hexdigest()


def read_checkpoint(path: str | Path, dims: T2MDims = T2MDims(),
                    contacts: int = FOOT_CONTACTS) -> tuple[dict[str, torch.Tensor], dict]:
    """The three encoders' tensors of a ``finest.tar`` (prefixed ``part.``) and its
    ``epoch``/``iter``; read with ``torch.load(weights_only=True)``, every shape checked."""
    path = Path(path)
    if not path.exists():
        raise EvaluatorError(f"--checkpoint {path}: no such file (text-to-motion's "
                             f"checkpoints/t2m/text_mot_match/model/finest.tar)")
    raw = read_evaluator_file(path, MAX_CHECKPOINT_BYTES, "checkpoint")
    from .safe_checkpoint import not_a_checkpoint
    why = not_a_checkpoint(raw[:4096])
    if why:
        raise EvaluatorError(f"{path}: {why}")
    try:
        ckpt = torch.load(io.BytesIO(raw), map_location="cpu", weights_only=True)
    except Exception as exc:                    # truncated zip, not a torch file, a refused global
        raise EvaluatorError(f"{path}: not a readable torch checkpoint ({type(exc).__name__}: "
                             f"{' '.join(str(exc).split())[:160]})") from None
    if not isinstance(ckpt, dict):
        raise EvaluatorError(f"{path}: holds a {type(ckpt).__name__}, expected the dict of "
                             f"TextMotionMatchTrainer.save")
    shapes = expected_shapes(dims, contacts)
    tensors: dict[str, torch.Tensor] = {}
    for part in PARTS:
        if part not in ckpt:
            raise EvaluatorError(f"{path}: no key {part!r} (finest.tar of text-to-motion's text_mot_match holds "
                                 f"{', '.join(PARTS)})")
        for k, v in check_part(ckpt[part], part, shapes[part], str(path)).items():
            tensors[f"{part}.{k}"] = v
    info = {k: ckpt[k] for k in ("epoch", "iter") if isinstance(ckpt.get(k), int) and not isinstance(ckpt[k], bool)}
    return tensors, info


def read_meta(folder: str | Path, dims: T2MDims = T2MDims()) -> tuple[np.ndarray, np.ndarray]:
    """``mean.npy``/``std.npy`` of the evaluator's ``meta/`` folder ((pose,) each, std > 0)."""
    from ..core.io import read_regular_file
    folder = Path(folder)
    out = []
    for name in ("mean.npy", "std.npy"):
        path = folder / name
        if not path.is_file():
            raise EvaluatorError(f"--meta {folder}: {name} is missing (text-to-motion's "
                                 f"checkpoints/t2m/Comp_v6_KLD01/meta holds mean.npy and std.npy)")
        try:
            a = np.load(io.BytesIO(read_regular_file(path, 1 << 24, name)), allow_pickle=False)
        except ValueError as exc:
            raise EvaluatorError(f"{path}: not a readable .npy ({' '.join(str(exc).split())[:120]})") from None
        if a.shape != (dims.pose,) or a.dtype not in (np.float32, np.float64) or not np.isfinite(a).all():
            raise EvaluatorError(f"{path}: expected {dims.pose} finite floats, got shape {a.shape} dtype {a.dtype}")
        out.append(a)
    if not (out[1] > 0).all():
        raise EvaluatorError(f"{folder / 'std.npy'}: column {int(np.argmin(out[1] > 0))} is not positive")
    return out[0], out[1]


#: the published evaluator's sizes: what ``hoibench evaluator import t2m`` expects
DEFAULT_DIMS = T2MDims()


def import_t2m(out: Path, checkpoint: Path, glove: Path, meta: Path, dims: T2MDims | None = None) -> str:
    """Write the evaluator folder ``out`` from text-to-motion's files (``finest.tar``, the
    ``glove/`` folder, the ``meta/`` folder with ``mean.npy``/``std.npy``); return its id.
    Every file is checked before anything is written. ``dims``: the layer sizes
    (:data:`DEFAULT_DIMS`, the published ones, when None)."""
    from .card import write_folder
    dims = DEFAULT_DIMS if dims is None else dims
    tensors, info = read_checkpoint(checkpoint, dims)
    words, vectors = read_glove(glove)
    mean, std = read_meta(meta, dims)
    for part, module in build_parts(dims).items():        # the checked tensors load strictly
        module.load_state_dict({k[len(part) + 1:]: v for k, v in tensors.items() if k.startswith(part + ".")})
    tensors["vocab.vectors"] = torch.from_numpy(vectors)
    tensors["meta.mean"], tensors["meta.std"] = torch.from_numpy(mean), torch.from_numpy(std)
    sources = {"checkpoint": {"file": Path(checkpoint).name, "sha256": _sha256_file(Path(checkpoint)), **info},
               "glove": {n: _sha256_file(Path(glove) / n) for n in ("our_vab_data.npy", "our_vab_words.pkl",
                                                                      "our_vab_idx.pkl")},
               "meta": {n: _sha256_file(Path(meta) / n) for n in ("mean.npy", "std.npy")}}
    card = {"backend": BACKEND, "kind": "contrastive", "variant": "human", "embed_dim": dims.output,
            "dims": asdict(dims), "max_frames": MAX_FRAMES, "unit_length": UNIT_LENGTH,
            "description": "Guo et al. 2022 text-motion matching evaluator (text-to-motion networks/modules.py)",
            "trained_on": TRAINED_ON, "sources": sources,
            "dataset": {"name": None, "features": "hml263", "representations": list(LEGACY_REPRESENTATIONS)},
            "vocabulary": words}
    return write_folder(out, tensors, card)


# ============================================================================ load
def verify_t2m_folder(folder: str | Path, backend: str = BACKEND) -> tuple[dict, bytes]:
    """(card, weights bytes) of a t2m-architecture evaluator folder of ``backend`` whose id
    checks out; one-line errors naming the file (and field) otherwise."""
    from ..core.io import load_json_bytes, read_regular_file
    from .card import CARD, FORMAT, MAX_CARD_BYTES, MAX_WEIGHTS_BYTES, WEIGHTS, changed_parts, check_safetensors, \
        compute_id
    folder = Path(folder)
    cpath, wpath = folder / CARD, folder / WEIGHTS
    for path in (cpath, wpath):
        if not path.exists():
            raise EvaluatorIntegrityError(f"{folder}: {path.name} is missing (incomplete copy?)")
    try:
        card = load_json_bytes(read_regular_file(cpath, MAX_CARD_BYTES, "evaluator card"), cpath)
        data = read_regular_file(wpath, MAX_WEIGHTS_BYTES, "evaluator weights")
    except ValueError as exc:
        raise CorruptEvaluatorFile(str(exc)) from None
    for key, t in (("backend", str), ("format", str), ("evaluator_id", str), ("dims", dict), ("vocabulary", list)):
        if not isinstance(card, dict) or not isinstance(card.get(key), t):
            raise CorruptEvaluatorFile(f"{cpath}: field {key}: missing or not a {t.__name__}")
    if card["backend"] != backend or card["format"] != FORMAT:
        raise EvaluatorIntegrityError(f"{cpath}: field backend/format: {card['backend']!r}/{card['format']!r} is not "
                                      f"a {backend!r} evaluator of {FORMAT!r}")
    check_safetensors(data, wpath)
    actual = compute_id(data, card)
    if actual != card["evaluator_id"]:
        detail = "; ".join(changed_parts(card, data)) or f"{CARD} field evaluator_id or integrity was modified"
        raise EvaluatorIntegrityError(f"{folder}: evaluator id mismatch: {CARD} says {card['evaluator_id'][:12]}... "
                                      f"but the files hash to {actual[:12]}...: {detail} after import; import again")
    return card, data


#: the name ``hoibench evaluator show`` looks up in a backend's loader module
verify_folder = verify_t2m_folder


def summary(card: dict, verified: bool | None = None) -> str:
    """The card as ``hoibench evaluator show`` prints it: id, backend, what it was trained
    on, the source files' sha256 (first 12 hex digits)."""
    state = "" if verified is None else ("  (id verified)" if verified else "  (ID MISMATCH)")
    lines = [f"evaluator {card.get('evaluator_id', '?')}{state}",
             f"  backend {card.get('backend')}: {card.get('description', '')}",
             f"  trained on: {card.get('trained_on', '?')}",
             f"  sizes: {card.get('dims')}, vocabulary {len(card.get('vocabulary') or [])} words"]
    for what, files in sorted((card.get("sources") or {}).items()):
        if isinstance(files, dict):
            lines.append(f"  {what}: " + ", ".join(f"{k} {str(v)[:12]}" for k, v in sorted(files.items())))
    return "\n".join(lines)


def load_t2m(folder: str | Path, *, threads: int | None = None, device: str = "cpu", **_ignored) -> "T2MEvaluator":
    """A verified :class:`T2MEvaluator` from ``folder``. There is no card gate (the weights
    were not trained here); ``hoibench evaluate`` measures the sanity gate on the store."""
    return load_folder(folder, T2MEvaluator, BACKEND, FOOT_CONTACTS, threads=threads, device=device)


def load_folder(folder: str | Path, cls: type, backend: str, contacts: int, *, threads: int | None = None,
                device: str = "cpu") -> "T2MEvaluator":
    """``cls`` (:class:`T2MEvaluator` or a subclass) built from the verified ``backend`` folder
    ``folder``, whose movement encoder leaves out ``contacts`` trailing pose columns."""
    from safetensors.torch import load as load_tensors
    from .card import WEIGHTS
    card, data = verify_t2m_folder(folder, backend)
    where = str(Path(folder) / WEIGHTS)
    try:
        dims = T2MDims(**{k: int(v) for k, v in card["dims"].items()})
        tensors = load_tensors(data)
    except (TypeError, ValueError) as exc:
        raise CorruptEvaluatorFile(f"{folder}: card field dims or {WEIGHTS}: {' '.join(str(exc).split())[:160]}") \
            from None
    except Exception as exc:                                   # SafetensorError
        raise CorruptEvaluatorFile(f"{where}: not a readable safetensors file ({str(exc)[:120]})") from None
    parts, shapes = build_parts(dims, contacts), expected_shapes(dims, contacts)
    for part, module in parts.items():
        own = {k[len(part) + 1:]: v for k, v in tensors.items() if k.startswith(part + ".")}
        module.load_state_dict(check_part(own, part, shapes[part], where))
    for key in ("vocab.vectors", "meta.mean", "meta.std"):
        if key not in tensors:
            raise CorruptEvaluatorFile(f"{where}: tensor {key} is missing")
    vocab = Vocabulary(card["vocabulary"], tensors["vocab.vectors"].numpy())
    stats = (tensors["meta.mean"].numpy(), tensors["meta.std"].numpy())
    return cls(parts, vocab, stats, card, dims, threads=threads, device=device)


# ============================================================================ embeddings
def _order(lengths: Sequence[int]) -> np.ndarray:
    """Longest first, as ``np.argsort(lengths)[::-1]`` (the reference's batch order)."""
    return np.argsort(np.asarray(lengths))[::-1].copy()


class T2MEvaluator(CardBacked):
    """Embeds motions and captions with the published t2m evaluator (same API as
    :class:`hoibench.evaluator.embed.Evaluator`: ``embed_motion``, ``embed_text``, ``id``, ``card``)."""

    variant = "human"
    #: trailing pose columns left out of the movement encoder's input, frames per step, caption tokens kept
    foot_contacts = FOOT_CONTACTS
    unit_length = UNIT_LENGTH
    max_tokens = MAX_TOKENS

    def __init__(self, parts: dict[str, nn.Module], vocab: Vocabulary, stats: tuple[np.ndarray, np.ndarray],
                 card: dict, dims: T2MDims, threads: int | None = None, device: str = "cpu"):
        self.device = torch.device(device)
        self.parts = {k: m.to(self.device).eval() for k, m in parts.items()}
        self.vocab, self.mean, self.std = vocab, stats[0], stats[1]
        self.card, self.dims = card, dims
        self.threads = EMBED_THREADS if threads is None else threads

    @property
    def representation(self) -> str | None:
        return None                           # the card lists accepted versions instead

    @property
    def embed_dim(self) -> int:
        return self.dims.output

    def motion_inputs(self, clip: np.ndarray, where: str) -> tuple[np.ndarray, int]:
        """(196, pose) normalised, zero-padded rows of one raw clip and its length (frames)."""
        clip = np.asarray(clip)
        if clip.ndim != 2 or clip.shape[1] < self.dims.pose:
            raise ValueError(f"{where}: expected (T, {self.dims.pose}) hml263 rows (or hoi269), got shape {clip.shape}")
        n = min(len(clip), MAX_FRAMES) // UNIT_LENGTH * UNIT_LENGTH
        if n < UNIT_LENGTH:
            raise ValueError(f"{where}: {len(clip)} frame(s); the t2m evaluator needs at least {UNIT_LENGTH}")
        rows = clip[:n, :self.dims.pose]
        dtype = np.result_type(rows.dtype, self.mean.dtype)
        out = np.zeros((MAX_FRAMES, self.dims.pose), np.float32)
        out[:n] = (rows.astype(dtype) - self.mean) / self.std
        return out, n

    def embed(self, features, lengths=None, batch_size: int = 32) -> np.ndarray:
        return self.embed_motion(features, lengths, batch_size)

    def embed_motion(self, features, lengths=None, batch_size: int = 32) -> np.ndarray:
        """(N, 512) float32 embeddings of raw feature rows: a padded (N, T, D) array with
        ``lengths``, or a list of (T_i, D) arrays (D = 263, or 269 read by its first 263)."""
        clips = as_clip_list(features, lengths)
        out = np.zeros((len(clips), self.embed_dim), np.float32)
        with deterministic(self.threads), torch.inference_mode():
            for s in range(0, len(clips), batch_size):
                prepared = [self.motion_inputs(c, f"features[{s + i}]") for i, c in enumerate(clips[s:s + batch_size])]
                order = _order([n for _, n in prepared])
                x = torch.from_numpy(np.stack([prepared[i][0] for i in order])).to(self.device)
                steps = torch.tensor([prepared[i][1] // self.unit_length for i in order])
                movements = self.parts["movement_encoder"](x[..., :x.shape[-1] - self.foot_contacts])
                emb = self.parts["motion_encoder"](movements, steps).float().cpu().numpy()
                out[s + order] = emb
        return out

    def text_tokens(self, captions: Sequence[str], tokens=None) -> list[list[str]]:
        """Each caption's ``word/POS`` tokens: ``tokens[i]`` when given (not None), else
        hoibench's HumanML3D tagger (:func:`hoibench.text.tokens.tokens`)."""
        from ..text.tokens import tokens as tag
        if tokens is not None and len(tokens) != len(captions):
            raise ValueError(f"tokens: expected {len(captions)} token lists, got {len(tokens)}")
        out = []
        for i, cap in enumerate(captions):
            given = None if tokens is None else tokens[i]
            if isinstance(given, str):
                given = given.split()
            out.append(list(given) if given is not None else tag(cap))
        return out

    def embed_text(self, captions: Sequence[str], tokens=None, batch_size: int = 32) -> np.ndarray:
        """(N, 512) float32 embeddings of captions. ``tokens``: per caption a list of
        ``word/POS`` strings (or one space-separated string, HumanML3D's column) or None."""
        if isinstance(captions, str):
            raise ValueError("captions: expected a list of strings, got one string")
        captions = list(captions)
        toks = self.text_tokens(captions, tokens)
        out = np.zeros((len(captions), self.embed_dim), np.float32)
        with deterministic(self.threads), torch.inference_mode():
            for s in range(0, len(captions), batch_size):
                enc = [self.vocab.encode(t, f"tokens[{s + i}]", self.max_tokens)
                       for i, t in enumerate(toks[s:s + batch_size])]
                order = np.argsort([-n for _, _, n in enc], kind="stable")
                words = torch.from_numpy(np.stack([enc[i][0] for i in order])).float().to(self.device)
                onehot = torch.from_numpy(np.stack([enc[i][1] for i in order])).float().to(self.device)
                lens = torch.tensor([enc[i][2] for i in order])
                out[s + order] = self.parts["text_encoder"](words, onehot, lens).float().cpu().numpy()
        return out


__all__ = ["BACKEND", "T2MDims", "T2MEvaluator", "MovementEncoder", "MotionEncoder", "TextEncoder", "build_parts",
           "expected_shapes", "check_part", "read_checkpoint", "read_meta", "import_t2m", "verify_t2m_folder",
           "verify_folder", "summary", "load_t2m", "LEGACY_REPRESENTATIONS", "SEQ_LEN"]
