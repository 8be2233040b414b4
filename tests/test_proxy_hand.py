"""Tests for hoibench.bodies.proxy_hand: the license-free proxy MANO hand."""
import hashlib
import io
import pickle
import pickletools
import subprocess
import sys

import numpy as np
import pytest

from hoibench.bodies import proxy_hand as ph
from hoibench.bodies.proxy import PROXY_SCALE_PER_BETA
from hoibench.bodies.proxy_hand import (
    MANO_JOINT_NAMES,
    MANO_NUM_JOINTS,
    MANO_PARENTS,
    MANO_TIP_VERTEX_IDS,
    PROXY_MANO_WRIST,
    ProxyHand,
    build_proxy_mano_arrays,
    load_mano_model,
    mano_model_path,
    write_proxy_mano,
)

RNG = np.random.default_rng(11)
T = 8
GO = RNG.normal(0.0, 0.8, (T, 3))
HP = RNG.normal(0.0, 0.6, (T, 45))
TRANSL = RNG.normal(0.0, 1.0, (T, 3))
BETAS = RNG.normal(0.0, 1.0, (T, 10))
SIDES = ("right", "left")
MIRROR = np.array([-1.0, 1.0, 1.0])


@pytest.fixture(scope="module")
def mano_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("mano_models")
    write_proxy_mano(root)
    write_proxy_mano(root, ext="npz")
    return root


def _smplx_forward(model, go, hp, transl, betas):
    import torch

    dt = next(model.buffers()).dtype
    t = lambda x: torch.tensor(np.asarray(x), dtype=dt)  # noqa: E731
    with torch.no_grad():
        out = model(global_orient=t(go), hand_pose=t(hp), transl=t(transl), betas=t(betas))
    return out.vertices.numpy().astype(np.float64), out.joints.numpy().astype(np.float64)


def _signed_volume(V, F):
    c = V[F].reshape(-1, 3).mean(0)
    a, b, d = V[F[:, 0]] - c, V[F[:, 1]] - c, V[F[:, 2]] - c
    return np.einsum("ij,ij->i", a, np.cross(b, d)).sum() / 6.0


# --------------------------------------------------------------------------- arrays
def test_structure():
    for side in SIDES:
        a = build_proxy_mano_arrays(side)
        assert a["v_template"].shape == (778, 3) and a["v_template"].dtype == np.float64
        assert a["f"].shape == (1492, 3) and a["f"].dtype == np.int64
        assert a["J"].shape == (16, 3) and a["J_regressor"].shape == (16, 778)
        assert a["weights"].shape == (778, 16)
        assert a["shapedirs"].shape == (778, 3, 10) and a["posedirs"].shape == (778, 3, 135)
        np.testing.assert_array_equal(a["hands_components"], np.eye(45))
        np.testing.assert_array_equal(a["hands_mean"], np.zeros(45))
        assert a["bs_style"] == "lbs" and a["bs_type"] == "lrotmin"
        kt = a["kintree_table"]
        assert kt.shape == (2, 16) and kt[0, 0] == 4294967295
        assert tuple(kt[0, 1:]) == MANO_PARENTS[1:] and tuple(kt[1]) == tuple(range(16))
        assert not a["posedirs"].any()
        # every face index used, no degenerate faces
        assert np.array_equal(np.unique(a["f"]), np.arange(778))
        assert (a["f"][:, 0] != a["f"][:, 1]).all() and (a["f"][:, 1] != a["f"][:, 2]).all()
    assert len(MANO_JOINT_NAMES) == MANO_NUM_JOINTS
    assert MANO_JOINT_NAMES[1:4] == ("index1", "index2", "index3")
    assert MANO_JOINT_NAMES[13:] == ("thumb1", "thumb2", "thumb3")
    a = build_proxy_mano_arrays()
    a["v_template"][0] = 99.0  # fresh copies: the cached build is untouched
    assert build_proxy_mano_arrays()["v_template"][0, 0] != 99.0


def test_rest_pose_frame():
    J = build_proxy_mano_arrays("right")["J"]
    np.testing.assert_allclose(J[0], PROXY_MANO_WRIST)
    assert (J[1:13, 0] < J[0, 0]).all()  # right hand: fingers along -x
    assert J[1, 2] > J[4, 2] > J[10, 2] > J[7, 2]  # index, middle, ring, pinky towards -z
    assert J[15, 2] > J[1, 2]  # thumb towards +z


def test_regressor_weights_and_parts_closed():
    for side in SIDES:
        a = build_proxy_mano_arrays(side)
        V, F, W = a["v_template"], a["f"], a["weights"]
        np.testing.assert_allclose(a["J_regressor"] @ V, a["J"], atol=1e-12)
        np.testing.assert_allclose(a["J_regressor"].sum(1), 1.0)
        assert (a["J_regressor"] >= 0).all()
        assert set(np.unique(W)) == {0.0, 1.0} and (W.sum(1) == 1.0).all()
        part = W.argmax(1)
        assert (part[F] == part[F][:, :1]).all()  # no face spans two parts
        for j in range(16):
            Fj = F[part[F[:, 0]] == j]
            edges = np.concatenate([Fj[:, [0, 1]], Fj[:, [1, 2]], Fj[:, [2, 0]]])
            fwd = {tuple(e) for e in edges.tolist()}
            assert len(fwd) == len(edges), f"{side} part {j}: a directed edge is repeated"
            assert {(b, a_) for a_, b in fwd} == fwd, f"{side} part {j} is not closed"
            nv = len(np.unique(Fj))
            assert nv - len(Fj) // 2 == 2, f"{side} part {j} is not a sphere"  # Euler: V - E + F
            assert _signed_volume(V, Fj) > 0, f"{side} part {j} is inward oriented"
            # the regressor ring of joint j lies on a part skinned to j or its parent
            ring = np.flatnonzero(a["J_regressor"][j])
            assert set(part[ring]) <= {j, MANO_PARENTS[j]}


def test_left_is_mirror_of_right():
    r, l = build_proxy_mano_arrays("right"), build_proxy_mano_arrays("left")
    np.testing.assert_array_equal(l["v_template"], r["v_template"] * MIRROR)
    np.testing.assert_array_equal(l["J"], r["J"] * MIRROR)
    np.testing.assert_array_equal(l["f"], r["f"][:, [0, 2, 1]])
    for k in ("J_regressor", "weights", "kintree_table", "posedirs", "hands_components", "hands_mean"):
        np.testing.assert_array_equal(l[k], r[k])
    np.testing.assert_array_equal(l["shapedirs"][..., 0], PROXY_SCALE_PER_BETA * l["v_template"])
    # posed: mirroring a rotation negates the y, z axis-angle components
    flip = np.array([1.0, -1.0, -1.0])
    vr, jr = ProxyHand("right")(GO, HP, BETAS, TRANSL)
    vl, jl = ProxyHand("left")(GO * flip, (HP.reshape(T, 15, 3) * flip).reshape(T, 45), BETAS, TRANSL * MIRROR)
    np.testing.assert_allclose(vl, vr * MIRROR, atol=1e-12)
    np.testing.assert_allclose(jl, jr * MIRROR, atol=1e-12)


def test_tips_and_beta0_scaling():
    hand = ProxyHand("right")
    a = build_proxy_mano_arrays("right")
    V, J = a["v_template"], a["J"]
    ids = np.array(list(MANO_TIP_VERTEX_IDS.values()))
    # each tip id is the far end of its finger's last segment, skinned to finger joint 3
    joint3 = {"index": 3, "middle": 6, "pinky": 9, "ring": 12, "thumb": 15}
    for name, idx in MANO_TIP_VERTEX_IDS.items():
        j = joint3[name]
        assert hand.part_joint[idx] == j
        d = V[hand.part_joint == j] - J[j]
        assert np.linalg.norm(V[idx] - J[j]) == pytest.approx(np.linalg.norm(d, axis=1).max())
    # beta_0: uniform scaling about the model origin, other betas do nothing
    for b0 in (-2.0, 1.5):
        betas = np.r_[b0, RNG.normal(size=9)]
        v, j = hand(np.zeros(3), np.zeros(45), betas)
        s = 1.0 + PROXY_SCALE_PER_BETA * b0
        np.testing.assert_allclose(v[0], s * V, atol=1e-15)
        np.testing.assert_allclose(j[0], s * J, atol=1e-15)
    v, j = hand(GO, HP, tips=True)
    assert j.shape == (T, 21, 3)
    np.testing.assert_array_equal(j[:, 16:], v[:, ids])


def test_proxyhand_rigid_parts_and_inputs():
    hand = ProxyHand("left")
    v, j = hand(GO, HP, BETAS, TRANSL)
    assert v.shape == (T, 778, 3) and j.shape == (T, 16, 3)
    s = 1.0 + PROXY_SCALE_PER_BETA * BETAS[:, 0]
    for k in range(16):  # every part moves rigidly: pairwise distances kept (scaled)
        idx = np.flatnonzero(hand.part_joint == k)[:6]
        d0 = np.linalg.norm(hand.v_template[idx, None] - hand.v_template[None, idx], axis=-1)
        d = np.linalg.norm(v[:, idx, None] - v[:, None, idx], axis=-1)
        np.testing.assert_allclose(d, s[:, None, None] * d0, atol=1e-12)
    np.testing.assert_allclose(j[:, 0], s[:, None] * hand.rest_joints[0] + TRANSL, atol=1e-12)
    # single frame and short hand_pose (PCA coefficients) broadcast / zero-pad
    v1, _ = hand(GO[0], HP[0, :6])
    v2, _ = hand(GO[:1], np.pad(HP[:1, :6], ((0, 0), (0, 39))))
    np.testing.assert_array_equal(v1, v2)
    with pytest.raises(ValueError, match="hand_pose"):
        hand(GO, np.zeros((T, 48)))
    with pytest.raises(ValueError, match="global_orient"):
        hand(np.zeros((T, 4)), HP)
    with pytest.raises(ValueError, match="betas"):
        hand(GO, HP, np.zeros(11))
    with pytest.raises(ValueError, match="side"):
        ProxyHand("middle")


# --------------------------------------------------------------------------- files
def test_files_byte_identical_and_plain(tmp_path, mano_dir):
    paths = write_proxy_mano(tmp_path)
    assert [p.name for p in paths] == ["MANO_RIGHT.pkl", "MANO_LEFT.pkl"]
    assert all(p.parent == tmp_path / "mano" for p in paths)
    first = [p.read_bytes() for p in paths]
    write_proxy_mano(tmp_path)
    assert [p.read_bytes() for p in paths] == first
    assert [(mano_dir / "mano" / p.name).read_bytes() for p in paths] == first
    assert not [q.name for q in (tmp_path / "mano").iterdir() if q.name.endswith(".tmp")]
    # a fresh build in this process and a fresh interpreter give the same bytes
    assert ph._pickle_bytes(ph._build.__wrapped__("right")) == first[0]
    code = ("import hashlib,sys; from hoibench.bodies.proxy_hand import _file_bytes as b; "
            "sys.stdout.write(' '.join(hashlib.sha256(b(s, 'pkl')).hexdigest() for s in ('right', 'left')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == [hashlib.sha256(b).hexdigest() for b in first]

    class OnlyNumpy(pickle.Unpickler):  # proves: no chumpy, no scipy, no numpy internals
        def find_class(self, module, name):
            if (module, name) in {("numpy", "ndarray"), ("builtins", "bytearray")}:
                return super().find_class(module, name)
            raise pickle.UnpicklingError(f"unexpected global {module}.{name}")

    for side, data in zip(("right", "left"), first):
        assert b"chumpy" not in data and b"scipy" not in data
        names = [arg for op, arg, _ in pickletools.genops(data) if op.name == "SHORT_BINUNICODE"]
        assert "numpy._core.multiarray" not in names and "numpy.core.multiarray" not in names
        d = OnlyNumpy(io.BytesIO(data), encoding="latin1").load()
        ref = build_proxy_mano_arrays(side)
        assert list(d) == list(ref)
        for k, v in ref.items():
            if isinstance(v, np.ndarray):
                assert type(d[k]) is np.ndarray and d[k].dtype == v.dtype and d[k].flags.writeable
                np.testing.assert_array_equal(d[k], v)
            else:
                assert type(d[k]) is str and d[k] == v
    with pytest.raises(ValueError, match="side"):
        write_proxy_mano(tmp_path, sides=("up",))
    with pytest.raises(ValueError, match="ext"):
        write_proxy_mano(tmp_path, ext="json")


def test_model_path_errors(tmp_path, mano_dir):
    assert mano_model_path(mano_dir, "left") == mano_dir / "mano" / "MANO_LEFT.pkl"
    assert mano_model_path(mano_dir, "right", ext="npz") == mano_dir / "mano" / "MANO_RIGHT.npz"
    with pytest.raises(FileNotFoundError) as exc:
        mano_model_path(tmp_path, "left")
    msg = str(exc.value)
    assert str(tmp_path / "mano" / "MANO_LEFT.pkl") in msg and "MANO_LEFT.npz" in msg
    assert "mano.is.tue.mpg.de" in msg and "write_proxy_mano" in msg


# --------------------------------------------------------------------------- smplx
@pytest.mark.parametrize("side", SIDES)
def test_smplx_matches_proxyhand(mano_dir, side):
    smplx = pytest.importorskip("smplx")
    import torch

    hand = ProxyHand(side)
    v_ref, j_ref = hand(GO, HP, BETAS, TRANSL)
    for ext, use_pca, flat in (("pkl", False, True), ("pkl", True, False), ("npz", False, False)):
        ncomp = 12
        model = smplx.create(str(mano_dir), model_type="mano", is_rhand=side == "right", ext=ext,
                             use_pca=use_pca, num_pca_comps=ncomp, flat_hand_mean=flat,
                             dtype=torch.float64, batch_size=T)
        assert model.get_num_verts() == 778 and model.is_rhand == (side == "right")
        np.testing.assert_array_equal(np.asarray(model.faces), hand.faces)
        hp = HP[:, :ncomp] if use_pca else HP
        v, j = _smplx_forward(model, GO, hp, TRANSL, BETAS)
        assert v.shape == (T, 778, 3) and j.shape[1] in (16, 21)  # + 5 tips if smplx adds them
        ref_v, ref_j = (hand(GO, hp, BETAS, TRANSL, tips=True) if use_pca else (v_ref, j_ref))
        np.testing.assert_allclose(v, ref_v, atol=1e-6, rtol=0)
        np.testing.assert_allclose(j[:, :16], ref_j[:, :16], atol=1e-6, rtol=0)
        if j.shape[1] == 21:
            np.testing.assert_allclose(j[:, 16:], v[:, list(MANO_TIP_VERTEX_IDS.values())], atol=1e-6)
        # smplx's finger-tip selector picks the proxy's tips
        np.testing.assert_array_equal(model.vertex_joint_selector.extra_joints_idxs.numpy(),
                                      list(MANO_TIP_VERTEX_IDS.values()))
    # default float32 model through hoibench's loader, and a file path instead of a folder
    model = load_mano_model(mano_dir, side, batch_size=T)
    assert not model.use_pca and model.flat_hand_mean
    v, j = _smplx_forward(model, GO, HP, TRANSL, BETAS)
    np.testing.assert_allclose(v, v_ref, atol=1e-5, rtol=0)
    name = "MANO_RIGHT.pkl" if side == "right" else "MANO_LEFT.pkl"
    model = smplx.create(str(mano_dir / "mano" / name), model_type="mano", use_pca=False,
                         dtype=torch.float64, batch_size=T)
    assert model.is_rhand == (side == "right")
    v, _ = _smplx_forward(model, GO, HP, TRANSL, BETAS)
    np.testing.assert_allclose(v, v_ref, atol=1e-6, rtol=0)


def test_smplx_rest_and_beta0(mano_dir):
    smplx = pytest.importorskip("smplx")
    import torch

    for side in SIDES:
        a = build_proxy_mano_arrays(side)
        model = smplx.create(str(mano_dir), model_type="mano", is_rhand=side == "right",
                             use_pca=False, dtype=torch.float64, batch_size=2)
        betas = np.zeros((2, 10))
        betas[1] = np.r_[2.0, RNG.normal(size=9)]
        v, j = _smplx_forward(model, np.zeros((2, 3)), np.zeros((2, 45)), np.zeros((2, 3)), betas)
        s = 1.0 + PROXY_SCALE_PER_BETA * 2.0
        np.testing.assert_allclose(v[0], a["v_template"], atol=1e-7)
        np.testing.assert_allclose(j[0, :16], a["J"], atol=1e-7)
        np.testing.assert_allclose(v[1], s * a["v_template"], atol=1e-7)
        np.testing.assert_allclose(j[1, :16], s * a["J"], atol=1e-7)
