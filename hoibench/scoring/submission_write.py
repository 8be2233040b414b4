"""Writing a submission (folder or ``.zip``, byte-reproducible, never over existing
files) and the ground-truth submission of a store (:func:`from_store`, ``hoibench
submission from-store``).
"""
from __future__ import annotations

import io
import json
import sys
import zipfile
from pathlib import Path
from typing import Iterable, Mapping

import numpy as np

from .. import __version__
from ..core.ids import check_id
from ..core.io import atomic_write_bytes, npz_bytes
from .submission_read import SAMPLES_DIR, SUBMISSION_JSON

# ====================================================================== writing
def check_output_free(out: str | Path, as_zip: bool) -> None:
    """``FileExistsError`` unless ``out`` is free: a ``.zip`` path that does not exist, or a
    folder that does not exist or is empty. A submission never overwrites or mixes with
    other files (a stale ``samples/`` file would join the submission)."""
    out = Path(out)
    if as_zip:
        if out.exists() or out.is_symlink():
            raise FileExistsError(f"{out}: already exists; a submission never overwrites a file: choose another --out")
    elif out.exists() or out.is_symlink():
        if not out.is_dir():
            raise FileExistsError(f"{out}: exists and is not a folder; choose another --out")
        if any(out.iterdir()):
            raise FileExistsError(f"{out}: not empty; a submission is written into a new or empty folder only "
                                  f"(delete it or choose another --out)")


def write_submission(out: str | Path, meta: Mapping, samples: Iterable[tuple[str, Mapping[str, np.ndarray]]]
                     | Mapping[str, Mapping[str, np.ndarray]], as_zip: bool = False) -> Path:
    """Write a submission folder (or ``.zip`` when ``as_zip``): ``submission.json`` and
    ``samples/<id>.npz`` (byte-reproducible, no pickles). Atomic per file (the zip as a
    whole). Returns the path written."""
    out = Path(out)
    check_output_free(out, as_zip)
    items = samples.items() if isinstance(samples, Mapping) else samples
    files: dict[str, bytes] = {SUBMISSION_JSON: (json.dumps(dict(meta), indent=2, sort_keys=True) + "\n").encode()}
    for sid, arrays in items:
        check_id(str(sid), "sample id")
        files[f"{SAMPLES_DIR}/{sid}.npz"] = npz_bytes({k: np.asarray(v) for k, v in arrays.items()})
    if as_zip:
        buf = io.BytesIO()
        with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_STORED) as zf:
            for name, data in files.items():
                info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))
                info.external_attr = 0o644 << 16
                zf.writestr(info, data)
        return atomic_write_bytes(out, buf.getvalue())
    for name, data in files.items():
        atomic_write_bytes(out / name, data)
    return out


def from_store(data: str | Path, out: str | Path, split: str = "test", as_zip: bool = False,
               method: str = "ground truth (real motion)") -> Path:
    """A ground-truth submission: K = 1 sample per test clip, the clip itself -- the "real
    motion" row of every table, scored by the same code path as any model."""
    from ..datasets.store import Store

    st = Store(data)
    manifest = st.manifest
    meta = {"method": method, "version": __version__, "url": "",
            "representation": manifest.get("representations", {}).get("hml263", ""),
            "fps": float(manifest["config"]["fps"]),
            "flags": {"uses_gt_length": True, "samples_per_prompt": 1, "checkpoint_selection": "n/a"},
            "source": {"store": manifest.get("dataset", ""), "split": split, "toolkit_version": __version__}}

    def samples():
        for sid in st.clip_ids(split):
            clip = st.load(sid)
            arrays = {"joints": clip["joints"][None].astype(np.float32)}
            if "obj_rot" in clip:
                arrays["obj_rot"] = clip["obj_rot"][None].astype(np.float32)
                arrays["obj_trans"] = clip["obj_trans"][None].astype(np.float32)
            if "hml263" in clip:
                arrays["hml263"] = clip["hml263"][None]
            if "markers" in clip:        # InterAct stores: the interact track's evaluator reads them
                arrays["markers"] = clip["markers"][None].astype(np.float32)
            yield sid, arrays

    return write_submission(out, meta, samples(), as_zip=as_zip)


# ====================================================================== CLI entry points
def main_submission_from_store(data: str | Path, out: str | Path, split: str = "test", as_zip: bool = False,
                               method: str = "ground truth (real motion)") -> int:
    """``hoibench submission from-store DATA --out OUT [--zip]``: write the ground-truth
    submission; exit status 0, or 2 when the store cannot be read."""
    try:
        path = from_store(data, out, split, as_zip, method)
    except (FileNotFoundError, KeyError, ValueError) as e:
        print(f"hoibench submission: error: {e.args[0] if isinstance(e, KeyError) else e}", file=sys.stderr)
        return 2
    print(f"wrote {path} ({'zip' if as_zip else 'folder'}; ground truth of split {split!r})")
    return 0
