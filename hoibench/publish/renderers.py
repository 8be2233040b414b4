"""Renderers by track: ``hoibench render DATA/clips/<id>.npz`` draws a stored clip the way
its track's ``renderer`` says (:mod:`hoibench.tracks.registry`): ``hoi`` (body mesh, object,
contacts; :func:`hoibench.publish.render.render_clip`) or ``multibody`` (a strip of frames
with capsules and objects; :func:`hoibench.publish.render_multibody.render_multibody`)."""
from __future__ import annotations

from pathlib import Path


def _render_hoi(store, root, clip_id: str, out, body: str | None = None) -> Path:
    from .render import render_clip
    return render_clip(root, clip_id, out, body=body)


def _render_multibody(store, root, clip_id: str, out, body: str | None = None) -> Path:
    from ..bodies.multibody import MultiBodyClip
    from .render_multibody import render_multibody
    return render_multibody(MultiBodyClip.from_arrays(store.load(clip_id), store.object_template), out)


#: renderers by a track's ``renderer`` name
RENDERERS = {"hoi": _render_hoi, "multibody": _render_multibody}


def render_store_clip(root, clip_id: str, out, body: str | None = None) -> Path:
    """Render clip ``clip_id`` of the store at ``root`` (a path or a
    :class:`~hoibench.datasets.store.Store`) to ``out`` with its track's renderer."""
    from ..datasets.store import Store
    from ..tracks.registry import track_for_store
    store = root if isinstance(root, Store) else Store(root)
    return RENDERERS[track_for_store(store).renderer](store, store.root, clip_id, out, body=body)


def is_submission(path: str | Path) -> bool:
    """Whether ``path`` looks like a submission: a ``.zip`` file, or a folder with
    ``submission.json`` or ``samples/``."""
    path = Path(path)
    if path.is_file():
        return path.suffix.lower() == ".zip"
    return path.is_dir() and ((path / "submission.json").is_file() or (path / "samples").is_dir())


def _store_clip(store, clip_id: str, taken_for: str, expected: str) -> str:
    """``clip_id`` after the id rule and a look-up in the store's manifest; the refusal says
    what the argument was taken for and what was expected."""
    from ..core.ids import check_id
    check_id(clip_id, "clip id", taken_for)
    ids = store.clip_ids()
    if clip_id not in ids:
        example = f" (e.g. {ids[0]})" if ids else ""
        raise ValueError(f"{store.root / 'manifest.json'}: no clip {clip_id!r}: {taken_for} was taken for a clip id "
                         f"of this store{example}; expected {expected}")
    return clip_id


#: what ``hoibench render`` accepts, for its refusals
RENDER_EXPECTED = "an id of the store's manifest (with --data), DATA/clips/<id>.npz, or a submission with --id ID"


def main_render(clip: str, data, clip_id: str | None, out, sample: int = 0, body: str = "proxy") -> Path:
    """``hoibench render``: a stored clip (``DATA/clips/<id>.npz``, or an id with ``data``), or
    with ``clip_id`` the submission ``clip``'s sample beside its ground truth. Refusals say
    what ``clip`` was taken for and what was expected."""
    from ..datasets.store import Store
    if clip_id is not None:                    # a submission's sample beside its ground truth
        if data is None:
            raise ValueError("render SUB --id ID: --data DATA (the store the submission is for) is required")
        if not Path(clip).exists():
            raise FileNotFoundError(f"{clip}: taken for a submission (with --id) but does not exist; expected a "
                                    f"submission folder or .zip")
        store = Store(data)
        _store_clip(store, clip_id, "--id", "a test id of the store the submission is for")
        from .render import render_comparison
        return render_comparison(clip, store, clip_id, out, sample=sample)
    path = Path(clip)
    if path.suffix == ".npz":
        root, cid, taken = path.parent.parent, path.stem, f"the file name of {clip}"
    elif data is None:
        raise ValueError(f"render {clip}: expected DATA/clips/<id>.npz, or an id with --data DATA")
    elif is_submission(path):
        raise ValueError(f"render {clip} --data {data}: {clip} is a submission, taken for a clip id without --id; "
                         f"give --id ID to draw its sample for one test id beside the ground truth")
    else:
        root, cid, taken = data, str(clip), f"{clip!r} (given without --id)"
    store = Store(root)
    return render_store_clip(store, _store_clip(store, cid, taken, RENDER_EXPECTED), out, body=body)


def main_render_worst(result_path, k: int, by: str, data, submission, out, fmt: str = ".gif",
                      log=print) -> list[Path]:
    """``hoibench render RESULT --worst K --by COLUMN``: the ``k`` test clips at the failure
    end of ``COLUMN`` of the result's per-clip table (:func:`hoibench.scoring.per_clip.worst`),
    each drawn beside its ground truth into ``out/<n>_<id>.gif`` (n = 1 for the worst).
    ``submission`` defaults to the path the result records; ``data`` is required."""
    from ..scoring.per_clip import check_worst_args, worst
    from ..scoring.results import read_result
    from ..datasets.store import Store
    from .render import render_comparison
    check_worst_args(k, by)
    if data is None:
        raise ValueError("render RESULT --worst K: --data DATA (the store the result was scored on) is required")
    result = read_result(result_path)
    rows = worst(result, k, by, where=str(result_path))
    sub = submission if submission is not None else (result.get("submission") or {}).get("path")
    if not sub or not Path(sub).exists():
        raise FileNotFoundError(f"{result_path}: the submission it records ({sub!r}) is not there; give "
                                f"--submission SUB")
    store = Store(data)
    sample = int(result["per_clip"].get("sample", 0))
    out = Path(out)
    written = []
    for n, row in enumerate(rows, 1):
        cid = _store_clip(store, str(row["id"]), f"per_clip row {n} of {result_path}", "a test id of --data")
        path = render_comparison(sub, store, cid, out / f"{n:02d}_{cid}{fmt}", sample=sample)
        log(f"[render] {n}/{len(rows)} {cid}: {by} {row[by]:.4g} -> {path}")
        written.append(path)
    return written


__all__ = ["RENDERERS", "render_store_clip", "main_render", "main_render_worst", "is_submission"]
