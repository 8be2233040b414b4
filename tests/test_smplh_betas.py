"""SMPL-H files with 16 shape components pose all 16 betas (NeuralDome and IMHD in InterAct's
release are posed so, with human_body_prior's ``BodyModel``): ``smplx`` alone keeps 10 of a
file with fewer than 300. Checked against an independent forward of the same file at zero
pose: ``v = v_template + shapedirs . betas``, ``J = J_regressor v``. A file with fewer
components than the data's betas is refused in one line naming it."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("smplx")


def _smplh_file(root, columns: int, seed: int = 0):
    """The proxy SMPL-H file with ``columns`` random shape directions (every one non-zero)."""
    from hoibench.bodies import write_proxy_model
    paths = write_proxy_model(root, "smplh", genders=("neutral",))
    with np.load(paths[0]) as z:
        arrays = {k: z[k] for k in z.files}
    rng = np.random.default_rng(seed)
    arrays["shapedirs"] = 0.01 * rng.standard_normal(arrays["shapedirs"].shape[:2] + (columns,))
    np.savez(paths[0], **arrays)
    return paths[0], arrays


def test_sixteen_betas_of_an_smplh_file_are_all_posed(tmp_path):
    from hoibench.bodies.smpl import body_forward, load_body_model
    path, a = _smplh_file(tmp_path, 16)
    betas = np.random.default_rng(1).normal(0, 1.5, 16)
    model = load_body_model(tmp_path, "smplh", "neutral", num_betas=16)
    assert int(model.num_betas) == 16
    joints, verts = body_forward(model, np.zeros((2, 156)), betas, None)
    v = a["v_template"] + a["shapedirs"] @ betas                       # independent forward, zero pose
    j = np.asarray(a["J_regressor"]) @ v
    np.testing.assert_allclose(verts[0], v, atol=2e-5)
    np.testing.assert_allclose(joints[1, :len(j)], j, atol=2e-5)
    only10 = a["v_template"] + a["shapedirs"][..., :10] @ betas[:10]
    assert np.abs(verts[0] - only10).max() > 1e-3                       # betas 11..16 moved the body
    assert int(load_body_model(tmp_path, "smplh", "neutral").num_betas) == 10   # the default is unchanged


def test_a_file_with_fewer_components_is_refused_naming_it(tmp_path):
    from hoibench.bodies.smpl import body_forward, load_body_model
    path, _ = _smplh_file(tmp_path, 10)
    with pytest.raises(ValueError) as exc:
        load_body_model(tmp_path, "smplh", "neutral", num_betas=16)
    assert str(path) in str(exc.value) and "16" in str(exc.value) and "\n" not in str(exc.value)
    model = load_body_model(tmp_path, "smplh", "neutral")
    with pytest.raises(ValueError) as exc:
        body_forward(model, np.zeros((1, 156)), np.ones(16))
    assert "num_betas" not in str(exc.value)                          # no advice the user cannot act on
