"""The baselines' presets are what their run cards record: the same dicts and the same hash
(``json.dumps(to_dict(), sort_keys=True)``, the config part of a run's resume fingerprint)
as the configs of 0.7.0, whose hashes are pinned here; and every section check names its field."""
from __future__ import annotations

import hashlib
import json
import re

import pytest

from hoibench.baselines.registry import SPECS

#: sha256 of the sorted-key JSON of each preset, as 0.7.0's config modules produced them
PINNED = {
    "catmo/paper": "0bc7c23531b7164c3d8f32542871763d5d2050001e77fcf40ad5b2cb01e6e1cd",
    "catmo/tiny": "f127c8429d307cd8fa205ae0b004dc0bf8ceb1dd2f73a8a6d0a0c4338c54bc97",
    "chainhoi/paper": "b460dcdb36e3dca1b4043f0273f45d0a9fea6a7a451fc82ed3cb60319b5985c9",
    "chainhoi/tiny": "53223987431c310df822c50aaa61ab62fe1cc30e4b6978044325487826b2801b",
    "ejim/micro": "4019afe28a5471013dc13dcab85730e0365bf0123908604104fa94b92abce838",
    "ejim/paper": "9641eff9c7e56f4577fdf32dd5f5481d4d64cf9114d6bb1a84b5142e88d72cec",
    "ejim/tiny": "5c655821a0ec43945cc0b85de241e1eea24b8f0511e2c52ab45e4d07c63ea21d",
    "syncdiff/paper": "96c44ee85fc9bb7fcc7476a6fe3729920f5212ba1630c805dc9d9c91d2f377ff",
    "syncdiff/tiny": "d15dc6d6806b397c50838fc0684c44fd2905a762f61e54cc1ff0028d88903ba2",
}


def _preset(key: str):
    baseline, name = key.split("/")
    return SPECS[baseline], SPECS[baseline].preset(name)


@pytest.mark.parametrize("key", sorted(PINNED))
def test_preset_hash_is_unchanged_and_round_trips(key):
    spec, cfg = _preset(key)
    d = cfg.to_dict()
    assert hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest() == PINNED[key]
    back = type(cfg).from_dict(json.loads(json.dumps(d)), spec.model_config) if spec.kind == "diffusion" \
        else type(cfg).from_dict(json.loads(json.dumps(d)))
    assert back == cfg and back.to_dict() == d


@pytest.mark.parametrize("key, change, message", [
    ("chainhoi/tiny", {"train.lr": 0.0}, "train.lr: expected (0, 1), got 0.0"),
    ("chainhoi/tiny", {"train.ema_decay": 1.0}, "train.ema_decay: expected [0, 1), got 1.0"),
    ("chainhoi/tiny", {"train.lambda_object": -1.0}, "train.lambda_object: expected >= 0, got -1.0"),
    ("chainhoi/tiny", {"model.mask": "x"}, "model.mask: expected one of ('paper', 'released'), got 'x'"),
    ("chainhoi/tiny", {"model.heads": 3}, "model.d_text (64) must be divisible by model.heads (3)"),
    ("ejim/tiny", {"model.dropout": 1.0}, "model.dropout: expected [0, 1), got 1.0"),
    ("catmo/tiny", {"gpt.temperature": 0.0}, "gpt.temperature: expected (0, 100], got 0.0"),
    ("catmo/tiny", {"gpt.object_tokens": 512}, "gpt.object_tokens and gpt.object_knn must not exceed gpt.object_points"),
    ("catmo/tiny", {"vq.beta": float("nan")}, "vq.beta: expected >= 0, got nan"),
    ("catmo/tiny", {"unknown.x": 1}, "override 'unknown.x'"),
    ("syncdiff/tiny", {"syncdiff.freq_position": "x"}, "syncdiff.freq_position: expected one of ('index', 'rate')"),
    ("syncdiff/tiny", {"model.latent": 66}, "model.latent (66) must be divisible by model.heads (4)"),
])
def test_a_bad_field_is_named(key, change, message):
    _, cfg = _preset(key)
    with pytest.raises(ValueError, match=re.escape(message)):
        cfg.replace(**change)


def test_the_closed_end_of_an_interval_is_accepted():
    _, cfg = _preset("catmo/tiny")
    assert cfg.replace(**{"gpt.temperature": 100.0}).gpt.temperature == 100.0
    assert cfg.replace(**{"train.weight_decay": 0.0}).train.weight_decay == 0.0


def test_an_unknown_section_is_refused_where_it_was():
    _, catmo = _preset("catmo/tiny")
    with pytest.raises(ValueError, match="config: unknown section"):
        type(catmo).from_dict({**catmo.to_dict(), "extra": {}})
    spec, chainhoi = _preset("chainhoi/tiny")       # a joint-level run card ignores other top-level keys
    assert type(chainhoi).from_dict({**chainhoi.to_dict(), "extra": {}}, spec.model_config) == chainhoi
