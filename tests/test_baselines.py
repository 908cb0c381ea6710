"""Baselines composite as their papers do, and ablations do not darken the image.

- ``3dgs`` (blend alpha, ellipsoid kernel): the rendered image equals Mitsuba's ``volprim_rf_basic`` at equal cut-offs
  (1e-4 on >= 95 % of pixels, mean 2e-3: volprim's fixed 1e-4 step after each hit skips Gaussians entered within
  1e-4 of the previous one), whatever the Gaussians' specular and transparency attributes are.
- ``2dgs`` / ``pgsr`` (blend alpha, surfels): equal a float64 numpy surfel compositor (1e-4 on >= 97 % of
  rays, mean 2e-3, as in test_inside_origins).
- GLINT without a set: the missing component's weight goes to the diffuse term, checked against the written-out
  weights and a numpy compositor of the other sets, so an ablation never loses energy.
- ``refgs``: tests/test_refgs.py (srgb of this compositor where its grid is dark, and its deferred shading).
"""
import json

import numpy as np
import pytest

import mitsuba as mi

from conftest import camera, make_integrator, random_set, rays, to_np
from glint_mi.model.gaussians import GaussianSet
from glint_mi.config import TrainConfig
from glint_mi.methods import config_for
from glint_mi.model.render import render_buffers
from glint_mi_plugins.glint_gaussians import make_shape
from test_inside_origins import brute_force


def _glassy_set(rng, n, **kw):
    """Random Gaussians with large specular and transparency attributes: GLINT's weights would change the image."""
    return random_set(rng, n, spread=(1, 1, 1), scale=(0.05, 0.25), specular=rng.uniform(0.2, 0.8, n),
                      transparency=rng.uniform(0.2, 0.8, n), **kw)


def test_methods_state_their_blend():
    for m in ("3dgs", "2dgs", "pgsr"):
        assert config_for(m, "tiny").blend == "alpha", m
    assert config_for("refgs", "tiny").blend == "refgs"  # tests/test_refgs.py: its deferred shading
    assert config_for("envgs", "tiny").blend == "envgs"
    assert config_for("glint", "tiny").blend == "fresnel"


def test_3dgs_configuration_equals_volprim_rf_basic(rng):
    cfg = config_for("3dgs", "tiny")
    g = _glassy_set(rng, 400)
    glint = {"type": "glint", "components": "all", "blend": cfg.blend, "aovs": "alpha",
             "alpha_min": 0.0, "alpha_max": 0.9999, "transmittance_min": 0.01,
             "interface": make_shape(g, cfg.kernel, extent=3.0, min_shell_ratio=0.0, opacity_shells=False)}
    ref = {"type": "volprim_rf_basic", "srgb_primitives": False, "max_depth": 100000}
    a = render_buffers(mi.load_dict({"type": "scene", "integrator": glint, "sensor": camera(40, 30)}))
    r = np.array(mi.render(mi.load_dict({"type": "scene", "integrator": ref, "sensor": camera(40, 30),
                                         "g": make_shape(g, cfg.kernel, extent=3.0, min_shell_ratio=0.0, opacity_shells=False)})))[..., :3]
    assert a["alpha"].mean() > 0.3, "test scene should cover the image"
    err = np.abs(a["rgb"] - r).max(-1)
    assert np.mean(err < 1e-4) > 0.95 and np.abs(a["rgb"] - r).mean() < 2e-3, f"mean abs {np.abs(a['rgb'] - r).mean()}"
    # GLINT with the interface alone (components: auto dropped both sets on a room without glass): the missing sets'
    # weights go to the diffuse term, so F0 and the specular / transparency attributes do not darken it either
    fres = render_buffers(mi.load_dict({"type": "scene", "sensor": camera(40, 30),
                                        "integrator": {**glint, "blend": "fresnel"}}))
    np.testing.assert_allclose(fres["rgb"], a["rgb"], atol=1e-6)


@pytest.mark.parametrize("method", ["2dgs", "pgsr"])
def test_surfel_baselines_equal_a_numpy_surfel_compositor(rng, method):
    cfg = config_for(method, "tiny")
    g = _glassy_set(rng, 150)
    integ = make_integrator({"interface": g}, kernels={"interface": cfg.kernel}, components="all", blend=cfg.blend)
    o = np.column_stack([rng.uniform(-0.8, 0.8, (96, 2)), np.full(96, -4.0)])
    d = np.column_stack([rng.uniform(-0.15, 0.15, (96, 2)), np.ones(96)])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    got = to_np(integ.trace(rays(o, d), mi.Bool(True))["rgb"]).T
    extent = float(mi.traverse(integ.sets["interface"].shape)["extent"])
    want = np.array([brute_force(g, cfg.kernel, o[i], d[i], extent)[0] for i in range(len(o))])
    assert np.abs(want).sum(1).mean() > 0.1, "rays should hit the cloud"
    err = np.abs(got - want).max(1)
    assert np.mean(err < 1e-4) >= 0.97 and err.mean() < 2e-3, f"colour error {err.mean():.2e}"


@pytest.mark.parametrize("components", ["interface", "interface,reflection", "interface,transmission",
                                        "interface,reflection,transmission"])
@pytest.mark.parametrize("mode", ["all", "auto"])
def test_a_missing_component_does_not_darken(rng, components, mode):
    """Against references computed outside the integrator: an opaque grey plane (beta 0.3, t 0.6) seen at normal
    incidence has k_s = 0.3 + 0.7 F0, k_d = (1 - k_s) 0.4, k_t = (1 - k_s) 0.6; c_R and c_T come from the float64
    numpy compositor along the mirror and the straight ray from the plane. A missing set's weight goes to the
    plane's own colour: C = (k_d + k_s) c_I + k_t c_T without reflections, etc., c_I alone without both."""
    plane = GaussianSet.from_activated([[0.0, 0.0, 0.0]], [100.0, 100.0, 0.01], opacities=1.0, colors=[[0.5] * 3],
                                       specular=0.3, transparency=0.6)
    sets = {"interface": plane, "reflection": random_set(rng, 200, center=(0, 0, -6), spread=(3, 3, 0.5)),
            "transmission": random_set(rng, 200, center=(0, 0, 2), spread=(1.5, 1.5, 0.3))}
    sets = {r: g for r, g in sets.items() if r in components.split(",")}
    integ = make_integrator(sets, components=mode, alpha_max=1 - 1e-7)
    n = 48
    o = np.column_stack([rng.uniform(-0.6, 0.6, (n, 2)), np.full(n, -4.0)])
    got = to_np(integ.trace(rays(o, np.tile([0.0, 0.0, 1.0], (n, 1))), mi.Bool(True))["rgb"]).T
    ks = 0.3 + 0.7 * 0.04
    kd, kt = (1 - ks) * 0.4, (1 - ks) * 0.6
    x_i = o * [1, 1, 0]
    comp = lambda role, direction: np.array([
        brute_force(sets[role], "surfel", x, np.array(direction, float), _extent(integ, role))[0] for x in x_i])
    c_i = np.full((n, 3), 0.5)
    c_r = comp("reflection", [0, 0, -1]) if "reflection" in sets else c_i
    c_t = comp("transmission", [0, 0, 1]) if "transmission" in sets else c_i
    for c in (c_r, c_t):  # the sets are seen: a test where they were not could not fail
        assert c is c_i or np.abs(c - c_i).max() > 0.05
    want = kd * c_i + ks * c_r + kt * c_t
    np.testing.assert_allclose(got, want, atol=2e-3)
    if components == "interface":  # the plane alone: its colour (G at a few cm of its centre: 1 - 3e-5)
        np.testing.assert_allclose(got, c_i, atol=5e-5)


def test_auto_gives_a_skipped_weight_to_the_diffuse_term(rng):
    """components auto traces reflections only where k_s > reflect_min (0.05): at normal incidence with beta 0,
    k_s = F0 = 0.04 is skipped and must go to the plane's own colour, C = (k_d + k_s) c_I + k_t c_T, not vanish."""
    plane = GaussianSet.from_activated([[0.0, 0.0, 0.0]], [100.0, 100.0, 0.01], opacities=1.0, colors=[[0.5] * 3],
                                       specular=0.0, transparency=0.6)
    sets = {"interface": plane, "reflection": random_set(rng, 200, center=(0, 0, -6), spread=(3, 3, 0.5)),
            "transmission": random_set(rng, 200, center=(0, 0, 2), spread=(1.5, 1.5, 0.3))}
    integ = make_integrator(sets, components="auto", alpha_max=1 - 1e-7)
    n = 32
    o = np.column_stack([rng.uniform(-0.6, 0.6, (n, 2)), np.full(n, -4.0)])
    got = to_np(integ.trace(rays(o, np.tile([0.0, 0.0, 1.0], (n, 1))), mi.Bool(True))["rgb"]).T
    ks = 0.04
    kd, kt = (1 - ks) * 0.4, (1 - ks) * 0.6
    c_t = np.array([brute_force(sets["transmission"], "surfel", x, np.array([0.0, 0, 1]),
                                _extent(integ, "transmission"))[0] for x in o * [1, 1, 0]])
    np.testing.assert_allclose(got, (kd + ks) * 0.5 + kt * c_t, atol=2e-3)


def _extent(integ, role):
    return float(mi.traverse(integ.sets[role].shape)["extent"])


def test_unknown_blend_is_refused():
    with pytest.raises(Exception, match="blend"):
        make_integrator({"interface": random_set(np.random.default_rng(0), 5)}, blend="fresnell")


def test_config_saved_with_the_old_fresnel_flag_loads(tmp_path):
    p = tmp_path / "config.json"
    p.write_text(json.dumps({"preset": "tiny", "fresnel": False}))
    assert TrainConfig.load(p).blend == "envgs"
    p.write_text(json.dumps({"preset": "tiny", "fresnel": True}))
    assert TrainConfig.load(p).blend == "fresnel"


def test_config_saved_before_prior_layer_resumes_as_it_was_trained(tmp_path):
    """A run saved before ``prior_layer`` existed trained with its priors on the interface everywhere: resuming it
    must not switch to the new default; the paper's method and TSGS keep the interface too."""
    from glint_mi.methods import config_for

    p = tmp_path / "config.json"
    p.write_text(json.dumps({"preset": "tiny"}))
    assert TrainConfig.load(p).prior_layer == "interface"
    assert TrainConfig.for_preset("tiny").prior_layer == "nearer"
    assert config_for("glint-paper", "tiny").prior_layer == config_for("tsgs", "tiny").prior_layer == "interface"


def test_bench_preset_draws_early_patches_from_coarser_images_for_every_method():
    """The bench preset's coarse-to-fine patches (docs/results/coarse_to_fine) are a way of spending its rays, as its
    epochs are: every method gets them but `glint-paper` (its whole-image depth fit refits the full-size images'
    priors only, so it keeps them throughout, as its paper); other presets have none."""
    from glint_mi.methods import METHODS

    for m in METHODS:
        assert config_for(m, "bench").pyramid() == ([] if m == "glint-paper" else [(4, 0.2), (2, 0.4)]), m
    for preset in ("tiny", "quick", "gpu"):
        assert config_for("glint", preset).pyramid() == config_for("3dgs", preset).pyramid() == [], preset
    assert config_for("3dgs", "bench", coarse_to_fine="").pyramid() == []  # --set coarse_to_fine= turns it off
    # no coarse image under 27 pixels a side (docs/results/coarse_to_fine, "The coarse-start floor checked on
    # 9801-9803"): at 96 x 54 the 1/4 level (24 x 13) is left out for every method, at 192 x 108 both are kept
    for m in METHODS:
        cfg = config_for(m, "bench")
        assert cfg.coarse_min_side == 27, m
        if m != "glint-paper":
            assert cfg.coarse_levels(96, 54) == ([(2, pytest.approx(0.4))], [4]), m
            assert cfg.coarse_levels(192, 108) == ([(4, pytest.approx(0.2)), (2, pytest.approx(0.4))], []), m
    assert config_for("glint", "converged").coarse_min_side == 0  # no coarse start there: the headline's configs


def test_only_glint_shares_a_clones_coverage_and_only_at_the_bench_preset():
    """clone_opacity: shared (docs/results/coarse_to_fine, forty-seventh session) is GLINT's at the bench preset, where
    it was decided; every baseline and glint-paper keep 3DGS's copy there (a baseline is what its paper is), and the
    other presets keep copy for every method; every baseline names 3DGS's split and its fixed Gaussian budget."""
    from glint_mi.methods import METHODS

    ours = {m for m in METHODS if m == "glint" or (m.startswith("glint-") and m != "glint-paper")}
    for m in METHODS:
        assert config_for(m, "bench").clone_opacity == ("shared" if m in ours else "copy"), m
        for preset in ("tiny", "quick", "gpu"):
            assert config_for(m, preset).clone_opacity == "copy", (m, preset)
    from glint_mi.training.components import ComponentsPolicy

    # GLINT without a glass cue trains as the 3dgs method (no_glass: 3dgs): with 3DGS's clones too
    assert ComponentsPolicy(config_for("glint", "bench")).no_glass_profile()["clone_opacity"] == "copy"
    # and 3DGS's split (children drawn from the parent), which every baseline names, whatever a preset gives GLINT
    from glint_mi.config import flatten

    for m in set(METHODS) - ours:
        assert flatten(METHODS[m].overrides).get("split_mode") == "sample", m
    assert ComponentsPolicy(config_for("glint", "bench")).no_glass_profile()["split_mode"] == "sample"
    # and 3DGS's budget, whole from the start, even where GLINT's cap rises over the growth window
    for m in set(METHODS) - ours:
        assert flatten(METHODS[m].overrides).get("cap_schedule") == "fixed", m
    linear = config_for("glint", "converged", cap_schedule="linear")
    assert linear.cap_schedule == "linear"
    assert ComponentsPolicy(linear).no_glass_profile()["cap_schedule"] == "fixed"
