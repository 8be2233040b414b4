"""Padding invariance of every baseline network: a batch of clips zero-padded to a common length
gives each clip, on its valid frames, what the clip gives alone (to 1e-6), whatever the padded
frames hold."""
from __future__ import annotations

import pytest
import torch

from hoibench.baselines.chainhoi.config import preset as chainhoi_preset
from hoibench.baselines.chainhoi.model import ChainHOI, STGCN
from hoibench.baselines.ejim.config import preset as ejim_preset
from hoibench.baselines.ejim.model import EJIM

LENGTHS = (7, 4)          # two clips padded to L = 9 frames
L = 9
TOL = 1e-6


def _valid() -> torch.Tensor:
    return torch.arange(L)[None] < torch.tensor(LENGTHS)[:, None]


def _denoiser_case(model, cfg, minilm: bool):
    """Inputs for a joint-level denoiser: (x, t, keep, text tokens, text pad, object tokens)."""
    g = torch.Generator().manual_seed(1)
    x = torch.randn(2, L, 24, 12, generator=g)
    x[~_valid()] = 1e3 * torch.randn(int((~_valid()).sum()), 24, 12, generator=g)   # padding holds garbage
    if minilm:
        text_in = torch.randn(2, 5, 8, generator=g)
    else:
        text_in = torch.randint(1, 10, (2, 5), generator=g)
    pad = torch.tensor([[False] * 5, [False] * 3 + [True] * 2])
    with torch.no_grad():
        text = model.encode_text(text_in, pad)
        obj = model.encode_object(torch.randn(2, cfg.object_points, 3, generator=g))
    return x, torch.tensor([3, 700]), torch.tensor([True, False]), text, pad, obj


def _check_denoiser(model, cfg, minilm: bool) -> None:
    model.eval()
    x, t, keep, text, pad, obj = _denoiser_case(model, cfg, minilm)
    with torch.no_grad():
        batch = model(x, t, keep, text, pad, obj, _valid())
        assert batch[~_valid()].abs().max().item() == 0.0
        for i, n in enumerate(LENGTHS):
            alone = model(x[i:i + 1, :n], t[i:i + 1], keep[i:i + 1], text[i:i + 1], pad[i:i + 1], obj[i:i + 1])
            assert (alone - batch[i:i + 1, :n]).abs().max().item() < TOL, f"clip {i} ({n} frames)"


@pytest.mark.parametrize("name", ["tiny", "paper"])
def test_chainhoi_padded_batch_equals_the_unpadded_clips(name):
    cfg = chainhoi_preset(name).model
    if name == "paper":                                 # paper widths, two of the six blocks
        cfg = chainhoi_preset(name).replace(**{"model.blocks": 2, "model.object_points": 64,
                                               "model.object_knn": 8}).model
    torch.manual_seed(0)
    minilm = cfg.text_encoder == "minilm"
    model = ChainHOI(cfg, vocab=0 if minilm else 10, text_width=8 if minilm else 0)
    _check_denoiser(model, cfg, minilm)


def test_chainhoi_temporal_branches_read_no_padding():
    """The ST-GCN alone, on a padded frame whose features are not zero after the 1x1
    convolutions' biases (the bias of every 1x1 convolution is set large)."""
    torch.manual_seed(0)
    m = STGCN(12, 3, (1, 2), 0.0).eval()
    with torch.no_grad():
        for b in m.branches:
            conv = b[0] if isinstance(b, torch.nn.Sequential) else b
            conv.bias.fill_(-2.0)                       # GELU(-2) < 0: the max-pool sees a negative pad
    z = torch.randn(2, L, 24, 12)
    with torch.no_grad():
        out = m(z, _valid())
        for i, n in enumerate(LENGTHS):
            alone = m(z[i:i + 1, :n], torch.ones(1, n, dtype=torch.bool))
            assert (alone - out[i:i + 1, :n]).abs().max().item() < TOL


@pytest.mark.parametrize("name", ["tiny", "paper"])
def test_ejim_padded_batch_equals_the_unpadded_clips(name):
    over = {"model.object_points": 64, "model.object_knn": 8}
    if name == "paper":
        over.update({"model.modules": 2})
    cfg = ejim_preset(name).replace(**over).model
    torch.manual_seed(0)
    minilm = cfg.text_encoder == "minilm"
    model = EJIM(cfg, vocab=0 if minilm else 10, text_width=8 if minilm else 0)
    _check_denoiser(model, cfg, minilm)


# ------------------------------------------------------------------ CATMO
def _catmo_model():
    from hoibench.baselines.catmo.config import preset as catmo_preset
    from hoibench.baselines.catmo.model import CATMO
    cfg = catmo_preset("tiny").replace(**{"gpt.object_points": 64, "gpt.object_knn": 8, "gpt.object_tokens": 8})
    torch.manual_seed(0)
    return CATMO(cfg, vocab=10, text_width=0, with_object=True).eval()


def test_catmo_padded_batch_equals_the_unpadded_clips():
    """Every CATMO network that reads a padded batch in training: the VQ-VAEs (encoder and
    decoder), the movement encoder and its decoder, the object head and the GPT (PAD after END)."""
    from hoibench.baselines.catmo.gpt import interleave
    m = _catmo_model()
    u = m.cfg.vq.unit
    units = (5, 2)                                      # clips of 20 and 8 rows padded to 24
    W = 6 * u
    rows = torch.arange(W)[None] < torch.tensor(units)[:, None] * u
    vu = rows[:, u - 1::u]
    g = torch.Generator().manual_seed(2)
    x = torch.randn(2, W, 263, generator=g) * rows[..., None]
    c = (torch.rand(2, W, 22, generator=g) > 0.5).float() * rows[..., None]
    feat = torch.randn(2, m.cfg.text.width, generator=g)
    with torch.no_grad():
        vq = m.motion_vq(x, vu)["out"]
        cvq = m.contact_vq(c, vu)["out"]
        emb = m.movement(x, rows)
        rec = m.movement.deconv(m.movement.conv(x, rows), rows)
        head = m.object_head(vq, torch.sigmoid(cvq), feat, rows)
        target, tvalid = interleave(torch.randint(0, 8, (2, 6), generator=g), torch.randint(0, 8, (2, 6), generator=g),
                                    torch.tensor(units), m.cfg.vq.motion_codes, m.cfg.vq.contact_codes)
        cond = torch.randn(2, m.gpt.cond.in_features, generator=g)
        logits = m.gpt(cond, target[:, :-1])
        for i, n in enumerate(units):
            s, r = slice(i, i + 1), n * u
            one = torch.ones(1, r, dtype=torch.bool)
            alone_vq = m.motion_vq(x[s, :r])["out"]
            pairs = [(alone_vq, vq[s, :r]), (m.contact_vq(c[s, :r])["out"], cvq[s, :r]),
                     (m.movement(x[s, :r], one), emb[s]),
                     (m.movement.deconv(m.movement.conv(x[s, :r])), rec[s, :r]),
                     (m.object_head(alone_vq, torch.sigmoid(m.contact_vq(c[s, :r])["out"]), feat[s]), head[s, :r]),
                     (m.gpt(cond[s], target[s, :2 * n]), logits[s, :2 * n + 1])]
            for k, (alone, batch) in enumerate(pairs):
                assert (alone - batch).abs().max().item() < TOL, f"clip {i}, network {k}"
        assert int(tvalid.sum()) == 2 * sum(units) + 2
