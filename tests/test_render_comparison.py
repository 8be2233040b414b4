"""``hoibench render SUB --id ID``: a generated sample beside its ground truth."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("pyvista")


def test_comparison_is_two_panels_and_bad_ids_are_one_line(template_store, tmp_path):
    from hoibench.publish.render import render_comparison
    from hoibench.datasets.store import Store
    from hoibench.scoring.submission import from_store
    sub = from_store(template_store, tmp_path / "gt")
    cid = Store(template_store).clip_ids("test")[0]
    png = render_comparison(sub, template_store, cid, tmp_path / "c.png", size=(200, 160))
    import imageio.v2 as iio
    img = iio.imread(png)
    assert img.shape[:2] == (160, 400)
    left, right = img[:, :200, :3].astype(int), img[:, 200:, :3].astype(int)
    assert np.abs(left - right).mean() < 30          # the ground truth beside itself: near-identical panels
    r = subprocess.run([sys.executable, "-m", "hoibench.cli", "render", str(sub), "--id", "nope", "--data",
                        str(template_store), "--out", str(tmp_path / "x.png")], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "nope" in r.stderr, r.stderr
