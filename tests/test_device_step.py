"""update: device — the chain rule, the densification statistic, selective Adam and the packing on Dr.Jit arrays
equal the host reference (glint_mi.training.optim.raw_gradients + Adam.step, GaussianSet.to_mitsuba) within float32
rounding; a trainer with either update trains the same."""
import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

import glint_mi

glint_mi.set_variant()

from conftest import LLVM  # noqa: E402

from glint_mi.training.device_step import DeviceUpdate  # noqa: E402
from glint_mi.model.gaussians import GaussianSet  # noqa: E402
from glint_mi.training.optim import RAW_FIELDS, Adam, raw_gradients  # noqa: E402
from glint_mi.training.strategy import Strategy  # noqa: E402

LRS = {"means": 1.6e-4, "log_scales": 5e-3, "quats_wxyz": 1e-3, "logit_opacity": 0.05, "sh": 2.5e-3,
       "sh_rest": 1.25e-4, "logit_specular": 0.01, "logit_transparency": 0.05, "normals": 2e-3}


def random_set(rng, n=64, k=4):
    return GaussianSet(means=rng.normal(size=(n, 3)), log_scales=rng.normal(-3, 0.5, size=(n, 3)),
                       quats_wxyz=rng.normal(size=(n, 4)), logit_opacity=rng.normal(size=n),
                       sh=rng.normal(size=(n, k, 3)), logit_specular=rng.normal(-4, 1, size=n),
                       logit_transparency=rng.normal(-3, 1, size=n), normals=rng.normal(size=(n, 3)) * 2.0)


def random_grads(rng, n, k, hit=0.4, nonfinite=0, normals=True):
    """Renderer-space gradients (float32, as dr.grad gives them) on a random share ``hit`` of the rows; without
    ``normals`` none for the normal attribute (normal_source: axis)."""
    rows = rng.random(n) < hit
    g = {"data": rng.normal(size=(n, 10)), "kernel_scales": rng.normal(size=(n, 3)), "opacities": rng.normal(size=n),
         "sh_coeffs": rng.normal(size=(n, k * 3)), "specular": rng.normal(size=n), "transparency": rng.normal(size=n),
         "normals": rng.normal(size=(n, 3))}  # the normal attribute's (normal_source: attribute)
    g = {key: (v * (rows if v.ndim == 1 else rows[:, None]) * 1e-3).astype(np.float32) for key, v in g.items()}
    for _ in range(nonfinite):
        g["data"][rng.integers(n), rng.integers(10)] = np.nan
    if not normals:
        del g["normals"]
    return g


def host_step(gs, grads, adam, strategy, role, kernel, degree, zero, lr_pos):
    """Trainer._update's host arithmetic (the reference)."""
    g = raw_gradients(gs, {k: v.astype(np.float64) for k, v in grads.items()}, kernel)
    g["sh"][:, (degree + 1) ** 2:] = 0.0
    for f in zero:
        g[f][:] = 0.0
    bad = sum(int(np.count_nonzero(~np.isfinite(v))) for v in g.values())
    for v in g.values():
        np.nan_to_num(v, copy=False, nan=0.0, posinf=0.0, neginf=0.0)
    strategy.accumulate(role, len(gs), g["means"], g["logit_opacity"])
    touched = (g["logit_opacity"] != 0) | np.any(g["means"] != 0, axis=1) | np.any(g["sh"][:, 0] != 0, axis=1)
    adam.step(role, gs, g, {"means": lr_pos}, rows=touched)
    return bad


def device_step(dev, grads, role, degree, zero, lr_pos):
    g = dev.gradients(role, {k: mi.Float(v.ravel()) for k, v in grads.items()}, dr.opaque(mi.UInt32, degree), zero)
    dr.eval(*g.values())
    seen, touched, means = dev.rows(role, g)
    dev.accumulate(role, seen, means)
    dr.eval(touched)
    dev.step(role, g, touched, {"means": dr.opaque(mi.Float64, lr_pos)})
    dev.schedule(role)


class _Cfg:
    """What Strategy reads for accumulate (nothing) - a stand-in config."""


@pytest.mark.parametrize("kernel, selective, zero, normals", [("surfel", True, set(), True),
                                                              ("gaussian", True, {"logit_specular"}, True),
                                                              ("surfel", False, {"logit_transparency"}, True),
                                                              ("surfel", True, set(), False)])
def test_device_update_equals_the_host_reference(kernel, selective, zero, normals):
    """Six steps of random sparse gradients (a different 40 % of the rows each step, two NaNs, SH degree 0 then 1,
    a falling position rate): values, moments, step counts and the densification sums equal the host's bit for bit
    on LLVM (the device repeats numpy's float64 / float32 mix operation by operation); elsewhere within float32
    rounding (CUDA's fast-math float32 division and square root): values to 2e-6 of their scale, moments rtol 1e-4.
    The NaN count is the host's. Without a normals gradient (normal_source: axis) neither steps the normals: their
    values, moments and step counts stay as loaded."""
    rng = np.random.default_rng(3)
    host = random_set(rng)
    n, k = len(host), host.sh.shape[1]
    gold = GaussianSet(**{f: getattr(host, f).copy() for f in RAW_FIELDS})
    a_host = Adam(LRS, selective=selective)
    a_dev = Adam(LRS, selective=selective)
    s_host = Strategy(_Cfg(), 2.5, np.random.default_rng(0))
    s_dev = Strategy(_Cfg(), 2.5, np.random.default_rng(0))
    dev = DeviceUpdate(a_dev, kernel, 2.5)
    dev.load("interface", gold, s_dev)
    bad = 0
    for it in range(6):
        grads = random_grads(rng, n, k, nonfinite=2 if it == 2 else 0, normals=normals)
        degree, lr_pos = (0 if it < 3 else 1), 1.0 - 0.1 * it
        bad += host_step(host, grads, a_host, s_host, "interface", kernel, degree, zero, lr_pos)
        device_step(dev, grads, "interface", degree, zero, lr_pos)
    dev.pull("interface", gold, s_dev)
    for f in RAW_FIELDS:
        ref, got = getattr(host, f), getattr(gold, f)
        m_ref, v_ref, n_ref = a_host.state["interface"][f]
        m_got, v_got, n_got = a_dev.state["interface"][f]
        np.testing.assert_array_equal(n_got, n_ref, err_msg=f)
        if LLVM:
            for x, y in ((got, ref), (m_got, m_ref), (v_got, v_ref)):
                np.testing.assert_array_equal(x, y, err_msg=f)
            continue
        np.testing.assert_allclose(got, ref, rtol=0, atol=2e-6 * max(1.0, float(np.abs(ref).max())), err_msg=f)
        np.testing.assert_allclose(m_got, m_ref, rtol=1e-4, atol=1e-12, err_msg=f)
        np.testing.assert_allclose(v_got, v_ref, rtol=1e-4, atol=1e-16, err_msg=f)
    assert not np.array_equal(host.means, random_set(np.random.default_rng(3)).means), "nothing moved"
    start = random_set(np.random.default_rng(3)).normals
    for gs, adam in ((host, a_host), (gold, a_dev)):
        assert np.array_equal(gs.normals, start) != normals, "the normals stepped without a gradient, or not with one"
        assert np.any(adam.state["interface"]["normals"][2] > 0) == normals
    np.testing.assert_allclose(s_dev.grad_sum["interface"], s_host.grad_sum["interface"], rtol=0 if LLVM else 1e-5)
    np.testing.assert_array_equal(s_dev.count["interface"], s_host.count["interface"])
    assert dev.read_bad()["interface"] == bad > 0


@pytest.mark.parametrize("kernel, shells, normals", [("surfel", True, True), ("gaussian", False, False)])
def test_device_pack_equals_to_mitsuba(kernel, shells, normals):
    """The renderer's arrays packed on the device equal GaussianSet.to_mitsuba (float64, then rounded): bit for bit
    on LLVM, to float32 rounding elsewhere; a zero quaternion (the identity) and a vanishing opacity included, and
    with normal_source: attribute the unit normals."""
    rng = np.random.default_rng(5)
    gs = random_set(rng, n=40)
    gs.quats_wxyz[7] = 0.0
    gs.logit_opacity[3] = -80.0  # an opacity whose shell shrinks to the floor
    dev = DeviceUpdate(Adam(LRS), kernel, 1.0)
    dev.load("interface", gs)
    got = dev.pack("interface", 0.3, shells, 3.33, normals)
    ref = gs.to_mitsuba(kernel, 0.3, shells, 3.33, normals)
    assert set(got) == set(ref) and ("normals" in ref) == normals
    for key, v in ref.items():
        if LLVM:
            np.testing.assert_array_equal(np.array(got[key]), v.ravel(), err_msg=key)
        else:
            np.testing.assert_allclose(np.array(got[key]), v.ravel(), rtol=3e-7, atol=1e-30, err_msg=key)


def test_host_round_trip_keeps_what_the_device_does_not_hold():
    """load -> pull without a step leaves the set, the Adam state and the strategy as they were (a set never
    stepped gets no Adam state, a strategy without statistics none)."""
    rng = np.random.default_rng(1)
    gs = random_set(rng, n=10)
    before = {f: getattr(gs, f).copy() for f in RAW_FIELDS}
    adam, strat = Adam(LRS), Strategy(_Cfg(), 1.0, np.random.default_rng(0))
    dev = DeviceUpdate(adam, "surfel", 1.0)
    dev.load("interface", gs, strat)
    dev.pull("interface", gs, strat)
    for f in RAW_FIELDS:
        np.testing.assert_array_equal(getattr(gs, f), before[f])
    assert "interface" not in adam.state and "interface" not in strat.grad_sum


def test_learning_rates_do_not_depend_on_the_batch_size():
    """The rule for learning rates as batches grow: none to change. The loss is a mean over the batch's rays, so a
    Gaussian's gradient scales with its share of the batch; Adam divides by the gradient's running RMS, so three
    steps with every gradient x 1/64 or x 64 move the parameters as the unscaled ones do (to 1e-5 of a step; eps
    1e-15 is far below any gradient here). What the batch size changes is the number of steps per epoch and the
    gradient's noise, not the step's length."""
    rng = np.random.default_rng(9)
    start = random_set(rng, n=32)
    grads = [random_grads(rng, 32, start.sh.shape[1], hit=0.6) for _ in range(3)]
    moved = {}
    for scale in (1.0, 1.0 / 64, 64.0):
        gs = GaussianSet(**{f: getattr(start, f).copy() for f in RAW_FIELDS})
        adam = Adam(LRS)
        dev = DeviceUpdate(adam, "surfel", 1.0)
        dev.load("interface", gs)
        for g in grads:
            device_step(dev, {k: v * np.float32(scale) for k, v in g.items()}, "interface", 1, set(), 1.0)
        dev.pull("interface", gs)
        moved[scale] = {f: getattr(gs, f) - getattr(start, f) for f in RAW_FIELDS}
    for scale in (1.0 / 64, 64.0):
        for f in RAW_FIELDS:
            ref = moved[1.0][f]
            assert np.abs(ref).max() > 0, f
            np.testing.assert_allclose(moved[scale][f], ref, rtol=0, atol=1e-5 * np.abs(ref).max() + 1e-7, err_msg=f)
