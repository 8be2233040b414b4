"""Split files (``splits/<dataset>.json``): named splits per dataset with their provenance.

Each file: ``{"dataset", "version", "default", "splits": {name: {"level": "sequence" |
"clip", "source", "rule" and/or "train"/"val"/"test" lists, ...}}}``. Rule-only splits
(BEHAVE's official Date03 rule, RICH's meta files) are applied by the loaders.

The folder is ``$HOIBENCH_SPLITS_DIR`` when set, else ``splits/`` next to the package
(a source checkout or an editable install).
"""
from __future__ import annotations

import json
import os
from pathlib import Path


def splits_dir() -> Path:
    env = os.environ.get("HOIBENCH_SPLITS_DIR")
    path = Path(env) if env else Path(__file__).resolve().parent.parent / "splits"
    if not path.is_dir():
        raise FileNotFoundError(f"split files: no folder {path} (set HOIBENCH_SPLITS_DIR)")
    return path


def available() -> list[str]:
    return sorted(p.stem for p in splits_dir().glob("*.json"))


def load(dataset: str) -> dict:
    path = splits_dir() / f"{dataset}.json"
    if not path.exists():
        raise FileNotFoundError(f"dataset: no split file {path} (available: {', '.join(available())})")
    return json.loads(path.read_text())


def get(dataset: str, name: str | None = None) -> dict:
    """One named split (the file's default when ``name`` is None)."""
    data = load(dataset)
    key = name or data["default"]
    if key not in data["splits"]:
        raise ValueError(f"split: {dataset} has no split {key!r} (available: {sorted(data['splits'])})")
    return data["splits"][key]


def summary_lines() -> list[str]:
    lines = [f"{'dataset':10s} {'split':15s} {'level':9s} {'train':>6s} {'val':>5s} {'test':>6s}  source"]
    for ds in available():
        data = load(ds)
        for name, sp in data["splits"].items():
            counts = [str(len(sp[k])) if k in sp else "-" for k in ("train", "val", "test")]
            mark = "*" if name == data["default"] else " "
            lines.append(f"{ds:10s} {name + mark:15s} {sp['level']:9s} {counts[0]:>6s} {counts[1]:>5s} "
                         f"{counts[2]:>6s}  {sp.get('rule') or sp['source']}")
    return lines
