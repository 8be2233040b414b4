"""Split files (``splits/<dataset>.json``): named splits per dataset with their provenance.

Each file: ``{"dataset", "version", "default", "splits": {name: {"level": "sequence" |
"clip", "source", "rule" and/or "train"/"val"/"test" lists, ...}}}``. Rule-only splits
(BEHAVE's official Date03 rule, RICH's meta files) are applied by the loaders.

The folder is ``$HOIBENCH_SPLITS_DIR`` when set, else ``splits/`` next to the package
(a source checkout or an editable install).
"""
from __future__ import annotations

import os
from pathlib import Path

from ..core.ids import InvalidIdError, check_id
from ..core.io import read_json_file

SPLIT_NAMES = ("train", "val", "test")


class SplitFileError(ValueError):
    """A split file that is not ``{"train": [id, ...], "val": [...], "test": [...]}`` of
    valid ids, each in one split only."""


def split_assignment(data: object, source: str) -> dict[str, str]:
    """``{"train": [...], "val": [...], "test": [...]}`` -> {id: split}, refusing (naming
    ``source``, the split and the entry) a file that is not a JSON object, a list that is
    not a list of ids, an entry that fails :func:`hoibench.core.ids.check_id`, or an id listed
    in two splits (a train/test leak). Keys other than the three splits are ignored."""
    if not isinstance(data, dict):
        raise SplitFileError(f"{source}: expected a JSON object with 'train'/'val'/'test' lists, "
                             f"got {type(data).__name__}")
    if not any(k in data for k in SPLIT_NAMES):
        raise SplitFileError(f"{source}: none of the keys 'train', 'val', 'test' (keys: {sorted(map(str, data))[:8]})")
    out: dict[str, str] = {}
    for split in SPLIT_NAMES:
        entries = data.get(split, [])
        if not isinstance(entries, list):
            raise SplitFileError(f"{source}: {split}: expected a list of ids, got {type(entries).__name__}")
        for i, name in enumerate(entries):
            try:
                check_id(name, f"{split}[{i}]", source)
            except InvalidIdError as exc:
                raise SplitFileError(str(exc)) from None
            if out.get(name, split) != split:
                raise SplitFileError(f"{source}: {name!r} is listed in both {out[name]!r} and {split!r} "
                                     "(an id in two splits leaks between them): refused")
            out[name] = split
    return out


def read_split_file(path: str | os.PathLike) -> dict[str, str]:
    """A user ``--split-file`` -> {id: split} (see :func:`split_assignment`)."""
    path = Path(path)
    if not path.exists():
        raise SplitFileError(f"--split-file: no file {path}")
    try:
        data = read_json_file(path, what="split file")
    except ValueError as exc:
        raise SplitFileError(str(exc)) from None
    return split_assignment(data, str(path))


def splits_dir() -> Path:
    env = os.environ.get("HOIBENCH_SPLITS_DIR")
    path = Path(env) if env else Path(__file__).resolve().parents[2] / "splits"
    if not path.is_dir():
        raise FileNotFoundError(f"split files: no folder {path} (set HOIBENCH_SPLITS_DIR)")
    return path


def available() -> list[str]:
    return sorted(p.stem for p in splits_dir().glob("*.json"))


def load(dataset: str) -> dict:
    """A shipped split file; each named split's id lists pass :func:`split_assignment`."""
    check_id(dataset, "dataset", "hoibench splits")
    path = splits_dir() / f"{dataset}.json"
    if not path.exists():
        raise FileNotFoundError(f"dataset: no split file {path} (available: {', '.join(available())})")
    data = read_json_file(path, what="split file")
    for name, sp in data.get("splits", {}).items():
        if any(k in sp for k in SPLIT_NAMES):
            split_assignment(sp, f"{path} split {name!r}")
    return data


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
