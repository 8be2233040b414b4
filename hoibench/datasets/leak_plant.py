"""Plant known duplicates into a copy of a store's test split (the leak check's ground truth).

:func:`plant_duplicates` copies a store and adds, for each kind, ``n`` new test clips made
from train clips (chosen by a seeded permutation of the sorted train ids):

* ``renamed``: the train clip unchanged under a new id; its captions copied verbatim;
* ``mirrored``: the left-right mirror image (joints ``M J[m(j)]``, ``M = diag(-1, 1, 1)``,
  object ``R' = M R M``, ``t' = M t``); captions with "left" and "right" swapped and one
  word appended (an n-gram near-duplicate);
* ``shifted``: a crop that starts ``shift_frames`` frames in (a fraction of a frame is
  interpolated: linear for positions, slerp for rotations) and ends ``shift_frames`` frames
  early; captions re-cased with their punctuation changed (a normalised duplicate).

Each planted clip is written as ``prepare`` writes clips (representations recomputed,
no body parameters: a mirrored or re-timed body has none that the loader measured), with
``texts/<id>.txt`` and a manifest row; the train split and its statistics are untouched.
Returns ``{planted id: {"kind", "source"}}`` (also the manifest's ``planted`` entry).
"""
from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np

from ..core.io import atomic_save_npz, atomic_write_json, atomic_write_text
from .leak_motion import mirror as mirror_joints
from .sequence import HOISequence
from .store import MANIFEST, Store, clip_arrays

KINDS = ("renamed", "mirrored", "shifted")
_SIGN = np.array([-1.0, 1.0, 1.0])


def _shift(x: np.ndarray, shift: float, n: int) -> np.ndarray:
    """``n`` frames of ``x`` (T, ...) at times ``shift + k`` (frames), linearly interpolated."""
    t = shift + np.arange(n)
    i0 = np.minimum(np.floor(t).astype(int), len(x) - 2)
    w = (t - i0).reshape((-1,) + (1,) * (x.ndim - 1))
    return (1 - w) * x[i0] + w * x[i0 + 1]


def _shift_rot(R: np.ndarray, shift: float, n: int) -> np.ndarray:
    from scipy.spatial.transform import Rotation, Slerp
    return Slerp(np.arange(len(R)), Rotation.from_matrix(R))(shift + np.arange(n)).as_matrix()


def _swap_sides(caption: str) -> str:
    return re.sub(r"\b(left|right)\b", lambda m: {"left": "right", "right": "left"}[m.group(1)], caption)


def _captions(kind: str, caps: list[str]) -> list[str]:
    if kind == "mirrored":
        return [_swap_sides(c).rstrip(".") + " again" for c in caps]
    if kind == "shifted":
        return [re.sub(r"[.,;!?]", "", c).upper() + "!" for c in caps]
    return list(caps)


def _planted(st: Store, src: str, kind: str, new_id: str, shift: float) -> HOISequence:
    a = st.load(src)
    J = a["joints"].astype(np.float64)
    R = a["obj_rot"].astype(np.float64) if "obj_rot" in a else None
    t = a["obj_trans"].astype(np.float64) if "obj_trans" in a else None
    if kind == "mirrored":
        J = mirror_joints(J)
        if R is not None:
            R, t = R * _SIGN[:, None] * _SIGN[None, :], t * _SIGN
    elif kind == "shifted":
        n = int(np.floor(len(J) - 1 - 2 * shift)) + 1
        if n < 2:
            raise ValueError(f"{st.root / 'clips' / (src + '.npz')}: joints: {len(J)} frames, too short to shift "
                             f"by {shift} frames")
        J = _shift(J, shift, n)
        if R is not None:
            R, t = _shift_rot(R, shift, n), _shift(t, shift, n)
    obj = str(a["object_name"]) if "object_name" in a else None
    verts = faces = None
    if obj and (st.root / "objects" / f"{obj}.npz").is_file():
        verts, faces = st.object_template(obj)
    return HOISequence(name=new_id, dataset=str(a.get("dataset", "")), subject=str(a.get("subject", "")),
                       fps=float(a["fps"]), joints=J.astype(np.float32), object_name=obj, object_vertices=verts,
                       object_faces=faces, obj_rot=None if R is None else R.astype(np.float32),
                       obj_trans=None if t is None else t.astype(np.float32),
                       provenance={"planted": kind, "source_clip": src, "shift_frames": shift})


def _read_captions(root: Path, clip_id: str) -> list[str]:
    p = root / "texts" / f"{clip_id}.txt"
    if not p.is_file():
        return []
    from ..core.io import read_text_file
    return [line.split("#")[0].strip() for line in read_text_file(p, what="caption file").splitlines()
            if line.split("#")[0].strip()]


def plant_duplicates(store: str | Path, out: str | Path, n: int = 2, seed: int = 0,
                     shift_frames: float = 3.3, kinds: tuple[str, ...] = KINDS) -> dict[str, dict]:
    """Copy ``store`` to ``out`` (which must not exist) and add ``n`` planted test clips of each
    of ``kinds`` (module docstring); returns {planted id: {"kind", "source"}}."""
    store, out = Path(store), Path(out)
    st = Store(store)
    train = sorted(st.clip_ids("train"))
    unknown = [k for k in kinds if k not in KINDS]
    if unknown:
        raise ValueError(f"kinds: unknown kind {unknown[0]!r} (expected {', '.join(KINDS)})")
    if n * len(kinds) > len(train):
        raise ValueError(f"{store / MANIFEST}: clips: {len(train)} train clips, {n * len(kinds)} needed")
    if out.exists():
        raise ValueError(f"{out}: exists (plant_duplicates writes a new copy)")
    shutil.copytree(store, out)
    dst = Store(out)
    order = np.random.default_rng(seed).permutation(len(train))
    mode = str(dst.manifest.get("config", {}).get("mode", "clean"))
    manifest, planted = dst.manifest, {}
    for k, kind in enumerate(kinds):
        for i in range(n):
            src = train[order[k * n + i]]
            new_id = f"planted-{kind}-{i}"
            seq = _planted(dst, src, kind, new_id, shift_frames)
            arrays = clip_arrays(seq, mode, "test", f"planted:{kind}:{src}")
            atomic_save_npz(out / "clips" / f"{new_id}.npz", **arrays)
            caps = _captions(kind, _read_captions(out, src))
            if caps:
                atomic_write_text(out / "texts" / f"{new_id}.txt", "".join(f"{c}#x#0.0#0.0\n" for c in caps))
            manifest["clips"].append({"id": new_id, "split": "test", "frames": seq.num_frames,
                                      "object": seq.object_name or "", "contact_frames": 0})
            planted[new_id] = {"kind": kind, "source": src}
    manifest["counts"]["clips"] = len(manifest["clips"])
    manifest["counts"]["by_split"] = {s: sum(1 for c in manifest["clips"] if c["split"] == s)
                                      for s in sorted({c["split"] for c in manifest["clips"]})}
    manifest["planted"] = planted
    atomic_write_json(out / MANIFEST, manifest)
    return json.loads(json.dumps(planted))   # read-ok: a deep copy of our own dict
