"""Reference baselines and other generators' outputs: ``hoibench baseline train|sample|show``
and ``hoibench import``. The baseline names come from :data:`hoibench.baselines.registry.SPECS`
(plus the sample-only ``mean-pose``), the import formats from
:data:`hoibench.scoring.importers.FORMATS` (read when ``import`` is parsed or its help shown)."""
from __future__ import annotations

import argparse
from pathlib import Path

from .common import H_SEED, H_STORE, H_THREADS, H_ZIP, LazyChoices, action_command

#: baselines with nothing to train: sampled from the store's train statistics
SAMPLE_ONLY = ("mean-pose",)
MAX_SEED = 2 ** 63 - 1


def _check_threads(threads: int | None) -> None:
    import os
    most = max(64, 4 * (os.cpu_count() or 1))
    if threads is not None and not 1 <= threads <= most:
        raise ValueError(f"--threads: expected an integer in [1, {most}], got {threads}")


def _check_seed(seed: int | None) -> None:
    if seed is not None and not 0 <= seed <= MAX_SEED:
        raise ValueError(f"--seed: expected an integer in [0, 2^63 - 1], got {seed}")


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


def _check_kernels() -> None:
    """``HOIBENCH_KERNELS`` read before anything is written (ValueError naming the variable)."""
    from ..baselines.kernels import choice
    choice()


def train_baseline(name: str, data: str | Path, out: str | Path, config: str = "tiny", device: str = "cpu",
                   steps: int | None = None, seed: int | None = None, mask: str | None = None,
                   threads: int | None = None, overrides: list[str] | None = None) -> int:
    """``hoibench baseline train``: check the options against the baseline, train, return 0."""
    from ..baselines.commands import parse_overrides
    from ..baselines.registry import SPECS, get_spec
    from ..baselines.trainer import train
    _check_threads(threads)
    _check_seed(seed)
    if mask is not None and name != "chainhoi":
        raise ValueError(f"--mask: the chain mask is ChainHOI's; {name} has none")
    if name not in SPECS:
        raise ValueError(f"baseline {name!r} has nothing to train; `hoibench baseline sample {name} ...` uses the "
                         f"store's train statistics directly")
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
    _check_kernels()
    train(name, data, out, cfg, device=device, threads=threads)
    return 0


def sample_baseline(name: str, run: str | Path | None, data: str | Path, out: str | Path, samples: int = 1,
                    seed: int = 0, device: str = "cpu", guidance: float | None = None, ddim_steps: int | None = None,
                    as_zip: bool = False, threads: int | None = None, temperature: float | None = None,
                    overrides: list[str] | None = None) -> int:
    """``hoibench baseline sample``: check the options against the baseline, sample, return 0."""
    from ..baselines.commands import parse_overrides
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
    _check_kernels()
    from ..baselines.sampler import sample
    over = parse_overrides(overrides)
    if over and name != "syncdiff":
        raise ValueError(f"--set: {name} has no inference-time settings (syncdiff's: syncdiff.explicit_sync, "
                         f"syncdiff.sync_every, syncdiff.sync_weight)")
    sample(run, data, out, samples=samples, seed=seed, device=device, guidance=guidance, steps=ddim_steps,
           temperature=temperature, as_zip=as_zip, baseline=name, threads=threads,
           **({"inference": over} if over else {}))
    return 0


def _cmd_baseline(args) -> int:
    if args.action == "train":
        return train_baseline(args.name, args.data, args.out, config=args.config, device=args.device,
                              steps=args.steps, seed=args.seed, mask=args.mask, threads=args.threads,
                              overrides=args.set)
    if args.action == "sample":
        return sample_baseline(args.name, args.run, args.data, args.out, samples=args.samples, seed=args.seed,
                               device=args.device, guidance=args.guidance, ddim_steps=args.ddim_steps,
                               temperature=args.temperature, as_zip=args.zip, threads=args.threads,
                               overrides=args.set)
    from ..baselines.commands import main_show
    return main_show(args.run)


def _cmd_import(args) -> int:
    from ..scoring.importers import import_results
    path, rep = import_results(args.format, args.results, args.data, args.out, match=args.match, mapping=args.map,
                               trust_pickle=args.trust_pickle, fps=args.fps, up=args.up, normalized=args.normalized,
                               method=args.method, as_zip=args.zip, body_models=args.body_models,
                               model_type=args.model_type, gender=args.gender)
    conv = rep["conversions"]
    print(f"wrote {path}: {rep['matched']}/{rep['test_ids']} test ids, K = {rep['samples_per_prompt'][0]} "
          f"(matched by {conv['match']}; {conv['source_fps']:g} -> {conv['store_fps']:g} fps; up {conv['up_axis']})")
    if rep["missing_ids"]:
        print(f"  missing: {len(rep['missing_ids'])} test ids without samples (e.g. {rep['missing_ids'][0]}): the "
              f"submission is incomplete")
    if rep.get("human_only"):
        print("  human-only: the results carry no object motion for this human-object store; submission.json has "
              "flags.human_only, so evaluate scores the embedding metrics, FSR and jitter on the human and "
              "reports the object metrics (CD, OCD, PS, penetration, ...) as not applicable; the leaderboard marks "
              "the row human-only (for object metrics: `hoibench import hoidiff ...` or `hoibench import chois ...`, "
              "the format is the first argument)")
    if rep["unmatched_entries"]:
        print(f"  unmatched: {len(rep['unmatched_entries'])} entries (e.g. {rep['unmatched_entries'][0]!r})")
    if rep["ambiguous_texts"]:
        print(f"  ambiguous: {len(rep['ambiguous_texts'])} texts shared by several clips (assigned in id order)")
    return 0


def _add_train(bsub, names: list[str]) -> None:
    b = bsub.add_parser("train", help="train a baseline on a store's train split")
    b.add_argument("name", choices=names, help="the baseline")
    b.add_argument("data", type=Path, help=H_STORE + ", annotated")
    b.add_argument("--out", type=Path, required=True, help="the run folder to write")
    b.add_argument("--config", default="tiny",
                   help="a named config: tiny (default; CPU minutes), paper, or the baseline's own "
                        "(chainhoi: released, the public code's network; ejim: micro)")
    b.add_argument("--steps", type=int, default=None,
                   help="optimiser steps (0: the untrained model); catmo: every stage's steps (0: untrained)")
    b.add_argument("--set", action="append", default=[], metavar="SECTION.FIELD=VALUE",
                   help="override one config field (JSON value), e.g. train.lr=5e-4; repeatable")
    b.add_argument("--seed", type=int, default=None, help="random seed (default: the config's)")
    b.add_argument("--mask", choices=["paper", "released"], default=None,
                   help="chainhoi only: Kinematic-aware Decoder mask (released: the published code's additive "
                        "float mask)")
    b.add_argument("--device", default="cpu", help="cpu (default) or cuda")
    b.add_argument("--threads", type=int, default=None, help=H_THREADS)
    b.set_defaults(func=_cmd_baseline)


def _add_sample(bsub, names: list[str], trained: list[str]) -> None:
    b = bsub.add_parser("sample", help="sample a baseline into a standard submission for the test split")
    b.add_argument("name", choices=names + list(SAMPLE_ONLY),
                   help=f"the baseline ({' and '.join(SAMPLE_ONLY)} needs no run)")
    b.add_argument("run", type=Path, nargs="?", default=None,
                   help=f"run folder ({', '.join(trained)}; none for {', '.join(SAMPLE_ONLY)})")
    b.add_argument("--data", type=Path, required=True, help="the store to sample its test split for")
    b.add_argument("--out", type=Path, required=True, help="the submission folder (or .zip with --zip) to write")
    b.add_argument("--samples", "-k", type=int, default=1,
                   help="samples per prompt (K, at most the protocol's 30; MultiModality needs 30)")
    b.add_argument("--seed", type=int, default=0, help=H_SEED)
    b.add_argument("--guidance", type=float, default=None, help="classifier-free guidance scale (default: config, 2)")
    b.add_argument("--ddim-steps", type=int, default=None, help="DDIM steps (default: config, 50)")
    b.add_argument("--temperature", type=float, default=None, help="catmo: sampling temperature (default: config, 1)")
    b.add_argument("--set", action="append", default=[], metavar="SECTION.FIELD=VALUE",
                   help="syncdiff: inference-time settings (syncdiff.explicit_sync, syncdiff.sync_every, "
                        "syncdiff.sync_weight), recorded in the submission")
    b.add_argument("--device", default="cpu", help="cpu (default) or cuda")
    b.add_argument("--threads", type=int, default=None, help=H_THREADS)
    b.add_argument("--zip", action="store_true", help=H_ZIP)
    b.set_defaults(func=_cmd_baseline)


def _add_baseline(sub) -> None:
    from ..baselines.registry import SPECS
    listed = ", ".join(list(SPECS) + list(SAMPLE_ONLY))
    bsub = action_command(
        sub, "baseline", f"train and sample reference baselines ({listed})",
        ["hoibench baseline train chainhoi data --config tiny --out runs/chainhoi-tiny",
         "hoibench baseline sample chainhoi runs/chainhoi-tiny --data data --out sub",
         "hoibench baseline train catmo data --out runs/catmo-tiny --set train.gpt_steps=3000",
         "hoibench baseline sample catmo runs/catmo-tiny --data data --out sub-catmo -k 30",
         "hoibench baseline sample mean-pose --data data --out sub-mean",
         "hoibench baseline show runs/chainhoi-tiny"],
        ["train", "sample", "show"])
    _add_train(bsub, sorted(SPECS))
    _add_sample(bsub, sorted(SPECS), list(SPECS))
    b = bsub.add_parser("show", help="show (and verify) a baseline run folder")
    b.add_argument("run", type=Path, help="the run folder")
    b.set_defaults(func=_cmd_baseline)


def _add_import(sub) -> None:
    s = sub.add_parser("import", help="turn existing generators' outputs (MDM, HOI-Diff, T2M-GPT/MoMask joints, "
                                      "CHOIS, feature folders) into a submission",
                       epilog="examples:\n  hoibench import mdm results.npy --data data --out sub --trust-pickle\n"
                              "  hoibench import joints t2mgpt_joints/ --data data --out sub --fps 20\n"
                              "  hoibench import features feats/ --data data --out sub --normalized",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    fmt = s.add_argument("format", help="the outputs' format (params: per-frame SMPL/SMPL-H/SMPL-X parameters, "
                                        "posed with --body-models)")
    fmt.choices = LazyChoices("hoibench.scoring.importers:FORMATS")      # importers load numpy: on use only
    s.add_argument("results", type=Path, help="results.npy (mdm, hoidiff) or a folder of files")
    s.add_argument("--data", type=Path, required=True, help="the store the outputs are for (" + H_STORE + ")")
    s.add_argument("--out", type=Path, required=True, help="the submission folder (or .zip with --zip) to write")
    s.add_argument("--match", choices=["id", "text"], default=None,
                   help="map entries to test ids by file name (id) or caption (text); default: text for mdm/hoidiff")
    s.add_argument("--map", type=Path, default=None, help="JSON {entry index or file stem: test id}")
    s.add_argument("--trust-pickle", action="store_true",
                   help="read MDM/HOI-Diff results.npy, a pickle: only for files you produced yourself")
    s.add_argument("--fps", type=float, default=None, help="the source frame rate (default: the format's, or the store's)")
    s.add_argument("--up", choices=["y", "z"], default="y", help="joints, params: the source's up axis")
    s.add_argument("--normalized", action="store_true", help="features: de-normalise with the store's statistics")
    s.add_argument("--body-models", type=Path, default=None,
                   help="params: the folder with your smplh/, smplx/ or smpl/ model files")
    s.add_argument("--model-type", choices=["smplh", "smplx", "smpl"], default="smplh",
                   help="params: the body model the parameters are for (default smplh)")
    s.add_argument("--gender", choices=["neutral", "male", "female"], default="neutral",
                   help="params: the model gender when a file has no 'gender' field (default neutral)")
    s.add_argument("--method", default=None, help="the method name written to submission.json")
    s.add_argument("--zip", action="store_true", help=H_ZIP)
    s.set_defaults(func=_cmd_import)


def register(sub) -> None:
    """baseline, import."""
    _add_baseline(sub)
    _add_import(sub)
