"""CATMO baseline: quantiser, EMA codebook and dead-code reset, interleaving, causal masking,
corruption, staged training and exact resume, deterministic sampling, submissions, CLI."""
from __future__ import annotations

import json
import shutil
import subprocess
import sys

import numpy as np
import pytest
import torch

from hoibench.baselines.catmo import data as CD
from hoibench.baselines.catmo.config import CatmoConfig, preset
from hoibench.baselines.catmo.gpt import IntertwinedGPT, corrupt, interleave
from hoibench.baselines.catmo.textmatch import matching_loss
from hoibench.baselines.catmo.trainer import STAGES, train
from hoibench.baselines.catmo.vqvae import VQVAE, EMAQuantizer
from hoibench.baselines.checkpoint import RunFolderError, verify_run


def small_config(**over) -> CatmoConfig:
    base = {"train.vq_steps": 3, "train.contact_steps": 2, "text.movement_ae_steps": 2, "text.match_steps": 2,
            "train.gpt_steps": 3, "object.steps": 2, "train.batch_size": 4, "train.checkpoint_every": 2,
            "train.log_every": 1, "vq.window": 16, "gpt.object_points": 64, "gpt.object_knn": 8,
            "gpt.object_tokens": 8, "vq.width": 16, "vq.code_dim": 16, "gpt.width": 32, "gpt.heads": 2,
            "gpt.layers": 2, "text.width": 16, "text.hidden": 32}
    base.update(over)
    return preset("tiny").replace(**base)


# ------------------------------------------------------------------ quantiser
def test_quantiser_picks_the_nearest_code_and_passes_the_gradient_straight_through():
    q = EMAQuantizer(5, 3, 0.99)
    q.codebook.copy_(torch.tensor([[0., 0, 0], [1, 0, 0], [0, 2, 0], [0, 0, -3], [5, 5, 5]]))
    q.initialised.fill_(True)
    q.eval()
    z = torch.tensor([[[0.9, 0.1, 0.0], [0.1, -0.1, -2.0], [4.0, 4.0, 6.0], [0.2, 0.9, 0.1]]], requires_grad=True)
    zq, idx, commit, perplexity = q(z)
    brute = ((z.detach()[0, :, None] - q.codebook[None]) ** 2).sum(-1).argmin(-1)
    assert idx[0].tolist() == brute.tolist() == [1, 3, 4, 0]
    assert torch.equal(zq.detach(), q.codebook[idx])
    w = torch.randn_like(z)
    (zq * w).sum().backward()
    assert torch.equal(z.grad, w)                           # d zq / d z = identity
    assert float(commit.detach()) == pytest.approx(float(((z.detach() - q.codebook[idx]) ** 2).mean()), rel=1e-6)
    # four tokens on four different codes: perplexity 4
    assert float(perplexity) == pytest.approx(4.0, rel=1e-6)


def test_ema_update_follows_the_formula_and_resets_dead_codes():
    mu = 0.9
    q = EMAQuantizer(3, 2, mu)
    q.codebook.copy_(torch.tensor([[0., 0], [10, 10], [-10, 0]]))
    q.ema_sum.copy_(q.codebook * torch.tensor([[4.], [2.], [1.05]]))
    q.ema_count.copy_(torch.tensor([4., 2., 1.05]))
    q.initialised.fill_(True)
    flat = torch.tensor([[1., 0], [0, 1], [10, 12]])
    idx = torch.tensor([0, 0, 1])
    q.update(flat, idx, torch.Generator().manual_seed(0))
    s0 = mu * torch.tensor([0., 0]) * 4 + (1 - mu) * torch.tensor([1., 1])
    n0 = mu * 4 + (1 - mu) * 2
    assert torch.allclose(q.codebook[0], s0 / n0)
    s1 = mu * torch.tensor([20., 20]) + (1 - mu) * torch.tensor([10., 12])
    n1 = mu * 2 + (1 - mu) * 1
    assert torch.allclose(q.codebook[1], s1 / n1)
    # code 2: count 0.9 * 1.05 = 0.945 < 1 -> reset to one of the batch vectors, statistics restarted
    assert any(torch.equal(q.codebook[2], v) for v in flat)
    assert float(q.ema_count[2]) == 1.0 and torch.equal(q.ema_sum[2], q.codebook[2])


def test_codebook_initialises_from_the_first_batch_and_the_vqvae_learns():
    torch.manual_seed(0)
    m = VQVAE(6, 16, 16, 8, 2, 1, 3, 0.9)
    x = torch.randn(8, 16, 6).cumsum(1) * 0.3
    opt = torch.optim.Adam(m.parameters(), 3e-3)
    g = torch.Generator().manual_seed(0)
    first = None
    for step in range(60):
        o = m(x, generator=g)
        loss = torch.nn.functional.smooth_l1_loss(o["out"], x) + 0.02 * o["commit"]
        first = float(loss.detach()) if first is None else first
        opt.zero_grad()
        loss.backward()
        if step == 0:                                       # the encoder learns through the quantiser
            assert m.encoder.net[0].weight.grad.abs().sum() > 0
        opt.step()
    assert bool(m.quantizer.initialised)
    assert float(loss) < 0.7 * first
    assert m.encode(x).shape == (8, 4) and m.decode(m.encode(x)).shape == x.shape


def test_padded_latents_reach_neither_the_decoder_nor_the_gradient():
    """Short clips are zero-padded to the window: their padded latents must not drift (they
    did, without bound, before they were masked) nor feed the decoder."""
    torch.manual_seed(0)
    m = VQVAE(5, 8, 16, 8, 2, 1, 3, 0.9)
    x = torch.randn(2, 16, 5)
    valid = torch.ones(2, 4, dtype=torch.bool)
    valid[0, 2:] = False                                    # clip 0: 8 valid rows of 16
    seen = {}

    def keep(mod, inp, out) -> None:
        out.retain_grad()
        seen["z"] = out
    hook = m.encoder.register_forward_hook(keep)
    out = m(x, valid, torch.Generator().manual_seed(0))["out"]
    out[0, :8].sum().backward()
    hook.remove()
    g = seen["z"].grad
    assert g[0, 2:].abs().max() == 0 and g[0, :2].abs().max() > 0
    m.eval()
    with torch.no_grad():
        zq = m.quantizer.lookup(m.encode(x))
        assert zq[0, 2:].abs().sum() > 0
        zq = m.quantizer.lookup(m.quantizer.indices(m.encoder(x, valid.repeat_interleave(4, 1))))
        zq[0, 2:] = 0
        out = m(x, valid)["out"]
        torch.testing.assert_close(out, m.decoder(zq, valid))
        assert out[0, 8:].abs().max() == 0                  # padded rows come back as zeros


# ------------------------------------------------------------------ intertwined GPT
def test_interleaving_order_end_and_padding():
    m = torch.tensor([[1, 2, 3], [4, 5, 6]])
    c = torch.tensor([[0, 1, 2], [3, 4, 0]])
    seq, valid = interleave(m, c, torch.tensor([3, 1]), motion_codes=10, contact_codes=5)
    END, PAD = 15, 16
    assert seq[0].tolist() == [1, 10, 2, 11, 3, 12, END]
    assert seq[1].tolist() == [4, 13, END, PAD, PAD, PAD, PAD]
    assert valid[1].tolist() == [True, True, True, False, False, False, False]


def test_a_motion_token_never_sees_its_own_contact_token():
    torch.manual_seed(0)
    Km, Kc = 12, 6
    gpt = IntertwinedGPT(Km, Kc, 8, 32, 2, 2, 2, 0.0, 6).eval()
    cond = torch.randn(1, 8)
    target, _ = interleave(torch.tensor([[3, 7, 1, 9]]), torch.tensor([[2, 0, 5, 1]]), torch.tensor([4]), Km, Kc)
    inp = target[:, :-1]                                    # [m1, c1, m2, c2, m3, c3, m4, c4]
    logits = gpt(cond, inp)                                 # position p predicts target p
    for i in range(4):
        c_pos = 2 * i + 1                                   # where c_i sits in the targets (and input index)
        changed = inp.clone()
        changed[0, c_pos] = Km + (int(inp[0, c_pos]) - Km + 1) % Kc
        new = gpt(cond, changed)
        # m_i (target 2i) and c_i (target 2i+1) are predicted without seeing c_i ...
        assert torch.equal(new[:, :c_pos + 1], logits[:, :c_pos + 1])
        # ... and m_{i+1} (target 2i+2) sees it
        assert not torch.allclose(new[:, c_pos + 1], logits[:, c_pos + 1])
    # c_i's prediction sees m_i
    changed = inp.clone()
    changed[0, 2] = (int(inp[0, 2]) + 1) % Km
    assert not torch.allclose(gpt(cond, changed)[:, 3], logits[:, 3])


@pytest.mark.parametrize("mode", ["token", "unit"])
def test_corruption_rate_modalities_and_pairing(mode):
    Km, Kc = 100_000, 50_000                                # large codebooks: a random draw ~never repeats a code
    B, U = 64, 50
    m = torch.randint(0, Km, (B, U))
    c = torch.randint(0, Kc, (B, U))
    seq, _ = interleave(m, c, torch.full((B,), U), Km, Kc)
    inp = seq[:, :-1]
    out = corrupt(inp, 0.3, Km, Kc, mode, torch.Generator().manual_seed(1))
    hit = out != inp
    assert abs(hit.float().mean().item() - 0.3) < 0.02
    assert (out[:, 0::2] < Km).all() and ((out[:, 1::2] >= Km) & (out[:, 1::2] < Km + Kc)).all()
    pairs_same = (hit[:, 0::2] == hit[:, 1::2]).float().mean().item()
    if mode == "unit":
        assert pairs_same > 0.999
    else:                                                   # independent draws agree 0.3^2 + 0.7^2 = 58% of the time
        assert abs(pairs_same - 0.58) < 0.03
    end = torch.tensor([[Km + Kc, Km + Kc + 1]])
    assert torch.equal(corrupt(end, 0.99, Km, Kc, mode, torch.Generator().manual_seed(0)), end)


def test_matching_loss_is_the_margin_contrastive_form():
    t = torch.tensor([[0., 0], [3, 4]])
    m = torch.tensor([[0., 1], [3, 4]])
    # positives: 1 and 0; negatives (offset 1): ||t0 - m1|| = 5, ||t1 - m0|| = sqrt(9 + 9)
    expected = (1 + 0) / 2 + (max(0, 10 - 5) + max(0, 10 - 18 ** 0.5)) / 2
    assert float(matching_loss(t, m, 10.0, 1)) == pytest.approx(expected)


def test_cached_incremental_passes_equal_the_full_forward():
    torch.manual_seed(0)
    gpt = IntertwinedGPT(9, 4, 5, 32, 3, 4, 2, 0.0, 6).eval()
    cond = torch.randn(2, 5)
    tokens = torch.tensor([[3, 10, 8, 9, 0, 12, 4], [1, 11, 2, 9, 7, 10, 5]])
    with torch.no_grad():
        full = gpt(cond, tokens)
        logits, cache = gpt.step(gpt.cond(cond)[:, None] + gpt.pos[:, :1], None)
        steps = [logits]
        for j in range(tokens.shape[1]):
            logits, cache = gpt.step(gpt.embed(tokens[:, j:j + 1]) + gpt.pos[:, j + 1:j + 2], cache)
            steps.append(logits)
        # a chunk of several positions at once (causal inside the chunk) gives the same
        half, cache = gpt.step(gpt.cond(cond)[:, None] + gpt.pos[:, :1], None)
        rest, _ = gpt.step(gpt.embed(tokens) + gpt.pos[:, 1:tokens.shape[1] + 1], cache)
    torch.testing.assert_close(torch.cat(steps, 1), full, atol=1e-5, rtol=1e-5)
    torch.testing.assert_close(torch.cat([half, rest], 1), full, atol=1e-5, rtol=1e-5)


def test_sampling_draws_only_legal_codes_and_is_seeded():
    torch.manual_seed(0)
    gpt = IntertwinedGPT(7, 3, 4, 16, 1, 2, 2, 0.0, 5).eval()
    cond = torch.randn(3, 4)
    a = gpt.sample(cond, 5, torch.Generator().manual_seed(4))
    b = gpt.sample(cond, 5, torch.Generator().manual_seed(4))
    c = gpt.sample(cond, 5, torch.Generator().manual_seed(5))
    assert torch.equal(a[0], b[0]) and torch.equal(a[1], b[1])
    assert not (torch.equal(a[0], c[0]) and torch.equal(a[1], c[1]))
    assert a[0].shape == (3, 5) and (a[0] < 7).all() and ((a[1] >= 0) & (a[1] < 3)).all()
    with pytest.raises(ValueError, match="units"):
        gpt.sample(cond, 0, torch.Generator())


def test_sampling_past_the_positional_table_slides_a_window_of_whole_units():
    """12 units from a GPT whose table holds 5: the draws equal those of a reference that runs
    the full forward over [condition; the window's tokens] for every draw, the window dropping
    its oldest 2 units (hop = max_units // 2) whenever the next input would pass the table;
    the first 5 units are those of a 5-unit sample."""
    torch.manual_seed(0)
    gpt = IntertwinedGPT(7, 3, 4, 16, 2, 2, 2, 0.0, 5).eval()
    cond = torch.randn(2, 4)
    m, c = gpt.sample(cond, 12, torch.Generator().manual_seed(9))
    g = torch.Generator().manual_seed(9)
    tokens, start = [], 0
    with torch.no_grad():
        for j in range(24):
            while j - start > 10:                       # inputs at positions 1..j-start, table 0..10
                start += 4
            window = torch.stack(tokens[start:], 1) if j > start else torch.zeros(2, 0, dtype=torch.long)
            logits = gpt(cond, window)[:, -1]
            lo, hi = (0, 7) if j % 2 == 0 else (7, 10)
            tokens.append(torch.multinomial(torch.softmax(logits[:, lo:hi], -1), 1, generator=g)[:, 0] + lo)
    ref = torch.stack(tokens, 1)
    assert torch.equal(m, ref[:, 0::2]) and torch.equal(c, ref[:, 1::2] - 7)
    m5, c5 = gpt.sample(cond, 5, torch.Generator().manual_seed(9))
    assert torch.equal(m[:, :5], m5) and torch.equal(c[:, :5], c5)


# ------------------------------------------------------------------ config
def test_config_round_trips_and_names_bad_fields():
    cfg = preset("tiny")
    assert CatmoConfig.from_dict(json.loads(json.dumps(cfg.to_dict()))) == cfg
    assert preset("paper").vq.motion_codes == 512 and preset("paper").vq.unit == 4
    with pytest.raises(ValueError, match="gpt.corruption"):
        cfg.replace(**{"gpt.corruption": "frame"})
    with pytest.raises(ValueError, match="unknown field"):
        cfg.replace(**{"gpt.nope": 1})
    with pytest.raises(ValueError, match="vq.window"):
        cfg.replace(**{"vq.window": 30})


# ------------------------------------------------------------------ training, resume, sampling
@pytest.fixture(scope="module")
def tiny_run(template_store, tmp_path_factory):
    out = tmp_path_factory.mktemp("catmo") / "run"
    res = train(template_store, out, small_config(), log=None)
    return out, res


def test_run_folder_records_every_stage_and_the_vq_report(tiny_run):
    out, res = tiny_run
    card, _ = verify_run(out, "catmo")
    assert card["checkpoint_id"] == res.checkpoint_id and not (out / "checkpoint").exists()
    assert [s for s in STAGES if card["curves"].get(s)] == list(STAGES)
    assert card["dataset"]["with_object"] is True and card["dataset"]["store_hml263_stats_sha256"]
    for split in ("train", "test"):
        rep = card["vq"][split]
        assert rep["motion"]["mpjpe_m"] > 0 and 1 <= rep["motion"]["perplexity"] <= rep["motion"]["codebook"]
        assert 0 <= rep["contact"]["accuracy"] <= 1 and rep["motion"]["codes_used"] >= 1


def test_resume_gives_the_uninterrupted_run(template_store, tiny_run, tmp_path):
    out, res = tiny_run
    for stop in (1, 4, 9):                                  # inside motion_vq, at a stage boundary, inside the GPT
        part = tmp_path / f"resumed{stop}"
        train(template_store, part, small_config(), stop_after=stop, log=None)
        assert (part / "checkpoint" / "last.pt").exists() and not (part / "card.json").exists()
        again = train(template_store, part, small_config(), log=None)
        assert again.checkpoint_id == res.checkpoint_id, stop
    assert train(template_store, part, small_config(), log=None).already_trained
    with pytest.raises(RunFolderError, match="gpt.layers"):
        train(template_store, part, small_config(**{"gpt.layers": 1}), log=None)


def test_sampling_is_deterministic_and_independent_of_other_clips(tiny_run, template_store, tmp_path):
    from hoibench.baselines.catmo.sampler import LoadedCatmo
    from hoibench.baselines.sampler import sample
    from hoibench.datasets.store import Store
    run = LoadedCatmo(tiny_run[0])
    st = Store(template_store)
    clip = st.load(st.clip_ids("test")[0])
    from hoibench.baselines import joint_data as D
    v, f = st.object_template(str(clip["object_name"]))
    pts = D.surface_points(v, f, run.object_points, "x")
    a = run.generate("a person lifts the box", pts, 23, 3, (0, "x"))
    b = run.generate("a person lifts the box", pts, 23, 3, (0, "x"))
    c = run.generate("a person lifts the box", pts, 23, 3, (1, "x"))
    for k in a:
        np.testing.assert_array_equal(a[k], b[k])
    assert not np.array_equal(a["joints"], c["joints"])
    assert a["joints"].shape == (3, 23, 22, 3) and a["contacts"].shape == (3, 23, 22) and a["contacts"].dtype == bool
    assert a["obj_rot"].shape == (3, 23, 3, 3) and a["obj_trans"].shape == (3, 23, 3)
    assert np.allclose(a["obj_rot"] @ np.swapaxes(a["obj_rot"], -1, -2), np.eye(3), atol=1e-4)
    one = sample(tiny_run[0], template_store, tmp_path / "one", limit=1, log=None)
    two = sample(tiny_run[0], template_store, tmp_path / "two", limit=3, log=None)
    first = st.clip_ids("test")[0]
    assert (one / "samples" / f"{first}.npz").read_bytes() == (two / "samples" / f"{first}.npz").read_bytes()


def test_a_clip_longer_than_the_gpt_table_is_generated(tiny_run, template_store):
    from hoibench.baselines.catmo.sampler import LoadedCatmo
    run = LoadedCatmo(tiny_run[0])
    assert run.config.gpt.max_units * run.config.vq.unit < 300
    pts = np.random.default_rng(0).normal(size=(run.object_points, 3)).astype(np.float32) * 0.2
    out = run.generate("a person lifts the box", pts, 300, 1, (0, "long"))
    assert out["joints"].shape == (1, 300, 22, 3) and np.isfinite(out["joints"]).all()
    assert out["obj_trans"].shape == (1, 300, 3) and np.isfinite(out["obj_trans"]).all()
    short = run.generate("a person lifts the box", pts, 200, 1, (0, "long"))
    np.testing.assert_allclose(out["joints"][:, :150], short["joints"][:, :150], atol=1e-4)


def test_sample_writes_a_valid_submission_and_refuses_another_store(tiny_run, template_store, tmp_path):
    from hoibench.baselines.sampler import StoreMismatch, sample
    from hoibench.scoring.submission import validation_report
    sub = sample(tiny_run[0], template_store, tmp_path / "sub", samples=2, log=None)
    rep = validation_report(sub, template_store)
    assert rep.complete, [p for p in rep.problems][:3]
    meta = json.loads((sub / "submission.json").read_text())
    assert meta["source"]["baseline"] == "catmo" and meta["source"]["temperature"] == 1.0
    other = tmp_path / "other"
    shutil.copytree(template_store, other)
    with np.load(other / "stats" / "hml263.npz") as z:
        arrays = {k: z[k] for k in z.files}
    arrays["std"] = arrays["std"] * 2
    np.savez(other / "stats" / "hml263.npz", **arrays)
    with pytest.raises(StoreMismatch, match="hml263"):
        sample(tiny_run[0], other, tmp_path / "sub2", log=None)
    with pytest.raises(ValueError, match="--temperature"):
        sample(tiny_run[0], template_store, tmp_path / "sub3", guidance=2.0, log=None)


def test_items_pair_each_motion_row_with_its_contacts_and_object(template_store):
    from hoibench.datasets.store import Store
    st = Store(template_store)
    data = CD.read_data(st, "train", 32)
    it = data.items[0]
    clip = st.load(it.clip_id)
    L = clip["hml263"].shape[0]
    np.testing.assert_allclose(it.motion * data.std + data.mean, clip["hml263"], atol=1e-5)
    np.testing.assert_array_equal(it.contacts, clip["contacts"][:L].astype(np.float32))
    np.testing.assert_allclose(it.obj * data.obj_std + data.obj_mean, clip["hoi269"][:, 263:], atol=1e-5)


def test_training_and_sampling_import_only_torch_numpy_safetensors(tiny_run, template_store, tmp_path):
    code = f"""
import sys
for m in ("scipy", "open3d", "pyvista", "pymeshlab", "trimesh", "transformers", "sentence_transformers",
          "matplotlib", "pandas", "smplx"):
    sys.modules[m] = None
from hoibench.baselines.sampler import sample
from hoibench.baselines.trainer import train
from hoibench.baselines.catmo.config import preset
cfg = preset("tiny").replace(**{{k: 1 for k in ("train.vq_steps", "train.contact_steps", "text.movement_ae_steps",
                                                "text.match_steps", "train.gpt_steps", "object.steps")}})
train("catmo", {str(template_store)!r}, {str(tmp_path / 'r')!r}, cfg, log=None)
sample({str(tiny_run[0])!r}, {str(template_store)!r}, {str(tmp_path / 's')!r}, limit=1, log=None)
print("ok")
"""
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0 and "ok" in res.stdout, res.stderr[-2000:]


@pytest.mark.parametrize("args, needle", [
    (["train", "catmo", "{data}", "--out", "{tmp}/r", "--steps", "5"], "trains in stages"),
    (["train", "catmo", "{data}", "--out", "{tmp}/r", "--set", "gpt.nope=1"], "unknown field 'nope'"),
    (["train", "catmo", "{data}", "--out", "{tmp}/r", "--set", "lr=1"], "SECTION.FIELD=VALUE"),
    (["train", "catmo", "{data}", "--out", "{tmp}/r", "--set", "gpt.corrupt_rate=1.5"], "gpt.corrupt_rate"),
    (["train", "catmo", "{data}", "--out", "{tmp}/r", "--mask", "paper"], "--mask"),
    (["sample", "catmo", "{run}", "--data", "{data}", "--out", "{tmp}/s", "--guidance", "2"], "--temperature"),
    (["sample", "catmo", "{run}", "--data", "{data}", "--out", "{tmp}/s", "--temperature", "0"], "--temperature"),
])
def test_cli_refuses_bad_options_in_one_line(template_store, tiny_run, tmp_path, args, needle):
    args = [a.format(data=template_store, tmp=tmp_path, run=tiny_run[0]) for a in args]
    r = subprocess.run([sys.executable, "-m", "hoibench.cli", "baseline"] + args, capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], r.stderr


def test_cli_trains_the_untrained_model_and_shows_it(template_store, tmp_path):
    exe = [sys.executable, "-m", "hoibench.cli", "baseline"]
    run = tmp_path / "run0"
    r = subprocess.run(exe + ["train", "catmo", str(template_store), "--out", str(run), "--steps", "0"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    r = subprocess.run(exe + ["show", str(run)], capture_output=True, text=True, timeout=120)
    assert "catmo run" in r.stdout and "0 steps" in r.stdout and "VQ on test" in r.stdout, r.stdout
