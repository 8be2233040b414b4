"""What every ``hoibench import`` format shares: its error type and the grouping of
per-sample files (``<id>.ext`` / ``<id>_<r>.ext``)."""
from __future__ import annotations

import re
from collections import defaultdict
from pathlib import Path

_REP = re.compile(r"^(.*?)(?:_(\d+))?$")


class ImportProblem(ValueError):
    """An input that cannot be imported (names the file and the field)."""


def _group_files(folder: Path, ext: str, ids: list[str]) -> dict[str, list[Path]]:
    """``<id>.ext`` / ``<id>_<r>.ext`` files grouped by stem (the id when it is a test id)."""
    if not folder.is_dir():
        raise ImportProblem(f"{folder}: not a folder of {ext} files")
    idset = set(ids)
    groups: dict[str, list[tuple[int, Path]]] = defaultdict(list)
    for p in sorted(folder.glob(f"*{ext}")):
        stem = p.name[:-len(ext)]
        if stem in idset:
            groups[stem].append((0, p))
            continue
        m = _REP.match(stem)
        base, rep = m.group(1), m.group(2)
        groups[base if rep is not None else stem].append((int(rep or 0), p))
    return {k: [p for _, p in sorted(v)] for k, v in groups.items()}



__all__ = ["ImportProblem"]
