"""The seeded weights of the ChainHOI ``released`` reference values (tests/data/README.md):
shared by tests/test_chainhoi_released.py and benchmarks/chainhoi_released.py."""
from __future__ import annotations

import zlib

import numpy as np
import torch


def fill(model: torch.nn.Module) -> None:
    """Deterministic weights by state-dict key (the same rule produced the reference values):
    ``w = N(0, 1)`` from ``RandomState(crc32(key))``; matrices / sqrt(fan-in), 1-D weights
    1 + 0.1 w, biases 0.1 w, the adjacency its initial value + 0.05 w; fixed tables kept."""
    trainable = {n for n, p in model.named_parameters() if p.requires_grad}
    with torch.no_grad():
        for name, v in model.state_dict().items():
            if name not in trainable:
                continue
            w = np.random.RandomState(zlib.crc32(name.encode())).standard_normal(tuple(v.shape))
            if name.endswith(".A"):
                w = v.numpy() + 0.05 * w
            elif w.ndim >= 2:
                w = w / np.sqrt(np.prod(w.shape[1:]))
            elif w.ndim == 1 and name.endswith("weight"):
                w = 1 + 0.1 * w
            else:
                w = 0.1 * w
            v.copy_(torch.from_numpy(np.asarray(w, np.float64)).float())
