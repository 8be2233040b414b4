"""``hoibench baseline train|sample|show``: a registry of baselines and the CLI entry points.

=========  =====================================  ==========================================
name       train                                  sample
=========  =====================================  ==========================================
chainhoi   ``train chainhoi DATA --out RUN``      ``sample chainhoi RUN --data DATA --out SUB``
ejim       ``train ejim DATA --out RUN``          ``sample ejim RUN --data DATA --out SUB``
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


def main_train(name: str, data: str | Path, out: str | Path, config: str = "tiny", device: str = "cpu",
               steps: int | None = None, seed: int | None = None, mask: str | None = None,
               threads: int | None = None) -> int:
    _check_threads(threads)
    _check_seed(seed)
    if mask is not None and name != "chainhoi":
        raise ValueError(f"--mask: the chain mask is ChainHOI's; {name} has none")
    if name not in TRAINABLE:
        raise ValueError(f"baseline {name!r} has nothing to train; `hoibench baseline sample {name} ...` uses the "
                         f"store's train statistics directly")
    from .registry import get_spec
    from .trainer import train
    cfg = get_spec(name).preset(config)
    over = {}
    if steps is not None:
        over["train.steps"] = steps
    if seed is not None:
        over["train.seed"] = seed
    if mask is not None:
        over["model.mask"] = mask
    if over:
        cfg = cfg.replace(**over)
    _check_device(device)
    train(name, data, out, cfg, device=device, threads=threads)
    return 0


def main_sample(name: str, run: str | Path | None, data: str | Path, out: str | Path, samples: int = 1,
                seed: int = 0, device: str = "cpu", guidance: float | None = None, ddim_steps: int | None = None,
                as_zip: bool = False, threads: int | None = None) -> int:
    _check_threads(threads)
    _check_seed(seed)
    if name == "mean-pose":
        if run is not None:
            raise ValueError("mean-pose takes no RUN folder (it uses the store's train statistics)")
        unused = [flag for flag, given in (("--samples", samples != 1), ("--seed", seed != 0),
                                           ("--guidance", guidance is not None), ("--ddim-steps", ddim_steps is not None),
                                           ("--device", device != "cpu"), ("--threads", threads is not None)) if given]
        if unused:
            raise ValueError(f"{', '.join(unused)}: mean-pose is deterministic and has no model; it writes one sample "
                             f"per prompt and takes none of these")
        from .trivial import write_mean_pose_submission
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
    sample(run, data, out, samples=samples, seed=seed, device=device, guidance=guidance, steps=ddim_steps,
           as_zip=as_zip, baseline=name)
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
    print("  text encoder: " + json.dumps({k: v for k, v in card.get("text", {}).items() if k != "vocab"}))
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
