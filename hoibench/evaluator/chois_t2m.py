"""CHOIS's text-motion evaluator (Li et al., ECCV 2024): the t2m architecture on joints24.

CHOIS trained Guo et al.'s matching model on OMOMO (GitHub ``lijiaman/chois_release``,
commit 9cd4cf6, ``t2m_eval/``); hoibench runs it with the ``t2m`` backend's modules
(:mod:`hoibench.evaluator.published_t2m`), one more weight set and input mapping:

* sizes (``networks/evaluator_wrapper.py`` ``EvaluatorModelWrapper.__init__``): ``dim_pose =
  24 * 3``, word 300, POS 15, text hidden 512, motion hidden 1024, co-embedding 512,
  ``max_motion_length = 120``, ``max_text_len = 30``; movement hidden/latent 512
  (text-to-motion's option defaults). The movement encoder reads all 72 columns
  (``build_models`` passes ``dim_pose`` and ``get_co_embeddings`` feeds ``motions`` whole:
  no foot-contact columns to drop);
* motions (``t2m_eval/motion_loaders/chois_eval_dataset.py`` ``__getitem__``, and
  ``t2m_eval/data/omomo_dataset.py`` for the ground truth): the window's global joints24
  positions (T, 24, 3), metres, z up, 30 fps, in CHOIS's canonical window frame (frame 0's
  pelvis-to-left-hip direction along +x, frame 0's SMPL translation at xy = 0), flattened to
  (T, 72), normalised ``(x - jpos_mean) / jpos_std`` (``t2m_mean_std_jpos.p``); no cropping
  (CHOIS's windows are 120 frames; hoibench keeps the first 120 of a longer clip), rows
  past the length zero *after* normalisation (``omomo_dataset.py``'s padding), length =
  frames, ``steps = frames // 4`` (``unit_length``; the frames are not cropped to a multiple
  of 4). Batches are sorted longest first, as ``get_co_embeddings`` does;
* captions: ``word/POS`` tokens, ``sos`` + the first 30 + ``eos`` (``max_text_len = 30``),
  GloVe ``our_vab`` vocabulary. CHOIS reads the *last* line of each clip's
  ``omomo_text_anno_txt_data/<seq>.txt`` (its loop keeps overwriting ``text_dict``).

Folder: as the t2m backend's (``weights.safetensors`` + ``card.json`` with ``"backend":
"chois"``); nothing is unpickled on load.
"""
from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch

from .published_t2m import (T2MDims, T2MEvaluator, _sha256_file, build_parts, load_folder, read_checkpoint, read_meta,
                            summary, verify_t2m_folder)
from .t2m_text import GLOVE_FILES, read_glove

BACKEND = "chois"
JOINTS = 24
POSE_DIM = JOINTS * 3
MAX_FRAMES = 120
UNIT_LENGTH = 4
MAX_TOKENS = 30
FPS = 30
#: the published evaluator's sizes (what ``hoibench evaluator import chois`` expects)
DEFAULT_DIMS = T2MDims(pose=POSE_DIM)
TRAINED_ON = ("CHOIS's OMOMO (FullBodyManipulation) windows of 120 frames at 30 fps, joints24 positions "
              "(t2m_eval/train_tex_mot_match.py); split not recorded in the files")


def import_chois(out: Path, checkpoint: Path, glove: Path, meta: Path, dims: T2MDims | None = None) -> str:
    """Write the evaluator folder ``out`` from CHOIS's files: ``finest.tar`` (its
    ``text_motion_features/model/``), the GloVe ``glove_840B/`` folder (``our_vab_*``) and a
    ``meta/`` folder with ``mean.npy``/``std.npy`` (72,) taken from
    ``t2m_mean_std_jpos.p`` (docs/evaluator.md); return the evaluator id."""
    from .card import write_folder
    dims = DEFAULT_DIMS if dims is None else dims
    tensors, info = read_checkpoint(checkpoint, dims, contacts=0)
    words, vectors = read_glove(glove)
    mean, std = read_meta(meta, dims)
    for part, module in build_parts(dims, 0).items():
        module.load_state_dict({k[len(part) + 1:]: v for k, v in tensors.items() if k.startswith(part + ".")})
    tensors["vocab.vectors"] = torch.from_numpy(vectors)
    tensors["meta.mean"], tensors["meta.std"] = torch.from_numpy(mean), torch.from_numpy(std)
    sources = {"checkpoint": {"file": Path(checkpoint).name, "sha256": _sha256_file(Path(checkpoint)), **info},
               "glove": {n: _sha256_file(Path(glove) / n) for n in GLOVE_FILES},
               "meta": {n: _sha256_file(Path(meta) / n) for n in ("mean.npy", "std.npy")}}
    card = {"backend": BACKEND, "kind": "contrastive", "variant": "human", "embed_dim": dims.output,
            "dims": asdict(dims), "max_frames": MAX_FRAMES, "unit_length": UNIT_LENGTH, "max_tokens": MAX_TOKENS,
            "fps": FPS, "description": "CHOIS's text-motion matching evaluator (t2m architecture on joints24; "
                                       "lijiaman/chois_release t2m_eval)",
            "trained_on": TRAINED_ON, "sources": sources,
            "dataset": {"name": "omomo", "features": "joints24", "representations": []},
            "vocabulary": words}
    return write_folder(out, tensors, card)


def verify_folder(folder: str | Path) -> tuple[dict, bytes]:
    """(card, weights bytes) of a ``chois`` evaluator folder whose id checks out."""
    return verify_t2m_folder(folder, BACKEND)


def load_chois(folder: str | Path, *, threads: int | None = None, device: str = "cpu",
               **_ignored) -> "ChoisEvaluator":
    """A verified :class:`ChoisEvaluator` from ``folder`` (no card gate, as the t2m backend)."""
    return load_folder(folder, ChoisEvaluator, BACKEND, 0, threads=threads, device=device)


class ChoisEvaluator(T2MEvaluator):
    """The t2m evaluator with CHOIS's input mapping (module docstring): joints24 rows, all
    72 columns read, 120 frames, no unit-length crop, 30 caption tokens."""

    foot_contacts = 0
    unit_length = UNIT_LENGTH
    max_tokens = MAX_TOKENS

    def embed_motion(self, features, lengths=None, batch_size: int = 32) -> np.ndarray:
        """(N, 512) float32 embeddings of joints24 clips: (N, T, 24, 3) or (N, T, 72) with
        ``lengths``, or a list of (T, 24, 3) / (T, 72) arrays."""
        if isinstance(features, (list, tuple)):
            features = [np.asarray(c).reshape(len(c), -1) if np.ndim(c) == 3 else c for c in features]
        elif np.ndim(features) == 4:
            f = np.asarray(features)
            features = f.reshape(f.shape[0], f.shape[1], -1)
        return super().embed_motion(features, lengths, batch_size)

    # ------------------------------------------------------------------ rows for scoring
    def store_rows(self, store, clip_id: str) -> np.ndarray:
        """(T, 72) joints24 rows of a stored clip's first 120 frames in CHOIS's window frame
        (:func:`hoibench.metrics.chois_inputs.window_joints24`: proxy hand joints, z-up)."""
        from ..metrics.chois_inputs import window_joints24
        joints = store.load(clip_id, keys=("joints",))["joints"][:MAX_FRAMES]
        return window_joints24(joints).reshape(len(joints), POSE_DIM)

    def sample_rows(self, arrays: dict, k: int, store, clip_id: str) -> np.ndarray:
        """(T, 72) joints24 rows of sample ``k`` of a submission file's ``joints``, as
        :meth:`store_rows` makes them (each clip in its own frame 0's window frame)."""
        from ..metrics.chois_inputs import window_joints24
        try:
            joints = np.asarray(arrays["joints"][k])[:MAX_FRAMES]
            return window_joints24(joints).reshape(len(joints), POSE_DIM)
        except (KeyError, ValueError) as exc:
            raise ValueError(f"{clip_id}: field joints: {exc}") from None

    def motion_inputs(self, clip: np.ndarray, where: str) -> tuple[np.ndarray, int]:
        """(120, 72) normalised, zero-padded rows of one clip's joints24 positions ((T, 24, 3)
        or (T, 72)) and its length (frames, at most 120)."""
        clip = np.asarray(clip)
        if clip.ndim == 3 and clip.shape[1:] == (JOINTS, 3):
            clip = clip.reshape(len(clip), POSE_DIM)
        if clip.ndim != 2 or clip.shape[1] != self.dims.pose:
            raise ValueError(f"{where}: expected joints24 positions (T, 24, 3) or (T, {self.dims.pose}), "
                             f"got shape {clip.shape}")
        n = min(len(clip), MAX_FRAMES)
        if n < UNIT_LENGTH:
            raise ValueError(f"{where}: {len(clip)} frame(s); CHOIS's evaluator needs at least {UNIT_LENGTH}")
        dtype = np.result_type(clip.dtype, self.mean.dtype)
        out = np.zeros((MAX_FRAMES, self.dims.pose), np.float32)
        out[:n] = (clip[:n].astype(dtype) - self.mean) / self.std
        return out, n


__all__ = ["BACKEND", "DEFAULT_DIMS", "ChoisEvaluator", "import_chois", "load_chois", "verify_folder", "summary"]
