"""``hoibench baseline train|sample|show``: a registry of baselines and the CLI entry points.

=========  =====================================  ==========================================
name       train                                  sample
=========  =====================================  ==========================================
chainhoi   ``train chainhoi DATA --out RUN``      ``sample chainhoi RUN --data DATA --out SUB``
ejim       ``train ejim DATA --out RUN``          ``sample ejim RUN --data DATA --out SUB``
catmo      ``train catmo DATA --out RUN``         ``sample catmo RUN --data DATA --out SUB``
syncdiff   ``train syncdiff DATA --out RUN``      ``sample syncdiff RUN --data DATA --out SUB`` (multi-body)
mean-pose  (nothing to train: train statistics)   ``sample mean-pose --data DATA --out SUB``
=========  =====================================  ==========================================
"""
from __future__ import annotations

from pathlib import Path

from .registry import SPECS

TRAINABLE = tuple(SPECS)
MAX_SEED = 2 ** 63 - 1


def _check_threads(threads: int | None) -> None:
    import os
    most = max(64, 4 * (os.cpu_count() or 1))
    if threads is not None and not 1 <= threads <= most:
        raise ValueError(f"--threads: expected an integer in [1, {most}], got {threads}")


def _check_seed(seed: int | None) -> None:
    if seed is not None and not 0 <= seed <= MAX_SEED:
        raise ValueError(f"--seed: expected an integer in [0, 2^63 - 1], got {seed}")


def parse_overrides(items: list[str] | None) -> dict:
    """``["train.lr=5e-4", "model.mask=\"released\""]`` -> ``{"train.lr": 0.0005, ...}`` (values are
    JSON; a bare word is taken as a string)."""
    import json
    out = {}
    for item in items or []:
        key, sep, raw = item.partition("=")
        if not sep or "." not in key:
            raise ValueError(f"--set {item!r}: expected SECTION.FIELD=VALUE, e.g. train.lr=5e-4")
        try:
            out[key.strip()] = json.loads(raw)  # read-ok: a command-line value, not a file
        except json.JSONDecodeError:
            out[key.strip()] = raw
    return out


def main_train(name: str, data: str | Path, out: str | Path, config: str = "tiny", device: str = "cpu",
               steps: int | None = None, seed: int | None = None, mask: str | None = None,
               threads: int | None = None, overrides: list[str] | None = None) -> int:
    _check_threads(threads)
    _check_seed(seed)
    if mask is not None and name != "chainhoi":
        raise ValueError(f"--mask: the chain mask is ChainHOI's; {name} has none")
    if name not in TRAINABLE:
        raise ValueError(f"baseline {name!r} has nothing to train; `hoibench baseline sample {name} ...` uses the "
                         f"store's train statistics directly")
    from .registry import get_spec
    from .trainer import train
    spec = get_spec(name)
    cfg = spec.preset(config)
    over = {}
    if steps is not None:
        if steps < 0:
            raise ValueError(f"--steps: expected an integer >= 0, got {steps}")
        if spec.kind == "tokens":
            if steps != 0:
                raise ValueError("--steps: CATMO trains in stages; set their steps with --set train.vq_steps=N, "
                                 "train.contact_steps, text.movement_ae_steps, text.match_steps, train.gpt_steps, "
                                 "object.steps (--steps 0: the untrained model)")
            over.update({k: 0 for k in ("train.vq_steps", "train.contact_steps", "text.movement_ae_steps",
                                        "text.match_steps", "train.gpt_steps", "object.steps")})
        else:
            over["train.steps"] = steps
    if seed is not None:
        over["train.seed"] = seed
    if mask is not None:
        over["model.mask"] = mask
    over.update(parse_overrides(overrides))
    if over:
        cfg = cfg.replace(**over)
    _check_device(device)
    train(name, data, out, cfg, device=device, threads=threads)
    return 0


def main_sample(name: str, run: str | Path | None, data: str | Path, out: str | Path, samples: int = 1,
                seed: int = 0, device: str = "cpu", guidance: float | None = None, ddim_steps: int | None = None,
                as_zip: bool = False, threads: int | None = None, temperature: float | None = None,
                overrides: list[str] | None = None) -> int:
    _check_threads(threads)
    _check_seed(seed)
    if name == "mean-pose":
        if run is not None:
            raise ValueError("mean-pose takes no RUN folder (it uses the store's train statistics)")
        unused = [flag for flag, given in (("--samples", samples != 1), ("--seed", seed != 0),
                                           ("--guidance", guidance is not None), ("--ddim-steps", ddim_steps is not None),
                                           ("--temperature", temperature is not None),
                                           ("--device", device != "cpu"), ("--threads", threads is not None)) if given]
        if unused:
            raise ValueError(f"{', '.join(unused)}: mean-pose is deterministic and has no model; it writes one sample "
                             f"per prompt and takes none of these")
        from ..scoring.mean_pose import write_mean_pose_submission
        path = write_mean_pose_submission(data, out, as_zip=as_zip)
        print(f"[mean-pose] wrote {path}")
        return 0
    if run is None:
        raise ValueError(f"baseline sample {name}: the RUN folder (from `hoibench baseline train {name}`) is required")
    _check_device(device)
    if threads:
        import torch
        torch.set_num_threads(threads)
    from .sampler import sample
    over = parse_overrides(overrides)
    if over and name != "syncdiff":
        raise ValueError(f"--set: {name} has no inference-time settings (syncdiff's: syncdiff.explicit_sync, "
                         f"syncdiff.sync_every, syncdiff.sync_weight)")
    sample(run, data, out, samples=samples, seed=seed, device=device, guidance=guidance, steps=ddim_steps,
           temperature=temperature, as_zip=as_zip, baseline=name, **({"inference": over} if over else {}))
    return 0


def main_show(run: str | Path) -> int:
    import json

    from .checkpoint import ID_KEY, verify_run
    if not Path(run).exists():
        raise FileNotFoundError(f"{run}: does not exist")
    card, _ = verify_run(run)
    ds = card["dataset"]
    curve = card.get("curve") or []
    print(f"{card['baseline']} run {card[ID_KEY][:12]} (verified): config {card['config'].get('name')}, "
          f"{card['summary'].get('parameters', 0) / 1e6:.2f} M parameters, {card['summary'].get('steps')} steps, "
          f"seed {card.get('seed')}")
    print(f"  trained on {ds.get('name')!r} ({ds.get('clips')} {ds.get('split')} clips, store "
          f"{str(ds.get('manifest_sha256'))[:12]}, {ds.get('representation')}, {ds.get('fps')} fps)")
    if curve:
        print(f"  loss {curve[0]['loss']:.4f} (step {curve[0]['step']}) -> {curve[-1]['loss']:.4f} "
              f"(step {curve[-1]['step']})")
    curves = card.get("curves") or {}                             # CATMO: one curve per stage
    order = list((card.get("summary") or {}).get("stage_steps") or {})
    for stage, rows in sorted(curves.items(), key=lambda kv: order.index(kv[0]) if kv[0] in order else len(order)):
        if rows:
            print(f"  {stage:12s} loss {rows[0]['loss']:.4f} (step {rows[0]['step']}) -> {rows[-1]['loss']:.4f} "
                  f"(step {rows[-1]['step']})")
    for split, rep in (card.get("vq") or {}).items():
        mv, ct = rep["motion"], rep["contact"]
        print(f"  VQ on {split} ({rep['clips']} clips): motion MPJPE {mv['mpjpe_m'] * 100:.2f} cm, perplexity "
              f"{mv['perplexity']:.1f} ({mv['codes_used']}/{mv['codebook']} codes); contacts accuracy "
              f"{ct['accuracy']:.3f}, F1 {ct['f1']:.3f}, perplexity {ct['perplexity']:.1f} "
              f"({ct['codes_used']}/{ct['codebook']} codes)")
    print("  text encoder: " + json.dumps({k: v for k, v in card.get("text", {}).items() if k != "vocab"}))
    sync = (card.get("config") or {}).get("syncdiff")
    if isinstance(sync, dict):                                # a card without a field: the field's default
        from dataclasses import asdict

        from .syncdiff.config import SyncConfig
        full = {**asdict(SyncConfig()), **sync}
        print("  syncdiff: " + ", ".join(f"{k} {json.dumps(full[k])}" for k in (
            "decompose", "align_loss", "explicit_sync", "freq_position", "high_groups", "cutoff", "low")))
    return 0


def _check_device(device: str) -> None:
    import re
    if device == "cpu":
        return
    if not re.fullmatch(r"cuda(:[0-9]{1,2})?", device):
        raise ValueError(f"--device: expected cpu or cuda[:N], got {device!r}")
    import torch
    dev = torch.device(device)
    if dev.type == "cuda" and not torch.cuda.is_available():
        raise ValueError(f"--device {device}: CUDA is not available on this machine (torch {torch.__version__}); "
                         f"use --device cpu")
