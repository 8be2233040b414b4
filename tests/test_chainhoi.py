"""ChainHOI baseline: graph, chain mask, losses, training, resume, sampling, run folders, CLI."""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from chainhoi_oracle import Oracle

from hoibench.baselines import joint_data as D
from hoibench.baselines.chainhoi import graph
from hoibench.baselines.chainhoi.config import preset
from hoibench.baselines.chainhoi.model import ChainHOI, KinematicDecoderLayer
from hoibench.baselines.layers import farthest_point_sample
from hoibench.baselines.chainhoi.spec import losses as chainhoi_losses
from hoibench.baselines.checkpoint import RunFolderError, verify_run
from hoibench.baselines.config import RunConfig
from hoibench.baselines.diffusion import GaussianDiffusion
from hoibench.baselines.joint_losses import interaction_positions
from hoibench.baselines.text import TextConditioner
from hoibench.baselines.trainer import make_batch, train, training_set

# ------------------------------------------------------------------ definitions, written out independently
SMPL_BONES = {(0, 1), (0, 2), (0, 3), (1, 4), (2, 5), (3, 6), (4, 7), (5, 8), (6, 9), (7, 10), (8, 11), (9, 12),
              (9, 13), (9, 14), (12, 15), (13, 16), (14, 17), (16, 18), (17, 19), (18, 20), (19, 21)}
FOOT_EDGES = {(7, 22), (8, 22), (10, 22), (11, 22)}
OBJECT_EDGES = {(j, 23) for j in (0, 10, 11, 12, 16, 17, 20, 21)}
CHAINS = [[0, 2, 5, 8, 11], [0, 1, 4, 7, 10], [0, 3, 6, 9, 12, 15], [9, 14, 17, 19, 21], [9, 13, 16, 18, 20],
          [0, 10, 11, 12, 16, 17, 20, 21, 23]]


def small_config(**over) -> RunConfig:
    base = {"train.steps": 4, "train.batch_size": 4, "train.max_frames": 40, "train.checkpoint_every": 2,
            "train.log_every": 1, "model.object_points": 64, "model.object_knn": 8, "train.contact_points": 32}
    base.update(over)
    return preset("tiny").replace(**base)


def test_adjacency_is_the_hoi_joint_graph():
    adj = graph.adjacency()
    expected = np.eye(24, dtype=np.float32)
    for a, b in SMPL_BONES | FOOT_EDGES | OBJECT_EDGES:
        expected[a, b] = expected[b, a] = 1
    np.testing.assert_array_equal(adj, expected)
    P = graph.partitions()
    np.testing.assert_array_equal(P[0], np.eye(24))
    # inward: every node except the root gathers from its root-side neighbours, rows sum to 1
    assert P[1][0].sum() == 0 and np.allclose(P[1][1:].sum(1), 1)
    assert P[1][23, [0, 10, 11, 12, 16, 17, 20, 21]].tolist() == [0.125] * 8
    np.testing.assert_array_equal(P[1] > 0, (P[2] > 0).T)


def test_chain_mask_matches_the_six_chains():
    member = graph.chain_membership()
    for c, nodes in enumerate(CHAINS):
        assert sorted(np.flatnonzero(member[c]).tolist()) == sorted(nodes)
    np.testing.assert_array_equal(graph.chain_mask(), ~member)


def test_chain_mask_really_restricts_attention():
    torch.manual_seed(0)
    layer = KinematicDecoderLayer(16, 4, 32, 0.0, "paper").eval()
    layer.keep_attention = True
    kt, nodes = torch.randn(3, 6, 16), torch.randn(3, 24, 16)
    out = layer(kt, nodes)
    w = layer.last_attention                                     # (B, heads, 6, 24)
    outside = torch.from_numpy(graph.chain_mask())[None, None].expand_as(w)
    assert w[outside].abs().max().item() == 0.0                  # exactly zero outside the chain
    assert torch.allclose(w.sum(-1), torch.ones_like(w.sum(-1)))
    # changing a node outside chain c leaves chain token c unchanged; inside, it changes
    for c, chain in enumerate(CHAINS):
        j_out = next(j for j in range(24) if j not in chain)
        moved = nodes.clone()
        moved[:, j_out] += 5.0
        assert torch.equal(layer(kt, moved)[:, c], out[:, c])
        moved = nodes.clone()
        moved[:, chain[-1]] += 5.0
        assert not torch.allclose(layer(kt, moved)[:, c], out[:, c])


def test_released_mask_masks_nothing():
    """The released code's float ``1 - mask`` is added to the scores: every node keeps weight."""
    torch.manual_seed(0)
    layer = KinematicDecoderLayer(16, 4, 32, 0.0, "released").eval()
    layer.keep_attention = True
    layer(torch.randn(2, 6, 16), torch.randn(2, 24, 16))
    w = layer.last_attention
    outside = torch.from_numpy(graph.chain_mask())[None, None].expand_as(w)
    assert w[outside].min().item() > 0


def test_farthest_point_sample_spreads_points():
    pts = torch.tensor([[[0.0, 0, 0], [0.01, 0, 0], [1, 0, 0], [0, 1, 0], [0.02, 0.01, 0]]])
    assert sorted(farthest_point_sample(pts, 3)[0].tolist()) == [0, 2, 3]


def test_surface_points_lie_on_the_mesh_and_are_seeded():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    f = np.array([[0, 1, 2]])
    p = D.surface_points(v, f, 200, "tri")
    assert np.allclose(p[:, 2], 0) and (p[:, :2] >= -1e-7).all() and (p[:, :2].sum(1) <= 1 + 1e-6).all()
    np.testing.assert_array_equal(p, D.surface_points(v, f, 200, "tri"))


def test_interaction_positions_equal_the_decoded_joints(template_store):
    from hoibench.representations import hoi269
    from hoibench.datasets.store import Store
    st = Store(template_store)
    clip = st.load(st.clip_ids("train")[0])
    joints, _, _ = hoi269.decode(clip["hoi269"])
    pos = interaction_positions(torch.from_numpy(clip["joint_level"]).double()).numpy()
    np.testing.assert_allclose(pos, joints[:, list(D.INTERACTION_JOINTS)], atol=1e-5)


def test_recentred_window_is_the_same_motion_in_its_own_frame(template_store):
    from hoibench.core.geometry import axis_angle_to_matrix, rotation_about_y
    from hoibench.datasets.store import Store
    st = Store(template_store)
    rows = st.load(st.clip_ids("train")[0])["joint_level"].astype(np.float64)
    a, n = 7, 20
    win = D.recentre_window(rows, a, n).astype(np.float64)
    R = rotation_about_y(rows[a, 0, 7])
    shift = rows[a, 0, 8:11] * np.array([1, 0, 1])
    full = interaction_positions(torch.from_numpy(rows[a:a + n])).numpy()
    mine = interaction_positions(torch.from_numpy(win)).numpy()
    np.testing.assert_allclose(mine, (full - shift) @ R.T, atol=1e-5)
    np.testing.assert_allclose(win[0, 0, [7, 8, 10]], 0, atol=1e-6)        # yaw 0, root at x = z = 0
    np.testing.assert_allclose(win[:, 23, 3:6], (rows[a:a + n, 23, 3:6] - shift) @ R.T, atol=1e-5)
    np.testing.assert_allclose(axis_angle_to_matrix(win[:, 23, 0:3]),
                               R[None] @ axis_angle_to_matrix(rows[a:a + n, 23, 0:3]), atol=1e-5)
    np.testing.assert_array_equal(win[:, 1:23], rows[a:a + n, 1:23].astype(np.float32))


def _fixed_loss(model, diffusion, batch, cfg, ts):
    mean, std = torch.from_numpy(ts.stats.mean), torch.from_numpy(ts.stats.std)
    return chainhoi_losses(model, diffusion, batch, cfg, mean, std, torch.Generator().manual_seed(123))


def test_a_training_step_reduces_the_loss_on_a_fixed_batch(template_store):
    cfg = small_config()
    ts = training_set(template_store, cfg)
    text = TextConditioner("tokens", 32, ts.vocab)
    torch.manual_seed(0)
    model = ChainHOI(cfg.model, vocab=len(ts.vocab))
    diffusion = GaussianDiffusion(cfg.diffusion)
    batch = make_batch(ts, cfg, 0, text, "cpu")
    opt = torch.optim.AdamW(model.parameters(), lr=1e-3)
    before = {k: float(v.detach()) for k, v in _fixed_loss(model, diffusion, batch, cfg, ts).items()}
    for _ in range(5):
        opt.zero_grad()
        _fixed_loss(model, diffusion, batch, cfg, ts)["loss"].backward()
        opt.step()
    after = {k: float(v.detach()) for k, v in _fixed_loss(model, diffusion, batch, cfg, ts).items()}
    assert after["loss"] < before["loss"]
    assert before["contact"] > 0                              # the contact term is active on this data


@pytest.mark.parametrize("distance", ["samples", "exact"])
def test_contact_loss_is_the_gated_squared_distance(template_store, distance):
    """L_h of a batch whose prediction is the GT equals a brute-force computation: the nearest
    surface sample, or the exact distance to the posed template mesh
    (:func:`hoibench.bodies.reference_distance.exact_triangle_distance`, float64)."""
    from hoibench.bodies.reference_distance import exact_triangle_distance
    cfg = small_config(**{"train.lambda_object": 0.0, "train.contact_distance": distance})
    ts = training_set(template_store, cfg)
    batch = make_batch(ts, cfg, 3, TextConditioner("tokens", 32, ts.vocab), "cpu")
    losses = _fixed_loss(Oracle(batch["x0"]), GaussianDiffusion(cfg.diffusion), batch, cfg, ts)
    assert float(losses["diffusion"]) == 0.0
    raw = batch["x0"].double() * torch.from_numpy(ts.stats.std).double() + torch.from_numpy(ts.stats.mean).double()
    total, count = 0.0, 0
    for b in range(raw.shape[0]):
        for i in range(raw.shape[1]):
            if not batch["valid"][b, i]:
                continue
            from hoibench.core.geometry import axis_angle_to_matrix
            R = axis_angle_to_matrix(raw[b, i, 23, 0:3].numpy())
            surf = batch["contact_points"][b].double().numpy() @ R.T + raw[b, i, 23, 3:6].numpy()
            joints = interaction_positions(raw[b:b + 1, i:i + 1])[0, 0].numpy()
            for k in range(8):
                if not batch["contacts"][b, i, k]:
                    continue
                if distance == "samples":
                    total += ((surf - joints[k]) ** 2).sum(1).min()
                else:
                    tri = batch["contact_mesh"][b].double().numpy() @ R.T + raw[b, i, 23, 3:6].numpy()
                    total += exact_triangle_distance(joints[k][None], tri.reshape(-1, 3),
                                                     np.arange(3 * len(tri)).reshape(-1, 3))[0] ** 2
                count += 1
    assert count > 0 and ("contact_mesh" in batch) == (distance == "exact")
    assert float(losses["contact"]) == pytest.approx(total / count, rel=1e-4)


@pytest.fixture(scope="module")
def tiny_run(template_store, tmp_path_factory):
    out = tmp_path_factory.mktemp("chainhoi") / "run"
    res = train("chainhoi", template_store, out, small_config(), log=None)
    return out, res


def test_run_folder_verifies_and_detects_edits(tiny_run, tmp_path):
    out, res = tiny_run
    card, _ = verify_run(out, "chainhoi")
    assert card["checkpoint_id"] == res.checkpoint_id and len(card["curve"]) == 4
    assert card["dataset"]["joint_stats_sha256"] and card["dataset"]["store_hoi269_stats_sha256"]
    assert not (out / "checkpoint").exists()
    bad = tmp_path / "bad"
    shutil.copytree(out, bad)
    c = json.loads((bad / "card.json").read_text())
    c["seed"] = 7
    (bad / "card.json").write_text(json.dumps(c))
    with pytest.raises(RunFolderError, match="seed"):
        verify_run(bad)


def test_resume_gives_the_uninterrupted_run(template_store, tiny_run, tmp_path):
    out, res = tiny_run
    part = tmp_path / "resumed"
    train("chainhoi", template_store, part, small_config(), stop_after=2, log=None)
    assert (part / "checkpoint" / "last.pt").exists() and not (part / "card.json").exists()
    segments = json.loads((part / "checkpoint" / "segments.json").read_text())["segments"]
    assert [(s["from"], s["to"]) for s in segments] == [(0, 2)] and segments[0]["seconds"] > 0
    again = train("chainhoi", template_store, part, small_config(), log=None)
    assert again.resumed_from == 2
    assert again.checkpoint_id == res.checkpoint_id
    # the run's wall time covers both processes, from step 0; the segments went with the checkpoint
    log = json.loads((part / "train_log.json").read_text())
    assert log["seconds_from_step"] == 0 and log["resumed_from"] == 2
    assert log["seconds"] == pytest.approx(segments[0]["seconds"] + log["segment_seconds"], abs=0.11)
    assert not (part / "checkpoint").exists()
    assert train("chainhoi", template_store, part, small_config(), log=None).already_trained


def test_an_interrupt_inside_a_step_keeps_every_step_before_it(template_store, tiny_run, tmp_path, monkeypatch):
    """Ctrl-C while step 3 computes its losses (checkpoints every 2 steps): the run saves the
    3 finished steps, and the resumed run ends with the uninterrupted run's weights."""
    from hoibench.baselines.chainhoi import spec as chainhoi_spec
    _, res = tiny_run
    real, calls = chainhoi_spec.losses, {"n": 0}

    def interrupted(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 4:
            raise KeyboardInterrupt("SIGINT")
        return real(*args, **kwargs)
    monkeypatch.setattr(chainhoi_spec, "losses", interrupted)
    part = tmp_path / "cut"
    with pytest.raises(KeyboardInterrupt):
        train("chainhoi", template_store, part, small_config(), log=None)
    monkeypatch.setattr(chainhoi_spec, "losses", real)
    again = train("chainhoi", template_store, part, small_config(), log=None)
    assert again.resumed_from == 3
    assert again.checkpoint_id == res.checkpoint_id


def test_sampling_is_deterministic_and_guidance_one_is_conditional(tiny_run, template_store):
    from hoibench.baselines.sampler import LoadedRun
    from hoibench.datasets.store import Store
    run = LoadedRun(tiny_run[0])
    st = Store(template_store)
    clip = st.load(st.clip_ids("test")[0])
    v, f = st.object_template(str(clip["object_name"]))
    pts = D.surface_points(v, f, run.config.model.object_points, "x")
    a = run.generate("a person lifts the box", pts, 12, 2, (0, "x"), steps=3)
    b = run.generate("a person lifts the box", pts, 12, 2, (0, "x"), steps=3)
    c = run.generate("a person lifts the box", pts, 12, 2, (1, "x"), steps=3)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    # guidance at scale 1 is the conditional model
    x = torch.randn(2, 12, 24, 12, generator=torch.Generator().manual_seed(3))
    t = torch.tensor([500, 500])
    tt, pad = run.text(["a person lifts the box"] * 2, "cpu")
    with torch.no_grad():
        text, obj = run.model.encode_text(tt, pad), run.model.encode_object(torch.from_numpy(np.stack([pts, pts])))

        def m(xx, tt_, keep):
            n = xx.shape[0] // 2
            return run.model(xx, tt_, keep, text.repeat(n, 1, 1), pad.repeat(n, 1), obj.repeat(n, 1, 1))
        cond = m(x, t, torch.ones(2, dtype=torch.bool))
        assert torch.allclose(GaussianDiffusion.guided(m, x, t, 1.0), cond, atol=1e-5)
        assert not torch.allclose(GaussianDiffusion.guided(m, x, t, 2.0), cond, atol=1e-5)


def test_sample_writes_a_valid_submission_and_refuses_another_store(tiny_run, template_store, tmp_path):
    from hoibench.baselines.sampler import StoreMismatch, sample
    from hoibench.scoring.submission import validation_report
    sub = sample(tiny_run[0], template_store, tmp_path / "sub", samples=2, steps=2, log=None)
    rep = validation_report(sub, template_store)
    assert rep.complete, [p for p in rep.problems][:3]
    meta = json.loads((sub / "submission.json").read_text())
    assert meta["source"]["checkpoint_id"] == tiny_run[1].checkpoint_id and meta["flags"]["samples_per_prompt"] == 2
    budget = meta["source"]["training"]                  # the run's training budget travels with its samples
    card = json.loads((tiny_run[0] / "card.json").read_text())
    assert budget["steps"] == 4 and budget["parameters"] == card["summary"]["parameters"] > 0
    assert budget["wall_seconds"] > 0 and budget["hardware"].startswith("CPU")
    assert budget["text_encoder"] == {"encoder": "tokens"}
    other = tmp_path / "other"
    shutil.copytree(template_store, other)
    with np.load(other / "stats" / "hoi269.npz") as z:
        arrays = {k: z[k] for k in z.files}
    arrays["mean"] = arrays["mean"] + 0.5
    np.savez(other / "stats" / "hoi269.npz", **arrays)
    with pytest.raises(StoreMismatch, match="normalisation statistics"):
        sample(tiny_run[0], other, tmp_path / "sub2", steps=2, log=None)


def test_training_and_sampling_import_only_torch_numpy_safetensors(tiny_run, template_store, tmp_path):
    code = f"""
import sys
for m in ("scipy", "open3d", "pyvista", "pymeshlab", "trimesh", "transformers", "sentence_transformers",
          "matplotlib", "pandas", "smplx"):
    sys.modules[m] = None
from hoibench.baselines.sampler import sample
from hoibench.baselines.trainer import train
from hoibench.baselines.chainhoi.config import preset
cfg = preset("tiny").replace(**{{"train.steps": 1, "train.batch_size": 2, "train.max_frames": 16}})
train("chainhoi", {str(template_store)!r}, {str(tmp_path / 'r')!r}, cfg, log=None)
sample({str(tiny_run[0])!r}, {str(template_store)!r}, {str(tmp_path / 's')!r}, steps=1, limit=1, log=None)
print("ok")
"""
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0 and "ok" in res.stdout, res.stderr[-2000:]


def test_cli_train_sample_show_and_one_line_errors(template_store, tmp_path):
    exe = [sys.executable, "-m", "hoibench.cli"]
    run = tmp_path / "run0"
    r = subprocess.run(exe + ["baseline", "train", "chainhoi", str(template_store), "--out", str(run), "--steps", "0"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    r = subprocess.run(exe + ["baseline", "show", str(run)], capture_output=True, text=True, timeout=120)
    assert "verified" in r.stdout and "0 steps" in r.stdout
    r = subprocess.run(exe + ["baseline", "sample", "chainhoi", str(run), "--data", str(template_store), "--out",
                              str(tmp_path / "sub"), "--ddim-steps", "1"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "sub" / "submission.json").exists()
    for args, needle in [(["baseline", "sample", "chainhoi", str(tmp_path), "--data", str(template_store), "--out",
                           str(tmp_path / "x")], "not a baseline run folder"),
                         (["baseline", "sample", "chainhoi", str(run), "--data", str(template_store), "--out",
                           str(tmp_path / "x"), "--samples", "0"], "--samples"),
                         (["baseline", "sample", "chainhoi", str(run), "--data", str(template_store), "--out",
                           str(tmp_path / "x"), "--samples", "31"], "protocol reads at most 30"),
                         (["baseline", "sample", "chainhoi", str(run), "--data", str(template_store), "--out",
                           str(tmp_path / "x"), "--guidance", "nan"], "--guidance"),
                         (["baseline", "train", "chainhoi", str(template_store), "--out", str(run), "--steps", "3"],
                          "already holds run"),
                         (["baseline", "sample", "chainhoi", str(run), "--data", str(template_store), "--out",
                           str(tmp_path / "x"), "--device", "cuda:0"], None)]:
        r = subprocess.run(exe + args, capture_output=True, text=True, timeout=300)
        if needle is None and torch.cuda.is_available():
            continue
        assert r.returncode == 2, (args, r.stderr)
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("hoibench baseline: error:"), r.stderr
        assert needle is None or needle in lines[0]


def test_an_interrupt_between_checkpoints_keeps_the_work_and_resumes_exactly(template_store, tiny_run, tmp_path,
                                                                             monkeypatch):
    import hoibench.baselines.trainer as trainer_mod
    calls = {"n": 0}

    def interrupt_at_step_3():
        calls["n"] += 1
        if calls["n"] == 4:                       # before step index 3: steps 0, 1, 2 are done
            raise KeyboardInterrupt

    cfg = small_config(**{"train.checkpoint_every": 4, "train.log_every": 2})
    ref = train("chainhoi", template_store, tmp_path / "ref", cfg, log=None)
    monkeypatch.setattr(trainer_mod, "check_interrupted", interrupt_at_step_3)
    with pytest.raises(KeyboardInterrupt):
        train("chainhoi", template_store, tmp_path / "run", cfg, log=None)
    monkeypatch.undo()
    ck = torch.load(tmp_path / "run" / "checkpoint" / "last.pt", weights_only=True)
    assert ck["step"] == 3 and json.loads(ck["window"])            # mid-window state kept
    again = train("chainhoi", template_store, tmp_path / "run", cfg, log=None)
    assert again.resumed_from == 3 and again.checkpoint_id == ref.checkpoint_id


def test_a_finished_run_names_what_differs(template_store, tiny_run):
    with pytest.raises(RunFolderError, match=r"config\.train\.seed"):
        train("chainhoi", template_store, tiny_run[0], small_config(**{"train.seed": 7}), log=None)


def test_submission_output_must_be_new_or_empty(tmp_path):
    from hoibench.scoring.submission import write_submission
    meta = {"method": "x"}
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "notes.txt").write_text("mine")
    with pytest.raises(FileExistsError, match="not empty"):
        write_submission(tmp_path / "full", meta, {})
    (tmp_path / "a.zip").write_bytes(b"keep")
    with pytest.raises(FileExistsError, match="already exists"):
        write_submission(tmp_path / "a.zip", meta, {}, as_zip=True)
    assert (tmp_path / "a.zip").read_bytes() == b"keep" and (tmp_path / "full" / "notes.txt").read_text() == "mine"
    write_submission(tmp_path / "new", meta, {})                     # a new folder is fine
    assert (tmp_path / "new" / "submission.json").exists()


@pytest.mark.parametrize("args, needle", [
    (["baseline", "train", "chainhoi", "DATA", "--out", "OUT", "--threads", "0"], "--threads"),
    (["baseline", "train", "chainhoi", "DATA", "--out", "OUT", "--device", "meta"], "--device"),
    (["baseline", "train", "ejim", "DATA", "--out", "OUT", "--mask", "released"], "--mask"),
    (["baseline", "train", "chainhoi", "DATA", "--out", "OUT", "--seed", "-1"], "--seed"),
    (["baseline", "sample", "mean-pose", "--data", "DATA", "--out", "OUT", "--guidance", "3"], "--guidance"),
    (["baseline", "show", "NOWHERE"], "does not exist"),
])
def test_cli_refuses_bad_options_in_one_line(template_store, tmp_path, args, needle):
    args = [str(template_store) if a == "DATA" else str(tmp_path / "o") if a == "OUT" else
            str(tmp_path / "nowhere") if a == "NOWHERE" else a for a in args]
    r = subprocess.run([sys.executable, "-m", "hoibench.cli"] + args, capture_output=True, text=True, timeout=300)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1 and needle in lines[0], r.stderr
    assert not (tmp_path / "o").exists()
