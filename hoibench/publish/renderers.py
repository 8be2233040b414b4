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
    """Render clip ``clip_id`` of the store at ``root`` to ``out`` with its track's renderer."""
    from ..datasets.store import Store
    from ..tracks.registry import track_for_store
    store = Store(root)
    return RENDERERS[track_for_store(store).renderer](store, root, clip_id, out, body=body)


__all__ = ["RENDERERS", "render_store_clip"]
