"""Import fixture shared by the tests of the t2m-architecture evaluators (``t2m``, ``chois``)."""
from __future__ import annotations

from pathlib import Path
from typing import Callable


def import_release(tmp_path_factory, name: str, write: Callable[[Path], dict[str, Path]], importer: Callable,
                   dims) -> tuple[Path, dict[str, Path], str]:
    """(root, files, evaluator id): ``write(root / "release")`` writes the release's files
    (``checkpoint``, ``glove``, ``meta``), ``importer`` makes the evaluator folder ``root / "ev"``."""
    root = tmp_path_factory.mktemp(name)
    files = write(root / "release")
    eid = importer(root / "ev", files["checkpoint"], files["glove"], files["meta"], dims=dims)
    return root, files, eid
