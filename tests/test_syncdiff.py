"""SyncDiff baseline: frequency split, alignment loss, explicit synchronization (hand-computed
cases), padding invariance, seeded sampling and exact resume on a tiny multi-body store."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch

from hoibench.baselines.syncdiff import frequency as F
from hoibench.baselines.syncdiff.sync import alignment_terms, explicit_sync
from hoibench.bodies.multibody import Body, MultiBodyClip
from hoibench.core import geometry as geo
from hoibench.representations import multibody as R


# ----------------------------------------------------------------------------- frequency split
def test_frequency_split_is_exact_on_known_sinusoids():
    n = 64
    t = torch.arange(n, dtype=torch.float64)[:, None]
    w = 2 * math.pi * t / n
    dc, k2, k5, k20 = 0.7, 1.5 * torch.cos(2 * w), -0.8 * torch.sin(5 * w), 0.3 * torch.cos(20 * w)
    x = torch.cat([dc + k2 + k5 + k20, 2 * k5 - k2], 1)                  # two columns
    low, coef = F.split(x, low=3, cutoff=16)
    high = F.high_frames(coef, n, 3)
    assert coef.shape == (26, 2)
    torch.testing.assert_close(low, torch.cat([dc + k2, -k2], 1), atol=1e-12, rtol=0)
    torch.testing.assert_close(high, torch.cat([k5, 2 * k5], 1), atol=1e-12, rtol=0)
    # low + high is the clipped signal: the k = 20 component (above the cutoff) is gone
    torch.testing.assert_close(low + high, x - torch.cat([k20, torch.zeros_like(k20)], 1), atol=1e-12, rtol=0)
    # k = 5 is the second high frequency (k = 4, 5, ...): its sine coefficient sits in row 3
    assert coef[3, 0].item() == pytest.approx(-0.8, abs=1e-12) and coef[3, 1].item() == pytest.approx(-1.6, abs=1e-12)
    assert float(coef.abs().sum()) == pytest.approx(2.4, abs=1e-10)


def test_frequency_limits_are_clamped_for_short_clips():
    n = 9                                                         # usable k <= 4
    x = torch.randn(n, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(0))
    low, coef = F.split(x, low=3, cutoff=16)
    assert coef[2:].abs().max() == 0                              # only k = 4 is usable above low
    t = torch.arange(n, dtype=torch.float64)[:, None]
    x4 = x - x.mean(0) - sum(F.synthesize(F.analyze(x, k - 1, k), n, k - 1) for k in (1, 2, 3, 4))
    # what is left of a 9-frame signal after k <= 4 is nothing (9 = 1 + 2 * 4 real degrees of freedom)
    assert float(x4.abs().max()) < 1e-12 and t.shape[0] == n
    torch.testing.assert_close(low + F.high_frames(coef, n, 3), x, atol=1e-12, rtol=0)


# ----------------------------------------------------------------------------- a small scene
def _rot(axis, angle):
    return np.asarray(geo.axis_angle_to_matrix(np.asarray(axis, float)[None] * np.asarray(angle)[:, None]))


def _scene(T=12) -> MultiBodyClip:
    s = np.linspace(0, 1, T)
    a = Body("plate", "object", np.stack([s, 0.1 * s, 0 * s], 1), _rot([0, 1, 0], 0.5 * s), None, "plate")
    b = Body("brush", "object", np.stack([0.2 + s, 0.1 + 0.05 * np.sin(6 * s), 0.1 * s], 1),
             _rot([1, 0, 0], 0.8 * s + 0.1), None, "brush")
    rng = np.random.default_rng(0)
    joints = rng.normal(0, 0.05, (1, 21, 3)) + np.stack([0.1 * s, 0.3 + 0 * s, 0.2 * s], 1)[:, None]
    h = Body("hand", "hand", joints[:, 0].copy(), None, joints, None, "right")
    return MultiBodyClip("scene", "test", "s", 20.0, [h, a, b])


def test_alignment_loss_is_zero_when_consistent_and_exact_for_a_known_offset():
    clip = _scene()
    x, blocks = R.encode(clip)
    x = torch.from_numpy(x)
    ones, frames = torch.ones(x.shape[1], dtype=torch.float64), torch.ones(x.shape[0], dtype=torch.bool)
    s, n = alignment_terms(x, blocks, ones, frames)
    assert float(s) < 1e-20 and int(n) == x.shape[0] * (63 + 7 + 63 + 7)
    # move the brush's individual translation by delta: edges plate->brush (|d|^2), brush->hand
    # (21 joints x |d|^2) and brush->plate (|d|^2) change, 23 |d|^2 per frame over 140 columns
    delta = torch.tensor([0.03, -0.04, 0.12], dtype=torch.float64)
    brush = next(b for b in blocks if b.body == "brush" and b.ref is None)
    y = x.clone()
    y[:, brush.start:brush.start + 3] += delta
    s, n = alignment_terms(y, blocks, ones, frames)
    assert float(s / n) == pytest.approx(23 * float(delta @ delta) / 140, rel=1e-9)
    # a delay of d frames of the brush grows the loss with d
    losses = []
    for d in (0, 1, 2, 4):
        y = x.clone()
        y[d:, brush.columns] = x[:len(x) - d, brush.columns]
        s, n = alignment_terms(y, blocks, ones, frames)
        losses.append(float(s / n))
    assert losses[0] < 1e-20 and losses[1] < losses[2] < losses[3]


def _rigid(name, t):
    T = len(t)
    return Body(name, "object", np.asarray(t, float), np.repeat(np.eye(3)[None], T, 0), None, name)


def test_explicit_sync_keeps_consistent_predictions_and_pulls_a_desynchronized_pair():
    x, blocks = R.encode(_scene())
    x = torch.from_numpy(x)
    out, gain = explicit_sync(x, blocks, 1.0)
    torch.testing.assert_close(out, x, atol=1e-9, rtol=0)
    # gain 1 + w n: the hand has 2 implied predictions, each object 1, each relative block 1
    assert gain[:63].tolist() == [3.0] * 63 and gain[63:].tolist() == [2.0] * (len(gain) - 63)
    # two objects, identity rotations: A at 0, B at 1 (x), but B|A says 1.5 (A|B is consistent, -1)
    clip = MultiBodyClip("pair", "test", "s", 20.0, [_rigid("A", [[0, 0, 0]]), _rigid("B", [[1, 0, 0]])])
    x, blocks = R.encode(clip)
    ba = next(b for b in blocks if b.body == "B" and b.ref == "A")
    x[0, ba.start] = 1.5
    for w, want_b in ((1.0, 1.25), (0.5, (1 + 0.5 * 1.5) / 1.5)):
        out, gain = explicit_sync(torch.from_numpy(x), blocks, w)
        out = out[0].numpy()
        assert out[7] == pytest.approx(want_b, abs=1e-12)                        # t_B: (t_B + w (t_A + r)) / (1 + w)
        assert out[0] == pytest.approx(0.0, abs=1e-12)                           # t_A: B says A is at 1 - 1 = 0
        assert out[ba.start] == pytest.approx((1.5 + w * 1.0) / (1 + w), abs=1e-12)   # B|A toward t_B - t_A = 1
        assert out[ba.start + 3:ba.start + 7].tolist() == [1.0, 0.0, 0.0, 0.0]
        assert gain.tolist() == [1 + w] * len(gain)
    out, _ = explicit_sync(torch.from_numpy(x), blocks, 0.0)
    assert np.array_equal(out.numpy(), x)


# ----------------------------------------------------------------------------- the model
def _tiny_cfg():
    from hoibench.baselines.syncdiff.config import preset
    return preset("tiny").replace(**{"model.latent": 16, "model.layers": 1, "model.heads": 2, "model.cond_width": 8,
                                     "model.time_width": 16, "model.bps_points": 16, "model.surface_points": 64,
                                     "train.batch_size": 4, "train.steps": 3, "train.log_every": 1,
                                     "train.checkpoint_every": 2, "diffusion.ddim_steps": 4, "syncdiff.sync_every": 2})


@pytest.mark.parametrize("freq_position, groups", [("index", 1), ("rate", 1), ("rate", 3)])
def test_padded_batch_gives_each_clip_what_it_gets_alone(freq_position, groups):
    from hoibench.baselines.syncdiff.trainer import build_model
    cfg = _tiny_cfg().replace(**{"syncdiff.freq_position": freq_position, "syncdiff.high_groups": groups})
    model = build_model(cfg, 10, 6, 0, 1, 1, seed=0).eval()
    g = torch.Generator().manual_seed(1)
    lens, widths = (40, 28), (10, 7)
    xs = [torch.randn(n, 10, generator=g) * (torch.arange(10) < w) for n, w in zip(lens, widths)]
    conds = torch.randn(2, model.cond_dim, generator=g)
    t = torch.tensor([500, 20])
    T = max(lens)
    xb = torch.zeros(2, T, 10)
    frames = torch.zeros(2, T, dtype=torch.bool)
    cols = torch.stack([(torch.arange(10) < w).float() for w in widths])
    for b, x in enumerate(xs):
        xb[b, :len(x)], frames[b, :len(x)] = x, True
    with torch.no_grad():
        both = model(xb, t, frames, cols, conds)["x0"]
        for b, x in enumerate(xs):
            alone = model(x[None], t[b:b + 1], torch.ones(1, len(x), dtype=torch.bool), cols[b:b + 1], conds[b:b + 1])
            torch.testing.assert_close(both[b, :len(x)], alone["x0"][0], atol=2e-5, rtol=1e-4)
            assert both[b, len(x):].abs().sum() == 0 and both[b, :, widths[b]:].abs().sum() == 0


def test_rate_positions_give_one_stroke_frequency_one_code_in_every_clip_length():
    from hoibench.baselines.syncdiff.trainer import build_model
    model = build_model(_tiny_cfg().replace(**{"syncdiff.freq_position": "rate"}), 10, 6, 0, 1, 1, seed=0)
    low = model.low
    # row 2 j (cos) / 2 j + 1 (sin) carries k = low + 1 + j; k = 6 in 60 frames and k = 12 in 120
    # frames are the same rate (0.1 cycles per frame), one code; k = 6 in 120 frames is not
    pos = model.frequency_positions(torch.tensor([60, 120]))
    j60, j120 = 6 - low - 1, 12 - low - 1
    torch.testing.assert_close(pos[0, 2 * j60], pos[1, 2 * j120])
    torch.testing.assert_close(pos[0, 2 * j60 + 1], pos[1, 2 * j120 + 1])
    assert (pos[0, 2 * j60] - pos[1, 2 * j60]).abs().max() > 0.1
    with pytest.raises(ValueError, match="freq_position"):
        _tiny_cfg().replace(**{"syncdiff.freq_position": "hz"})


# ----------------------------------------------------------------------------- train, resume, sample
@pytest.fixture(scope="module")
def store(tmp_path_factory):
    from hoibench.datasets import multibody as mbl
    from hoibench.datasets import synthetic_multibody as syn
    from hoibench.datasets.store import PrepareConfig, prepare
    base = tmp_path_factory.mktemp("syncdiff")
    mbl.write_synthetic_layout(base / "raw", 8, seed=0)      # 2 test clips
    cfg = PrepareConfig("multibody-synthetic", fps=syn.FPS)
    prepare(mbl.prepare_jobs(base / "raw", None, base / "data", cfg), base / "data", cfg)
    return base


def test_resume_gives_the_same_checkpoint_and_seeded_sampling_is_byte_identical(store, capsys):
    from hoibench.baselines.sampler import sample
    from hoibench.baselines.trainer import train
    from hoibench.scoring.validate import validate
    cfg = _tiny_cfg()
    full = train("syncdiff", store / "data", store / "run_full", cfg, log=None)
    part = train("syncdiff", store / "data", store / "run_part", cfg, stop_after=1, log=None)
    assert part.checkpoint_id == "" and (store / "run_part" / "checkpoint" / "last.pt").exists()
    done = train("syncdiff", store / "data", store / "run_part", cfg, log=None)
    assert done.resumed_from == 1 and done.checkpoint_id == full.checkpoint_id
    from hoibench.baselines.commands import main_show
    main_show(store / "run_full")
    shown = capsys.readouterr().out
    assert 'freq_position "rate"' in shown and "decompose true" in shown and "high_groups 1" in shown
    subs = [sample(store / "run_full", store / "data", store / f"sub{i}", samples=2, seed=7, limit=2, log=None)
            for i in range(2)]
    for name in sorted(p.name for p in (subs[0] / "samples").iterdir()):
        assert (subs[0] / "samples" / name).read_bytes() == (subs[1] / "samples" / name).read_bytes()
    other = sample(store / "run_full", store / "data", store / "sub_other", samples=2, seed=8, limit=2, log=None)
    name = sorted((other / "samples").iterdir())[0].name
    assert (other / "samples" / name).read_bytes() != (subs[0] / "samples" / name).read_bytes()
    # the store's 2 test clips, K = 2: every structural check passes (a 3-step model's bodies may
    # still move faster than the plausibility limit)
    assert [p for p in validate(subs[0], store / "data") if "implausible" not in p.message] == []
    # explicit synchronization acts at sampling only: switched off there, the samples change
    nosync = sample(store / "run_full", store / "data", store / "sub_nosync", samples=2, seed=7, limit=1, log=None,
                    inference={"syncdiff.explicit_sync": False})
    assert (nosync / "samples" / name).read_bytes() != (subs[0] / "samples" / name).read_bytes()
    assert json.loads((nosync / "submission.json").read_text())["source"]["explicit_sync"] is False
    with pytest.raises(ValueError, match="not an inference-time setting"):
        sample(store / "run_full", store / "data", store / "sub_x", limit=1, log=None,
               inference={"syncdiff.decompose": False})
