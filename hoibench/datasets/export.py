"""Export a processed store to the folder layouts existing generators train on.

``humanml3d`` (HumanML3D / text-to-motion / MDM / T2M-GPT readers)::

    OUT/new_joint_vecs/<id>.npy   (T-1, 263) float32 hml263 features
    OUT/new_joints/<id>.npy       (T-1, 22, 3) float32 joints decoded from the features
    OUT/texts/<id>.txt            caption#tokens#start#end lines (tokens = word/POS)
    OUT/{train,val,test,all}.txt  clip ids
    OUT/Mean.npy, OUT/Std.npy     normalisation statistics of the train split

``hoidiff`` (HOI-Diff's ``<dataset>_t2m`` folder, read with ``data_root = OUT``)::

    OUT/dataset_split.json                          {<dataset>: {"train": [...], "test": [...]}}
    OUT/<dataset>_t2m/sequences_263_rep/<id>/hoi_motion.npy   (T-1, 269) float32
    OUT/<dataset>_t2m/sequences/<id>/object_motion.npz        name, angles (T,3), trans (T,3)
    OUT/<dataset>_t2m/texts/<id>.txt
    OUT/<dataset>_t2m/object_mesh/<obj>/<obj>.obj, sample_points.npy (1024 surface points)
    OUT/<dataset>_t2m/Mean_local.npy, Std_local.npy

Not exported (documented in docs/datasets.md): HOI-Diff's ``affordance/`` files and
``bps_1024.npy`` object encodings, which are model-specific features.

Texts come from ``DATA/texts/<id>.txt`` (written by ``hoibench annotate``); a clip without
a text file is exported without one and listed in the returned report.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core.geometry import matrix_to_axis_angle
from ..core.ids import check_id
from ..core.io import (atomic_save_npy, atomic_save_npz, atomic_write_bytes, atomic_write_json, atomic_write_text,
                       load_npy_file, read_text_file)
from ..representations import hml263
from .store import Store

FORMATS = ("humanml3d", "hoidiff")
#: the report every export writes last: a folder holding it is an earlier export
REPORT = "hoibench_export.json"


def _checked_ids(store: Store) -> dict[str | None, list[str]]:
    """Clip ids of the manifest per split (None: all), each passing :func:`check_id`
    before it becomes an exported file or folder name."""
    src = store.root / "manifest.json"
    ids = {s: [check_id(c, "clip id", src) for c in store.clip_ids(s)] for s in ("train", "val", "test")}
    ids[None] = [check_id(c, "clip id", src) for c in store.clip_ids()]
    return ids


def _texts(store: Store, clip_id: str) -> str | None:
    path = store.root / "texts" / f"{clip_id}.txt"
    return read_text_file(path, what="caption file") if path.exists() else None


def check_export_out(out: Path, overwrite: bool = False) -> None:
    """``out`` must be new, empty, or an earlier export (it holds ``hoibench_export.json``);
    FileExistsError otherwise, unless ``overwrite`` (files of the same names are replaced)."""
    if out.exists() and not out.is_dir():
        raise FileExistsError(f"{out}: exists and is not a folder; choose a new folder")
    if out.is_dir() and not overwrite and not (out / REPORT).is_file():
        held = sorted(p.name for p in out.iterdir())
        if held:
            raise FileExistsError(f"{out}: not empty and not an earlier export (holds {', '.join(held[:3])}"
                                  f"{'...' if len(held) > 3 else ''}); choose a new folder, or pass --overwrite "
                                  f"to replace files of the same names")


def export(data: str | Path, out: str | Path, fmt: str = "humanml3d", overwrite: bool = False) -> dict:
    """Write ``data`` (a store) to ``out`` in ``fmt``; returns a report (counts, missing texts).
    ``out`` must be new, empty or an earlier export unless ``overwrite`` (:func:`check_export_out`)."""
    if fmt not in FORMATS:
        raise ValueError(f"--format: expected one of {FORMATS}, got {fmt!r}")
    out = Path(out)
    check_export_out(out, overwrite)
    store = Store(data)
    ids = _checked_ids(store)
    no_text: list[str] = []
    if fmt == "humanml3d":
        for cid in ids[None]:
            clip = store.load(cid)
            atomic_save_npy(out / "new_joint_vecs" / f"{cid}.npy", clip["hml263"].astype(np.float32))
            atomic_save_npy(out / "new_joints" / f"{cid}.npy", hml263.decode(clip["hml263"]).astype(np.float32))
            text = _texts(store, cid)
            if text is None:
                no_text.append(cid)
            else:
                atomic_write_text(out / "texts" / f"{cid}.txt", text)
        for split in ("train", "val", "test"):
            atomic_write_text(out / f"{split}.txt", "".join(f"{i}\n" for i in ids[split]))
        atomic_write_text(out / "all.txt", "".join(f"{i}\n" for i in ids[None]))
        stats = store.stats("hml263")
        atomic_save_npy(out / "Mean.npy", stats.mean)
        atomic_save_npy(out / "Std.npy", stats.std)
    else:
        ds = check_id(store.manifest["dataset"], "dataset", store.root / "manifest.json")
        root = out / f"{ds}_t2m"
        atomic_write_json(out / "dataset_split.json", {ds: {"train": ids["train"] + ids["val"], "test": ids["test"]}})
        objects = set()
        for cid in ids[None]:
            clip = store.load(cid)
            if "hoi269" not in clip:
                raise ValueError(f"{cid}: no object: the hoidiff layout needs HOI clips")
            atomic_save_npy(root / "sequences_263_rep" / cid / "hoi_motion.npy", clip["hoi269"].astype(np.float32))
            atomic_save_npz(root / "sequences" / cid / "object_motion.npz", name=clip["object_name"],
                            angles=matrix_to_axis_angle(clip["obj_rot"].astype(np.float64)),
                            trans=clip["obj_trans"].astype(np.float64))
            objects.add(check_id(str(clip["object_name"]), "object name", store.root / "clips" / f"{cid}.npz"))
            text = _texts(store, cid)
            if text is None:
                no_text.append(cid)
            else:
                atomic_write_text(root / "texts" / f"{cid}.txt", text)
        for obj in sorted(objects):
            v, f = store.object_template(obj)
            atomic_write_bytes(root / "object_mesh" / obj / f"{obj}.obj", _obj_bytes(v, f))
            atomic_save_npy(root / "object_mesh" / obj / "sample_points.npy", _surface_points(v, f, 1024, obj))
        stats = store.stats("hoi269")
        atomic_save_npy(root / "Mean_local.npy", stats.mean)
        atomic_save_npy(root / "Std_local.npy", stats.std)
    report = {"format": fmt, "clips": len(store.clip_ids()), "missing_texts": no_text,
              "source_manifest": {k: store.manifest[k] for k in ("dataset", "toolkit_version", "representations")}}
    atomic_write_json(out / REPORT, report)
    return report


def _obj_bytes(v: np.ndarray, f: np.ndarray) -> bytes:
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in v]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f]
    return ("\n".join(lines) + "\n").encode()


def _surface_points(v: np.ndarray, f: np.ndarray, n: int, name: str) -> np.ndarray:
    """``n`` area-weighted surface samples, seeded from the object name (deterministic)."""
    import hashlib
    seed = int.from_bytes(hashlib.sha256(name.encode()).digest()[:8], "little")
    rng = np.random.default_rng(seed)
    tri = v[f].astype(np.float64)
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    idx = rng.choice(len(f), size=n, p=area / area.sum())
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    w = np.stack([1 - s, s * (1 - r2), s * r2], -1)
    return np.einsum("nk,nkd->nd", w, tri[idx]).astype(np.float32)


def read_humanml3d(root: str | Path) -> dict[str, dict]:
    """Read a HumanML3D-layout folder back: {id: {"features", "joints", "texts": [(caption,
    tokens, start, end)], "split"}} (tokens as a list of 'word/POS')."""
    root = Path(root)
    split_of = {}
    for split in ("train", "val", "test"):
        p = root / f"{split}.txt"
        if not p.exists():
            continue
        for line in read_text_file(p, what="split list").splitlines():
            cid = line.strip()
            if not cid:
                continue
            check_id(cid, "clip id", p)
            if split_of.get(cid, split) != split:
                raise ValueError(f"{p}: {cid!r} is listed in both {split_of[cid]}.txt and {split}.txt: refused")
            split_of[cid] = split
    out = {}
    for cid, split in split_of.items():
        texts = []
        tp = root / "texts" / f"{cid}.txt"
        if tp.exists():
            for line in read_text_file(tp, what="caption file").splitlines():
                parts = line.strip().split("#")
                if len(parts) != 4:
                    raise ValueError(f"{tp}: expected caption#tokens#start#end, got {line!r}")
                texts.append((parts[0], parts[1].split(" "), float(parts[2]), float(parts[3])))
        out[cid] = {"features": load_npy_file(root / "new_joint_vecs" / f"{cid}.npy", what="feature file"),
                    "joints": load_npy_file(root / "new_joints" / f"{cid}.npy", what="joint file"), "texts": texts,
                    "split": split}
    return out


__all__ = ["FORMATS", "export", "read_humanml3d"]
