"""ChainHOI's HOI joint graph and kinetic chains (Zeng et al., CVPR 2025, sections 3.3-3.4).

Graph (24 nodes): the 22 SMPL joints with their bones, a foot-contact node 22 linked to the
ankles and feet (7, 8, 10, 11) and an object node 23 linked to the eight potential
interaction joints (0, 10, 11, 12, 16, 17, 20, 21) -- :func:`hoibench.core.skeleton.hoi_graph_edges`.

Spatial partitions (ST-GCN's "spatial configuration"): identity, inward (from a node's
neighbours nearer the root: its parent joint; for node 22 the foot joints, for node 23 the
interaction joints) and outward (the transpose). Each partition is row-normalised, so a node
averages over its neighbours in that partition: ``A_k = D_k^-1 E_k``.

Kinetic chains (six tokens): right leg, left leg, spine-head, right arm, left arm and the
human-object chain. :func:`chain_mask` is the boolean cross-attention mask of the
Kinematic-aware Decoder: ``True`` where a chain token may NOT attend to a node.
"""
from __future__ import annotations

import numpy as np

from ...core import skeleton as sk

NODES = sk.NUM_GRAPH_NODES

KINETIC_CHAINS: dict[str, tuple[int, ...]] = {
    "right_leg": (0, 2, 5, 8, 11),
    "left_leg": (0, 1, 4, 7, 10),
    "spine_head": (0, 3, 6, 9, 12, 15),
    "right_arm": (9, 14, 17, 19, 21),
    "left_arm": (9, 13, 16, 18, 20),
    "human_object": (0, 10, 11, 12, 16, 17, 20, 21, 23),
}


def directed_edges() -> list[tuple[int, int]]:
    """(source, target) edges pointing away from the root: bones parent -> child, foot
    joints -> node 22, interaction joints -> node 23."""
    edges = sk.bone_edges()
    edges += [(j, sk.FOOT_CONTACT_NODE) for j in sk.FOOT_NODE_NEIGHBOURS]
    edges += [(j, sk.OBJECT_NODE) for j in sk.OBJECT_NODE_NEIGHBOURS]
    return edges


def _row_normalise(a: np.ndarray) -> np.ndarray:
    deg = a.sum(1, keepdims=True)
    return np.divide(a, deg, out=np.zeros_like(a), where=deg > 0)


def partitions() -> np.ndarray:
    """(3, 24, 24) float32: identity, inward, outward; ``out[k, i, j]`` is the weight with
    which node i gathers node j."""
    inward = np.zeros((NODES, NODES), np.float32)
    for src, dst in directed_edges():
        inward[dst, src] = 1.0          # a node gathers from the node nearer the root
    outward = inward.T.copy()
    return np.stack([np.eye(NODES, dtype=np.float32), _row_normalise(inward), _row_normalise(outward)])


def adjacency() -> np.ndarray:
    """(24, 24) 0/1 symmetric adjacency with self-loops (the union of the partitions)."""
    return (partitions() > 0).any(0).astype(np.float32)


def chain_membership() -> np.ndarray:
    """(6, 24) bool: ``[c, j]`` is True when node j belongs to chain c."""
    m = np.zeros((len(KINETIC_CHAINS), NODES), bool)
    for c, nodes in enumerate(KINETIC_CHAINS.values()):
        m[c, list(nodes)] = True
    return m


def chain_mask() -> np.ndarray:
    """(6, 24) bool attention mask (PyTorch convention): True = not allowed to attend."""
    return ~chain_membership()
