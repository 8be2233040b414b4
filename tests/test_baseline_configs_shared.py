"""The config sections the baselines share (:mod:`hoibench.baselines.config`):
ChainHOI's and EJIM's model configs derive their conditioning fields from
``ConditioningConfig``, every ``train`` section its optimiser fields from ``TrainLoopConfig``.
A dataclass lists a base's fields first; what a run card records and how a bad config is
reported must not see that. The expected values here were recorded from the config modules
as they were before the shared classes (commit de782fd), by a scratch script that was not
committed; the presets' serialised dicts are pinned in test_baseline_config_presets.py."""
from __future__ import annotations

import re

import pytest

from hoibench.baselines.catmo.config import CatmoTrainConfig
from hoibench.baselines.config import (ARCH_LIMITS, CONDITIONING_INTS, ConditioningConfig, TrainConfig, TrainLoopConfig,
                                       check_parameter_count, sizing)
from hoibench.baselines.registry import SPECS


def test_the_shared_sections_hold_the_fields_and_defaults_each_config_had():
    for baseline in ("chainhoi", "ejim"):
        model = SPECS[baseline].model_config()
        assert isinstance(model, ConditioningConfig)
        assert {k: getattr(model, k) for k in ("dropout", "object_points", "object_tokens", "object_knn",
                                               "text_encoder", "text_max_tokens", "text_layers")} == \
            {"dropout": 0.1, "object_points": 512, "object_tokens": 16, "object_knn": 32, "text_encoder": "minilm",
             "text_max_tokens": 32, "text_layers": 1}
    assert set(CONDITIONING_INTS) < {f for f in ConditioningConfig.__dataclass_fields__}
    loop = ("batch_size", "lr", "weight_decay", "grad_clip", "min_frames", "checkpoint_every", "log_every", "seed")
    assert tuple(TrainLoopConfig.__dataclass_fields__) == loop
    assert [getattr(TrainConfig(), k) for k in loop] == [32, 1e-4, 0.01, 1.0, 8, 500, 50, 0]
    assert [getattr(CatmoTrainConfig(), k) for k in loop] == [16, 2e-4, 0.0, 1.0, 8, 500, 100, 0]


@pytest.mark.parametrize("key, named, other", [
    ("chainhoi/tiny", "model.blocks", "model.object_points"),
    ("chainhoi/paper", "model.ff_mult", "model.text_max_tokens"),
    ("ejim/tiny", "model.d_state", "model.text_layers"),
    ("ejim/micro", "model.modules", "model.object_points"),
    ("chainhoi/tiny", "train.batch_size", "train.contact_points"),
    ("catmo/tiny", "train.batch_size", "train.log_every"),
])
def test_of_two_fields_over_their_limits_the_same_one_is_named(key, named, other):
    baseline, name = key.split("/")
    message = f"{named}: expected an integer in [1, {ARCH_LIMITS[named.split('.')[1]]}], got 9000"
    with pytest.raises(ValueError, match=re.escape(message)):
        SPECS[baseline].preset(name).replace(**{named: 9000, other: 9000})


def test_a_config_over_the_parameter_limit_lists_its_own_fields_first():
    pytest.importorskip("torch")
    spec = SPECS["chainhoi"]
    cfg = spec.preset("paper").replace(**{"model.blocks": 24, "model.d_text": 512, "model.object_tokens": 64,
                                          "model.object_points": 1024, "model.text_max_tokens": 64,
                                          "model.text_layers": 4})
    with pytest.raises(ValueError, match=re.escape(
            "larger than paper: model.blocks = 24, model.d_text = 512, model.object_points = 1024, "
            "model.object_tokens = 64)")):
        check_parameter_count(lambda c: spec.build_model(c, *sizing(c, 100, 384)), cfg, spec.preset("paper"), "x")
