"""Sampling a trained CATMO run (``hoibench baseline sample catmo``).

For a prompt of ``T`` frames: ``U = ceil(T / 4)`` motion/contact index pairs are drawn from
the intertwined GPT (each from the softmax of its modality's logits / temperature, from a CPU
generator seeded by ``(seed, clip id)``: the same draws on every device and whatever other
clips are sampled), decoded by the two VQ decoders into ``4U`` normalised hml263 rows and
contact logits, and cut to ``T`` rows. Rows are de-normalised with the run's statistics and
decoded into joints (:func:`hml263.decode`); on the HOI tracks the object head turns the
decoded motion, the contact probabilities and the object's geometry into the six object
channels, and :func:`hoi269.decode` gives the object rotations and translations. The
generated contacts (probability > 0.5) come back from :meth:`LoadedCatmo.generate` for
analysis; submissions carry joints and the object pose only.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import torch

from ...representations import hml263, hoi269
from ...datasets.store import Store
from .. import checkpoint as ckpt
from ..registry import get_spec
from ..sampler import check_store_fits, load_model_tensors, run_text_conditioner
from ..trainer import _seed
from .config import CatmoConfig
from .model import CATMO


class LoadedCatmo:
    """A verified CATMO run: config, modules (eval mode), statistics, text conditioner."""

    def __init__(self, folder: str | Path, device: str = "cpu", verified: tuple[dict, bytes] | None = None):
        from safetensors.torch import load as load_tensors
        self.folder = Path(folder)
        self.card, data = verified or ckpt.verify_run(self.folder, "catmo")
        self.id = self.card[ckpt.ID_KEY]
        self.spec = get_spec("catmo")
        self.config = CatmoConfig.from_dict(self.card["config"], f"{self.folder / ckpt.CARD}: config")
        tensors = load_tensors(data)
        self.requires_object = bool(self.card["dataset"].get("with_object"))
        try:
            self.mean = tensors.pop("stats.hml263_mean").numpy()
            self.std = tensors.pop("stats.hml263_std").numpy()
            self.obj_mean = tensors.pop("stats.object_mean").numpy() if self.requires_object else None
            self.obj_std = tensors.pop("stats.object_std").numpy() if self.requires_object else None
        except KeyError as exc:
            raise ckpt.RunFolderError(f"{self.folder / ckpt.WEIGHTS}: tensor {exc.args[0]} is missing (the run's "
                                      f"normalisation statistics)") from None
        self.text, vocab = run_text_conditioner(self.card, self.config.text.encoder, self.config.text.max_tokens,
                                                self.folder)
        self.device = torch.device(device)
        from ..config import check_parameter_count, sizing
        from .config import preset
        check_parameter_count(lambda c: CATMO(c, *sizing(c, len(vocab or []), self.text.width), self.requires_object),
                              self.config,
                              preset("paper"), f"{self.folder / ckpt.CARD}: config")
        self.model = CATMO(self.config, len(vocab or []), self.text.width, self.requires_object)
        load_model_tensors(self.model, tensors, self.folder)
        self.model.to(self.device).eval()
        self.object_points = self.config.gpt.object_points

    def check_store(self, store: Store) -> None:
        """:class:`StoreMismatch` when ``store``'s statistics, representation, fps or kind
        (human-only / human-object) differ from the run's."""
        check_store_fits(store, self.card["dataset"], self.id,
                         stats=("hml263",) + (("hoi269",) if self.requires_object else ()), representation="hml263")

    def options(self, guidance: float | None = None, steps: int | None = None, temperature: float | None = None
                ) -> dict:
        if guidance is not None or steps is not None:
            raise ValueError("--guidance, --ddim-steps: CATMO samples tokens autoregressively (no diffusion); "
                             "use --temperature")
        t = self.config.gpt.temperature if temperature is None else float(temperature)
        if not (math.isfinite(t) and 0 < t <= 100):
            raise ValueError(f"--temperature: expected a number in (0, 100], got {temperature!r}")
        return {"temperature": t}

    @torch.no_grad()
    def generate(self, caption: str, points: np.ndarray | None, length: int, k: int, seed_parts: tuple,
                 temperature: float = 1.0) -> dict[str, np.ndarray]:
        """``k`` samples of ``length`` frames: joints (k, length, 22, 3), contacts (k, length,
        22) bool and, with an object, obj_rot (k, length, 3, 3) and obj_trans (k, length, 3)."""
        m, dev, unit = self.model, self.device, self.config.vq.unit
        units = -(-length // unit)                     # past gpt.max_units: a sliding window (IntertwinedGPT.sample)
        tt, tpad = self.text([caption] * k, dev)
        zt = m.text(tt, tpad)
        feat = None
        if self.requires_object:
            if points is None:
                raise ValueError("CATMO was trained on a human-object store: an object is required")
            feat = m.object_feature(torch.from_numpy(np.repeat(points[None], k, 0)).to(dev))
        gen = torch.Generator().manual_seed(_seed(*seed_parts))
        mi, ci = m.gpt.sample(m.condition(zt, feat), units, gen, temperature)
        motion = m.motion_vq.decode(mi)[:, :length]
        cprob = torch.sigmoid(m.contact_vq.decode(ci)[:, :length])
        rows = motion.float().cpu().numpy() * self.std + self.mean
        out = {"contacts": (cprob > 0.5).cpu().numpy()}
        if self.requires_object:
            obj = m.object_head(motion, cprob, feat).float().cpu().numpy() * self.obj_std + self.obj_mean
            joints, rot, trans = hoi269.decode(np.concatenate([rows, obj], -1))
            out.update(obj_rot=rot.astype(np.float32), obj_trans=trans.astype(np.float32))
        else:
            joints = hml263.decode(rows)
        out["joints"] = joints.astype(np.float32)
        return out

    def generate_sample(self, caption: str, points: np.ndarray | None, length: int, k: int, seed_parts: tuple,
                        temperature: float) -> dict[str, np.ndarray]:
        """Submission arrays: joints (and the object pose on the HOI tracks)."""
        out = self.generate(caption, points, length, k, seed_parts, temperature)
        out.pop("contacts")
        return out
