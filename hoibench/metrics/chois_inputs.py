"""What CHOIS's evaluator and metrics read, made from hoibench's 22 joints (y-up, metres).

CHOIS (Li et al., ECCV 2024; GitHub ``lijiaman/chois_release`` @ 9cd4cf6) scores *joints24*:
SMPL-X's 22 body joints plus joints 28 and 43 (the first joints of the left and right middle
fingers), in a z-up world. hoibench's submissions and stores hold 22 joints, so:

* **hand joints** (:func:`proxy_hand_joints`): the proxy joint fit's (the one
  :mod:`hoibench.metrics.body_surface` poses the penetration surface with): each wrist takes
  its parent's global rotation (OMOMO's hands are flat and rigid with the wrist), and the
  hand joint is ``J_wrist + s R_wrist (r_h - r_wrist)`` with ``r`` the proxy SMPL-X rest
  joints (20 -> 28 and 21 -> 43, 0.094 m at scale 1) and ``s`` the clip's body scale. Both
  the generated clip and its ground truth get them this way, so a hand joint error measures
  the wrists and forearms, never the rule.
* **z-up** (:func:`z_up`): ``(x, y, z) -> (x, -z, y)``, the inverse of the OMOMO loader's
  ``F``: a store's clip returns to OMOMO's own world axes.
* **CHOIS's window frame** (:func:`canonical_window`), as ``manip/data/cano_traj_dataset.py``
  ``cal_normalize_data_input`` builds its evaluation windows: a rotation about the world z
  axis (through the origin, ``lafan1/utils.py`` ``rotate_at_frame_w_obj`` with ``floor_z``)
  that turns frame 0's root x axis (body left), projected on the floor, onto +x; then a
  shift of the floor plane (``process_window_data``) that puts frame 0's SMPL translation at
  xy = 0. The translation is the pelvis minus the rest pelvis offset ``J0`` (SMPL: ``pelvis =
  J0 + transl``); submissions carry no body shape, so ``J0`` is the proxy SMPL-X rest pelvis
  (:func:`rest_pelvis_xy`; a real subject's differs by up to a few centimetres). Frame 0's
  root rotation is the proxy fit's pelvis rotation (rest children 1, 2, 3 onto the posed
  ones, least squares).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

#: SMPL-X joints CHOIS adds to the 22 body joints (evaluation_metrics.py ``use_joints24``)
HAND_JOINTS = (28, 43)
WRISTS = (20, 21)
#: y-up (hoibench) -> z-up (OMOMO, CHOIS): (x, y, z) -> (x, -z, y)
Y_TO_Z = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])


@lru_cache(maxsize=1)
def proxy_rest_joints() -> np.ndarray:
    """(55, 3) the proxy SMPL-X rest joints (model frame, metres; cached)."""
    from ..bodies.proxy import ProxyBody
    return ProxyBody("smplx").rest_joints.astype(np.float64)


def rest_pelvis_xy() -> np.ndarray:
    """(2,) the proxy SMPL-X rest pelvis's model x, y (m): in OMOMO's z-up world ``pelvis =
    J0 + transl`` adds them to the translation's x, y."""
    return proxy_rest_joints()[0, :2].copy()


def _check(joints, where: str = "joints") -> np.ndarray:
    j = np.asarray(joints, np.float64)
    if j.ndim != 3 or j.shape[1] != 22 or j.shape[2] != 3:
        raise ValueError(f"{where}: expected (T, 22, 3) joints, got shape {j.shape}")
    return j


def proxy_fit(joints) -> tuple[float, np.ndarray]:
    """(body scale ``s``, global rotations (T, 22, 3, 3)) of the proxy joint fit of joints
    (T, 22, 3): :func:`hoibench.metrics.body_surface.joint_global_rotations` of the rest joints
    scaled by :func:`hoibench.bodies.contact.body_scale`."""
    from ..bodies.contact import body_scale
    from .body_surface import joint_global_rotations
    j = _check(joints)
    s = body_scale(j)
    return s, joint_global_rotations(j, proxy_rest_joints()[:22] * s)


def proxy_hand_joints(joints, fit: tuple[float, np.ndarray] | None = None) -> np.ndarray:
    """(T, 2, 3) the proxy fit's left and right hand joints (SMPL-X 28, 43) of y-up joints
    (T, 22, 3) (module docstring); ``fit``: their :func:`proxy_fit`, when already made."""
    j = _check(joints)
    s, R = proxy_fit(j) if fit is None else fit
    rest = proxy_rest_joints()
    out = np.empty((len(j), 2, 3))
    for k, (hand, wrist) in enumerate(zip(HAND_JOINTS, WRISTS)):
        out[:, k] = j[:, wrist] + s * R[:, wrist] @ (rest[hand] - rest[wrist])
    return out


def joints24(joints, fit: tuple[float, np.ndarray] | None = None) -> np.ndarray:
    """(T, 24, 3): the 22 joints, then the proxy hand joints (same axes as ``joints``)."""
    j = _check(joints)
    return np.concatenate([j, proxy_hand_joints(j, fit)], axis=1)


def z_up(points) -> np.ndarray:
    """y-up points (..., 3) in OMOMO's z-up axes."""
    return np.asarray(points, np.float64) @ Y_TO_Z.T


def canonical_window(joints) -> tuple[np.ndarray, np.ndarray]:
    """(rotation (3, 3), shift (3,)) taking z-up world points to CHOIS's window frame,
    ``p' = rotation p + shift``, from y-up joints (T, 22, 3) (module docstring)."""
    j = _check(joints)[:1]
    root = Y_TO_Z @ proxy_fit(j)[1][0, 0]                                    # model -> z-up world
    left = root[:, 0] * np.array([1.0, 1.0, 0.0])
    norm = np.linalg.norm(left)
    heading = np.arctan2(left[1], left[0]) if norm > 1e-9 else 0.0
    c, s = np.cos(-heading), np.sin(-heading)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    pelvis = rot @ z_up(j[0, 0])
    transl_xy = pelvis[:2] - rest_pelvis_xy()
    return rot, np.array([-transl_xy[0], -transl_xy[1], 0.0])


def from_window(points_y, reference_joints) -> np.ndarray:
    """World y-up points of y-up-axis points (..., 3) given in CHOIS's window frame of the clip
    whose y-up joints (T, 22, 3) are ``reference_joints``: the inverse of
    :func:`canonical_window` (CHOIS saves its generated joints in that frame)."""
    rot, shift = canonical_window(reference_joints)
    window_z = np.asarray(points_y, np.float64) @ Y_TO_Z.T
    return ((window_z - shift) @ rot) @ Y_TO_Z


def window_joints24(joints) -> np.ndarray:
    """(T, 24, 3) joints24 of y-up joints (T, 22, 3), z-up, in CHOIS's window frame: what its
    evaluator embeds."""
    rot, shift = canonical_window(joints)
    return z_up(joints24(joints)) @ rot.T + shift


__all__ = ["HAND_JOINTS", "proxy_rest_joints", "Y_TO_Z", "rest_pelvis_xy", "proxy_fit", "proxy_hand_joints", "joints24", "z_up",
           "canonical_window", "from_window", "window_joints24"]
