"""Shared steps of the hand-object loaders (TACO, OAKINK2): MANO hands posed from released
parameters, rigid object tracks, resampling by time, a source world mapped to y-up.

Hands: both TACO's and OAKINK2's toolkits build MANO with ``center_idx=0`` (the wrist joint
at the origin) and then add the released translation, so the released translation is the
wrist's world position. hoibench poses the user's MANO (or the proxy) through ``smplx``
(``use_pca=False``, ``flat_hand_mean=True``) with ``transl = 0``, and moves the result so
joint 0 sits at the released translation: ``joints = MANO(pose, betas) - J_0 + tsl``. The
21 joints are MANO's 16 in MANO order then the finger tips at ``smplx``'s MANO tip
vertices 744, 320, 443, 554, 671 (not manopth's 745, 317, 444, 556, 673).

Objects: a (T, 4, 4) pose ``P`` moves model vertices as ``v_world = P[:3,:3] v + P[:3,3]``;
the template is centred on its vertex mean ``m``, so ``rot = F R`` and ``trans = F (t + R m)``
(``F`` the source-world-to-y-up rotation).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..core import geometry as geo
from ..core import plausibility as pl
from ..bodies.multibody import Body, MultiBodyClip, check_clip
from .behave import SequenceError, _lerp, _slerp_resample, resample_rigid

__all__ = ["ZUP_TO_YUP", "MANO_TIPS", "BOTTOM_ROW_TOL", "rigid_poses", "mano_joints", "hand_body", "object_body",
           "axis_to_yup"]

#: z-up -> y-up: (x, y, z) -> (x, z, -y) (a rotation of -90 degrees about x).
ZUP_TO_YUP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
#: smplx's MANO tip vertices: thumb, index, middle, ring, pinky.
MANO_TIPS = (744, 320, 443, 554, 671)
BOTTOM_ROW_TOL = 1e-6
_CHUNK = 256


def axis_to_yup(axis: np.ndarray) -> np.ndarray:
    """A proper rotation taking the signed unit axis ``axis`` (one of +-x, +-y, +-z) to +y."""
    a = np.asarray(axis, np.float64)
    table = {(1, 1): np.eye(3), (1, -1): np.diag([1.0, -1.0, -1.0]), (2, 1): ZUP_TO_YUP,
             (2, -1): np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]]),
             (0, 1): np.array([[0, -1.0, 0], [1.0, 0, 0], [0, 0, 1.0]]),
             (0, -1): np.array([[0, 1.0, 0], [-1.0, 0, 0], [0, 0, 1.0]])}
    k = int(np.argmax(np.abs(a)))
    return table[(k, int(np.sign(a[k])))]


def rigid_poses(P, where: str) -> tuple[np.ndarray, np.ndarray, float]:
    """(R (T,3,3) nearest rotations, t (T,3), largest correction) of (T, 4, 4) poses;
    SequenceError naming ``where`` and the frame for a pose that is not rigid."""
    try:
        P = pl.real_array(P, "object poses", where)
    except ValueError as exc:
        raise SequenceError(str(exc)) from None
    if P.ndim != 3 or P.shape[1:] != (4, 4):
        raise SequenceError(f"{where}: expected shape (T, 4, 4), got {P.shape}")
    bad = np.flatnonzero(np.abs(P[:, 3] - np.array([0.0, 0.0, 0.0, 1.0])).max(-1) > BOTTOM_ROW_TOL)
    if len(bad):
        raise SequenceError(f"{where}: frame {int(bad[0])}: bottom row {P[bad[0], 3].tolist()}, expected [0, 0, 0, 1]")
    R = P[:, :3, :3]
    err = np.abs(R @ R.swapaxes(-1, -2) - np.eye(3)).max(axis=(-2, -1))
    bad = np.flatnonzero((err > pl.ROTATION_TOL) | (np.abs(np.linalg.det(R) - 1.0) > pl.ROTATION_TOL))
    if len(bad):
        raise SequenceError(f"{where}: frame {int(bad[0])}: not a rotation (within {pl.ROTATION_TOL})")
    u, _, vt = np.linalg.svd(R)
    Rn = u @ vt
    return Rn, P[:, :3, 3].copy(), float(np.abs(Rn - R).max()) if len(R) else 0.0


@lru_cache(maxsize=4)
def _mano(model_dir: str, side: str):
    from ..bodies.proxy_hand import load_mano_model
    return load_mano_model(model_dir, side, use_pca=False, flat_hand_mean=True)


def mano_joints(body_models, side: str, aa: np.ndarray, betas: np.ndarray, tsl: np.ndarray) -> np.ndarray:
    """(T, 21, 3) joints (see the module docstring) of MANO ``side`` from ``body_models/mano``:
    ``aa`` (T, 16, 3) axis-angle (joint 0 global), ``betas`` (T, 10), ``tsl`` (T, 3) the wrist."""
    import torch
    model = _mano(str(body_models), side)
    buf = next(model.buffers())

    def tens(x):
        return torch.from_numpy(np.ascontiguousarray(x, dtype=np.float64)).to(device=buf.device, dtype=buf.dtype)

    out = []
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        with torch.no_grad():
            for s in range(0, len(aa), _CHUNK):
                e = min(len(aa), s + _CHUNK)
                r = model(global_orient=tens(aa[s:e, 0]), hand_pose=tens(aa[s:e, 1:].reshape(e - s, 45)),
                          betas=tens(betas[s:e]), transl=tens(np.zeros((e - s, 3))))
                v = r.vertices.detach().cpu().numpy().astype(np.float64)
                j = r.joints.detach().cpu().numpy().astype(np.float64)[:, :16]
                out.append(np.concatenate([j, v[:, list(MANO_TIPS)]], 1))
    finally:
        torch.set_num_threads(threads)
    joints = np.concatenate(out)
    return joints - joints[:, :1] + np.asarray(tsl, np.float64)[:, None]


def hand_body(name: str, side: str, body_models, aa: np.ndarray, betas: np.ndarray, tsl: np.ndarray,
              src_t: np.ndarray, dst: np.ndarray, F: np.ndarray) -> Body:
    """A hand Body at times ``dst``: every joint rotation slerped, betas and the wrist
    lerped, then posed and mapped by ``F``; ``rot`` = F R(global), ``trans`` = the wrist."""
    aa_d = _slerp_resample(src_t, dst, np.asarray(aa, np.float64))
    b_d = _lerp(src_t, dst, np.asarray(betas, np.float64))
    t_d = _lerp(src_t, dst, np.asarray(tsl, np.float64))
    joints = mano_joints(body_models, side, aa_d, b_d, t_d) @ F.T
    rot = F @ np.asarray(geo.axis_angle_to_matrix(aa_d[:, 0]))
    return Body(name=name, kind="hand", trans=joints[:, 0].copy(), rot=rot, joints=joints, side=side)


def object_body(name: str, template: str, R: np.ndarray, t: np.ndarray, mean: np.ndarray,
                src_t: np.ndarray, dst: np.ndarray, F: np.ndarray) -> Body:
    """An object Body at times ``dst`` for source poses ``R v + t`` of a template centred on ``mean``."""
    rot, trans = resample_rigid(src_t, dst, R, t + R @ np.asarray(mean, np.float64))
    return Body(name=name, kind="object", trans=trans @ F.T, rot=F @ rot, template=template)


def checked_clip(clip: MultiBodyClip, cid: str) -> MultiBodyClip:
    """``clip`` once :func:`~hoibench.bodies.multibody.check_clip` accepts it; a
    :class:`SequenceError` naming ``cid`` where it does not."""
    try:
        check_clip(clip)
    except ValueError as exc:
        raise SequenceError(f"{cid}: {exc}") from None
    return clip
