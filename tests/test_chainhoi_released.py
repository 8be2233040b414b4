"""ChainHOI ``released``: the public code's denoiser (parameter count, outputs with the same
weights, graph), and hoibench's padding fix.

Reference values (``tests/data/chainhoi_released_reference.npz``, see tests/data/README.md):
the public denoiser ``ChainHOI`` of ``Huanggh531/ChainHOI`` commit 4990160
(``src/models/nets/chainhoi.py``) instantiated outside the project with the BEHAVE settings of
``scripts/train_behave.sh`` (45,979,565 parameters, ``sum(p.numel() for p in
model.parameters())``) and with a tiny width (736,821), weights from :func:`chainhoi_seeded_weights.fill`, inputs
from ``numpy.random.RandomState(7)``, eval mode.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from chainhoi_seeded_weights import fill

from hoibench.baselines.chainhoi.released import ReleasedDenoiser, released_partitions
from hoibench.baselines.chainhoi.released_config import ReleasedConfig

REF = Path(__file__).parent / "data" / "chainhoi_released_reference.npz"
TINY = dict(blocks=3, base_dim=8, up_blocks=(2,), model_dim=8, heads=2, decoder_layers=2, gn_groups=2, time_dim=16)
PUBLIC_PARAMS = {"full": 45_979_565, "tiny": 736_821}


@pytest.fixture(scope="module")
def ref():
    with np.load(REF) as z:
        return dict(z)


def inputs(ref: dict, tag: str):
    rs = np.random.RandomState(7)
    B, L = ref[f"{tag}_valid"].shape
    x = rs.standard_normal((B, L, 24, 12)).astype(np.float32)
    text = rs.standard_normal((B, 5, 512)).astype(np.float32)
    obj = rs.standard_normal((B, 16, 512)).astype(np.float32)
    f = torch.from_numpy
    return f(x), f(ref[f"{tag}_valid"]), f(ref[f"{tag}_t"]), f(text), f(ref[f"{tag}_text_valid"]), f(obj)


def model(tag: str, padding: str = "reference") -> ReleasedDenoiser:
    cfg = ReleasedConfig(padding=padding, **(TINY if tag == "tiny" else {}))
    m = ReleasedDenoiser(cfg).eval()
    fill(m)
    return m


def n_params(m: torch.nn.Module) -> int:
    return sum(p.numel() for p in m.parameters())


@pytest.fixture(scope="module")
def full():
    return ReleasedDenoiser(ReleasedConfig())


def test_parameter_count_equals_public_network(full):
    assert n_params(full) == PUBLIC_PARAMS["full"]
    assert n_params(ReleasedDenoiser(ReleasedConfig(**TINY))) == PUBLIC_PARAMS["tiny"]


def test_same_weights_same_output_as_public_code(ref):
    """The tiny-width variant (the full-size values, ``full_out``, are checked by
    benchmarks/chainhoi_released_reference.py: 46 M seeded weights take 10 s to draw)."""
    with torch.no_grad():
        out = model("tiny")(*inputs(ref, "tiny")).numpy()
    assert np.abs(out - ref["tiny_out"]).max() <= 1e-5


def test_masked_padding_equals_reference_on_an_unpadded_sequence(ref):
    x, valid, t, text, tv, obj = inputs(ref, "tiny")
    assert bool(valid[0].all()) and not bool(valid[1].all())
    with torch.no_grad():
        out = model("tiny", "masked")(x, valid, t, text, tv, obj).numpy()
    assert np.abs(out[0] - ref["tiny_out"][0]).max() <= 1e-5          # GroupNorm is per sample
    assert np.abs(out[1] - ref["tiny_out"][1]).max() > 1e-3           # the reference reads padded frames


def test_padded_batch_equals_unpadded_sequences(ref):
    """``padding="masked"``: each sequence's output does not depend on the batch's padding
    (padded frames hold arbitrary values); ``reference`` leaks (default initialisation)."""
    x, _, t, text, tv, obj = inputs(ref, "tiny")
    lengths = [6, 3]
    valid = torch.arange(6)[None] < torch.tensor(lengths)[:, None]
    x = x * 3.0 + 1.0                                                   # large garbage in the padded frames
    for padding in ("masked", "reference"):
        torch.manual_seed(0)
        m = ReleasedDenoiser(ReleasedConfig(padding=padding, **TINY)).eval()
        with torch.no_grad():
            batch = m(x, valid, t, text, tv, obj)
            same = []
            for b, n in enumerate(lengths):
                alone = m(x[b:b + 1, :n], valid[b:b + 1, :n], t[b:b + 1], text[b:b + 1], tv[b:b + 1], obj[b:b + 1])
                same.append(torch.allclose(batch[b, :n], alone[0], atol=1e-6))
        if padding == "masked":
            assert all(same)
            assert float(batch[1, 3:].abs().max()) == 0.0               # padded frames are zero
        else:
            assert same == [True, False]                                # the padded sequence changes


def test_adjacency_is_the_public_graph_with_released_direction(ref):
    A = released_partitions()
    np.testing.assert_allclose(A, ref["A_init"], atol=1e-7)
    # In (k = 1): a parent gathers (averages) its children: node 0 from 1, 2, 3; node 9 from 12, 13, 14
    np.testing.assert_allclose(A[1][:, 0][[1, 2, 3]], 1 / 3)
    np.testing.assert_allclose(A[1][:, 9][[12, 13, 14]], 1 / 3)
    assert A[1][0, 1] == 0.0                                          # a child does not gather its parent in "In"
    np.testing.assert_allclose(A[2][0, 1], 1.0)                       # ... it does in "Out"
    m = ReleasedDenoiser(ReleasedConfig(**TINY))
    assert all(b.gcn_block.gcn.A.requires_grad for b in m.blocks)     # learnable adjacency


def test_widths_double_at_blocks_two_and_four(full):
    m = full
    widths = [b.input_proj[0].out_channels for b in m.blocks]
    assert widths == [64, 128, 128, 256, 256, 256]
    kim = m.blocks[-1].joint_block
    assert (kim.proj_after_cross_att.in_features, kim.proj_after_cross_att.out_features) == (6 * 64, 24 * 256)
    assert [b.conv.dilation[0] for b in m.blocks[0].gcn_block.tcn.branches[:4].children() for b in [b[3]]] == \
        [1, 2, 3, 4]


def test_released_mask_is_additive_and_paper_mask_is_boolean():
    rel = ReleasedDenoiser(ReleasedConfig(**TINY)).blocks[0].joint_block.mask
    pap = ReleasedDenoiser(ReleasedConfig(mask="paper", **TINY)).blocks[0].joint_block.mask
    assert rel.dtype == torch.float32 and pap.dtype == torch.bool
    assert torch.equal(rel, pap.float())                              # +1 outside the chain, +0 inside
    assert ReleasedConfig().mask == "released"
