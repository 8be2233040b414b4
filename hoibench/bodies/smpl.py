"""SMPL / SMPL-H / SMPL-X through the optional ``smplx`` package (user-supplied files).

The model files are licensed and never shipped; point :func:`load_body_model` at your own
copies laid out as ``smplx.create`` expects::

    model_dir/smpl/SMPL_NEUTRAL.pkl
    model_dir/smplh/SMPLH_MALE.pkl   (or .npz)
    model_dir/smplx/SMPLX_FEMALE.npz (or .pkl)

``.pkl`` model files are unpickled by ``smplx``: load only files you downloaded yourself.
:func:`hoibench.bodies.write_proxy_model` writes a license-free stand-in with the SMPL-H
layout (``ext='npz'``).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["MODEL_FILE_PREFIX", "POSE_LAYOUTS", "import_smplx", "model_path", "load_body_model",
           "body_forward"]

#: File-name prefix per model type (``<PREFIX>_<GENDER>.<ext>``).
MODEL_FILE_PREFIX = {"smpl": "SMPL", "smplh": "SMPLH", "smplx": "SMPLX"}
_DEFAULT_EXTS = {"smpl": ("pkl",), "smplh": ("npz", "pkl"), "smplx": ("npz", "pkl")}

#: Accepted flat pose widths per model type -> named axis-angle blocks (in order).
#: SMPL-H 156 = root 3 + body 63 + left hand 45 + right hand 45 (BEHAVE / AMASS);
#: SMPL-X 165 = root 3 + body 63 + jaw 3 + left eye 3 + right eye 3 + hands 90 (AMASS).
POSE_LAYOUTS: dict[str, dict[int, tuple[tuple[str, int], ...]]] = {
    "smpl": {72: (("global_orient", 3), ("body_pose", 69)),
             66: (("global_orient", 3), ("body_pose", 63))},
    "smplh": {156: (("global_orient", 3), ("body_pose", 63), ("left_hand_pose", 45), ("right_hand_pose", 45)),
              66: (("global_orient", 3), ("body_pose", 63))},
    "smplx": {165: (("global_orient", 3), ("body_pose", 63), ("jaw_pose", 3), ("leye_pose", 3),
                    ("reye_pose", 3), ("left_hand_pose", 45), ("right_hand_pose", 45)),
              156: (("global_orient", 3), ("body_pose", 63), ("left_hand_pose", 45), ("right_hand_pose", 45)),
              66: (("global_orient", 3), ("body_pose", 63))},
}


def import_smplx():
    """Import ``smplx`` or raise an ImportError that says how to install it."""
    try:
        import smplx  # noqa: WPS433
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError("SMPL-family body models need the optional 'smplx' package: "
                          "pip install hoibench[smplx]") from exc
    return smplx


def _check_type(model_type: str) -> str:
    mt = str(model_type).lower()
    if mt not in MODEL_FILE_PREFIX:
        raise ValueError(f"model_type: expected one of {sorted(MODEL_FILE_PREFIX)}, got {model_type!r}")
    return mt


def model_path(model_dir, model_type: str = "smplh", gender: str = "neutral",
               ext: str | None = None) -> Path:
    """Path of the model file ``model_dir/<model_type>/<PREFIX>_<GENDER>.<ext>``.

    With ``ext=None`` the first existing of the usual extensions is taken (SMPL: pkl;
    SMPL-H / SMPL-X: npz, then pkl). Raises FileNotFoundError naming every path tried.
    """
    mt = _check_type(model_type)
    from ..core.plausibility import GENDERS     # the gender becomes part of a file name
    if str(gender).lower() not in GENDERS:
        raise ValueError(f"gender: expected one of {GENDERS}, got {str(gender)[:40]!r}")
    folder = Path(model_dir).expanduser() / mt
    exts = _DEFAULT_EXTS[mt] if ext is None else (str(ext).lstrip("."),)
    if mt == "smpl" and exts != ("pkl",):
        raise ValueError("smplx reads SMPL models from .pkl files only (ext='pkl')")
    tried = [folder / f"{MODEL_FILE_PREFIX[mt]}_{str(gender).upper()}.{e}" for e in exts]
    return first_file(tried, f"{mt} body model",
                      f"Download the {mt.upper()} files yourself (they are licensed) and pass the folder "
                      f"that contains '{mt}/', or write the license-free proxy with "
                      "hoibench.bodies.write_proxy_model(model_dir).")


def first_file(tried: list[Path], what: str, advice: str) -> Path:
    """The first of ``tried`` that is a file; FileNotFoundError naming ``what``, every path
    tried and then ``advice`` where none is."""
    for p in tried:
        if p.is_file():
            return p
    raise FileNotFoundError(f"{what} not found: looked for {', '.join(str(p) for p in tried)}. {advice}")


def load_body_model(model_dir, model_type: str = "smplh", gender: str = "neutral",
                    ext: str | None = None, **kwargs):
    """Create a ``smplx`` body model from the user's files.

    Checks that ``model_dir/<model_type>/<PREFIX>_<GENDER>.<ext>`` exists (error names the
    paths it looked for), then calls ``smplx.create(model_dir, model_type, gender=...,
    ext=...)``. For SMPL-H / SMPL-X the defaults are ``use_pca=False,
    flat_hand_mean=True`` (full 45-D axis-angle hands, zero = flat hand: BEHAVE's
    semantics); ``kwargs`` override them and are passed on (``num_betas``, ``dtype``...).
    """
    mt = _check_type(model_type)
    path = model_path(model_dir, mt, gender, ext)
    smplx = import_smplx()
    opts = dict(kwargs)
    if mt in ("smplh", "smplx"):
        opts.setdefault("use_pca", False)
        opts.setdefault("flat_hand_mean", True)
        opts["ext"] = path.suffix[1:]
    import contextlib
    import io
    want = int(opts.get("num_betas") or 10)
    with contextlib.redirect_stdout(io.StringIO()):  # smplx prints a notice about 10 betas
        if mt in _WIDE_BETAS and want > 10:
            model = _wide_betas_class(smplx, mt, want)(str(Path(model_dir).expanduser() / mt),
                                                       gender=str(gender).lower(), **opts)
        else:
            model = smplx.create(str(Path(model_dir).expanduser()), model_type=mt, gender=str(gender).lower(), **opts)
    if int(model.num_betas) < want and mt in _WIDE_BETAS:
        raise ValueError(f"{path}: the {mt.upper()} model file has fewer than {want} shape components (shapedirs "
                         f"columns): the data's {want} betas need a model file that holds them (SMPL-H's "
                         f"model.npz has 16)")
    return model


#: model types whose files may hold 11..299 shape components that ``smplx`` would cut to 10
_WIDE_BETAS = {"smpl": "SMPL", "smplh": "SMPLH"}


def _wide_betas_class(smplx, mt: str, num_betas: int):
    """``smplx``'s SMPL / SMPL-H class keeping ``num_betas`` shape components of a file that has
    them. ``smplx`` keeps ``min(num_betas, 10)`` when the file's ``shapedirs`` has fewer than
    ``SHAPE_SPACE_DIM`` (300) columns; with ``SHAPE_SPACE_DIM = num_betas`` it keeps all
    ``num_betas`` (as human_body_prior's ``BodyModel`` does with SMPL-H's 16), and a file with
    fewer columns still falls back to 10, which the caller refuses."""
    base = getattr(smplx, _WIDE_BETAS[mt])
    return type(base.__name__, (base,), {"SHAPE_SPACE_DIM": int(num_betas), "__module__": __name__})


def _model_type_of(model) -> str:
    smplx = import_smplx()
    if isinstance(model, smplx.SMPLX):
        return "smplx"
    if isinstance(model, smplx.SMPLH):
        return "smplh"
    if isinstance(model, smplx.SMPL):
        return "smpl"
    raise TypeError(f"model: expected a smplx SMPL/SMPLH/SMPLX module, got {type(model).__name__}")


def body_forward(model, poses, betas=None, trans=None, batch_size: int = 512,
                 return_vertices: bool = True, expression=None) -> tuple[np.ndarray, np.ndarray | None]:
    """Run a ``smplx`` model over a sequence in chunks, under ``torch.no_grad()``.

    Args:
        model: from :func:`load_body_model` (hands must be axis-angle: ``use_pca=False``).
        poses: (T, D) axis-angle, radians, laid out as :data:`POSE_LAYOUTS`: SMPL-H
            D = 156 (root 3 + body 63 + left hand 45 + right hand 45, BEHAVE's
            ``poses``) or 66 (hands flat); SMPL D = 72 or 66; SMPL-X D = 165, 156 or 66.
            With ``flat_hand_mean=True`` zero hand pose is the flat hand.
        betas: (k,) or (T, k) shape coefficients, k <= ``model.num_betas`` (zero-padded);
            None = mean shape.
        trans: (T, 3) or (3,) translation, metres; None = 0.
        batch_size: frames per ``smplx`` call.
        expression: SMPL-X only: (E,) or (T, E) expression coefficients, E <=
            ``model.num_expression_coeffs`` (zero-padded); None = neutral face.

    Returns:
        ``(joints (T, J, 3), vertices (T, V, 3) or None)`` as numpy arrays in the model's
        dtype (float32 by default); ``J`` includes ``smplx``'s extra vertex joints
        (joints[:, :22] are the 22 body joints).
    """
    import torch

    mt = _model_type_of(model)
    poses = np.asarray(poses)
    if poses.ndim != 2 or poses.shape[1] not in POSE_LAYOUTS[mt]:
        raise ValueError(f"poses: expected (T, D) with D in {sorted(POSE_LAYOUTS[mt])} for {mt}, "
                         f"got {poses.shape}")
    if mt != "smpl" and getattr(model, "use_pca", False):
        raise ValueError("body_forward needs axis-angle hands: create the model with use_pca=False")
    T = len(poses)
    buf = next(model.buffers())
    device, dtype = buf.device, buf.dtype
    nb = int(model.num_betas)
    if betas is None:
        betas = np.zeros(nb)
    betas = np.asarray(betas, dtype=np.float64)
    if betas.ndim not in (1, 2) or (betas.ndim == 2 and len(betas) not in (1, T)):
        raise ValueError(f"betas: expected (k,) or (T, k), got {betas.shape}")
    if betas.shape[-1] > nb:
        if np.any(betas[..., nb:] != 0):
            raise ValueError(f"betas: {betas.shape[-1]} coefficients given (non-zero past the {nb}th) but the "
                             f"body model poses {nb}: its file must hold {betas.shape[-1]} shape components")
        betas = betas[..., :nb]
    betas = np.concatenate([betas, np.zeros(betas.shape[:-1] + (nb - betas.shape[-1],))], -1)
    betas = np.broadcast_to(betas, (T, nb))
    trans = np.zeros((T, 3)) if trans is None else np.broadcast_to(np.asarray(trans, np.float64), (T, 3))
    if expression is not None:
        if mt != "smplx":
            raise ValueError(f"expression: only SMPL-X has expression coefficients, the model is {mt}")
        ne = int(model.num_expression_coeffs)
        expression = np.asarray(expression, dtype=np.float64)
        if expression.ndim not in (1, 2) or (expression.ndim == 2 and len(expression) not in (1, T)) \
                or expression.shape[-1] > ne:
            raise ValueError(f"expression: expected (E,) or ({T}, E) with E <= {ne} (the model's "
                             f"num_expression_coeffs), got {expression.shape}")
        expression = np.concatenate([expression, np.zeros(expression.shape[:-1] + (ne - expression.shape[-1],))], -1)
        expression = np.broadcast_to(expression, (T, ne))

    layout = POSE_LAYOUTS[mt][poses.shape[1]]
    widths = {"global_orient": 3, "body_pose": 3 * model.NUM_BODY_JOINTS}
    if mt != "smpl":
        widths.update(left_hand_pose=45, right_hand_pose=45)
    if mt == "smplx":
        widths.update(jaw_pose=3, leye_pose=3, reye_pose=3)

    def tens(x):
        return torch.from_numpy(np.array(x, dtype=np.float64)).to(device=device, dtype=dtype)

    joints_out, verts_out = [], []
    saved_bs = getattr(model, "batch_size", None)
    saved_threads = torch.get_num_threads()
    # one intra-op thread: torch's float32 reductions depend on its thread count, and a store
    # must be byte-identical whatever the executor (pool workers run one thread each)
    torch.set_num_threads(1)
    try:
        if mt == "smplx":  # SMPL-X repeats its landmark coefficients model.batch_size times
            model.batch_size = 1
        with torch.no_grad():
            for s in range(0, T, int(batch_size)):
                e = min(T, s + int(batch_size))
                n = e - s
                args = {k: np.zeros((n, w)) for k, w in widths.items()}
                col = 0
                for name, w in layout:
                    args[name][:, :w] = poses[s:e, col:col + w]
                    col += w
                args = {k: tens(v) for k, v in args.items()}
                if mt == "smplx":
                    args["expression"] = (tens(expression[s:e]) if expression is not None else
                                          torch.zeros((n, model.num_expression_coeffs), dtype=dtype, device=device))
                out = model(betas=tens(betas[s:e]), transl=tens(trans[s:e]),
                            return_verts=return_vertices, **args)
                joints_out.append(out.joints.detach().cpu().numpy())
                if return_vertices:
                    verts_out.append(out.vertices.detach().cpu().numpy())
    finally:
        torch.set_num_threads(saved_threads)
        if saved_bs is not None:
            model.batch_size = saved_bs
    joints = np.concatenate(joints_out) if joints_out else np.zeros((0, 0, 3))
    verts = (np.concatenate(verts_out) if verts_out else np.zeros((0, 0, 3))) if return_vertices else None
    return joints, verts


def clip_hand_convention(clip: dict) -> bool:
    """``flat_hand_mean`` of a stored clip's body parameters: the clip's ``flat_hand_mean``
    array; a store written before it was recorded: False for RICH clips (their toolkit's
    convention), True otherwise."""
    if "flat_hand_mean" in clip:
        return bool(np.asarray(clip["flat_hand_mean"]))
    from ..core.io import load_json_bytes
    try:
        prov = load_json_bytes(str(clip.get("provenance", "{}")), "provenance")
    except ValueError:
        prov = {}
    return not (isinstance(prov, dict) and prov.get("source") == "rich")


def clip_body_forward(clip: dict, model_dir, return_vertices: bool = True, **model_kwargs
                      ) -> tuple[np.ndarray, np.ndarray | None]:
    """Rebuild a stored clip's body from its parameters with the user's model files:
    ``(joints (T, J, 3), vertices (T, V, 3) or None)`` in the store's y-up world.

    Reads ``body_model_type``, ``gender``, ``betas``, ``poses``, ``trans`` and the hand
    convention (:func:`clip_hand_convention`) and ``expression`` stored with the clip (see
    :class:`hoibench.datasets.sequence.BodyParams`), so every consumer poses the body the way
    the source did. ``model_kwargs`` go to :func:`load_body_model`.
    """
    missing = [k for k in ("body_model_type", "gender", "poses", "trans") if k not in clip]
    if missing:
        raise ValueError(f"clip {str(clip.get('name', '?'))}: no body parameters stored (missing {', '.join(missing)})")
    mt = str(clip["body_model_type"])
    betas = np.asarray(clip["betas"], np.float64) if "betas" in clip else None
    expression = np.asarray(clip["expression"], np.float64) if "expression" in clip else None
    opts = dict(model_kwargs)
    if betas is not None:
        opts.setdefault("num_betas", int(betas.shape[-1]))
    if mt in ("smplh", "smplx"):
        opts.setdefault("flat_hand_mean", clip_hand_convention(clip))
    if mt == "smplx" and expression is not None:
        opts.setdefault("num_expression_coeffs", int(expression.shape[-1]))
    model = load_body_model(model_dir, mt, str(clip["gender"]), **opts)
    return body_forward(model, np.asarray(clip["poses"], np.float64), betas, np.asarray(clip["trans"], np.float64),
                        return_vertices=return_vertices, expression=expression)
