"""Gaussians whose bounding shell contains the ray origin are seen (primary and secondary rays, gradients included).

Mitsuba's ellipsoid test never reports a shell around the ray origin; the integrator walks from one shell diameter
behind the origin. Reference: an independent numpy compositor that solves the ray/shell quadratic itself (both roots,
so an origin inside a shell is a hit), evaluates the kernel (surfel: at the plane crossing; ellipsoid: at the 3DGRT
peak), keeps kernels ahead of the origin and composites in order of shell entry.

Tolerances: 1e-4 abs per channel on >= 97 % of rays and 2e-3 mean (float32 shell tests near tangency differ from the
float64 reference, as in test_integrator); gradients vs central FD 2 % or 2e-3 abs.
"""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import drjit as dr
import mitsuba as mi

from conftest import central_difference, make_integrator, rays, to_np
from glint_mi.model.gaussians import GaussianSet

ALPHA_MIN, ALPHA_MAX, T_MIN = 1 / 255, 0.99, 1e-4


def brute_force(gset: GaussianSet, kernel: str, o, d, extent: float, opacity_shells: bool = True):
    """(colour [3], alpha, expected distance, shells holding the origin) of one ray, in float64. The shell is the
    full one of the packing (min_shell_ratio) shrunk here, not by the code under test, to where opacity x G =
    exp(-extent^2 / 2) when ``opacity_shells`` (the shapes' default)."""
    arr = gset.to_mitsuba(kernel, opacity_shells=False)
    act = gset.activated()
    hits, around = [], 0
    for i in range(len(gset)):
        R = Rotation.from_quat(arr["data"][i, 6:10]).as_matrix()
        r2 = extent ** 2 + 2 * np.log(act["opacity"][i]) if opacity_shells else extent ** 2
        if r2 <= 0:
            continue  # never reaches the cut-off: no contribution (its shell is a speck)
        c, shell, ks = act["means"][i], arr["data"][i, 3:6].astype(np.float64) * np.sqrt(r2), act["scales"][i]
        ol, dl = R.T @ (o - c), R.T @ d
        a, b, cc = np.sum((dl / shell) ** 2), np.sum(ol * dl / shell ** 2), np.sum((ol / shell) ** 2) - 1.0
        disc = b * b - a * cc
        if disc < 0:
            continue
        t0, t1 = (-b - np.sqrt(disc)) / a, (-b + np.sqrt(disc)) / a
        if t1 <= 0:
            continue  # the shell lies behind the origin
        around += t0 < 0
        if kernel == "surfel":
            t = -ol[2] / dl[2]
            u = ol + t * dl
            power = (u[0] / ks[0]) ** 2 + (u[1] / ks[1]) ** 2
        else:
            ols, dls = ol / ks, dl / ks
            t = -(ols @ dls) / (dls @ dls)
            power = np.sum((ols + t * dls) ** 2)
        alpha = min(act["opacity"][i] * np.exp(-0.5 * power), ALPHA_MAX)
        if t > 0 and alpha >= ALPHA_MIN:
            hits.append((t0, alpha, np.maximum(act["sh"][i, 0] * 0.28209479177387814 + 0.5, 0.0), t))
    C, A, Dt, T = np.zeros(3), 0.0, 0.0, 1.0
    for _, alpha, col, t in sorted(hits, key=lambda h: h[0]):
        w = T * alpha
        C, A, Dt, T = C + w * col, A + w, Dt + w * t, T * (1 - alpha)
        if T < T_MIN:
            break
    return C, A, (Dt / A if A > 0 else 0.0), around


def cloud(rng, n=60, scale=(0.2, 0.8)):
    """Large Gaussians in a 2 m box: most points of the box lie inside several shells."""
    return GaussianSet.from_activated(rng.uniform(-1, 1, (n, 3)), rng.uniform(*scale, (n, 3)), rng.normal(size=(n, 4)),
                                      opacities=rng.uniform(0.05, 0.3, n), colors=rng.uniform(0, 1, (n, 3)))


def _extent(integ, role="interface"):
    return float(mi.traverse(integ.sets[role].shape)["extent"])


@pytest.mark.parametrize("kernel", ["surfel", "ellipsoid"])
def test_camera_rays_inside_gaussians_match_brute_force(rng, kernel):
    g = cloud(rng)
    integ = make_integrator({"interface": g}, kernels={"interface": kernel}, components="interface")
    o = rng.uniform(-0.8, 0.8, (96, 3))
    d = rng.normal(size=(96, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    out = integ.trace(rays(o, d), mi.Bool(True))
    got_c, got_a, got_t = to_np(out["interface"]).T, to_np(out["alpha"]), to_np(out["distance"])
    ref = [brute_force(g, kernel, o[i], d[i], _extent(integ)) for i in range(len(o))]
    want_c, want_a, want_t = (np.array([r[k] for r in ref]) for k in range(3))
    assert np.mean([r[3] > 0 for r in ref]) > 0.9, "most origins should lie inside some shell"
    err = np.abs(got_c - want_c).max(1)
    assert np.mean(err < 1e-4) >= 0.97 and err.mean() < 2e-3, f"colour error {err.mean():.2e}"
    np.testing.assert_allclose(got_a, want_a, atol=2e-3)
    valid = want_a > 0.05
    np.testing.assert_allclose(got_t[valid], want_t[valid], rtol=1e-2, atol=1e-2)
    # without the walk back, the Gaussians around the origin vanish (what the option restores)
    old = make_integrator({"interface": g}, kernels={"interface": kernel}, components="interface",
                          inside_origins=False)
    assert np.abs(to_np(old.trace(rays(o, d), mi.Bool(True))["alpha"]) - want_a).mean() > 0.05


def test_large_surfel_near_the_camera_is_seen():
    """A surfel of sigma 5 m, 5 m ahead, tilted 60 deg: its shell holds the camera; it must render like sigma 1 m."""
    n = np.array([0.0, np.sin(np.radians(60)), -np.cos(np.radians(60))])
    q = Rotation.align_vectors([n], [[0, 0, 1]])[0].as_quat()[None]
    alphas = []
    for sigma in (1.0, 5.0):
        g = GaussianSet.from_activated([[0, 0, 5.0]], [[sigma, sigma, sigma * 1e-3]], q, opacities=[0.9])
        out = make_integrator({"interface": g}, components="interface").trace(rays([[0, 0, 0]], [[0, 0, 1]]),
                                                                              mi.Bool(True))
        alphas.append(float(to_np(out["alpha"])[0]))
        assert abs(float(to_np(out["distance"])[0]) - 5.0) < 1e-4
    np.testing.assert_allclose(alphas, [0.9, 0.9], atol=1e-5)


@pytest.mark.parametrize("kernel", ["surfel", "ellipsoid"])
def test_secondary_rays_see_gaussians_around_x_i(rng, kernel):
    """The transmission pass starts at x_I, inside the shells of transmission Gaussians there."""
    xy = rng.uniform(-2, 2, (300, 2))
    wall = GaussianSet.from_activated(np.column_stack([xy, np.zeros(300)]), [0.15, 0.15, 0.01], opacities=0.9,
                                      colors=[0.5, 0.5, 0.5], transparency=0.9)
    behind = cloud(rng, 40, (0.3, 0.6))
    behind.means[:, 2] = rng.uniform(-0.3, 1.0, 40)  # around and behind the wall at z = 0
    integ = make_integrator({"interface": wall, "transmission": behind}, kernels={"transmission": kernel},
                            components="all", aovs="transmission,alpha")
    o = np.column_stack([rng.uniform(-0.5, 0.5, (64, 2)), np.full(64, -3.0)])
    d = np.column_stack([rng.normal(0, 0.05, (64, 2)), np.ones(64)])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    out = integ.trace(rays(o, d), mi.Bool(True))
    x_i = o + to_np(out["distance"])[:, None] * d
    got = to_np(out["transmission"]).T
    ref = [brute_force(behind, kernel, x_i[i], d[i], _extent(integ, "transmission")) for i in range(64)]
    assert np.mean([r[3] > 0 for r in ref]) > 0.5, "x_I should lie inside transmission shells"
    want = np.array([r[0] for r in ref])
    err = np.abs(got - want).max(1)
    assert np.mean(err < 1e-4) >= 0.97 and err.mean() < 2e-3, f"c_T error {err.mean():.2e}"


@pytest.mark.parametrize("kernel", ["surfel", "ellipsoid"])
def test_gradients_of_a_gaussian_around_the_origin(rng, kernel):
    """Replay gradients of a Gaussian that holds every ray origin match central finite differences."""
    g = GaussianSet.from_activated([[0.0, 0.0, 0.3], [0.2, -0.1, 2.0]], [[1.2, 1.0, 0.9], [0.5, 0.6, 0.4]],
                                   [[0.1, 0.2, 0.0, 1.0], [0.0, 0.0, 0.3, 1.0]], opacities=[0.5, 0.6],
                                   colors=[[0.8, 0.3, 0.2], [0.1, 0.5, 0.9]])
    integ = make_integrator({"interface": g}, kernels={"interface": kernel}, components="interface",
                            shape_kw={"extent": 5.0}, aovs="alpha")
    o = rng.normal([0, 0, 0], 0.05, (8, 3))
    d = rng.normal([0, 0, 1], 0.05, (8, 3))
    r = rays(o, d)
    params = mi.traverse(integ)
    W = mi.Color3f(0.7, 1.0, 0.4)

    def loss_np():
        with dr.suspend_grad():
            out = integ.trace(r, mi.Bool(True))
            return float(np.sum(to_np(dr.dot(out["rgb"], W))) + np.sum(to_np(out["alpha"])))
    checked = 0
    for key, idxs in (("interface.opacities", [0]), ("interface.sh_coeffs", [0, 1, 2]), ("interface.data", [0, 2])):
        dr.enable_grad(params[key])
        params.update()
        out = integ.trace(r, mi.Bool(True))
        integ.backward(r, mi.Bool(True), out, {"rgb": mi.Color3f(W), "alpha": mi.Float(1.0)})
        grad = np.array(dr.grad(params[key])).ravel()
        dr.disable_grad(params[key])
        for i in idxs:
            fd = central_difference(params, key, i, loss_np)
            assert abs(grad[i] - fd) <= max(0.02 * abs(fd), 2e-3), f"{key}[{i}]: replay {grad[i]:+.5f} FD {fd:+.5f}"
            checked += abs(fd) > 1e-2
    assert checked >= 4, "the Gaussian around the origin should carry gradients"
