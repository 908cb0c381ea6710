"""The configuration's layers (issue 45): every field in exactly one layer, the layers compose into the run's config,
and a run folder's config.json stays flat (old ones still load: tests/test_train.py resumes the oldest format)."""
import dataclasses
import json

import pytest

from glint_mi.config import LAYERS, ConfigError, LossConfig, RenderConfig, TrainConfig


def test_every_field_is_in_exactly_one_layer():
    seen = {}
    for name, cls in LAYERS.items():
        for f in dataclasses.fields(cls):
            assert f.name not in seen, (f.name, seen.get(f.name), name)
            seen[f.name] = name
    assert list(seen) == [f.name for f in dataclasses.fields(TrainConfig)]  # the same fields, in layer order
    assert list(LAYERS) == ["run", "model", "render", "optim", "losses", "schedule", "densify", "evaluation"]


def test_layers_compose_and_split():
    cfg = TrainConfig.for_preset("bench", w_l1=2.0, max_hits=64)
    losses, render = cfg.layer("losses"), cfg.layer("render")
    assert isinstance(losses, LossConfig) and losses.w_l1 == 2.0 and render.max_hits == 64
    again = TrainConfig.compose(*(cfg.layer(n) for n in LAYERS))
    assert again == cfg
    partial = TrainConfig.compose(LossConfig(w_trans=0.0), RenderConfig(max_hits=32))
    assert partial.w_trans == 0.0 and partial.max_hits == 32 and partial.kernel == TrainConfig().kernel
    with pytest.raises(ConfigError, match="unknown config layer 'loss'; the layers are run, model"):
        cfg.layer("loss")
    with pytest.raises(ConfigError, match="dict is not a config layer"):
        TrainConfig.compose({"w_l1": 1.0})
    with pytest.raises(ConfigError, match="'max_hits' = 0: must be >= 1"):  # composed configs are checked
        TrainConfig.compose(RenderConfig(max_hits=0))


def test_saved_config_is_flat_and_round_trips(tmp_path):
    cfg = TrainConfig.for_preset("tiny", seed=3, w_depth=0.2)
    cfg.save(tmp_path / "config.json")
    values = json.loads((tmp_path / "config.json").read_text())
    assert all(not isinstance(v, dict) for v in values.values())
    assert TrainConfig.load(tmp_path / "config.json") == cfg
