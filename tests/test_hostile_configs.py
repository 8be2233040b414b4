"""Config values in re-signed cards (an id is a hash, not a signature): every architecture
field of evaluator and baseline configs is range-checked naming the field, and the parameter
count is derived from the config (or measured on torch's ``meta`` device) and refused before
anything is allocated."""
from __future__ import annotations

import pytest

from hoibench.evaluator.config import MAX_PARAMETER_FACTOR, EvaluatorConfig, ModelConfig, TrainConfig, preset


@pytest.mark.parametrize("field,value", [("layers", 100_000), ("width", 1_048_576), ("heads", 0), ("max_frames", -1),
                                         ("text_max_tokens", 10 ** 8), ("text_max_tokens", 64.0), ("ff_dim", 0),
                                         ("embed_dim", 1 << 20), ("dropout", 1.0), ("init_temperature", 0.0)])
def test_evaluator_model_fields_are_range_checked_naming_the_field(field, value):
    with pytest.raises(ValueError, match=rf"model\.{field}"):
        ModelConfig(**{field: value})


@pytest.mark.parametrize("field,value", [("epochs", 0), ("batch_size", 1), ("lr", 0.0), ("threads", -1),
                                         ("text_finetune_layers", 1000)])
def test_evaluator_train_fields_are_range_checked(field, value):
    with pytest.raises(ValueError, match=rf"train\.{field}"):
        TrainConfig(**{field: value})


def test_evaluator_card_config_out_of_range_is_refused_from_the_card_dict():
    d = preset("tiny").to_dict()
    d["model"]["layers"] = 100_000
    with pytest.raises(ValueError, match=r"model\.layers: expected an integer in \[1, 32\], got 100000"):
        EvaluatorConfig.from_dict(d)


def test_evaluator_parameter_count_from_the_config_matches_the_model_and_is_bounded():
    torch = pytest.importorskip("torch")
    from hoibench.evaluator.model import MotionEncoder
    for variant in ("human", "hoi"):
        cfg = preset("tiny", variant).model
        assert cfg.motion_parameters() == sum(p.numel() for p in MotionEncoder(cfg).parameters())
    paper = ModelConfig()
    assert ModelConfig(width=512, ff_dim=2048).motion_parameters() < MAX_PARAMETER_FACTOR * paper.motion_parameters()
    with pytest.raises(ValueError, match="refused before allocating"):   # each field within range, the product not
        ModelConfig(width=2048, layers=32, heads=8, ff_dim=8192)
    del torch


def test_baseline_fields_are_bounded_naming_the_field():
    from hoibench.baselines.registry import get_spec
    for name, field in (("chainhoi", "blocks"), ("chainhoi", "d_model"), ("ejim", "modules"), ("ejim", "d_model")):
        cfg = get_spec(name).preset("tiny")
        for value in (100_000, 16_384):
            with pytest.raises(ValueError, match=rf"model\.{field}: expected an integer in \[1, \d+\]"):
                cfg.replace(**{f"model.{field}": value})
    with pytest.raises(ValueError, match=r"train\.max_frames"):
        get_spec("ejim").preset("tiny").replace(**{"train.max_frames": 1 << 20})
    from hoibench.baselines.catmo.config import preset as catmo_preset
    with pytest.raises(ValueError, match=r"gpt\.layers"):
        catmo_preset("tiny").replace(**{"gpt.layers": 100_000})


def test_baseline_parameter_count_is_measured_without_allocating_and_refused():
    pytest.importorskip("torch")
    from hoibench.baselines.config import check_parameter_count
    from hoibench.baselines.registry import get_spec
    spec = get_spec("ejim")
    build = lambda c: spec.build_model(c, 50, 64)  # noqa: E731
    paper = spec.preset("paper")
    tiny = spec.preset("tiny")
    assert 0 < check_parameter_count(build, tiny, paper, "config") < 2 * 8_740_888    # EJIM's paper size
    big = tiny.replace(**{"model.d_model": 2048})      # within the field's bound, 25 x the paper size
    with pytest.raises(ValueError, match=r"card.json: config: .*parameters.*model\.d_model = 2048"):
        check_parameter_count(build, big, paper, "card.json: config")
