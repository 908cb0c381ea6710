"""The ``refgs`` baseline: Ref-GS's deferred directional shading (plugins/glint_env.py).

- The mip-mapped latitude-longitude grid equals a float64 numpy reading of the same definition (2 x 2 averaged
  levels, bilinear with longitude wrap, linear between levels) to 1e-5.
- With the grid dark (s ~ 0) a refgs image is srgb of the 2DGS composite: equal to the float64 numpy surfel
  compositor, srgb-encoded, where alpha > 0.05 and 0 elsewhere (the same tolerance as the 2DGS equivalence).
- On an opaque plane of known normal and roughness the pixel is srgb(c + exp(grid(reflect(d, n), r L))) (1e-4).
- Gradients of the image with respect to the grid and the roughness (beta) agree with central finite differences
  (2 %, 3 %), the shading head's with respect to the normal too (3 %), and the path-replay backward equals plain AD
  for every packed surfel entry (1e-4).
- Training, checkpoint, resume and the saved model carry the grid: a resumed run equals a straight one bit for
  bit (one thread) and the model's scene renders what the trainer evaluated.
"""
import json
import subprocess
import sys
from pathlib import Path

import drjit as dr
import mitsuba as mi
import numpy as np
import pytest

from conftest import BITWISE, central_difference, make_integrator, random_set, rays, to_np
from glint_mi.conventions import linear_to_srgb
from glint_mi.model.gaussians import GaussianSet
from glint_mi.methods import config_for
from glint_mi_plugins.glint_env import DirectionalGrid, srgb
from test_inside_origins import brute_force

ROOT = Path(__file__).resolve().parent.parent


def _np_srgb(x):
    return linear_to_srgb(np.clip(x, 1e-10, 1.0))


def _np_lookup(values: np.ndarray, direction: np.ndarray, level: float) -> np.ndarray:
    """The grid's definition in float64 numpy: [h, w, 3] level 0, one unit direction, a fractional level."""
    levels = [values.astype(np.float64)]
    while len(levels) < int(np.log2(values.shape[0])):
        a = levels[-1]
        levels.append(0.25 * (a[0::2, 0::2] + a[0::2, 1::2] + a[1::2, 0::2] + a[1::2, 1::2]))
    z = np.clip(direction[2], -1 + 1e-6, 1 - 1e-6)
    u = np.arctan2(direction[1], direction[0]) / (2 * np.pi) + 0.5
    v = np.arccos(z) / np.pi
    level = np.clip(level, 0, len(levels) - 1)
    out = np.zeros(3)
    for k, a in enumerate(levels):
        wk = max(0.0, 1 - abs(level - k))
        if wk == 0:
            continue
        h, w = a.shape[:2]
        x, y = u * w - 0.5, v * h - 0.5
        x0, y0 = np.floor(x), np.floor(y)
        fx, fy = x - x0, y - y0
        xs = [int(x0) % w, (int(x0) + 1) % w]
        ys = [min(max(int(y0), 0), h - 1), min(max(int(y0) + 1, 0), h - 1)]
        val = ((1 - fx) * (1 - fy) * a[ys[0], xs[0]] + fx * (1 - fy) * a[ys[0], xs[1]]
               + (1 - fx) * fy * a[ys[1], xs[0]] + fx * fy * a[ys[1], xs[1]])
        out += wk * val
    return out


def test_grid_lookup_equals_its_numpy_definition(rng):
    grid = DirectionalGrid(4)
    values = rng.normal(size=(grid.h, grid.w, 3)).astype(np.float32)
    grid.set_numpy(values)
    assert np.array_equal(grid.numpy(), values)
    n = 300
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d[:4] = [[0, 0, 1], [0, 0, -1], [-1, 1e-7, 0], [-1, -1e-7, 0]]  # the poles and both sides of the seam
    lev = rng.uniform(-0.5, grid.levels - 0.5, n)
    got = to_np(grid.lookup(mi.Vector3f(*[mi.Float(d[:, i]) for i in range(3)]), mi.Float(lev))).T
    want = np.array([_np_lookup(values, d[i], lev[i]) for i in range(n)])
    np.testing.assert_allclose(got, want, atol=1e-5)
    # a constant grid reads that constant at every direction and level (the lookup's weights sum to 1)
    grid.set_numpy(np.full_like(values, 0.7))
    const = to_np(grid.lookup(mi.Vector3f(*[mi.Float(d[:, i]) for i in range(3)]), mi.Float(lev)))
    np.testing.assert_allclose(const, 0.7, atol=1e-6)
    # the pyramid is linear in level 0 and grad() is its transpose: <P x, y> = <x, P^T y> for random x, y
    x = rng.normal(size=grid.data.size)
    grid.data = x
    y = rng.normal(size=dr.width(grid.mips))
    dr.enable_grad(grid.mips)
    dr.set_grad(grid.mips, mi.Float(y))
    assert np.dot(to_np(grid.mips), y) == pytest.approx(np.dot(x, grid.grad()), rel=1e-5)
    grid.clear_grad()
    assert not np.any(grid.grad())
    with pytest.raises(ValueError, match="env_levels"):
        DirectionalGrid(0)
    with pytest.raises(ValueError, match="16 x 32 x 3"):
        DirectionalGrid(4, np.zeros((8, 16, 3)))


def test_dark_grid_gives_srgb_of_the_2dgs_composite(rng):
    cfg = config_for("refgs", "tiny")
    assert cfg.blend == "refgs" and cfg.components == "interface" and cfg.sh_degree == 0
    g = random_set(rng, 150, spread=(1, 1, 1), scale=(0.05, 0.25), specular=rng.uniform(0.2, 0.8, 150))
    integ = make_integrator({"interface": g}, components="all", blend="refgs", env_levels=5)
    integ.env.set_numpy(np.full((32, 64, 3), -40.0, np.float32))  # s = e^-40
    o = np.column_stack([rng.uniform(-1.2, 1.2, (120, 2)), np.full(120, -4.0)])
    d = np.column_stack([rng.uniform(-0.15, 0.15, (120, 2)), np.ones(120)])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    got = to_np(integ.trace(rays(o, d), mi.Bool(True))["rgb"]).T
    extent = float(mi.traverse(integ.sets["interface"].shape)["extent"])
    ref = [brute_force(g, "surfel", o[i], d[i], extent) for i in range(len(o))]
    want = np.array([_np_srgb(c) if a > 0.05 else np.zeros(3) for c, a, _, _ in ref])
    covered = np.array([a > 0.05 for _, a, _, _ in ref])
    assert 0.2 < covered.mean() < 0.95, "rays should both hit and miss the cloud"
    err = np.abs(got - want).max(1)
    # srgb's slope (up to 12.92 near 0) scales the compositor's 1e-4 agreement
    assert np.mean(err < 1e-3) >= 0.97 and err.mean() < 5e-3, f"colour error {err.mean():.2e}"


def test_plane_pixel_is_albedo_plus_the_reflected_grid(rng):
    r0 = 0.4
    plane = GaussianSet.from_activated([[0.0, 0.0, 0.0]], [100.0, 100.0, 0.01], opacities=1.0,
                                       colors=[[0.2, 0.3, 0.1]], specular=r0)
    integ = make_integrator({"interface": plane}, components="all", blend="refgs", env_levels=4,
                            alpha_max=1 - 1e-7)
    values = rng.normal(-2.0, 0.8, (16, 32, 3)).astype(np.float32)
    integ.env.set_numpy(values)
    n = 40
    o = np.column_stack([rng.uniform(-0.5, 0.5, (n, 2)), np.full(n, -4.0)])
    d = np.column_stack([rng.uniform(-0.6, 0.6, (n, 2)), np.ones(n)])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    got = to_np(integ.trace(rays(o, d), mi.Bool(True))["rgb"]).T
    normal = np.array([0.0, 0.0, 1.0])
    want = []
    for di in d:
        wo = di - 2 * (di @ normal) * normal
        s = np.exp(np.minimum(_np_lookup(values, wo / np.linalg.norm(wo), r0 * 4), 5.0))
        want.append(_np_srgb(np.array([0.2, 0.3, 0.1]) + s))
    np.testing.assert_allclose(got, np.array(want), atol=1e-4)


def test_refgs_gradients_match_finite_differences(rng):
    g = random_set(rng, 40, spread=(1, 1, 0.3), scale=(0.2, 0.5), specular=rng.uniform(0.2, 0.8, 40),
                   colors=rng.uniform(0.05, 0.4, (40, 3)))
    integ = make_integrator({"interface": g}, components="all", blend="refgs", env_levels=3)
    integ.env.set_numpy(rng.normal(-1.5, 0.6, (8, 16, 3)).astype(np.float32))
    n = 150
    o = np.tile([0.2, 0.1, -4.0], (n, 1))
    tgt = np.column_stack([rng.uniform(-0.8, 0.8, (n, 2)), np.zeros(n)])
    ray = rays(o, tgt - o)
    w = rng.normal(size=(n, 3)).astype(np.float32)
    params = mi.traverse(integ)
    for k in ("interface.specular", "interface.data"):
        dr.enable_grad(params[k])
    integ.env.enable_grad()
    out = integ.trace(ray, mi.Bool(True), record=True)
    dr.eval(out["passes"])
    integ.backward(ray, mi.Bool(True), out, {"rgb": mi.Color3f(*[mi.Float(w[:, i]) for i in range(3)])})
    value = lambda: float(np.sum(to_np(integ.trace(ray, mi.Bool(True))["rgb"]).T * w))
    g_env = integ.env.grad()  # level 0's, through the pyramid's transpose
    base = integ.env.data.copy()
    checked = 0
    for i in np.argsort(-np.abs(g_env))[:4]:
        fd = []
        for s in (1, -1):
            b = base.copy()
            b[i] += s * 1e-2
            integ.env.data = b
            fd.append(value())
        integ.env.data = base
        assert abs(g_env[i] - (fd[0] - fd[1]) / 2e-2) <= 0.02 * abs(g_env[i]) + 1e-4, ("env", i)
        checked += 1
    g_spec = to_np(dr.grad(params["interface.specular"]))
    for i in np.argsort(-np.abs(g_spec))[:3]:
        # a small step: the level's linear weights have kinks at integer levels
        fd = central_difference(params, "interface.specular", int(i), value, 2e-3)
        assert abs(g_spec[i] - fd) <= 0.03 * abs(g_spec[i]) + 2e-3, ("beta", i, g_spec[i], fd)
        checked += 1
    g_data = to_np(dr.grad(params["interface.data"])).reshape(len(g), -1)
    # the path-replay backward equals plain AD through the trace for every packed entry (rel 1e-4)
    dr.clear_grad(params["interface.data"])
    W = mi.Color3f(*[mi.Float(w[:, i]) for i in range(3)])
    dr.backward(dr.sum(dr.sum(integ.trace(ray, mi.Bool(True), ad=True)["rgb"] * W)))
    np.testing.assert_allclose(to_np(dr.grad(params["interface.data"])).reshape(len(g), -1), g_data, rtol=1e-4,
                               atol=1e-5)
    assert checked == 7


@BITWISE
def test_refgs_trains_resumes_and_saves_its_grid(tmp_path, monkeypatch):
    from glint_mi.dataset.generate import Preset, make_scene
    from glint_mi.scene import read_scene, scene_xml
    from glint_mi.training.trainer import Trainer
    from test_train import _interrupt_at

    room = tmp_path / "room"
    make_scene(room, seed=0, preset=Preset.named("tiny"), sfm="none")
    (tmp_path / "scene.xml").write_text(scene_xml(room))
    spec = read_scene(tmp_path / "scene.xml")
    cfg = lambda: config_for("refgs", "tiny", iterations=24, patches=4, checkpoint_every=1000, log_every=1000)
    threads = dr.thread_count()
    dr.set_thread_count(1)
    try:
        a = Trainer(tmp_path / "a", cfg(), scene=spec, log=lambda *x: None)
        start = a.env.copy()
        a.train(progress=False)
        b = Trainer(tmp_path / "b", cfg(), scene=spec, log=lambda *x: None)
        _interrupt_at(b, monkeypatch, 11)
        with pytest.raises(KeyboardInterrupt):
            b.train(progress=False)
        b2 = Trainer(tmp_path / "b", cfg(), resume=True, log=lambda *x: None)
        assert b2.it == 12
        b2.train(progress=False)
    finally:
        dr.set_thread_count(threads)
    assert not np.array_equal(a.env, start), "the grid should train"
    assert np.array_equal(a.env, b2.env)
    assert np.array_equal(a.sets["interface"].sh, b2.sets["interface"].sh)
    # the saved model renders what the trainer renders
    a.save_model()
    assert (tmp_path / "a" / "model" / "env.npy").exists()
    from glint_mi.evaluate import load_model

    integ = load_model(tmp_path / "a", a.cfg)
    saved = np.load(tmp_path / "a" / "model" / "env.npy")
    assert np.array_equal(saved.transpose(2, 0, 1).ravel(), a.env)  # the trainer's grid, as [h, w, 3]
    assert np.array_equal(integ.env.numpy(), saved)
    from glint_mi.evaluate import evaluate

    m_live = evaluate(a.integ_for_eval(), a.ds.test_views, write=False)["metrics"]
    m_saved = evaluate(integ, a.ds.test_views, write=False)["metrics"]
    assert m_saved["psnr"] == pytest.approx(m_live["psnr"], abs=1e-4)


def test_shading_head_normal_gradient_matches_finite_differences(rng):
    """d pixel / d composited normal (through the reflected direction and the grid's bilinear weights), per ray:
    the head alone, where finite differences do not cross shells (the rotations' path to the normal is the one
    tests/test_integrator.py checks for GLINT's mirror rays)."""
    from glint_mi_plugins.glint_env import refgs_shade

    grid = DirectionalGrid(4)
    grid.set_numpy(rng.normal(-1.5, 0.6, (16, 32, 3)).astype(np.float32))
    n = 64
    N = rng.normal(size=(n, 3))
    N[:, 2] = -np.abs(N[:, 2]) - 0.5  # facing the rays
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    d = np.column_stack([rng.uniform(-0.3, 0.3, (n, 2)), np.ones(n)])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    C, B = rng.uniform(0.05, 0.3, (n, 3)), rng.uniform(0.1, 0.9, n)
    w = rng.normal(size=(n, 3))
    vec = lambda a: mi.Vector3f(*[mi.Float(a[:, k]) for k in range(3)])

    def value(normals, grad=False):
        Nv = vec(normals)
        if grad:
            dr.enable_grad(Nv)
        rgb = refgs_shade(mi.Color3f(*[mi.Float(C[:, k]) for k in range(3)]), mi.Float(np.ones(n)), mi.Float(B),
                          dr.normalize(Nv), vec(d), grid)
        total = dr.sum(rgb.x * mi.Float(w[:, 0]) + rgb.y * mi.Float(w[:, 1]) + rgb.z * mi.Float(w[:, 2]))
        if grad:
            dr.backward(total)
            return np.array(dr.grad(Nv)).T
        return float(np.array(total).ravel()[0])

    g = value(N, grad=True)
    h, ok = 1e-3, 0
    for r in range(0, n, 4):
        for k in range(3):
            p, m = N.copy(), N.copy()
            p[r, k] += h
            m[r, k] -= h
            fd = (value(p) - value(m)) / (2 * h)
            assert abs(g[r, k] - fd) <= 0.03 * abs(g[r, k]) + 5e-3, (r, k, g[r, k], fd)
            ok += abs(fd) > 1e-2
    assert ok >= 10, "the test should exercise non-zero normal derivatives"
