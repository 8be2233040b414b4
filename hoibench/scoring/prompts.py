"""``hoibench submission prompts``: what a generator needs to produce a submission, without
reading hoibench's code -- one JSON line per test clip.

Fields: ``id`` (the submission's sample name: ``samples/<id>.npz``), ``captions`` (every
caption of the clip; the evaluator draws one per replication, baselines condition on the
first), ``frames`` (the ground truth's length T at ``fps``: submit (K, T, 22, 3) joints to
use the GT length), ``fps``, ``object`` (name, or null on a human-only store), ``object_mesh``
(path of the centred template ``.npz`` with ``vertices`` (V, 3) metres and ``faces`` (F, 3);
the submission's object pose maps it as ``R v + t``), ``group`` (semantic group id),
``representation`` (the store's representation version, for ``submission.json``) and the
store's frame conventions (``up`` y, metres, canonical frame of frame 0). InterAct's
object-to-human and human-to-object tracks (``--protocol interact-o2h-clean`` /
``interact-h2o-clean``) add ``task``, ``condition`` and ``submit``: the object's motion or the
human's markers per frame in ``conditions/<id>.npz`` beside the prompts file
(:mod:`hoibench.scoring.interact_task_files`; ``interact`` stores keep InterAct's frame).

A ten-line generation loop (docs/leaderboards.md has it with the zip step)::

    import json, numpy as np, pathlib
    out = pathlib.Path("my_sub/samples"); out.mkdir(parents=True, exist_ok=True)
    for line in open("prompts.jsonl"):
        p = json.loads(line)
        joints, obj_rot, obj_trans = my_model(p["captions"][0], p["object_mesh"], p["frames"])
        np.savez(out / f"{p['id']}.npz", joints=joints[None].astype("float32"),
                 obj_rot=obj_rot[None].astype("float32"), obj_trans=obj_trans[None].astype("float32"))
    json.dump({"method": "my model", "version": "1.0", "representation": p["representation"], "fps": p["fps"],
               "flags": {"samples_per_prompt": 1}}, open("my_sub/submission.json", "w"))
"""
from __future__ import annotations

import json
from pathlib import Path

from ..core.io import MAX_SMALL_JSON_BYTES, atomic_write_text, read_json_file
from ..datasets.store import Store


def _group_id(path: Path) -> str | None:
    """``group_id`` of a clip's annotation file (read through the guarded reader)."""
    ann = read_json_file(path, MAX_SMALL_JSON_BYTES, "annotation file")
    group = ann.get("group_id") if isinstance(ann, dict) else None
    if group is not None and not isinstance(group, (str, int)):
        raise ValueError(f"{path}: group_id: expected a string, got {type(group).__name__}")
    return group


def task_of(st: Store, protocol=None) -> str | None:
    """The InterAct task (``o2h``, ``h2o``) whose track ``protocol`` selects on store ``st``
    (:func:`hoibench.tracks.registry.fitting_track`: a protocol of another dataset's track is
    refused), or None for a text-to-motion track."""
    if protocol is None:
        return None
    from ..tracks.protocol import get_protocol
    from ..tracks.registry import fitting_track
    return fitting_track(st, get_protocol(protocol)).extras.get("task")


def prompts(data: str | Path, split: str = "test", protocol=None, conditions: str | Path | None = None) -> list[dict]:
    """One dict per clip of ``split`` (fields above); ValueError naming the clip and file when
    a clip has no captions. Under a protocol of InterAct's o2h or h2o track each line also
    carries ``task``, ``condition`` (``conditions/<id>.npz``, written into the folder
    ``conditions``) and ``submit`` (:mod:`hoibench.scoring.interact_task_files`)."""
    from ..evaluator.text import read_captions
    st = Store(data)
    task = task_of(st, protocol)
    if task and conditions is None:
        raise ValueError(f"submission prompts --protocol {protocol}: --out is required: the {task} task's "
                         f"conditions files are written beside the prompts file")
    fps = float(st.manifest["config"]["fps"])
    rep = st.manifest.get("representations", {}).get("hml263", "")
    ids = st.clip_ids(split)
    if not ids:
        raise ValueError(f"{data}: split {split!r} has no clips")
    paths = {}
    if task:
        from .interact_task_files import write_conditions
        paths = write_conditions(st, ids, task, Path(conditions))
    out = []
    for cid in ids:
        caps = read_captions(st.root, cid)
        if not caps:
            raise ValueError(f"{st.root}/texts/{cid}.txt: missing or empty: clip {cid} has no caption "
                             f"(run `hoibench annotate {data}` first)")
        clip = st.load(cid, keys=("joints", "object_name"))
        name = str(clip["object_name"]) if "object_name" in clip else None
        ann = st.root / "annotations" / f"{cid}.json"
        group = _group_id(ann) if ann.exists() else None
        out.append({"id": cid, "captions": [c.text for c in caps], "frames": int(clip["joints"].shape[0]),
                    "fps": fps, "object": name,
                    "object_mesh": str((st.root / "objects" / f"{name}.npz").resolve()) if name else None,
                    "group": group, "representation": rep, "up": "y", "units": "m", "frame": "canonical (frame 0: root at x = z = 0, "
                                                                     "facing +z, floor y = 0)"})
        if task:
            from .interact_task_files import prompt_fields
            out[-1].update(prompt_fields(task, paths[cid]))
    return out


#: the fields every line of a prompts file has
PROMPT_FIELDS = ("captions", "fps", "frames", "id")


def is_prompts_file(path: str | Path) -> bool:
    """Whether ``path`` is a prompts file this toolkit wrote: every line a JSON object with
    :data:`PROMPT_FIELDS` (read through the guarded reader; a special file is not)."""
    from ..core.io import MAX_JSON_BYTES, load_json_bytes, read_text_file
    try:
        lines = [s for s in read_text_file(path, MAX_JSON_BYTES, "prompts file").splitlines() if s.strip()]
        rows = [load_json_bytes(s, path) for s in lines]
    except ValueError:
        return False
    return bool(rows) and all(isinstance(r, dict) and all(k in r for k in PROMPT_FIELDS) for r in rows)


def check_prompts_out(out: str | Path) -> None:
    """FileExistsError unless ``out`` is new or an earlier prompts file."""
    p = Path(out)
    if p.is_dir():
        raise FileExistsError(f"--out {out}: is a folder; name a new file such as {p / 'prompts.jsonl'}")
    if (p.exists() or p.is_symlink()) and not is_prompts_file(p):
        raise FileExistsError(f"--out {out}: exists and is not a prompts file written by hoibench: not "
                              f"overwritten; choose a new file")


def write_prompts(data: str | Path, out: str | Path | None = None, split: str = "test", protocol=None) -> str:
    """The JSON lines of :func:`prompts`; written atomically to ``out`` when given. An existing
    ``out`` is replaced only when it is a prompts file (:func:`is_prompts_file`): any other file
    is refused before the store is read, never overwritten. ``protocol``: one of InterAct's
    o2h/h2o protocols adds the conditions, in ``conditions/`` beside ``out``."""
    if out is not None:
        check_prompts_out(out)
    cond = Path(out).parent / "conditions" if out is not None else None
    text = "".join(json.dumps(p, sort_keys=True, allow_nan=False) + "\n"
                   for p in prompts(data, split, protocol, cond))
    if out is not None:
        atomic_write_text(out, text)
    return text
