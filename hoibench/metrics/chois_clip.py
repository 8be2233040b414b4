"""Per-clip entry point of CHOIS's metrics for the scorer (catalogue ``clip_fn``).

:func:`chois_clip_metrics` ``(inp, settings) -> {name: value}`` reads a
:class:`hoibench.metrics.physical.ClipInput` whose ground-truth fields the scorer fills
(catalogue ``needs_ground_truth``): ``gt_joints`` (T, 22, 3), ``gt_obj_rot`` (T, 3, 3),
``gt_obj_trans`` (T, 3), y-up like ``joints``. Everything else is made here from the 22
joints, the same way for the generated clip and its ground truth:

* joints24 (:mod:`hoibench.metrics.chois_inputs`: the proxy fit's hand joints), z-up;
* body vertices for ``mpvpe`` and penetration: the proxy joint-fit surface
  (:func:`hoibench.metrics.body_surface.proxy_vertices_from_joints`, 6,890 vertices; CHOIS
  uses SMPL-X's 10,475), and the hand vertices (CHOIS's ``data/part_vert_ids``) are the
  proxy's left then right wrist-and-finger vertices;
* the root's global rotation for ``rot_dist``: the proxy fit's pelvis rotation;
* the object's signed distance (:mod:`hoibench.metrics.chois_sdf` reads it through
  ``normalise``/``sample``): exact from the template mesh (``sdf: exact``, default), or
  CHOIS's way, trilinear on a 256^3 grid of exact values at the grid's nodes (``sdf:
  grid256``); distances in the grid's normalised units (half the template's largest extent).

Settings (protocol key ``chois``): ``up`` (``y``: ClipInput's joints; or ``z``),
``rest_frame`` (``chois``: hand penetration with CHOIS's ``R (v - com)``; ``transpose``:
``R^T (v - com)``), ``joints`` (``"24"``: joints24, CHOIS's; ``"22"``: the wrists and its
0.10 m contact rule), ``sdf`` (above). Frobenius rotation distances do not depend on the
frame, so rotations are used as given.
"""
from __future__ import annotations

from functools import lru_cache
from typing import Any, Mapping

import numpy as np

from . import chois as ch

SETTINGS = {"up": ("y", "z"), "rest_frame": ("chois", "transpose"), "joints": ("24", "22"),
            "sdf": ("exact", "grid256")}
#: nodes per axis of CHOIS's signed-distance grids (mesh_to_sdf, 256^3)
GRID_NODES = 256


def check_settings(mapping: Mapping, where: str) -> None:
    """The protocol's ``chois`` mapping: known keys with allowed values (ValueError naming
    ``where`` and the field)."""
    for key, value in mapping.items():
        if key not in SETTINGS:
            raise ValueError(f"{where}: field {key!r} is not one of {sorted(SETTINGS)}")
        if value not in SETTINGS[key]:
            raise ValueError(f"{where}: field {key!r} must be one of {SETTINGS[key]}, got {value!r}")


def _z_up(a: np.ndarray, up: str) -> np.ndarray:
    from .chois_inputs import z_up
    return z_up(a) if up == "y" else np.asarray(a, np.float64)


def _posed(template, rot, trans) -> np.ndarray:
    """(T, V, 3) ``R v_template + t`` (ClipInput's object convention)."""
    return np.einsum("tij,vj->tvi", np.asarray(rot, np.float64), np.asarray(template, np.float64)) \
        + np.asarray(trans, np.float64)[:, None, :]


class MeshSdf:
    """The exact signed distance of a mesh (negative inside) behind the grid interface of
    :class:`hoibench.metrics.chois_sdf.SdfGrid`: ``normalise`` maps points to ``(p - centroid)
    * 2 / max(extents)`` (centroid: the bounding box's centre) and ``sample`` returns the
    distance in those units, unclamped."""

    def __init__(self, vertices, faces):
        self.vertices = np.asarray(vertices, np.float64)
        self.faces = np.asarray(faces, np.int64)
        lo, hi = self.vertices.min(0), self.vertices.max(0)
        self.centroid, self.extents = (lo + hi) / 2.0, hi - lo
        self.half = float(np.max(self.extents)) / 2.0

    def normalise(self, points) -> np.ndarray:
        return (np.asarray(points, np.float64) - self.centroid) / self.half

    def sample(self, coords) -> np.ndarray:
        from ..bodies.distance import signed_distance
        c = np.asarray(coords, np.float64)
        d = signed_distance(c.reshape(-1, 3) * self.half + self.centroid, self.vertices, self.faces)
        return d.reshape(c.shape[:-1]) / self.half


def grid_sdf(vertices, faces, nodes: int = GRID_NODES):
    """A :class:`~hoibench.metrics.chois_sdf.SdfGrid` of ``nodes``^3 exact values at the grid's
    nodes over the template's bounding cube (``[-1, 1]`` per axis of :class:`MeshSdf`'s
    normalised frame), read trilinearly as CHOIS reads its mesh_to_sdf grids."""
    from .chois_sdf import SdfGrid
    exact = MeshSdf(vertices, faces)
    axis = np.linspace(-1.0, 1.0, int(nodes))
    grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), -1)
    values = np.concatenate([exact.sample(chunk) for chunk in np.array_split(grid.reshape(-1, 3), 64)])
    return SdfGrid(values.reshape(nodes, nodes, nodes), centroid=exact.centroid, extents=exact.extents)


@lru_cache(maxsize=8)
def _sdf(kind: str, vertices: bytes, faces: bytes):
    v = np.frombuffer(vertices, np.float64).reshape(-1, 3)
    f = np.frombuffer(faces, np.int64).reshape(-1, 3)
    return MeshSdf(v, f) if kind == "exact" else grid_sdf(v, f)


def object_sdf(template_vertices, template_faces, kind: str = "exact"):
    """The template's signed distance of ``kind`` (``exact`` | ``grid256``), cached per mesh."""
    v = np.ascontiguousarray(template_vertices, np.float64)
    f = np.ascontiguousarray(template_faces, np.int64)
    return _sdf(kind, v.tobytes(), f.tobytes())


@lru_cache(maxsize=1)
def proxy_hand_vertex_ids() -> np.ndarray:
    """The proxy body's left then right hand vertices (wrist and finger capsules)."""
    from ..bodies.proxy import ProxyBody
    part = ProxyBody("smplh").part_joint
    left = np.flatnonzero((part == 20) | ((part >= 22) & (part < 37)))
    right = np.flatnonzero((part == 21) | (part >= 37))
    return np.concatenate([left, right])


def _penetrations(verts: np.ndarray, obj_rot, obj_trans, sdf, rest_frame: str) -> dict[str, float]:
    """hand/body penetration (trainer_chois.py L909-938) and compute_collision's pair, in the
    clip's own frame; the template's frame origin (``obj_trans``) plays the part of CHOIS's
    rest-pose origin (the vertex mean: hoibench's OMOMO templates are centred on it)."""
    from .chois_sdf import collision_penetration, hand_penetration
    legacy = rest_frame == "chois"
    out = {"hand_penetration": hand_penetration(verts, obj_trans, obj_rot, sdf, proxy_hand_vertex_ids(), legacy),
           "body_penetration": hand_penetration(verts, obj_trans, obj_rot, sdf, None, legacy)}
    out["penetration_percent"], out["penetration"] = collision_penetration(verts, obj_rot, obj_trans, 1.0, sdf)
    return out


def _body(joints22: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(joints24, proxy vertices, root rotations) of joints (T, 22, 3), in their own axes."""
    from .body_surface import proxy_vertices_from_joints
    from .chois_inputs import joints24, proxy_fit
    j = np.asarray(joints22, np.float64)
    fit = proxy_fit(j)
    return joints24(j, fit), proxy_vertices_from_joints(j), fit[1][:, 0]


def chois_clip_metrics(inp: Any, settings: Mapping | None = None) -> dict[str, float]:
    """CHOIS's numbers for one generated clip against its test clip's ground truth, by
    catalogue name; a metric whose inputs the ClipInput lacks is left out (the scorer reads
    it as NaN, undefined; no GT: none)."""
    settings = dict(settings or {})
    up, rest_frame = settings.get("up", "y"), settings.get("rest_frame", "chois")
    gt_joints = getattr(inp, "gt_joints", None)
    if gt_joints is None:
        return {}
    n = min(len(inp.joints), len(gt_joints))
    (p, verts, pr), (g, gv, gr) = _body(np.asarray(inp.joints)[:n]), _body(np.asarray(gt_joints)[:n])
    p, g, pv, gv = _z_up(p, up), _z_up(g, up), _z_up(verts, up), _z_up(gv, up)
    if str(settings.get("joints", "24")) == "22":
        p, g = p[:, :22], g[:, :22]
    out: dict[str, float] = {}
    out["lhand_jpe"], out["rhand_jpe"], out["hand_jpe"] = ch.hand_jpe(p, g)
    out["mpjpe"] = ch.mpjpe(p, g)
    out["trans_err"] = ch.trans_err(p[:, 0], g[:, 0])
    out["mpvpe"] = ch.mpvpe(pv, gv, p, g)
    out["rot_dist"] = ch.rot_dist(pr, gr)
    try:
        out["foot_sliding"] = ch.foot_sliding(p, ch.floor_height(p))
        out["gt_foot_sliding"] = ch.foot_sliding(g, ch.floor_height(g))
    except ImportError:                          # scikit-learn missing: the catalogue says "not computed"
        pass
    gro, grt = getattr(inp, "gt_obj_rot", None), getattr(inp, "gt_obj_trans", None)
    if inp.template_vertices is None or inp.obj_rot is None or inp.obj_trans is None or gro is None or grt is None:
        return out
    prot, ptrans = np.asarray(inp.obj_rot, np.float64)[:n], np.asarray(inp.obj_trans, np.float64)[:n]
    pobj = _posed(inp.template_vertices, prot, ptrans)
    gobj = _posed(inp.template_vertices, np.asarray(gro)[:n], np.asarray(grt)[:n])
    out.update(ch.contact_scores(ch.contact_labels(g, _z_up(gobj, up)), ch.contact_labels(p, _z_up(pobj, up))))
    out.update(ch.object_errors(_z_up(pobj.mean(axis=1), up), _z_up(gobj.mean(axis=1), up), prot, np.asarray(gro)[:n]))
    faces = getattr(inp, "template_faces", None)
    if faces is not None:
        sdf = object_sdf(inp.template_vertices, faces, settings.get("sdf", "exact"))
        out.update(_penetrations(verts, prot, ptrans, sdf, rest_frame))
    return out


__all__ = ["SETTINGS", "GRID_NODES", "MeshSdf", "grid_sdf", "object_sdf", "proxy_hand_vertex_ids",
           "check_settings", "chois_clip_metrics"]
