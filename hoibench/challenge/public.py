"""``hoibench challenge public``: what the participants of a hosted challenge may have.

``public/`` holds::

    store/            the store with its train split only: train clip files, train texts,
                      the train-split statistics, every object template; a manifest whose
                      rows, counts and checksums cover the train clips only
    prompts.jsonl     the test prompts (``hoibench submission prompts``: captions, frames,
                      fps, object, group, representation) with ``object_mesh`` paths
                      relative to ``public/``
    README.md         how to make and check a submission

Nothing computed from a test motion is written: no test clip file, no test row of the
manifest (its contact-frame count and checksum are derived from the motion), no statistics
other than the train split's (the store's statistics are train-only by construction), no
test contact labels. The test prompts state lengths, as the protocol's prompts do.
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path

from ..core.io import atomic_write_json, atomic_write_text, read_json_file

README = """\
# {title}: public data

- `store/`: the train split (motions, texts, statistics, object meshes), a hoibench store:
  `hoibench baseline train chainhoi store --out run` trains on it as on any store.
- `prompts.jsonl`: one test prompt per line (id, captions, frames, fps, object, object_mesh,
  group, representation). Generate `samples/<id>.npz` for each (docs/leaderboards.md),
  write `submission.json`, zip the folder's contents and upload.
"""


def write_public(data: str | Path, out: str | Path, title: str = "hoibench challenge") -> Path:
    """Write the participants' folder ``out`` (must not exist or be empty); return it."""
    from ..datasets.store import Store
    from ..scoring.prompts import prompts
    data, out = Path(data), Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ValueError(f"--out {out}: exists and is not an empty folder; choose a new folder")
    st = Store(data)
    train = set(st.clip_ids("train"))
    test = st.clip_ids("test")
    if not train or not test:
        raise ValueError(f"{data}: the store needs a train and a test split (train {len(train)}, test {len(test)})")
    lines = prompts(data, "test")

    test_set = set(test)

    def ignore(folder: str, names: list[str]) -> list[str]:
        here = Path(folder).resolve()
        if here == data.resolve():
            return [n for n in names if n in ("manifest.json", "errors.jsonl") or n.startswith(".")]
        return [n for n in names if n.startswith(".") or n.split(".")[0] in test_set
                or (here == (data / "clips").resolve() and n.split(".")[0] not in train)]
    shutil.copytree(data, out / "store", ignore=ignore)
    manifest = read_json_file(data / "manifest.json", 256 << 20, "manifest.json")
    manifest["clips"] = [c for c in manifest["clips"] if c["id"] in train]
    manifest["source_checksums"] = {k: v for k, v in manifest.get("source_checksums", {}).items() if k in train}
    counts = manifest.get("counts", {})
    counts.update({"clips": len(manifest["clips"]), "by_split": {"train": len(manifest["clips"])},
                   "frames": sum(int(c.get("frames", 0)) for c in manifest["clips"]),
                   "contact_frames": sum(int(c.get("contact_frames", 0)) for c in manifest["clips"]),
                   "failed": 0})
    manifest["counts"] = counts
    manifest.pop("errors", None)
    manifest["public"] = {"note": "train split only; test prompts in ../prompts.jsonl"}
    atomic_write_json(out / "store" / "manifest.json", manifest)
    index = out / "store" / "annotations" / "index.json"
    if index.is_file():                  # semantic groups: train members only
        atomic_write_json(index, _without(read_json_file(index, 64 << 20, "annotations/index.json"), test_set))
    text = ""
    for p in lines:
        if p.get("object_mesh"):
            p["object_mesh"] = (Path("store") / "objects" / Path(p["object_mesh"]).name).as_posix()
        text += json.dumps(p, sort_keys=True, allow_nan=False) + "\n"
    atomic_write_text(out / "prompts.jsonl", text)
    atomic_write_text(out / "README.md", README.format(title=title))
    return out


def _without(obj, drop: set[str]):
    """``obj`` with every string in ``drop`` removed from its lists and keys."""
    if isinstance(obj, dict):
        return {k: _without(v, drop) for k, v in obj.items() if k not in drop}
    if isinstance(obj, list):
        return [_without(v, drop) for v in obj if not (isinstance(v, str) and v in drop)]
    return obj


__all__ = ["write_public"]
