"""Load the HumanML3D reference ``process_file`` from a user's own checkout, for side-by-side
timing. Nothing of the reference is shipped: point ``--reference-dir`` at a clone of
https://github.com/EricGuo5513/HumanML3D (its ``common/`` package, ``paramUtil.py`` and
``motion_representation.ipynb`` are read from there at run time).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np


def load_process_file(reference_dir: str | Path):
    """Return ``process_file(positions, feet_thre)`` executed from the notebook's cells."""
    ref = Path(reference_dir)
    nb_path = ref / "motion_representation.ipynb"
    if not nb_path.exists():
        raise FileNotFoundError(f"--reference-dir: no motion_representation.ipynb in {ref}")
    if not hasattr(np, "float"):
        np.float = float  # the reference still uses the alias removed in numpy 1.24
    sys.path.insert(0, str(ref))
    import torch
    from common.skeleton import Skeleton  # noqa: F401  (from the user's checkout)
    import paramUtil

    from hoibench.core.skeleton import REFERENCE_TARGET_OFFSETS

    ns: dict = {}
    exec("from common.skeleton import Skeleton\nfrom common.quaternion import *\n"
         "from paramUtil import *\nimport numpy as np\nimport torch\n", ns)
    cells = json.loads(nb_path.read_text())["cells"]
    for cell in cells:
        src = "".join(cell.get("source", []))
        if cell["cell_type"] == "code" and ("def uniform_skeleton" in src or "def process_file" in src):
            exec(compile(src, str(nb_path), "exec"), ns)
    ns.update(l_idx1=5, l_idx2=8, fid_r=[8, 11], fid_l=[7, 10], face_joint_indx=[2, 1, 17, 16],
              joints_num=22, n_raw_offsets=torch.from_numpy(paramUtil.t2m_raw_offsets),
              kinematic_chain=paramUtil.t2m_kinematic_chain,
              tgt_offsets=torch.from_numpy(REFERENCE_TARGET_OFFSETS.copy()))
    return ns["process_file"]
