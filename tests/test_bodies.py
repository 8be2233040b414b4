"""Tests for hoibench.bodies: the proxy SMPL-H body and the smplx loader."""
import os
import time

import numpy as np
import pytest

from hoibench.bodies import (
    PROXY_SCALE_PER_BETA,
    SMPLH_PARENTS,
    ProxyBody,
    body_forward,
    build_proxy_arrays,
    load_body_model,
    proxy_rest_joints,
    write_proxy_model,
)
from hoibench.bodies import proxy as proxy_mod
from hoibench.core.geometry import axis_angle_to_matrix
from hoibench.core.skeleton import PARENTS, SMPL_REST_JOINTS, forward_kinematics

RNG = np.random.default_rng(7)
T = 16
POSE52 = RNG.normal(0.0, 0.6, (T, 52, 3))
TRANS = RNG.normal(0.0, 1.0, (T, 3))
BETAS = RNG.normal(0.0, 1.0, (T, 10))


@pytest.fixture(scope="module")
def proxy_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("bodies")
    write_proxy_model(root)
    return root


@pytest.fixture(scope="module")
def smplh(proxy_dir):
    smplx = pytest.importorskip("smplx")
    return smplx.create(str(proxy_dir), model_type="smplh", gender="neutral", ext="npz",
                        use_pca=False, flat_hand_mean=True)


def _run_smplx(model, pose52, trans, betas):
    import torch

    n = len(pose52)
    t = lambda x: torch.tensor(np.asarray(x, dtype=np.float32))  # noqa: E731
    with torch.no_grad():
        out = model(global_orient=t(pose52[:, 0]), body_pose=t(pose52[:, 1:22].reshape(n, -1)),
                    left_hand_pose=t(pose52[:, 22:37].reshape(n, -1)),
                    right_hand_pose=t(pose52[:, 37:52].reshape(n, -1)),
                    transl=t(trans), betas=t(betas))
    return out.joints.numpy().astype(np.float64), out.vertices.numpy().astype(np.float64)


# --------------------------------------------------------------------------- arrays
def test_arrays_structure():
    a = build_proxy_arrays()
    V = len(a["v_template"])
    assert V == 6890  # >= every smplx vertex_ids['smplh'] index (max 6787)
    shapes = {"v_template": (V, 3), "J": (52, 3), "J_regressor": (52, V), "weights": (V, 52),
              "kintree_table": (2, 52), "shapedirs": (V, 3, 16), "posedirs": (V, 3, 459),
              "hands_componentsl": (45, 45), "hands_componentsr": (45, 45),
              "hands_meanl": (45,), "hands_meanr": (45,)}
    for k, s in shapes.items():
        assert a[k].shape == s, k
    assert a["f"].ndim == 2 and a["f"].shape[1] == 3 and np.issubdtype(a["f"].dtype, np.integer)
    np.testing.assert_allclose(a["J_regressor"].sum(1), 1.0, atol=1e-12)
    np.testing.assert_allclose(a["weights"].sum(1), 1.0, atol=1e-12)
    np.testing.assert_allclose(a["J_regressor"] @ a["v_template"], a["J"], atol=1e-12)
    np.testing.assert_array_equal(a["J"][:22], SMPL_REST_JOINTS)
    parents = a["kintree_table"][0].copy()
    parents[0] = -1
    assert tuple(parents) == SMPLH_PARENTS and SMPLH_PARENTS[:22] == PARENTS
    np.testing.assert_array_equal(a["shapedirs"][..., 0], PROXY_SCALE_PER_BETA * a["v_template"])
    assert not a["shapedirs"][..., 1:].any() and not a["posedirs"].any()


def test_faces_valid_and_closed():
    a = build_proxy_arrays()
    V, F = a["v_template"], a["f"]
    assert F.min() == 0 and F.max() == len(V) - 1
    assert len(np.unique(F)) == len(V)  # every vertex is on the surface
    assert (F[:, 0] != F[:, 1]).all() and (F[:, 1] != F[:, 2]).all() and (F[:, 0] != F[:, 2]).all()
    area = 0.5 * np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1)
    assert area.min() > 1e-7
    # closed: every directed edge appears once and its reverse once
    e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    fwd = {tuple(x) for x in e.tolist()}
    assert len(fwd) == len(e) and all((b, a_) in fwd for a_, b in fwd)


def test_watertight_trimesh():
    trimesh = pytest.importorskip("trimesh")
    a = build_proxy_arrays()
    m = trimesh.Trimesh(a["v_template"], a["f"], process=False)
    assert m.is_watertight and m.is_winding_consistent and m.volume > 0


def test_build_deterministic_and_fast():
    t0 = time.perf_counter()
    fresh = proxy_mod._build.__wrapped__("smplh")
    assert time.perf_counter() - t0 < 2.0
    again = build_proxy_arrays()
    assert list(fresh) == list(again)
    for k in fresh:
        assert fresh[k].dtype == again[k].dtype and fresh[k].tobytes() == again[k].tobytes(), k


def test_unsupported_model_type():
    with pytest.raises(NotImplementedError, match="smplh"):
        build_proxy_arrays("smpl")
    with pytest.raises(NotImplementedError):
        ProxyBody("smpl")


def test_write_proxy_model_byte_identical(tmp_path):
    p1 = write_proxy_model(tmp_path / "a")
    p2 = write_proxy_model(tmp_path / "a")
    p3 = write_proxy_model(tmp_path / "b", genders=("male",))
    assert [p.name for p in p1] == ["SMPLH_MALE.npz", "SMPLH_FEMALE.npz", "SMPLH_NEUTRAL.npz"]
    assert all(p.parent == tmp_path / "a" / "smplh" for p in p1)
    data = [p.read_bytes() for p in p1]
    assert data == [p.read_bytes() for p in p2] and p3[0].read_bytes() == data[0]
    assert sorted(os.listdir(tmp_path / "a" / "smplh")) == sorted(p.name for p in p1)  # no temp files
    with np.load(p1[0], allow_pickle=False) as z:
        assert z["v_template"].shape == (6890, 3)


# --------------------------------------------------------------------------- rest / shape
def test_proxy_rest_joints():
    np.testing.assert_array_equal(proxy_rest_joints(), SMPL_REST_JOINTS)
    np.testing.assert_allclose(proxy_rest_joints(np.r_[1.0, np.zeros(9)]), 1.05 * SMPL_REST_JOINTS, atol=1e-15)
    assert proxy_rest_joints(BETAS).shape == (T, 22, 3)


def test_smplx_rest_joints(smplh):
    import torch

    out = smplh(betas=torch.zeros(1, 10), transl=torch.zeros(1, 3))
    np.testing.assert_allclose(out.joints[0, :22].detach().numpy(), SMPL_REST_JOINTS, atol=1e-6)
    b = torch.zeros(1, 10)
    b[0, 0] = 1.0
    out = smplh(betas=b)
    np.testing.assert_allclose(out.joints[0, :22].detach().numpy(), 1.05 * SMPL_REST_JOINTS, atol=1e-6)


def test_smplx_posed_matches_fk_and_proxybody(smplh):
    pose = POSE52.copy()
    pose[:, 22:] = 0.0  # body only
    j_smplx, v_smplx = _run_smplx(smplh, pose, TRANS, BETAS)
    fk, _ = forward_kinematics(axis_angle_to_matrix(pose[:, :22]), proxy_rest_joints(BETAS), TRANS)
    np.testing.assert_allclose(j_smplx[:, :22], fk, atol=1e-5)
    verts, joints = ProxyBody().forward(pose[:, :22], TRANS, BETAS)
    assert verts.shape == (T, 6890, 3) and joints.shape == (T, 22, 3)
    np.testing.assert_allclose(joints, fk, atol=1e-12)
    np.testing.assert_allclose(verts, v_smplx, atol=1e-5)


def test_hands_and_body_forward(smplh, proxy_dir):
    model = load_body_model(proxy_dir, "smplh", "male")
    poses = POSE52.reshape(T, 156)
    joints, verts = body_forward(model, poses, BETAS, TRANS, batch_size=5)
    j_ref, v_ref = _run_smplx(smplh, POSE52, TRANS, BETAS)
    np.testing.assert_allclose(joints, j_ref, atol=1e-5)
    np.testing.assert_allclose(verts, v_ref, atol=1e-5)
    v_np, j_np = ProxyBody().forward(POSE52, TRANS, BETAS)
    np.testing.assert_allclose(v_np, verts, atol=1e-5)
    np.testing.assert_allclose(j_np, joints[:, :22], atol=1e-5)
    # 66-D poses = flat hands; shared betas (k,) and trans (3,) broadcast
    j66, v66 = body_forward(model, poses[:, :66], BETAS[0], TRANS[0])
    v_np, _ = ProxyBody().forward(POSE52[:, :22], TRANS[0], BETAS[0])
    np.testing.assert_allclose(v66, v_np, atol=1e-5)


def test_extra_joints_on_landmarks(smplh):
    j, _ = _run_smplx(smplh, np.zeros((1, 52, 3)), np.zeros((1, 3)), np.zeros((1, 10)))
    j = j[0]
    assert j.shape[0] == 73
    nose, reye, leye, rear, lear = j[52:57]
    assert np.linalg.norm(nose - SMPL_REST_JOINTS[15]) < 0.2 and nose[2] > SMPL_REST_JOINTS[15, 2]
    assert reye[0] < 0 < leye[0] and rear[0] < 0 < lear[0]
    assert (j[57:60, 1] < -1.1).all() and (j[60:63, 1] < -1.1).all()  # toes / heels at the sole
    assert (j[63:68, 0] > SMPL_REST_JOINTS[20, 0] + 0.05).all()  # left finger tips
    assert (j[68:73, 0] < SMPL_REST_JOINTS[21, 0] - 0.05).all()  # right finger tips


def test_proxybody_input_checks():
    body = ProxyBody()
    v, j = body.forward(np.zeros((2, 66)))
    np.testing.assert_allclose(j, np.broadcast_to(SMPL_REST_JOINTS, (2, 22, 3)), atol=1e-15)
    np.testing.assert_allclose(v[0], body.v_template, atol=1e-15)
    with pytest.raises(ValueError, match="body_pose_aa"):
        body.forward(np.zeros((2, 21, 3)))
    with pytest.raises(ValueError, match="betas"):
        body.forward(np.zeros((2, 22, 3)), betas=np.zeros(17))


# --------------------------------------------------------------------------- loader errors
def test_load_body_model_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError) as exc:
        load_body_model(tmp_path, "smplh", "female")
    assert str(tmp_path / "smplh" / "SMPLH_FEMALE.npz") in str(exc.value)
    assert str(tmp_path / "smplh" / "SMPLH_FEMALE.pkl") in str(exc.value)
    with pytest.raises(FileNotFoundError, match="SMPLX_NEUTRAL.npz"):
        load_body_model(tmp_path, "smplx", ext="npz")
    with pytest.raises(ValueError, match="model_type"):
        load_body_model(tmp_path, "mano")


def test_body_forward_rejects_bad_poses(proxy_dir):
    pytest.importorskip("smplx")
    model = load_body_model(proxy_dir, "smplh", "female")
    with pytest.raises(ValueError, match="poses"):
        body_forward(model, np.zeros((3, 72)))
    with pytest.raises(ValueError, match="its file must hold 16 shape components"):
        body_forward(model, np.zeros((3, 156)), betas=np.ones(16))
