"""Does sharing the evaluator's text encoder inflate a baseline's scores? (docs/baselines.md)

A 2 x 2 measurement on one store: the same baseline (ChainHOI tiny, same steps and seed)
conditioned on ``tokens`` (a trainable word-level encoder: no weights shared with any
evaluator) and on ``minilm`` (the frozen all-MiniLM-L6-v2 the default evaluator reads texts
with), each scored by

- the track's evaluator (text branch: all-MiniLM-L6-v2, fine-tuned), and
- an *independent* evaluator: the same motion branch, sizes and recipe, whose text branch is
  a small BERT initialised at random (seeded) and trained from scratch with the evaluator
  (it shares MiniLM's WordPiece vocabulary -- a word list, not weights -- and nothing else).

Inflation of metric m (difference of differences, per replication; the replications draw the
same pools for every submission, so the pairs are matched):

    (m[minilm-cond, MiniLM ev] - m[tokens-cond, MiniLM ev]) - (m[minilm-cond, indep. ev] - m[tokens-cond, indep. ev])

with a 95% t interval over the replications. The ground truth is scored by both evaluators
as the scale of each. Everything is reused when it already exists (deterministic), so a rerun
only redoes what is missing.

    python benchmarks/text_encoder_inflation.py --data demo-out/data \\
        --evaluator leaderboards/synthetic/evaluator --work inflation \\
        [--tokens-run baseline-runs/runs/chainhoi-tiny]
"""
from __future__ import annotations

import argparse
import json
import math
import shutil
import time
from pathlib import Path

import numpy as np

METRICS = (("r_precision_top1", "R@1"), ("r_precision_top3", "R@3"), ("mm_dist", "MM-Dist"), ("fid", "FID"))
#: tokenizer files copied from the packaged MiniLM folder (the vocabulary, no weights)
TOKENIZER_FILES = ("vocab.txt", "tokenizer.json", "tokenizer_config.json", "special_tokens_map.json")


def scratch_text_encoder(folder: Path, seed: int = 0, hidden: int = 128, layers: int = 2) -> Path:
    """A randomly initialised BERT (``hidden`` wide, ``layers`` deep, seeded) with MiniLM's
    WordPiece vocabulary, written as a local Hugging Face folder."""
    if (folder / "config.json").exists():
        return folder
    import torch
    from transformers import BertConfig, BertModel

    from hoibench.evaluator.text import packaged_minilm_path
    src = packaged_minilm_path()
    tmp = folder.with_name(folder.name + ".tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    for name in TOKENIZER_FILES:
        shutil.copyfile(src / name, tmp / name)
    vocab = sum(1 for _ in open(src / "vocab.txt", encoding="utf-8"))  # read-ok: the packaged vocabulary
    torch.manual_seed(seed)
    cfg = BertConfig(vocab_size=vocab, hidden_size=hidden, num_hidden_layers=layers, num_attention_heads=4,
                     intermediate_size=2 * hidden, max_position_embeddings=128)
    BertModel(cfg).save_pretrained(str(tmp), safe_serialization=True)
    tmp.rename(folder)
    return folder


def independent_evaluator(data: Path, work: Path, seed: int = 0) -> Path:
    """The track's tiny recipe with the scratch text branch trained from the first epoch."""
    from hoibench.evaluator.card import SHIPPED_TEXT_ENCODER
    from hoibench.evaluator.config import preset
    from hoibench.evaluator.train import train_evaluator
    out = work / "evaluator-independent"
    if (out / "card.json").exists():
        return out
    text = scratch_text_encoder(work / "scratch-text-encoder", seed=seed)
    cfg = preset("tiny", "human", seed=seed, text_unfreeze_epoch=0, text_finetune_layers=0, text_lr=1e-3)
    train_evaluator(data, out, cfg, text_encoder=str(text))
    shutil.copytree(text, out / SHIPPED_TEXT_ENCODER)
    return out


def baseline_submission(data: Path, work: Path, encoder: str, run: Path | None, seed: int = 0) -> Path:
    """ChainHOI tiny conditioned on ``encoder``, trained (or reused) and sampled once per prompt."""
    from hoibench.baselines.registry import get_spec
    from hoibench.baselines.sampler import sample
    from hoibench.baselines.trainer import train
    sub = work / "submissions" / f"chainhoi-tiny-{encoder}"
    if (sub / "submission.json").exists():
        return sub
    run = run or work / "runs" / f"chainhoi-tiny-{encoder}"
    cfg = get_spec("chainhoi").preset("tiny").replace(**{"model.text_encoder": encoder, "train.seed": seed})
    train("chainhoi", data, run, cfg)
    sample(run, data, sub, seed=seed, log=None)
    return sub


def score(sub: Path, data: Path, ev: Path, out: Path) -> dict:
    from hoibench.core.io import atomic_write_json, read_json_file
    from hoibench.scoring.evaluate import evaluate
    if out.exists():
        return read_json_file(out, what="result")
    res = evaluate(sub, data, ev)
    atomic_write_json(out, res)
    return res


def per_rep(res: dict, key: str) -> np.ndarray:
    return np.array([r[key] for r in res["per_replication"]], dtype=np.float64)


def t_interval(x: np.ndarray) -> tuple[float, float]:
    """(mean, 95% half-width) of a sample, Student t."""
    from scipy import stats
    n = len(x)
    half = float(stats.t.ppf(0.975, n - 1) * x.std(ddof=1) / math.sqrt(n)) if n > 1 else float("nan")
    return float(x.mean()), half


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, required=True, help="the store (e.g. demo-out/data)")
    ap.add_argument("--evaluator", type=Path, required=True, help="the track's evaluator (MiniLM text branch)")
    ap.add_argument("--work", type=Path, default=Path("inflation"), help="runs, submissions, results, table")
    ap.add_argument("--tokens-run", type=Path, default=None,
                    help="an existing ChainHOI tiny run conditioned on tokens (default: train one in --work)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    from hoibench.core.io import atomic_write_json, atomic_write_text
    from hoibench.scoring.submission import from_store
    work = args.work
    t0 = time.perf_counter()
    ev = {"MiniLM": args.evaluator, "independent": independent_evaluator(args.data, work, args.seed)}
    gt = work / "submissions" / "gt"
    if not (gt / "submission.json").exists():
        from_store(args.data, gt)
    minilm = baseline_submission(args.data, work, "minilm", None, args.seed)
    while args.tokens_run is not None and not (args.tokens_run / "card.json").exists():
        print(f"waiting for {args.tokens_run} to finish training", flush=True)   # trained by another process
        time.sleep(60)
    subs = {"GT": gt, "tokens": baseline_submission(args.data, work, "tokens", args.tokens_run, args.seed),
            "minilm": minilm}
    res = {(s, e): score(subs[s], args.data, ev[e], work / "results" / f"{s}-{e}.json")
           for s in subs for e in ev}
    ids = {e: res[("GT", e)]["evaluator_id"][:12] for e in ev}
    lines = [f"store {args.data}, protocol {res[('GT', 'MiniLM')]['protocol']}, "
             f"{res[('GT', 'MiniLM')]['replications']} replications; evaluators: MiniLM {ids['MiniLM']}, "
             f"independent {ids['independent']}", "",
             "| conditioner | evaluator | " + " | ".join(n for _, n in METRICS) + " |",
             "|---|---|" + "|".join("---:" for _ in METRICS) + "|"]
    for s in subs:
        for e in ev:
            cells = [f"{m:.4g} ± {h:.2g}" for m, h in (t_interval(per_rep(res[(s, e)], k)) for k, _ in METRICS)]
            lines.append(f"| {s} | {e} | " + " | ".join(cells) + " |")
    summary = {}
    lines += ["", "| inflation (difference of differences) | " + " | ".join(n for _, n in METRICS) + " |",
              "|---|" + "|".join("---:" for _ in METRICS) + "|"]
    cells = []
    for k, n in METRICS:
        d = ((per_rep(res[("minilm", "MiniLM")], k) - per_rep(res[("tokens", "MiniLM")], k))
             - (per_rep(res[("minilm", "independent")], k) - per_rep(res[("tokens", "independent")], k)))
        m, h = t_interval(d)
        summary[k] = {"mean": m, "ci95": h, "outside_ci": bool(abs(m) > h)}
        cells.append(f"{m:+.4g} ± {h:.2g}")
    lines.append("| minilm-conditioned advantage under the MiniLM evaluator, beyond the independent one | "
                 + " | ".join(cells) + " |")
    lines += ["", f"total {time.perf_counter() - t0:.0f} s"]
    text = "\n".join(lines)
    atomic_write_text(work / "table.md", text + "\n")
    atomic_write_json(work / "inflation.json", {"evaluators": ids, "inflation": summary})
    print(text)


if __name__ == "__main__":
    main()
