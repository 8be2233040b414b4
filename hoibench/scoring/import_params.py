"""Body-parameter outputs (``hoibench import params``): per-frame SMPL / SMPL-H / SMPL-X
parameters, as OMOMO/CHOIS-style generators and InterAct write them, posed with the user's
body models into a standard submission.

Input: a folder of ``<id>.npz`` or ``<id>_<r>.npz`` files (one sample each), with

=================================  =========================================================
key                                meaning
=================================  =========================================================
``poses`` (T, D)                   axis-angle, radians, laid out as
                                   :data:`hoibench.bodies.smpl.POSE_LAYOUTS` (SMPL-H 156 or
                                   66, SMPL-X 165/156/66, SMPL 72/66); or the split names
``root_orient`` + ``pose_body``    (T, 3) + (T, 63): OMOMO/CHOIS; or
``global_orient`` + ``body_pose``  (T, 3) + (T, 63): ``smplx``'s argument names
``betas`` (k,), (1, k) or (T, k)   shape coefficients (optional: mean shape)
``trans`` (T, 3)                   metres (optional: 0)
``gender`` (scalar string)         optional; else ``--gender``
``obj_rot`` (T, 3, 3) or           optional object pose ``v = R v_template + t`` in the same
``obj_rotvec`` (T, 3),             frame; without it the submission is human-only
``obj_trans`` (T, 3)               (``flags.human_only``)
=================================  =========================================================

Joints are the model's first 22 joints (``smplx``'s order), ``J = FK(poses, betas) + trans``
computed by :func:`hoibench.bodies.smpl.body_forward` with the model files under
``--body-models`` (``<model_type>/<PREFIX>_<GENDER>.npz|pkl``; hands flat-mean, axis-angle).
A z-up source (``--up z``) is turned y-up with ``(x, y, z) -> (x, z, -y)``, the object's
rotation and translation with it.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core.geometry import axis_angle_to_matrix
from .import_common import ImportProblem, _group_files

#: the z-up -> y-up rotation, p_y = F p_z: (x, y, z) -> (x, z, -y)
Z_TO_Y = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
MODEL_TYPES = ("smpl", "smplh", "smplx")
_MAX_FRAMES = 100_000


def _problem(msg: str) -> Exception:
    return ImportProblem(msg)


def _array(z, key: str, path: Path, ndim: tuple[int, ...], tail: tuple[int, ...] = ()) -> np.ndarray:
    a = np.asarray(z[key])
    if a.dtype.kind not in "fiu" or a.ndim not in ndim or (tail and tuple(a.shape[-len(tail):]) != tail):
        want = " or ".join("(" + ", ".join(["T"] * (n - len(tail)) + [str(t) for t in tail]) + ")" for n in ndim)
        raise _problem(f"{path}: field {key}: expected a real array {want}, got {a.dtype} {a.shape}")
    a = a.astype(np.float64)
    if not np.isfinite(a).all():
        raise _problem(f"{path}: field {key}: non-finite values")
    return a


def _poses(z, path: Path, model_type: str) -> np.ndarray:
    from ..bodies.smpl import POSE_LAYOUTS
    if "poses" in z.files:
        p = _array(z, "poses", path, (2,))
        if p.shape[1] not in POSE_LAYOUTS[model_type]:
            raise _problem(f"{path}: field poses: {p.shape[1]} values per frame; {model_type} takes "
                           f"{' or '.join(map(str, sorted(POSE_LAYOUTS[model_type])))} (--model-type?)")
        return p
    for root, body in (("root_orient", "pose_body"), ("global_orient", "body_pose")):
        if root in z.files or body in z.files:
            if root not in z.files or body not in z.files:
                raise _problem(f"{path}: field {body if root in z.files else root}: missing (give both "
                               f"{root} (T, 3) and {body} (T, 63))")
            r, b = _array(z, root, path, (2,), (3,)), _array(z, body, path, (2,), (63,))
            if len(r) != len(b):
                raise _problem(f"{path}: field {body}: {len(b)} frames but {root} has {len(r)}")
            return np.concatenate([r, b], 1)
    raise _problem(f"{path}: field poses: missing (give poses (T, D), root_orient + pose_body, or "
                   f"global_orient + body_pose)")


def _gender(z, path: Path, default: str) -> str:
    if "gender" not in z.files:
        return default
    g = np.asarray(z["gender"])
    if g.dtype.kind not in "US" or g.size != 1:
        raise _problem(f"{path}: field gender: expected one string (male, female, neutral), got {g.dtype} {g.shape}")
    g = str(g.reshape(()).item())
    g = g.decode() if isinstance(g, bytes) else g
    if g.lower() not in ("male", "female", "neutral"):
        raise _problem(f"{path}: field gender: expected male, female or neutral, got {g!r}")
    return g.lower()


class _Members(dict):
    """The arrays of one ``.npz`` (``files`` as ``np.load``'s result names them)."""

    @property
    def files(self) -> list[str]:
        return list(self)


def read_param_file(path: Path, model_type: str, gender: str, models, up: str, budget=None) -> dict[str, np.ndarray]:
    """One sample: ``{"joints" (T, 22, 3)[, "obj_rot" (T, 3, 3), "obj_trans" (T, 3)]}``, y-up.
    ``models``: a cache ``{gender: model}`` filled by :func:`load_model`; ``budget``: the
    import's :class:`~hoibench.scoring.importers.ReadBudget` (None: the guarded reader's default)."""
    from ..bodies.smpl import body_forward
    from ..core.io import load_raw_npz
    try:
        z = _Members(budget.npz(path, "body-parameter file") if budget is not None
                     else load_raw_npz(path, what="body-parameter file"))
        poses = _poses(z, path, model_type)
        T = len(poses)
        if not 1 <= T <= _MAX_FRAMES:
            raise _problem(f"{path}: field poses: {T} frames (expected 1..{_MAX_FRAMES})")
        betas = _array(z, "betas", path, (1, 2)) if "betas" in z.files else None
        if betas is not None and betas.ndim == 2 and len(betas) not in (1, T):
            raise _problem(f"{path}: field betas: {len(betas)} rows; expected 1 or T = {T}")
        if betas is not None and betas.ndim == 2 and len(betas) == 1:
            betas = betas[0]
        trans = _array(z, "trans", path, (2,), (3,)) if "trans" in z.files else np.zeros((T, 3))
        if len(trans) != T:
            raise _problem(f"{path}: field trans: {len(trans)} frames but poses has {T}")
        g = _gender(z, path, gender)
        obj = {}
        if "obj_rot" in z.files:
            obj["rot"] = _array(z, "obj_rot", path, (3,), (3, 3))
        elif "obj_rotvec" in z.files:
            obj["rot"] = axis_angle_to_matrix(_array(z, "obj_rotvec", path, (2,), (3,)))
        if "obj_trans" in z.files:
            obj["trans"] = _array(z, "obj_trans", path, (2,), (3,))
    except (OSError, ValueError, KeyError, EOFError) as exc:
        if isinstance(exc, ImportProblem):
            raise
        raise _problem(f"{path}: not a readable .npz ({type(exc).__name__}: {exc})") from None
    if len(obj) == 1:
        have = next(iter(obj))
        raise _problem(f"{path}: field {'obj_trans' if have == 'rot' else 'obj_rot'}: missing (the object pose "
                       f"needs a rotation and a translation)")
    for k, v in obj.items():
        if len(v) != T:
            raise _problem(f"{path}: field obj_{k}: {len(v)} frames but poses has {T}")
    model = load_model(models, model_type, g)
    if betas is not None and betas.shape[-1] > int(model.num_betas):
        raise _problem(f"{path}: field betas: {betas.shape[-1]} coefficients; the {model_type} model files hold "
                       f"{int(model.num_betas)}")
    joints = body_forward(model, poses, betas, trans, return_vertices=False)[0][:, :22].astype(np.float64)
    out = {"joints": joints}
    if obj:
        out["obj_rot"], out["obj_trans"] = obj["rot"], obj["trans"]
    if up == "z":
        out["joints"] = joints @ Z_TO_Y.T
        if obj:
            out["obj_rot"] = np.einsum("ij,tjk->tik", Z_TO_Y, obj["rot"])
            out["obj_trans"] = obj["trans"] @ Z_TO_Y.T
    return out


def load_model(models: dict, model_type: str, gender: str):
    """The body model for ``gender`` from ``models["dir"]``, cached in ``models``."""
    if gender not in models:
        from ..bodies.smpl import load_body_model
        try:
            models[gender] = load_body_model(models["dir"], model_type, gender)
        except (FileNotFoundError, ImportError) as exc:
            raise _problem(f"--body-models {models['dir']}: {exc}") from None
    return models[gender]


def read_param_files(folder: Path, ids: list[str], up: str, body_models, model_type: str,
                     gender: str, budget=None) -> list[tuple[str, str, dict]]:
    """``(key, "", arrays)`` per file group (``<id>.npz`` / ``<id>_<r>.npz``): samples stacked
    (K, T, ...) and cut to the shortest."""
    if body_models is None:
        raise _problem("--body-models: required for params (the folder with smplh/, smplx/ or smpl/ model files)")
    if model_type not in MODEL_TYPES:
        raise _problem(f"--model-type: expected one of {', '.join(MODEL_TYPES)}, got {model_type!r}")
    models: dict = {"dir": str(body_models)}
    out = []
    for key, files in _group_files(Path(folder), ".npz", ids).items():
        samples = [read_param_file(p, model_type, gender, models, up, budget) for p in files]
        kinds = {tuple(sorted(s)) for s in samples}
        if len(kinds) > 1:
            raise _problem(f"{files[0].parent}: samples of {key} differ in what they carry (object pose in some only)")
        T = min(len(s["joints"]) for s in samples)
        out.append((key, "", {k: np.stack([s[k][:T] for s in samples]) for k in samples[0]}))
    return out


__all__ = ["Z_TO_Y", "MODEL_TYPES", "read_param_file", "read_param_files", "read_params_request", "load_model"]


def read_params_request(req) -> list[tuple[str, str, dict]]:
    """The ``params`` import format's reader (:class:`hoibench.scoring.importers.ResultReader`)."""
    return read_param_files(req.results, req.ids, req.up, req.body_models, req.model_type, req.gender, req.budget)
