"""The main job and looking at clips: ``hoibench demo`` and ``hoibench render``."""
from __future__ import annotations

import argparse
from pathlib import Path

from .common import H_SEED


def _cmd_demo(args) -> int:
    from ..demo import run_demo
    run_demo(Path(args.out), seed=args.seed, baselines=not args.no_baselines)
    return 0


def _cmd_render(args) -> int:
    from ..publish.renderers import main_render, main_render_worst
    if args.worst is not None:
        main_render_worst(args.clip, args.worst, args.by, args.data, args.submission, args.out)
        return 0
    if args.submission is not None:
        raise ValueError("render: --submission goes with RESULT --worst K (for one id: render SUB --id ID)")
    print(f"wrote {main_render(args.clip, args.data, args.id, args.out, sample=args.sample, body=args.body)}")
    return 0


def register(sub) -> None:
    """demo, render."""
    s = sub.add_parser("demo", help="run the main job on the embedded synthetic data",
                       epilog="example: hoibench demo --out demo-out")
    s.add_argument("--out", type=Path, default=Path("demo-out"), help="the folder to write (default demo-out)")
    s.add_argument("--seed", type=int, default=0, help=H_SEED)
    s.add_argument("--no-baselines", action="store_true",
                   help="skip training the tiny ChainHOI and CATMO (~9 of the demo's ~13 minutes on 2 idle cores)")
    s.set_defaults(func=_cmd_demo)

    s = sub.add_parser("render", help="render a processed clip to PNG, GIF or MP4 (off-screen)",
                       epilog="examples:\n  hoibench render data/clips/Date01_Sub01_boxsmall_lift.npz --out clip.gif\n"
                              "  hoibench render Date01_Sub01_boxsmall_lift --data data --out clip.gif\n"
                              "  hoibench render sub.zip --id Date03_Sub01_backpack_hold --data data --out cmp.gif\n"
                              "  hoibench render result.json --worst 5 --by mm_dist --data data --out worst/",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    s.add_argument("clip", help="DATA/clips/<id>.npz, or a clip id together with --data, or a submission with --id, "
                                "or a result of `hoibench evaluate` with --worst")
    s.add_argument("--data", type=Path, default=None, help="the store the clip id (or the submission) belongs to")
    s.add_argument("--id", default=None, help="with a submission: draw its sample for this id beside the ground truth")
    s.add_argument("--sample", type=int, default=0, help="with --id: which of the K samples (default 0)")
    s.add_argument("--out", type=Path, required=True,
                   help=".png (middle frame), .gif or .mp4; with --worst a folder (one GIF per clip)")
    s.add_argument("--worst", type=int, default=None, metavar="K",
                   help="with a result: draw the K test clips at the failure end of --by, each beside its ground truth")
    s.add_argument("--by", default="mm_dist",
                   help="with --worst: a column of the result's per-clip table (default mm_dist; also text_rank, "
                        "cd, ocd, ps, fsr, jitter_mps3, penetration_depth_max_m, contact_iou, ...)")
    s.add_argument("--submission", type=Path, default=None,
                   help="with --worst: the scored submission (default: the path the result records)")
    s.add_argument("--body", choices=["proxy", "skeleton"], default="proxy",
                   help="proxy (default: a body surface from the stored parameters) or skeleton")
    s.set_defaults(func=_cmd_render)
