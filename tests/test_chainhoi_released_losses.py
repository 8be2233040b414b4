"""ChainHOI ``released``: exact point-to-triangle distance, joint positions, grouped statistics,
the losses (``L_h`` over 22 joints against the posed mesh, ``L_o`` on posed vertices), the
PointNet++ object encoder and the config's recipe."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from chainhoi_oracle import Oracle

from hoibench.baselines import joint_data as D
from hoibench.baselines.chainhoi import released_losses as RL
from hoibench.baselines.chainhoi.pointnet2 import PointNet2MSG, ball_query
from hoibench.baselines.chainhoi.spec import config_class, preset
from hoibench.baselines.joint_losses import interaction_positions


def test_point_triangle_distance_matches_trimesh():
    trimesh = pytest.importorskip("trimesh")
    rs = np.random.RandomState(0)
    tri = rs.standard_normal((300, 3, 3))
    tri[:20, 2] = tri[:20, 0] + 1e-9 * rs.standard_normal((20, 3))      # near-degenerate triangles
    pts = rs.standard_normal((300, 3)) * 1.5
    closest = trimesh.triangles.closest_point(tri, pts)
    want = np.linalg.norm(closest - pts, axis=1)
    got = RL.point_triangle_distance(torch.from_numpy(pts), torch.from_numpy(tri)).numpy()
    np.testing.assert_allclose(got, want, atol=1e-9)


def test_mesh_distance_is_the_nearest_triangle():
    rs = np.random.RandomState(1)
    tris = torch.from_numpy(rs.standard_normal((5, 40, 3, 3)))
    pts = torch.from_numpy(rs.standard_normal((5, 3)))
    d = RL.mesh_distance(pts, tris)
    brute = torch.stack([RL.point_triangle_distance(pts[i].expand(40, 3), tris[i]).min() for i in range(5)])
    torch.testing.assert_close(d, brute)


def test_joint_positions_agree_with_the_interaction_joints():
    rows = torch.randn(2, 5, 24, 12, dtype=torch.float64)
    full = RL.joint_positions(rows)
    assert full.shape == (2, 5, 22, 3)
    torch.testing.assert_close(full[..., list(D.INTERACTION_JOINTS), :], interaction_positions(rows))


def test_grouped_stats_leave_the_global_root_unnormalised_and_share_group_std():
    rs = np.random.RandomState(2)
    clips = [rs.standard_normal((30, 24, 12)).astype(np.float32) * (1 + np.arange(12)) for _ in range(3)]
    st = D.grouped_stats(clips)
    np.testing.assert_array_equal(st.mean[0, 7:11], 0.0)
    np.testing.assert_array_equal(st.std[0, 7:11], 1.0)
    ric_std = st.std[1:22, 0:3]
    assert np.allclose(ric_std, ric_std.flat[0])                        # one std for the whole ric group
    assert np.allclose(st.std[23, 0:3], st.std[23, 0]) and st.std[23, 0] != st.std[23, 3]
    per_channel = D.JointStats.from_rows(clips)
    assert not np.allclose(per_channel.std[1:22, 0:3], ric_std)


def _cube():
    trimesh = pytest.importorskip("trimesh")
    m = trimesh.creation.box(extents=(0.2, 0.2, 0.2))
    return torch.from_numpy(np.asarray(m.vertices, np.float32)), torch.from_numpy(np.asarray(m.faces, np.int64))


def test_object_loss_is_the_posed_vertex_error_over_all_frames():
    v, _ = _cube()
    B, L = 2, 4
    gt = torch.zeros(B, L, 24, 12)
    pred = gt.clone()
    pred[..., 23, 3] += 0.3                                              # every frame shifted 0.3 m in x
    valid = torch.ones(B, L, dtype=torch.bool)
    valid[1, 2:] = False
    verts = v[None].expand(B, -1, -1)
    vv = torch.ones(B, len(v), dtype=torch.bool)
    got = RL.object_loss(pred, gt, valid, verts, vv)
    assert float(got) == pytest.approx(0.09 / 3 * 6 / 8, rel=1e-5)     # 6 valid of 8 frames (B x L mean)
    assert float(RL.object_loss(gt, gt, valid, verts, vv)) == 0.0


def test_contact_loss_is_the_squared_distance_to_the_posed_mesh():
    trimesh = pytest.importorskip("trimesh")
    v, f = _cube()
    rows = torch.zeros(2, 3, 24, 12, dtype=torch.float64)
    rows[..., 1:22, 0:3] = torch.randn(2, 3, 21, 3, dtype=torch.float64) * 0.3
    rows[..., 0, 7] = 0.4                                                # yaw
    rows[..., 0, 8:11] = torch.tensor([0.1, 0.9, -0.2], dtype=torch.float64)
    rows[..., 23, 0:3] = torch.tensor([0.2, -0.5, 0.3], dtype=torch.float64)
    rows[..., 23, 3:6] = torch.tensor([0.3, 0.8, 0.1], dtype=torch.float64)
    contacts = torch.zeros(2, 3, 22, dtype=torch.bool)
    contacts[0, 0, [0, 20, 21]] = True
    contacts[0, 2, 10] = True
    valid = torch.ones(2, 3, dtype=torch.bool)
    got = RL.contact_loss(rows, rows, contacts, valid, v[None].double().expand(2, -1, -1), f[None].expand(2, -1, -1))
    posed = RL.posed_vertices(rows, v[None].double().expand(2, -1, -1)).numpy()
    joints = RL.joint_positions(rows).numpy()
    d2 = []
    for (l, j) in ((0, 0), (0, 20), (0, 21), (2, 10)):
        mesh = trimesh.Trimesh(posed[0, l], f.numpy(), process=False)
        _, dist, _ = trimesh.proximity.closest_point(mesh, joints[0, l, j][None])
        d2.append(dist[0] ** 2)
    assert float(got) == pytest.approx(np.mean(d2) / 2, rel=1e-6)      # clip 1 has no contact: / B = 2


def test_ball_query_takes_the_first_points_inside_and_repeats_the_first():
    xyz = torch.tensor([[[0.0, 0, 0], [5, 0, 0], [0.05, 0, 0], [0.08, 0, 0], [3, 0, 0]]])
    idx = ball_query(xyz, xyz[:, :2], 0.1, 4)
    assert idx[0, 0].tolist() == [0, 2, 3, 0]
    assert idx[0, 1].tolist() == [1, 1, 1, 1]


def test_pointnet2_msg_size_and_shapes():
    """2,078,176 parameters: the public ``PointNet2SemSegMSG`` (Huanggh531/ChainHOI @ 4990160,
    src/models/nets/points_encoder.py, with erikwijmans/Pointnet2_PyTorch's
    pointnet2_ops/pointnet2_modules.py @ 5b98379) instantiated outside the project, its CUDA
    operators replaced by parameter-free stand-ins; same state-dict keys and shapes."""
    m = PointNet2MSG()
    assert sum(p.numel() for p in m.parameters()) == 2_078_176
    torch.manual_seed(0)
    m.eval()
    with torch.no_grad():
        out = m(torch.rand(1, 512, 3) * 0.4)
    assert out.shape == (1, 16, 512) and bool(torch.isfinite(out).all())


def test_released_preset_is_the_public_recipe():
    cfg = preset("released")
    t = cfg.train
    assert (t.lr, t.weight_decay, t.grad_clip, t.ema_decay, t.batch_size) == (1e-4, 0.0, 0.0, 0.0, 16)
    assert cfg.model.mask == "released" and cfg.model.padding == "masked"
    assert (cfg.model.base_dim, cfg.model.model_dim, cfg.model.heads, cfg.model.decoder_layers) == (64, 64, 4, 4)
    assert config_class(cfg.to_dict()) is type(cfg.model)
    assert config_class(preset("paper").to_dict()) is type(preset("paper").model)
    again = type(cfg).from_dict(cfg.to_dict(), config_class(cfg.to_dict()))
    assert again == cfg
    with pytest.raises(ValueError, match="released"):
        preset("relased")


def test_training_batches_carry_meshes_and_per_joint_contacts(template_store):
    """``released`` batches: grouped statistics, 512 template vertices for PointNet++, the
    padded template mesh and (B, L, 22) contact labels of each window; with a prediction equal
    to the GT, ``L_diff`` and ``L_o`` vanish and ``L_h`` is the brute-force mean squared
    joint-to-mesh distance over the contact pairs (trimesh)."""
    trimesh = pytest.importorskip("trimesh")
    from hoibench.baselines.diffusion import GaussianDiffusion
    from hoibench.baselines.text import TextConditioner
    from hoibench.baselines.trainer import make_batch, training_set
    cfg = preset("released").replace(**{"train.batch_size": 3, "train.max_frames": 24, "model.text_encoder": "tokens"})
    ts = training_set(template_store, cfg)
    np.testing.assert_array_equal(ts.stats.std[0, 7:11], 1.0)
    batch = make_batch(ts, cfg, 5, TextConditioner("tokens", 32, ts.vocab), "cpu")
    assert batch["points"].shape == (3, 512, 3) and batch["joint_contacts"].shape[2] == 22
    name = ts.items[0].object_name
    v, f = ts.meshes[name]
    assert {tuple(p) for p in D.vertex_points(v, 512, name).tolist()} <= {tuple(p) for p in v.astype(np.float32).tolist()}
    mean, std = torch.from_numpy(ts.stats.mean).double(), torch.from_numpy(ts.stats.std).double()
    batch = {k: (v.double() if torch.is_tensor(v) and v.is_floating_point() else v) for k, v in batch.items()}
    out = RL.losses(Oracle(batch["x0"]), GaussianDiffusion(cfg.diffusion), batch, cfg, mean, std, torch.Generator().manual_seed(1))
    assert float(out["diffusion"]) == 0.0 and float(out["object"]) == 0.0
    raw = batch["x0"] * std + mean
    joints = RL.joint_positions(raw).numpy()
    total = 0.0
    for b in range(3):
        verts = batch["mesh_vertices"][b][batch["mesh_vertex_valid"][b]]
        posed = RL.posed_vertices(raw[b:b + 1], verts[None])[0].numpy()
        d2 = []
        for l, j in zip(*np.nonzero((batch["joint_contacts"][b] & batch["valid"][b][:, None]).numpy())):
            mesh = trimesh.Trimesh(posed[l], batch["mesh_faces"][b].numpy(), process=False)
            d2.append(trimesh.proximity.closest_point(mesh, joints[b, l, j][None])[1][0] ** 2)
        total += np.mean(d2) if d2 else 0.0
    assert total > 0
    assert float(out["contact"]) == pytest.approx(total / 3, rel=1e-6)
