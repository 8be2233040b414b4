"""The 22-joint SMPL skeleton shared by every part of hoibench.

Joint order is SMPL's first 22 joints (the body without hands). All positions are in
metres, y-up, in the SMPL model frame (T-pose) unless stated otherwise.

The HOI joint graph used by the ``joint_level`` representation (ChainHOI's layout) adds
two nodes: node 22 carries the foot contacts and node 23 the object pose.
"""
from __future__ import annotations

import numpy as np

NUM_JOINTS = 22

JOINT_NAMES: tuple[str, ...] = (
    "pelvis", "left_hip", "right_hip", "spine1", "left_knee", "right_knee", "spine2",
    "left_ankle", "right_ankle", "spine3", "left_foot", "right_foot", "neck",
    "left_collar", "right_collar", "head", "left_shoulder", "right_shoulder",
    "left_elbow", "right_elbow", "left_wrist", "right_wrist",
)
JOINT_INDEX: dict[str, int] = {name: i for i, name in enumerate(JOINT_NAMES)}

PARENTS: tuple[int, ...] = (-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19)

#: HumanML3D's kinematic chains (right leg, left leg, spine, right arm, left arm).
KINEMATIC_CHAINS: tuple[tuple[int, ...], ...] = (
    (0, 2, 5, 8, 11),
    (0, 1, 4, 7, 10),
    (0, 3, 6, 9, 12, 15),
    (9, 14, 17, 19, 21),
    (9, 13, 16, 18, 20),
)

#: Unit bone directions of HumanML3D's raw skeleton (``t2m_raw_offsets``): the T-pose
#: direction of each joint from its parent, used by the inverse kinematics.
RAW_OFFSETS = np.array(
    [[0, 0, 0], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, -1, 0], [0, 1, 0],
     [0, -1, 0], [0, -1, 0], [0, 1, 0], [0, 0, 1], [0, 0, 1], [0, 1, 0], [1, 0, 0],
     [-1, 0, 0], [0, 0, 1], [0, -1, 0], [0, -1, 0], [0, -1, 0], [0, -1, 0], [0, -1, 0],
     [0, -1, 0]], dtype=np.float64)

#: HumanML3D's reference target skeleton (clip 000021): parent-relative offsets in metres
#: that ``hml263`` legacy mode retargets every clip to. Stored as float32 because the
#: reference holds them in a float32 tensor.
REFERENCE_TARGET_OFFSETS = np.array(
    [[0, 0, 0], [0.103074, 0, 0], [-0.109883, 0, 0], [0, 0.131568, 0], [0, -0.393623, 0],
     [0, -0.390188, 0], [0, 0.14319, 0], [0, -0.432433, 0], [0, -0.425643, 0],
     [0, 0.057365, 0], [0, 0, 0.143382], [0, 0, 0.149419], [0, 0.21936, 0],
     [0.137487, 0, 0], [-0.143383, 0, 0], [0, 0, 0.103039], [0, -0.131614, 0],
     [0, -0.122984, 0], [0, -0.25684, 0], [0, -0.263092, 0], [0, -0.266012, 0],
     [0, -0.269876, 0]], dtype=np.float32)

#: Rest (T-pose) joint positions of the SMPL family's mean shape in the model frame,
#: metres. The proxy body model is built around these, so ``trans`` means the same as in
#: the real model files.
SMPL_REST_JOINTS = np.array(
    [[-0.001795, -0.223333, 0.028219], [0.067725, -0.314740, 0.021404],
     [-0.069466, -0.313855, 0.023899], [-0.004328, -0.114370, 0.001523],
     [0.102001, -0.689938, 0.016908], [-0.107756, -0.696424, 0.015049],
     [0.001159, 0.020810, 0.002615], [0.088406, -1.087899, -0.026785],
     [-0.091982, -1.094839, -0.027263], [0.002616, 0.073732, 0.028040],
     [0.114764, -1.143690, 0.092503], [-0.117354, -1.142983, 0.096085],
     [-0.000162, 0.287603, -0.014817], [0.081461, 0.195482, -0.006050],
     [-0.079143, 0.192565, -0.010575], [0.004990, 0.352572, 0.036532],
     [0.172438, 0.225951, -0.014918], [-0.175155, 0.225116, -0.019719],
     [0.432050, 0.213179, -0.042374], [-0.428897, 0.211787, -0.041119],
     [0.681284, 0.222165, -0.043545], [-0.684196, 0.219560, -0.046679]], dtype=np.float64)

# Joints HumanML3D uses for facing, foot contacts and the leg-length scale.
RIGHT_HIP, LEFT_HIP, RIGHT_SHOULDER, LEFT_SHOULDER = 2, 1, 17, 16
FACE_JOINTS: tuple[int, int, int, int] = (RIGHT_HIP, LEFT_HIP, RIGHT_SHOULDER, LEFT_SHOULDER)
LEFT_FOOT_JOINTS: tuple[int, int] = (7, 10)    # left ankle, left foot
RIGHT_FOOT_JOINTS: tuple[int, int] = (8, 11)   # right ankle, right foot
FEET: tuple[int, int] = (10, 11)               # the joints FSR looks at
LEG_SCALE_JOINTS: tuple[int, int] = (5, 8)     # right knee, right ankle: lower-leg bones

#: Body parts in the annotator's words -> joints. The annotator's vocabulary files may
#: refine the wording; the joint sets are defined here once.
BODY_PARTS: dict[str, tuple[int, ...]] = {
    "left_hand": (20,),
    "right_hand": (21,),
    "left_arm": (16, 18, 20),
    "right_arm": (17, 19, 21),
    "left_foot": (7, 10),
    "right_foot": (8, 11),
    "left_leg": (1, 4, 7, 10),
    "right_leg": (2, 5, 8, 11),
    "hips": (0, 1, 2),
    "back": (3, 6, 9),
    "torso": (0, 3, 6, 9),
    "head": (12, 15),
}

# HOI joint graph (24 nodes): SMPL bones, a foot-contact node and an object node.
#: joint index -> its left/right counterpart (itself on the midline): a left-right mirror
#: reads ``joints[..., MIRROR_JOINTS, :]`` with x negated
MIRROR_JOINTS: tuple[int, ...] = tuple(
    JOINT_INDEX[n.replace("left_", "right_")] if n.startswith("left_") else
    JOINT_INDEX[n.replace("right_", "left_")] if n.startswith("right_") else i for i, n in enumerate(JOINT_NAMES))
FOOT_CONTACT_NODE = 22
OBJECT_NODE = 23
NUM_GRAPH_NODES = 24
FOOT_NODE_NEIGHBOURS: tuple[int, ...] = (7, 8, 10, 11)
OBJECT_NODE_NEIGHBOURS: tuple[int, ...] = (0, 10, 11, 12, 16, 17, 20, 21)


def bone_edges() -> list[tuple[int, int]]:
    """(parent, child) pairs of the 21 SMPL bones."""
    return [(p, c) for c, p in enumerate(PARENTS) if p >= 0]


def hoi_graph_edges() -> list[tuple[int, int]]:
    """Undirected edges of the 24-node HOI graph: bones, foot node 22, object node 23."""
    edges = bone_edges()
    edges += [(j, FOOT_CONTACT_NODE) for j in FOOT_NODE_NEIGHBOURS]
    edges += [(j, OBJECT_NODE) for j in OBJECT_NODE_NEIGHBOURS]
    return edges


def hoi_graph_adjacency(self_loops: bool = True) -> np.ndarray:
    """Symmetric (24, 24) 0/1 adjacency matrix of :func:`hoi_graph_edges`."""
    adj = np.zeros((NUM_GRAPH_NODES, NUM_GRAPH_NODES), dtype=np.float32)
    for a, b in hoi_graph_edges():
        adj[a, b] = adj[b, a] = 1.0
    if self_loops:
        adj[np.arange(NUM_GRAPH_NODES), np.arange(NUM_GRAPH_NODES)] = 1.0
    return adj


def offsets_from_joints(joints: np.ndarray) -> np.ndarray:
    """Parent-relative offsets ``joints[j] - joints[parent[j]]`` of (..., 22, 3) positions
    (zero for the root)."""
    joints = np.asarray(joints)
    parents = np.array(PARENTS)
    out = joints - joints[..., np.maximum(parents, 0), :]
    out[..., 0, :] = 0.0
    return out


def joints_from_offsets(offsets: np.ndarray, root: np.ndarray | None = None) -> np.ndarray:
    """Inverse of :func:`offsets_from_joints`: accumulate offsets along the tree."""
    offsets = np.asarray(offsets)
    out = np.zeros_like(offsets)
    if root is not None:
        out[..., 0, :] = root
    for j in range(1, NUM_JOINTS):  # parents precede children in SMPL order
        out[..., j, :] = out[..., PARENTS[j], :] + offsets[..., j, :]
    return out


def forward_kinematics(local_rotations: np.ndarray, rest_joints: np.ndarray,
                       trans: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """SMPL-style forward kinematics of the 22-joint body.

    Args:
        local_rotations: (..., 22, 3, 3) parent-relative rotation matrices (joint 0 is the
            global orientation, applied about the pelvis).
        rest_joints: (22, 3) or (..., 22, 3) rest (T-pose) joint positions, metres.
        trans: (..., 3) root translation (SMPL ``transl``), added to every joint.

    Returns:
        ``(joints, global_rotations)``: (..., 22, 3) posed positions
        ``J_j = G_parent (rest_j - rest_parent) + J_parent``, ``J_0 = rest_0 + trans``, and
        (..., 22, 3, 3) global rotations ``G_j = G_parent R_j``.
    """
    rots = np.asarray(local_rotations, dtype=np.float64)
    rest = np.asarray(rest_joints, dtype=np.float64)
    if rots.shape[-3:] != (NUM_JOINTS, 3, 3):
        raise ValueError(f"local_rotations: expected shape (..., 22, 3, 3), got {rots.shape}")
    if rest.shape[-2:] != (NUM_JOINTS, 3):
        raise ValueError(f"rest_joints: expected shape (..., 22, 3), got {rest.shape}")
    lead = rots.shape[:-3]
    glob = np.empty(lead + (NUM_JOINTS, 3, 3))
    joints = np.empty(lead + (NUM_JOINTS, 3))
    rest = np.broadcast_to(rest, lead + (NUM_JOINTS, 3))
    glob[..., 0, :, :] = rots[..., 0, :, :]
    joints[..., 0, :] = rest[..., 0, :] + (0.0 if trans is None else np.asarray(trans))
    for j in range(1, NUM_JOINTS):
        p = PARENTS[j]
        glob[..., j, :, :] = glob[..., p, :, :] @ rots[..., j, :, :]
        bone = rest[..., j, :] - rest[..., p, :]
        joints[..., j, :] = (glob[..., p, :, :] @ bone[..., None])[..., 0] + joints[..., p, :]
    return joints, glob
