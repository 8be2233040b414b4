"""Baseline runs for ``hoibench baseline``: ``--set`` overrides and ``show`` of a run folder
(the train and sample commands are in :mod:`hoibench.commands.baselines`).

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
