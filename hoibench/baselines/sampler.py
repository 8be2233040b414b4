"""Sampling a trained joint-level diffusion run into a standard submission (``hoibench baseline sample``).

For each clip of the split (the test split by default): the condition is its first caption
(``DATA/texts/<id>.txt``) and its object's centred template; ``K`` samples of the ground
truth's length (T frames: T joint-level rows) are drawn by DDIM (50 steps) with classifier-free
guidance (scale 2) from noise seeded by ``(seed, clip id)``, so a clip's samples do not depend
on which other clips are sampled, in what order or on how many workers. The rows are
de-normalised with the run's statistics, converted to hoi269 (:func:`joint_level.to_hoi269`)
and decoded (:func:`hoi269.decode`) into joints (K, T, 22, 3), object rotations (K, T, 3, 3)
and translations (K, T, 3) in the canonical frame (y up, metres), and written with
:func:`hoibench.scoring.submission.write_submission`.

Sampling refuses a store whose normalisation statistics or representation differ from the
ones the run was trained with.
"""
from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Callable

import numpy as np
import torch

from .. import __version__
from ..core.interrupts import check_interrupted
from ..core.threads import set_torch_threads
from ..representations import hoi269, joint_level
from ..datasets.store import Store
from . import checkpoint as ckpt
from . import joint_data as D
from .config import RunConfig
from .diffusion import GaussianDiffusion
from .registry import get_spec
from .text import TextConditioner
from .trainer import _seed


class StoreMismatch(ckpt.RunFolderError):
    """The store to sample for is not the one the run was trained on (statistics, representation)."""


def run_text_conditioner(card: dict, encoder: str, max_tokens: int, folder: Path
                         ) -> tuple[TextConditioner, list[str] | None]:
    """(text conditioner, vocabulary or None) of a run card; :class:`RunFolderError` when the
    local sentence encoder is not the one the run was trained with."""
    info = card.get("text", {})
    vocab = info.get("vocab") if info.get("encoder") == "tokens" else None
    text = TextConditioner(encoder, max_tokens, vocab)
    if info.get("encoder") == "minilm" and info.get("weights_sha256") != text.weights_sha256:
        raise ckpt.RunFolderError(f"{folder / ckpt.CARD}: field text.weights_sha256: the local sentence encoder "
                                  f"differs from the one this run was trained with")
    return text, vocab


def load_model_tensors(model, tensors: dict, folder: Path) -> None:
    """Load the ``model.``-prefixed tensors of a run's weights into ``model``, naming the
    file when they do not fit the card's config."""
    state = {k[len("model."):]: v for k, v in tensors.items() if k.startswith("model.")}
    try:
        model.load_state_dict(state)
    except RuntimeError as exc:
        raise ckpt.RunFolderError(f"{folder / ckpt.WEIGHTS}: tensors do not match the card's config "
                                  f"({' '.join(str(exc).split())[:400]})") from None


class LoadedRun:
    """A verified run: config, model (EMA weights, eval mode), statistics, text conditioner."""

    requires_object = True

    def __init__(self, folder: str | Path, device: str = "cpu", baseline: str | None = None,
                 verified: tuple[dict, bytes] | None = None):
        from safetensors.torch import load as load_tensors
        self.folder = Path(folder)
        self.card, data = verified or ckpt.verify_run(self.folder, baseline)
        self.id = self.card[ckpt.ID_KEY]
        self.spec = get_spec(self.card["baseline"])
        self.config = RunConfig.from_dict(self.card["config"], self.spec.config_class(self.card["config"]),
                                          f"{self.folder / ckpt.CARD}: config")
        tensors = load_tensors(data)
        self.stats = D.JointStats(tensors.pop("stats.mean").numpy(), tensors.pop("stats.std").numpy())
        self.text, vocab = run_text_conditioner(self.card, self.config.model.text_encoder,
                                                self.config.model.text_max_tokens, self.folder)
        self.device = torch.device(device)
        from .config import check_parameter_count, sizing
        check_parameter_count(lambda c: self.spec.build_model(c, *sizing(c, len(vocab or []), self.text.width)),
                              self.config,
                              self.spec.preset("paper"), f"{self.folder / ckpt.CARD}: config")
        self.model = self.spec.build_model(self.config, len(vocab or []), self.text.width)
        load_model_tensors(self.model, tensors, self.folder)
        self.model.to(self.device).eval()
        self.diffusion = GaussianDiffusion(self.config.diffusion)
        self.object_points = self.config.model.object_points
        self.object_source = getattr(self.config.model, "object_source", "surface")

    def check_store(self, store: Store) -> None:
        """:class:`StoreMismatch` when ``store``'s hoi269 statistics or representation differ
        from the card's (the run's normalisation would not fit its data)."""
        check_store_fits(store, self.card["dataset"], self.id, stats=("hoi269",), representation="hoi269")

    @torch.no_grad()
    def generate(self, caption: str, points: np.ndarray, length: int, k: int, seed_parts: tuple,
                 guidance: float | None = None, steps: int | None = None) -> np.ndarray:
        """(k, length, 24, 12) raw joint-level rows for one prompt."""
        dev = self.device
        tt, tpad = self.text([caption] * k, dev)
        text = self.model.encode_text(tt, tpad)
        obj = self.model.encode_object(torch.from_numpy(np.repeat(points[None], k, 0)).to(dev))

        def x0_model(x, t, keep):
            n = x.shape[0] // k          # 2 under classifier-free guidance: [cond, uncond]
            return self.model(x, t, keep, text.repeat(n, 1, 1), tpad.repeat(n, 1), obj.repeat(n, 1, 1))

        gen = torch.Generator().manual_seed(_seed(*seed_parts))
        x0 = self.diffusion.ddim_sample(x0_model, (k, length, 24, 12), generator=gen, device=dev,
                                        steps=steps, guidance=guidance)
        return self.stats.denormalize(x0.float().cpu().numpy())

    def options(self, guidance: float | None = None, steps: int | None = None, temperature: float | None = None
                ) -> dict:
        """The sampling options, checked: classifier-free guidance scale and DDIM steps."""
        if temperature is not None:
            raise ValueError(f"--temperature: {self.spec.title} samples by DDIM; the temperature is CATMO's")
        cfg = self.config
        scale = cfg.diffusion.guidance if guidance is None else float(guidance)
        if not (math.isfinite(scale) and 0 <= scale <= 100):
            raise ValueError(f"--guidance: expected a number in [0, 100], got {guidance!r}")
        n_steps = cfg.diffusion.ddim_steps if steps is None else int(steps)
        if not 1 <= n_steps <= cfg.diffusion.steps:
            raise ValueError(f"--ddim-steps: expected an integer in [1, {cfg.diffusion.steps}], got {steps!r}")
        return {"ddim_steps": n_steps, "guidance": scale}

    def generate_sample(self, caption: str, points: np.ndarray | None, length: int, k: int, seed_parts: tuple,
                        ddim_steps: int, guidance: float) -> dict[str, np.ndarray]:
        """Submission arrays (joints, obj_rot, obj_trans) of ``k`` samples of ``length`` frames."""
        return rows_to_sample(self.generate(caption, points, length, k, seed_parts, guidance=guidance,
                                            steps=ddim_steps))


def load_run(folder: str | Path, device: str = "cpu", baseline: str | None = None):
    """The verified run folder as a sampler, loaded by the sample entry point its baseline's
    registry spec names: :class:`LoadedRun` for the diffusion baselines,
    ``hoibench.baselines.catmo.sampler.LoadedCatmo`` for CATMO."""
    verified = ckpt.verify_run(Path(folder), baseline)
    return get_spec(verified[0]["baseline"]).entry_point("sample")(folder, device, verified=verified)


def check_store_fits(store: Store, dataset: dict, run_id: str, stats: tuple[str, ...], representation: str) -> None:
    """:class:`StoreMismatch` naming every difference between ``store`` and the card's
    ``dataset`` block: the ``stats`` normalisation statistics (card field
    ``store_<name>_stats_sha256``), the ``representation`` version and the fps."""
    diffs = []
    for name in stats:
        sha, want = store.stats_sha256(name), dataset.get(f"store_{name}_stats_sha256")
        if sha != want:
            diffs.append(f"normalisation statistics (stats/{name}.npz sha256 {sha[:12] or 'missing'}..., the run's "
                         f"{str(want)[:12]}...)")
    rep = store.manifest.get("representations", {}).get(representation, "")
    if rep != dataset.get("representation"):
        diffs.append(f"representation ({rep!r}, the run's {dataset.get('representation')!r})")
    fps = float(store.manifest.get("config", {}).get("fps", 0.0))
    if fps != dataset.get("fps"):
        diffs.append(f"fps ({fps}, the run's {dataset.get('fps')})")
    if diffs:
        raise StoreMismatch(f"{store.root}: this store differs from the one run {run_id[:12]} was trained on "
                            f"({dataset.get('name')!r}): {'; '.join(diffs)}. Sample for the store the run was "
                            f"trained on, or train on this one")


def rows_to_sample(rows: np.ndarray) -> dict[str, np.ndarray]:
    """Raw joint-level rows (K, T, 24, 12) -> submission arrays (joints, obj_rot, obj_trans)."""
    feats = joint_level.to_hoi269(rows)
    joints, rot, trans = hoi269.decode(feats)
    return {"joints": joints.astype(np.float32), "obj_rot": rot.astype(np.float32),
            "obj_trans": trans.astype(np.float32)}


def sample(run: str | Path, data: str | Path, out: str | Path, *, samples: int = 1, seed: int = 0,
           split: str = "test", device: str = "cpu", guidance: float | None = None, steps: int | None = None,
           temperature: float | None = None, as_zip: bool = False, limit: int | None = None,
           baseline: str | None = None, log: Callable[[str], None] | None = print,
           inference: dict | None = None, threads: int | None = None) -> Path:
    """Write a submission of ``samples`` (K) samples per clip of ``split`` to ``out``
    (``baseline``: refuse a run of another baseline; ``inference``: SyncDiff's inference-time
    settings, ``{"syncdiff.explicit_sync": False}``; ``threads``: torch threads, default the
    machine's free cores, :func:`hoibench.core.threads.set_torch_threads`)."""
    log = log or (lambda s: None)
    set_torch_threads(threads)
    if not (isinstance(samples, int) and 1 <= samples <= 1000):
        raise ValueError(f"--samples: expected an integer in 1..1000, got {samples!r}")
    loaded = load_run(run, device, baseline)
    if hasattr(loaded, "write_store_submission"):        # SyncDiff: a multi-body submission
        if guidance is not None or temperature is not None:
            raise ValueError(f"--guidance/--temperature: {loaded.spec.title} samples without guidance or temperature")
        return loaded.write_store_submission(data, out, samples=samples, seed=seed, split=split, steps=steps,
                                             as_zip=as_zip, limit=limit, log=log, inference=inference)
    if inference:
        raise ValueError(f"inference settings {sorted(inference)}: {loaded.spec.title} has none")
    store = Store(data)
    loaded.check_store(store)
    from ..tracks.protocol import default_protocol_id
    from ..scoring.submission import submission_context
    cap = submission_context(store, None)[2]         # validation's K cap: the default protocol's
    if samples > cap:
        raise ValueError(f"--samples: {samples} samples per prompt; the {default_protocol_id(store.manifest)} protocol "
                         f"reads at most {cap} (replication r uses sample r mod K, MultiModality the first "
                         f"mm_samples), and validation refuses more")
    ids = store.clip_ids(split)
    if limit is not None:
        ids = ids[:limit]
    if not ids:
        raise ValueError(f"{data}: split {split!r} has no clips")
    from ..evaluator.text import read_captions
    opts = loaded.options(guidance, steps, temperature)
    points_cache: dict[str, np.ndarray] = {}
    tag = f"[{loaded.spec.name}]"
    meta = submission_meta(loaded.spec.title, loaded.spec.name, loaded, store, samples=samples, seed=seed,
                           split=split, representation=store.manifest.get("representations", {}).get("hml263", ""),
                           selection="last (EMA)" if loaded.spec.kind == "diffusion" else "last",
                           settings={**opts, "caption": "first caption of each clip"})
    t0 = time.perf_counter()

    def gen():
        for i, cid in enumerate(ids):
            check_interrupted()
            clip = store.load(cid)
            if loaded.requires_object and "object_name" not in clip:
                raise ValueError(f"{data}: clip {cid}: field object_name missing: {loaded.spec.title} samples "
                                 f"human-object clips")
            caps = read_captions(store.root, cid)
            if not caps:
                raise ValueError(f"{store.root}/texts/{cid}.txt: missing or empty: no caption to condition on "
                                 f"(annotate the store first)")
            points = None
            if loaded.requires_object:
                name = str(clip["object_name"])
                if name not in points_cache:
                    v, f = store.object_template(name)
                    points_cache[name] = D.input_points(v, f, loaded.object_points, name,
                                                        getattr(loaded, "object_source", "surface"))
                points = points_cache[name]
            T = int(clip["joints"].shape[0])
            arrays = loaded.generate_sample(caps[0].text, points, T, samples, (seed, "sample", cid), **opts)
            el = time.perf_counter() - t0
            log(f"{tag} sampled {i + 1}/{len(ids)} {cid} (K={samples}, T={T}) {el:.1f} s")
            yield cid, arrays

    return write_logged(out, meta, gen(), clips=len(ids), samples=samples, tag=tag, t0=t0, as_zip=as_zip, log=log)


def submission_meta(title: str, baseline: str, run, store: Store, *, samples: int, seed: int, split: str,
                    representation: str, selection: str, settings: dict) -> dict:
    """A baseline submission's ``submission.json`` block: method, representation, flags, and a
    ``source`` naming the run (baseline, checkpoint id, config, seed), the sampling
    ``settings``, the store and split, and the run's training budget. ``run``: a loaded run
    (``id``, ``config``, ``folder``, ``card``)."""
    return {"method": f"{title} ({run.config.name}, hoibench reproduction)", "version": __version__,
            "url": "", "representation": representation, "fps": float(store.manifest["config"]["fps"]),
            "flags": {"uses_gt_length": True, "samples_per_prompt": samples, "checkpoint_selection": selection},
            "source": {"baseline": baseline, "checkpoint_id": run.id, "config": run.config.name, "seed": seed,
                       **settings, "store": store.manifest.get("dataset", ""), "split": split,
                       "toolkit_version": __version__, "training": ckpt.training_budget(run.folder, run.card)}}


def write_logged(out, meta: dict, items, *, clips: int, samples: int, tag: str, t0: float, as_zip: bool,
                 log: Callable[[str], None]) -> Path:
    """Write the submission (``items``: (clip id, arrays) pairs) and log its size and the
    average inference time per sample (AIT, seconds, from ``t0``)."""
    from ..scoring.submission import write_submission
    path = write_submission(out, meta, items, as_zip=as_zip)
    el = time.perf_counter() - t0
    log(f"{tag} wrote {path}: {clips} clips x {samples} samples in {el:.1f} s "
        f"(AIT {el / (clips * samples):.3f} s per sample)")
    return path
