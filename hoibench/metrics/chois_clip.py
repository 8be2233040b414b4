"""Per-clip entry point of CHOIS's metrics for the scorer (catalogue ``clip_fn``).

:func:`chois_clip_metrics` ``(inp, settings) -> {name: value}`` reads a
:class:`hoibench.metrics.physical.ClipInput` and the ground truth of its test clip from
optional fields (``getattr``; absent -> the metrics that need them are NaN):

* ``gt_joints`` (T, 22|24, 3), ``gt_obj_rot`` (T, 3, 3), ``gt_obj_trans`` (T, 3): the test
  clip's body joints and object pose (same up axis and frame rate as ``joints``);
* ``verts`` / ``gt_verts`` (T, V, 3) body vertices (mpvpe, penetration);
  ``root_rot`` / ``gt_root_rot`` (T, 3, 3) root global rotations (rot_dist);
* ``hand_vertex_ids`` (N,) (CHOIS's ``data/part_vert_ids`` left then right hand),
  ``object_sdf`` (:class:`hoibench.metrics.chois_sdf.SdfGrid` of the rest-pose object),
  ``obj_scale`` (T,) (compute_collision's scale; 1 when absent).

Settings (protocol key ``chois``): ``up`` (``y``: ClipInput's joints, converted to CHOIS's
z-up as ``(x, -z, y)``; or ``z``), ``rest_frame`` (``chois``: hand penetration with CHOIS's
``R (v - com)``; ``transpose``: ``R^T (v - com)``). Frobenius rotation distances do not
depend on the frame, so rotations are used as given.
"""
from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from . import chois as ch

#: fields of ClipInput the metrics read beyond today's (see the module docstring)
GT_FIELDS = ("gt_joints", "gt_obj_rot", "gt_obj_trans")
OPTIONAL_FIELDS = ("verts", "gt_verts", "root_rot", "gt_root_rot", "hand_vertex_ids", "object_sdf", "obj_scale")
SETTINGS = {"up": ("y", "z"), "rest_frame": ("chois", "transpose")}
_Y_TO_Z = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])      # (x, y, z) y-up -> (x, -z, y) z-up


def check_settings(mapping: Mapping, where: str) -> None:
    """The protocol's ``chois`` mapping: known keys with allowed values (ValueError naming
    ``where`` and the field)."""
    for key, value in mapping.items():
        if key not in SETTINGS:
            raise ValueError(f"{where}: field {key!r} is not one of {sorted(SETTINGS)}")
        if value not in SETTINGS[key]:
            raise ValueError(f"{where}: field {key!r} must be one of {SETTINGS[key]}, got {value!r}")


def _z_up(a: np.ndarray | None, up: str) -> np.ndarray | None:
    if a is None:
        return None
    a = np.asarray(a, np.float64)
    return a @ _Y_TO_Z.T if up == "y" else a


def _posed(template, rot, trans) -> np.ndarray:
    """(T, V, 3) ``R v_template + t`` (ClipInput's object convention)."""
    return np.einsum("tij,vj->tvi", np.asarray(rot, np.float64), np.asarray(template, np.float64)) \
        + np.asarray(trans, np.float64)[:, None, :]


def _penetrations(inp: Any, n: int, rest_frame: str) -> dict[str, float]:
    """hand/body penetration (trainer_chois.py L909-938) and compute_collision's pair, in the
    clip's own frame. ``object_sdf`` is the grid of the template in its own frame, whose
    origin (``obj_trans``) plays the part of CHOIS's rest-pose origin (the vertex mean)."""
    out: dict[str, float] = {}
    from .chois_sdf import collision_penetration, hand_penetration
    verts, sdf = getattr(inp, "verts", None), getattr(inp, "object_sdf", None)
    if verts is None or sdf is None:
        return out
    verts = np.asarray(verts, np.float64)[:n]
    obj_rot, origin = np.asarray(inp.obj_rot, np.float64)[:n], np.asarray(inp.obj_trans, np.float64)[:n]
    legacy = rest_frame == "chois"
    ids = getattr(inp, "hand_vertex_ids", None)
    if ids is not None:
        out["hand_penetration"] = hand_penetration(verts, origin, obj_rot, sdf, ids, legacy)
    out["body_penetration"] = hand_penetration(verts, origin, obj_rot, sdf, None, legacy)
    scale = getattr(inp, "obj_scale", None)
    out["penetration_percent"], out["penetration"] = collision_penetration(
        verts, obj_rot, origin, 1.0 if scale is None else np.asarray(scale, np.float64)[:n], sdf)
    return out


def chois_clip_metrics(inp: Any, settings: Mapping | None = None) -> dict[str, float]:
    """CHOIS's numbers for one generated clip against its test clip's ground truth, by
    catalogue name; a metric whose inputs the ClipInput lacks is left out (the scorer reads
    it as NaN, undefined; no GT: none)."""
    settings = dict(settings or {})
    up, rest_frame = settings.get("up", "y"), settings.get("rest_frame", "chois")
    gt_joints = getattr(inp, "gt_joints", None)
    if gt_joints is None:
        return {}
    p, g = _z_up(inp.joints, up), _z_up(gt_joints, up)
    n = min(len(p), len(g))
    p, g = p[:n], g[:n]
    out: dict[str, float] = {}
    out["lhand_jpe"], out["rhand_jpe"], out["hand_jpe"] = ch.hand_jpe(p, g)
    out["mpjpe"] = ch.mpjpe(p, g)
    out["trans_err"] = ch.trans_err(p[:, 0], g[:, 0])
    verts, gt_verts = getattr(inp, "verts", None), getattr(inp, "gt_verts", None)
    if verts is not None and gt_verts is not None:
        out["mpvpe"] = ch.mpvpe(_z_up(verts, up)[:n], _z_up(gt_verts, up)[:n], p, g)
    rr, grr = getattr(inp, "root_rot", None), getattr(inp, "gt_root_rot", None)
    if rr is not None and grr is not None:
        out["rot_dist"] = ch.rot_dist(np.asarray(rr)[:n], np.asarray(grr)[:n])
    try:
        out["foot_sliding"] = ch.foot_sliding(p, ch.floor_height(p))
        out["gt_foot_sliding"] = ch.foot_sliding(g, ch.floor_height(g))
    except ImportError:                          # scikit-learn missing: the catalogue says "not computed"
        pass
    gro, grt = getattr(inp, "gt_obj_rot", None), getattr(inp, "gt_obj_trans", None)
    if inp.template_vertices is None or inp.obj_rot is None or inp.obj_trans is None or gro is None or grt is None:
        return out
    pv = _posed(inp.template_vertices, inp.obj_rot, inp.obj_trans)[:n]
    gv = _posed(inp.template_vertices, gro, grt)[:n]
    out.update(ch.contact_scores(ch.contact_labels(g, _z_up(gv, up)), ch.contact_labels(p, _z_up(pv, up))))
    pcom, gcom = _z_up(pv.mean(axis=1), up), _z_up(gv.mean(axis=1), up)
    out.update(ch.object_errors(pcom, gcom, np.asarray(inp.obj_rot)[:n], np.asarray(gro)[:n]))
    out.update(_penetrations(inp, n, rest_frame))
    return out


__all__ = ["GT_FIELDS", "OPTIONAL_FIELDS", "check_settings", "chois_clip_metrics"]
