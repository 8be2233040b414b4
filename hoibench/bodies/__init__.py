"""Body surfaces: SMPL-family models via ``smplx`` (user-supplied files) and the
license-free proxy body (:mod:`hoibench.bodies.proxy`).

``smplx`` is an optional extra (``pip install hoibench[smplx]``), imported only when a
model is loaded.
"""
from .proxy import (
    PROXY_NUM_BETAS,
    PROXY_SCALE_PER_BETA,
    SMPLH_JOINT_NAMES,
    SMPLH_NUM_JOINTS,
    SMPLH_PARENTS,
    ProxyBody,
    build_proxy_arrays,
    proxy_rest_joints,
    write_proxy_model,
)
from .smpl import (MODEL_FILE_PREFIX, POSE_LAYOUTS, body_forward, clip_body_forward, clip_hand_convention,
                   load_body_model, model_path)

__all__ = [
    "PROXY_NUM_BETAS",
    "PROXY_SCALE_PER_BETA",
    "SMPLH_JOINT_NAMES",
    "SMPLH_NUM_JOINTS",
    "SMPLH_PARENTS",
    "ProxyBody",
    "build_proxy_arrays",
    "proxy_rest_joints",
    "write_proxy_model",
    "MODEL_FILE_PREFIX",
    "POSE_LAYOUTS",
    "body_forward",
    "clip_body_forward",
    "clip_hand_convention",
    "load_body_model",
    "model_path",
]
