"""The configuration's layers (issues 45, 64): every field in exactly one layer, TrainConfig holds one instance of
each, a field is set by its path or bare name, and a run folder's config.json holds the layers as objects (flat ones
still load: tests/test_train.py resumes the oldest format)."""
import argparse
import dataclasses
import json
from pathlib import Path

import pytest

from glint_mi.config import LAYERS, ConfigError, LossConfig, RenderConfig, TrainConfig

ROOT = Path(__file__).resolve().parent.parent


def test_every_field_is_in_exactly_one_layer():
    seen = {}
    for name, cls in LAYERS.items():
        for f in dataclasses.fields(cls):
            assert f.name not in seen, (f.name, seen.get(f.name), name)
            seen[f.name] = name
    assert list(seen) == list(TrainConfig().flat())  # the same fields, in layer order
    assert list(LAYERS) == ["run", "model", "render", "optim", "losses", "schedule", "densify", "evaluation"]
    # TrainConfig holds the layers, not their fields
    assert [f.name for f in dataclasses.fields(TrainConfig)] == list(LAYERS)
    cfg = TrainConfig()
    assert all(type(getattr(cfg, n)) is c for n, c in LAYERS.items())
    assert cfg.w_normal is cfg.losses.w_normal and "w_normal" not in vars(cfg)


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


def test_saved_config_holds_layers_and_round_trips(tmp_path):
    cfg = TrainConfig.for_preset("tiny", seed=3, w_depth=0.2)
    cfg.save(tmp_path / "config.json")
    values = json.loads((tmp_path / "config.json").read_text())
    assert list(values) == list(LAYERS) and values["losses"]["w_depth"] == 0.2 and values["run"]["seed"] == 3
    assert TrainConfig.load(tmp_path / "config.json") == cfg
    # a flat config.json (every run before 2026-11-28) still loads, to the same config
    (tmp_path / "flat.json").write_text(json.dumps(cfg.flat()))
    assert TrainConfig.load(tmp_path / "flat.json") == cfg


def test_fields_by_path():
    """--set losses.w_normal=0.1 (issue 64): a path names the field's owner; a bare name still resolves to it; a path
    through the wrong layer, an unknown layer or one field given twice with two values is refused."""
    cfg = TrainConfig.for_preset("tiny", **{"losses.w_normal": 0.05, "render.max_hits": 32})
    assert cfg.losses.w_normal == 0.05 and cfg.render.max_hits == 32
    assert TrainConfig.for_preset("tiny", w_normal=0.05, max_hits=32) == cfg
    assert TrainConfig.from_dict({"losses": {"w_normal": 0.05}}).w_normal == 0.05
    with pytest.raises(ConfigError, match=r"'render.w_normal': w_normal is in the losses layer; write losses.w_normal"):
        TrainConfig.for_preset("tiny", **{"render.w_normal": 0.1})
    with pytest.raises(ConfigError, match=r"'loss.w_normal': no layer 'loss'"):
        TrainConfig.for_preset("tiny", **{"loss.w_normal": 0.1})
    with pytest.raises(ConfigError, match=r"'w_normal' is given twice"):
        TrainConfig.from_dict({"w_normal": 0.1, "losses.w_normal": 0.2})
    with pytest.raises(ConfigError, match=r"unknown field\(s\) w_norml \(did you mean w_normal\?\)"):
        TrainConfig.for_preset("tiny", w_norml=0.1)
    again = cfg.replace(**{"losses.w_normal": 0.2})
    assert again.w_normal == 0.2 and cfg.w_normal == 0.05  # a checked copy
    # presets, schedule variants and methods say what they override by path
    from glint_mi.config import PRESETS, VARIANTS
    from glint_mi.methods import METHODS

    for what in (*PRESETS.values(), *VARIANTS.values(), *(m.overrides for m in METHODS.values())):
        assert all(k.split(".")[0] in LAYERS for k in what), what
    assert METHODS["3dgs"].overrides["model.kernel"] == "ellipsoid" and PRESETS["tiny"]["run.iterations"] == 300


def test_the_converged_preset_is_the_converged_tables_run():
    """``--preset converged`` is the command of the converged table's GLINT runs (converge_98xx/s54.sh: capacity
    `wide`, depth_prior_ref 0.02): with that table's protocol flags (96 x 54, no SfM depth term) its config is a
    committed run's config.json in every field but the iterations the epochs resolve to; each baseline's is its own
    point's run (growth; glint-paper at 120 epochs) in every field but those the converged preset and its
    migrations name."""
    from glint_mi.config import TrainConfig
    from glint_mi.methods import config_for

    groups = ROOT / "docs/results/converge_98xx/groups"
    protocol = dict(downscale=2, w_sfm_depth=0.0, eval_every=1000, threads=1)
    saved = TrainConfig.load(groups / "s54_d54/runs/scene_9801/glint/config.json").flat()
    now = config_for("glint", "converged", **protocol).flat()
    differ = {k: (saved[k], now[k]) for k in saved if saved[k] != now[k]}
    assert differ == {"iterations": (4253, 4000)}, differ
    # the table's baselines ran --preset bench with the growth flags, before the coarse start and the clones'
    # coverage existed (read back as "" and copy, config.MIGRATIONS): the preset's name and iterations differ, and
    # the falling normal prior's floor, which a constant prior (prior_decay 1) never reads; 3dgs-priors has followed
    # GLINT's falling prior and its per-view depth weight since those runs (methods.WITH_PRIORS)
    for method, run, since in (("3dgs", "e60_grow", {}), ("tsgs", "e60_grow", {}),
                               ("3dgs-priors", "e60_grow", {"prior_decay": (1.0, 0.5), "depth_prior_ref": (0.0, 0.02)}),
                               ("glint-paper", "e120_grow_c", {})):
        saved = TrainConfig.load(groups / run / f"runs/scene_9802/{method}/config.json").flat()
        now = config_for(method, "converged", **protocol).flat()
        differ = {k: (saved[k], now[k]) for k in saved if saved[k] != now[k]}
        assert saved["prior_decay"] == 1.0 and differ.pop("prior_decay_ref") == (0.0, 8.0), method
        assert differ == {"preset": ("bench", "converged"), "iterations": (saved["iterations"], now["iterations"]),
                          **since}, (method, differ)


def test_a_method_at_a_preset_is_checked_and_reaches_every_path():
    """A method's ``at`` entry (its fields under one preset) is validated when the method is defined, reaches
    config_for and the optimize CLI under that preset only, and yields to --set."""
    from glint_mi.config import ConfigError
    from glint_mi.methods import METHODS, Method, config_for
    from glint_mi.optimize import build_config

    with pytest.raises(ConfigError, match="'at' names preset 'nope'"):
        Method("x", {}, "x", at={"nope": {"epochs": 1.0}})
    with pytest.raises(ConfigError, match="densify_top"):
        Method("x", {}, "x", at={"converged": {"densify_top": -1.0}})
    assert config_for("3dgs", "converged").densify_top == 0.12 and config_for("glint", "converged").densify_top == 0.25
    assert config_for("3dgs", "bench").densify_top == config_for("glint", "bench").densify_top
    assert config_for("glint-paper", "converged").epochs == 120.0 and config_for("glint-paper", "bench").epochs == 10.0
    assert METHODS["glint-no-trans"].at == {} and config_for("glint-no-trans", "converged").densify_top == 0.25
    assert config_for("3dgs", "converged", densify_top=0.3).densify_top == 0.3
    args = lambda **kw: argparse.Namespace(**{**dict(config=None, iterations=None, seed=None, set=[],
                                                     preset="converged", variant=None, method="3dgs"), **kw})
    assert build_config(args()).densify_top == 0.12 and build_config(args(method="glint")).densify_top == 0.25
    bench = build_config(args(preset="bench"))
    assert bench.densify_top == build_config(args(preset="bench", method="glint")).densify_top
    said = []
    assert build_config(args(set=["densify_top=0.3"]), note=said.append).densify_top == 0.3
    assert said == ["the command line sets densify_top = 0.3 over method 3dgs at preset converged's 0.12"], said
    assert build_config(args(method="glint-paper")).epochs == 120.0


def test_a_preset_changes_no_methods_kernel_but_glints():
    """The converged preset gives GLINT (and its ablations) 3DGS's ellipsoids; every surfel method keeps surfels and
    3DGS its ellipsoids under every preset."""
    from glint_mi.config import PRESETS
    from glint_mi.methods import METHODS, config_for

    surfels = ("2dgs", "2dgs-priors", "pgsr", "envgs", "refgs", "tsgs", "glint-paper")
    for preset in PRESETS:
        for name in METHODS:
            want = ("surfel" if name in surfels else "ellipsoid" if name.startswith("3dgs") or preset == "converged"
                    else "surfel")
            assert config_for(name, preset).kernel == want, (preset, name)


def test_a_config_copied_with_a_change_leaves_the_original_alone():
    """dataclasses.replace(cfg, field=...) hands the layers to __init__, which copies them: the change lands in the
    copy only (it used to write into the layer both configs shared)."""
    import dataclasses

    from glint_mi.config import TrainConfig

    c = TrainConfig.for_preset("tiny", normal_weight="uniform")
    d = dataclasses.replace(c, normal_weight="near", prior_layer="interface")
    assert (c.normal_weight, c.prior_layer) == ("uniform", "nearer")
    assert (d.normal_weight, d.prior_layer) == ("near", "interface") and d.losses is not c.losses


@pytest.mark.parametrize("field", ["cue_photo", "prior_photo"])
def test_photo_quantiles_are_a_quantile_or_off(field):
    from glint_mi.config import ConfigError, TrainConfig

    assert getattr(TrainConfig.from_dict({field: 0.75}), field) == 0.75
    for bad in (1.0, -0.1):
        with pytest.raises(ConfigError, match=field + r".*quantile in \(0, 1\)"):
            TrainConfig.from_dict({field: bad})
    with pytest.raises(ConfigError, match=field + r".*depth_align sfm"):
        TrainConfig.from_dict({field: 0.75, "depth_align": "image"})
