"""The hidden reference data of a hosted challenge, and reading it back.

A reference folder (zipped into the bundle as ``reference_data.zip``; Codabench mounts it
at ``/app/input/ref``) holds::

    challenge.json     track, protocol id and sha256, evaluator id, store fingerprint,
                       leaderboard columns, phase -> split, hoibench version
    store/             the store: manifest, stats, objects, texts, groups, and the clip
                       files of the scored split only (other splits' rows stay in the
                       manifest: the evaluator's card is matched against them)
    evaluator/         the evaluator folder

:func:`engine_id` turns a hex id into an integer of at most 10 digits, because engines'
score columns are numbers only (Codabench stores ``Decimal(20, 10)``): a row's hidden
``evaluator_id8`` / ``protocol_sha8`` columns let :mod:`.engine_results` refuse rows scored
with another evaluator or protocol.
"""
from __future__ import annotations

import shutil
from pathlib import Path

from ..core.io import atomic_write_json, read_json_file

CHALLENGE_JSON = "challenge.json"
FORMAT = "hoibench-challenge-1"


def engine_id(hex_id: str) -> int:
    """The first 8 hex digits of ``hex_id`` as an integer (< 2**32: 10 decimal digits)."""
    return int(str(hex_id)[:8], 16)


def write_reference(data: Path, evaluator: Path, out: Path, info: dict, split: str = "test") -> Path:
    """Copy the store (clip files of ``split`` only) and the evaluator into ``out`` with
    ``challenge.json`` = ``info``. ``out`` must not exist."""
    from ..datasets.store import Store
    data, evaluator, out = Path(data), Path(evaluator), Path(out)
    if out.exists():
        raise ValueError(f"{out}: exists; the reference folder is written fresh")
    keep = set(Store(data).clip_ids(split))

    def ignore(folder: str, names: list[str]) -> list[str]:
        if Path(folder).resolve() == (data / "clips").resolve():
            return [n for n in names if not (n.endswith(".npz") and n[:-4] in keep)]
        return [n for n in names if n.startswith(".")]
    shutil.copytree(data, out / "store", ignore=ignore)
    shutil.copytree(evaluator, out / "evaluator", ignore=shutil.ignore_patterns(".*", "checkpoint*"))
    atomic_write_json(out / CHALLENGE_JSON, {"format": FORMAT, **info})
    return out


def read_reference(ref: Path) -> dict:
    """``challenge.json`` of a reference folder, checked (one-line errors naming the field)."""
    ref = Path(ref)
    info = read_json_file(ref / CHALLENGE_JSON, 1 << 20, CHALLENGE_JSON)
    if not isinstance(info, dict) or info.get("format") != FORMAT:
        raise ValueError(f"{CHALLENGE_JSON}: field format: expected {FORMAT!r}")
    for key in ("protocol", "evaluator_id", "columns", "track"):
        if key not in info:
            raise ValueError(f"{CHALLENGE_JSON}: field {key}: missing")
    for sub in ("store", "evaluator"):
        if not (ref / sub).is_dir():
            raise ValueError(f"reference data: folder {sub}/ missing")
    return info


__all__ = ["CHALLENGE_JSON", "FORMAT", "engine_id", "write_reference", "read_reference"]
