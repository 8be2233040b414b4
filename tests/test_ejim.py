"""EJIM baseline: parallel selective scan, Mamba padding/direction exactness, progressive masking,
deterministic sampling, a training step, CLI."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import torch

from hoibench.baselines.ejim.config import preset
from hoibench.baselines.ejim.mamba import BiMamba, MambaBlock, reversal_index
from hoibench.baselines.ejim.model import DIB, EJIM, LIMB_GROUPS, limb_order, update_mask
from hoibench.baselines.scan import linear_scan, linear_scan_reference, selective_scan


@pytest.mark.parametrize("L", [1, 2, 5, 64, 197])
def test_parallel_scan_equals_the_recurrence_forward_and_gradient(L):
    g = torch.Generator().manual_seed(L)
    a = (torch.rand(3, L, 4, 5, generator=g) * 0.999 + 1e-3).requires_grad_()
    b = torch.randn(3, L, 4, 5, generator=g).requires_grad_()
    w = torch.randn(3, L, 4, 5, generator=g)
    h, ref = linear_scan(a, b), linear_scan_reference(a, b)
    assert (h - ref).abs().max().item() < 1e-5
    ga, gb = torch.autograd.grad((h * w).sum(), (a, b))
    ra, rb = torch.autograd.grad((ref * w).sum(), (a, b))
    assert (ga - ra).abs().max().item() < 1e-5 and (gb - rb).abs().max().item() < 1e-5


def test_selective_scan_equals_the_s6_recurrence_written_out():
    g = torch.Generator().manual_seed(0)
    b_, L, d, n = 2, 9, 3, 4
    u, delta = torch.randn(b_, L, d, generator=g), torch.rand(b_, L, d, generator=g) * 0.2
    A = -torch.rand(d, n, generator=g) * 3 - 0.1
    B, C, D = torch.randn(b_, L, n, generator=g), torch.randn(b_, L, n, generator=g), torch.randn(d, generator=g)
    y = selective_scan(u, delta, A, B, C, D)
    h = torch.zeros(b_, d, n)
    for t in range(L):
        h = torch.exp(delta[:, t, :, None] * A) * h + delta[:, t, :, None] * B[:, t, None, :] * u[:, t, :, None]
        expect = (h * C[:, t, None, :]).sum(-1) + D * u[:, t]
        assert torch.allclose(y[:, t], expect, atol=1e-5)


def test_reversal_index_keeps_prefix_and_padding():
    valid = torch.tensor([[1, 1, 1, 1, 1, 0], [1, 1, 1, 0, 0, 0]], dtype=torch.bool)
    assert reversal_index(valid, 0).tolist() == [[4, 3, 2, 1, 0, 5], [2, 1, 0, 3, 4, 5]]
    assert reversal_index(valid, 2).tolist() == [[0, 1, 4, 3, 2, 5], [0, 1, 2, 3, 4, 5]]


def test_mamba_on_a_padded_batch_equals_the_unpadded_sequences():
    torch.manual_seed(0)
    m = BiMamba(8, 4, 2, 4, 0.0).eval()
    x = torch.randn(2, 9, 8)
    valid = torch.tensor([[True] * 7 + [False] * 2, [True] * 4 + [False] * 5])
    out = m(x, valid, prefix=2)
    for i, n in enumerate((7, 4)):
        assert torch.allclose(m(x[i:i + 1, :n], None, prefix=2), out[i:i + 1, :n], atol=1e-6)
    fwd = MambaBlock(8, 4, 2, 4).eval()
    y = fwd(x)                                      # causal: changing the last step leaves the rest
    x2 = x.clone()
    x2[:, -1] += 1.0
    assert torch.allclose(fwd(x2)[:, :-1], y[:, :-1], atol=1e-6)


def test_limb_order_covers_every_joint_and_duplicates_only_the_foot_node():
    seq, seps = limb_order()
    assert len(seq) == 23 + 1 + len(LIMB_GROUPS)      # 23 tokens, node 22 twice, 5 separators
    assert [seq[p] for p in seps] == [-1] * 5
    counts = np.bincount([j for j in seq if j >= 0], minlength=23)
    assert counts[22] == 2 and (np.delete(counts, 22) == 1).all()


def test_update_mask_drops_the_k_lowest_visible_joints_cumulatively():
    scores = torch.arange(23, dtype=torch.float32).flip(0)[None]          # joint 22 lowest, 0 highest
    m1 = update_mask(torch.zeros(1, 23, dtype=torch.bool), scores, 3)
    assert torch.nonzero(m1[0]).flatten().tolist() == [20, 21, 22]
    m2 = update_mask(m1, scores, 3)                                       # already-masked stay masked
    assert torch.nonzero(m2[0]).flatten().tolist() == [17, 18, 19, 20, 21, 22]
    # ties: lower joint index is dropped first; at least one joint stays visible
    m3 = update_mask(torch.zeros(1, 23, dtype=torch.bool), torch.zeros(1, 23), 2)
    assert torch.nonzero(m3[0]).flatten().tolist() == [0, 1]
    almost = torch.ones(1, 23, dtype=torch.bool)
    almost[0, 5] = almost[0, 9] = False
    assert (~update_mask(almost, scores, 3)).sum().item() == 1
    assert torch.equal(update_mask(m1, scores, 0), m1)


def test_masked_joints_receive_no_attention_and_no_update():
    torch.manual_seed(0)
    dib = DIB(8, 1, 0.0).eval()
    h, o = torch.randn(2, 3, 23, 8), torch.randn(2, 3, 8)
    masked = torch.zeros(2, 3, 23, dtype=torch.bool)
    masked[..., [4, 11, 22]] = True
    h1, o1, s = dib(h, o, masked)
    assert torch.equal(h1[masked], h[masked])                              # no update
    assert s[masked].abs().max().item() == 0.0                             # no attention to them
    h2 = h.clone()
    h2[..., 11, :] += 10.0                                                 # moving a masked joint
    h3, o3, _ = dib(h2, o, masked)
    assert torch.allclose(h3[~masked], h1[~masked], atol=1e-6) and torch.allclose(o3, o1, atol=1e-6)


def test_progressive_masking_in_the_model_follows_the_rule():
    cfg = preset("micro").replace(**{"model.modules": 3, "model.mask_k": 4}).model
    torch.manual_seed(0)
    model = EJIM(cfg, vocab=10).eval()
    x = torch.randn(2, 6, 24, 12)
    ids, pad = torch.randint(1, 10, (2, 4)), torch.zeros(2, 4, dtype=torch.bool)
    with torch.no_grad():
        model(x, torch.tensor([5, 900]), torch.ones(2, dtype=torch.bool), model.encode_text(ids, pad), pad,
              model.encode_object(torch.randn(2, cfg.object_points, 3)))
    counts = [m.sum(-1) for m in model.last_masks]
    assert [int(c.min()) for c in counts] == [4, 8, 12] and [int(c.max()) for c in counts] == [4, 8, 12]
    assert all(torch.equal(a & b, a) for a, b in zip(model.last_masks, model.last_masks[1:]))   # cumulative


def test_dib_scores_are_the_attention_weights_without_dropout():
    torch.manual_seed(0)
    dib = DIB(8, 2, 0.5)
    h, o = torch.randn(2, 3, 23, 8), torch.randn(2, 3, 8)
    masked = torch.zeros(2, 3, 23, dtype=torch.bool)
    masked[..., [2, 7]] = True
    dib.eval()
    tok = dib.norm(torch.cat([o[:, :, None], h], 2).reshape(6, 24, 8))
    keymask = torch.cat([torch.zeros(2, 3, 1, dtype=torch.bool), masked], 2).reshape(6, 24)
    with torch.no_grad():
        _, w = dib.attn(tok, tok, tok, key_padding_mask=keymask, need_weights=True, average_attn_weights=True)
        s_eval = dib(h, o, masked)[2]
    torch.testing.assert_close(s_eval, w[:, 0, 1:].reshape(2, 3, 23))     # PyTorch's weights in eval mode
    dib.train()
    with torch.no_grad():
        outs = [dib(h, o, masked) for _ in range(2)]                      # two dropout draws
        _, wt = dib.attn(tok, tok, tok, key_padding_mask=keymask, need_weights=True)
    assert not torch.allclose(outs[0][0], outs[1][0])                    # dropout acted on the update
    assert (wt[:, 0, 1:].reshape(2, 3, 23) - s_eval).abs().max() > 1e-3   # and on PyTorch's returned weights
    torch.testing.assert_close(outs[0][2], s_eval)
    torch.testing.assert_close(outs[1][2], s_eval)


def test_progressive_masks_do_not_depend_on_the_dropout_draw():
    """Attention dropout (0.5) in the first module's DIB #2, no other dropout: the outputs
    differ between draws and from sampling's, the joints that DIB chooses do not."""
    cfg = preset("micro").replace(**{"model.modules": 3, "model.object_points": 64, "model.object_knn": 8}).model
    torch.manual_seed(0)
    model = EJIM(cfg, vocab=10)
    model.modules_[0].dib2.attn.dropout = 0.5
    x = torch.randn(2, 6, 24, 12)
    ids, pad = torch.randint(1, 10, (2, 4)), torch.zeros(2, 4, dtype=torch.bool)
    with torch.no_grad():
        text, obj = model.encode_text(ids, pad), model.encode_object(torch.randn(2, cfg.object_points, 3))

    def run(train: bool, seed: int):
        model.train(train)
        torch.manual_seed(seed)
        with torch.no_grad():
            out = model(x, torch.tensor([5, 900]), torch.ones(2, dtype=torch.bool), text, pad, obj)
        return out, [m.clone() for m in model.last_masks]

    ref_out, ref = run(False, 0)
    for seed in (1, 2):
        out, masks = run(True, seed)
        assert not torch.allclose(out, ref_out)                         # dropout acted
        assert torch.equal(masks[0], ref[0]) and int(masks[0].sum()) == 2 * 6 * cfg.mask_k


def small_config(**over):
    base = {"train.steps": 3, "train.batch_size": 3, "train.max_frames": 24, "train.checkpoint_every": 3,
            "train.log_every": 1, "model.object_points": 64, "model.object_knn": 8, "model.d_model": 16,
            "model.d_state": 4}
    base.update(over)
    return preset("tiny").replace(**base)


def test_a_training_step_reduces_the_loss_on_a_fixed_batch(template_store):
    from hoibench.baselines.diffusion import GaussianDiffusion
    from hoibench.baselines.ejim.spec import build_model, losses
    from hoibench.baselines.text import TextConditioner
    from hoibench.baselines.trainer import make_batch, training_set
    cfg = small_config()
    ts = training_set(template_store, cfg)
    torch.manual_seed(0)
    model = build_model(cfg, len(ts.vocab), 0)
    batch = make_batch(ts, cfg, 0, TextConditioner("tokens", 32, ts.vocab), "cpu")
    diffusion = GaussianDiffusion(cfg.diffusion)
    mean, std = torch.from_numpy(ts.stats.mean), torch.from_numpy(ts.stats.std)

    def loss():
        return losses(model, diffusion, batch, cfg, mean, std, torch.Generator().manual_seed(5))

    before = {k: float(v.detach()) for k, v in loss().items()}
    assert set(before) == {"loss", "diffusion", "object", "smooth"}
    opt = torch.optim.AdamW(model.parameters(), lr=3e-3)
    for _ in range(5):
        opt.zero_grad()
        loss()["loss"].backward()
        opt.step()
    assert float(loss()["loss"].detach()) < before["loss"]


def test_train_sample_is_deterministic_and_valid(template_store, tmp_path):
    from hoibench.baselines.sampler import sample
    from hoibench.baselines.trainer import train
    from hoibench.scoring.submission import validation_report
    run = tmp_path / "run"
    res = train("ejim", template_store, run, small_config(), log=None)
    assert res.card["baseline"] == "ejim"
    a = sample(run, template_store, tmp_path / "a", steps=2, limit=3, log=None)
    b = sample(run, template_store, tmp_path / "b", steps=2, limit=3, log=None)
    for f in sorted((a / "samples").iterdir()):
        assert f.read_bytes() == (b / "samples" / f.name).read_bytes()
    full = sample(run, template_store, tmp_path / "full", steps=1, log=None)
    assert validation_report(full, template_store).complete
    with pytest.raises(ValueError, match="not 'chainhoi'"):
        sample(run, template_store, tmp_path / "c", steps=1, baseline="chainhoi", log=None)


def test_cli_trains_ejim_with_zero_steps(template_store, tmp_path):
    r = subprocess.run([sys.executable, "-m", "hoibench.cli", "baseline", "train", "ejim", str(template_store),
                        "--out", str(tmp_path / "r"), "--steps", "0"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    r = subprocess.run([sys.executable, "-m", "hoibench.cli", "baseline", "show", str(tmp_path / "r")],
                       capture_output=True, text=True, timeout=120)
    assert r.stdout.startswith("ejim run")
