"""The glint integrator: reference equality, the Fresnel split, energy, gradients vs finite differences,
component switching, second order, scene loading and bad input.

Tolerances: interface vs volprim_rf_basic 1e-4 abs (float32, identical maths); Fresnel identity 1e-5;
AD vs central FD (h = 1e-3, float32) 2 % relative or 2e-3 absolute, in the smooth regime (rays near kernel centres,
extent 5 so no shell boundary or cut-off is crossed by the FD step).
"""
import numpy as np
import pytest

import drjit as dr
import mitsuba as mi

from conftest import camera, central_difference, make_integrator, random_set, rays, to_np
from glint_mi.model import examples
from glint_mi.model.gaussians import GaussianSet
from glint_mi.model.render import render_buffers
from glint_mi_plugins.glint_gaussians import make_shape


def test_interface_matches_volprim_rf_basic(rng):
    g = random_set(rng, 400, spread=(1, 1, 1), scale=(0.05, 0.2))
    glint = {"type": "glint", "components": "interface", "aovs": "interface,alpha", "alpha_min": 0.0,
             "alpha_max": 0.9999, "transmittance_min": 0.01, "interface": make_shape(g, "ellipsoid", extent=3.0, min_shell_ratio=0.0, opacity_shells=False)}
    ref = {"type": "volprim_rf_basic", "srgb_primitives": False, "max_depth": 100000}
    a = render_buffers(mi.load_dict({"type": "scene", "integrator": glint, "sensor": camera()}))
    r = np.array(mi.render(mi.load_dict({"type": "scene", "integrator": ref, "sensor": camera(),
                                         "g": make_shape(g, "ellipsoid", extent=3.0, min_shell_ratio=0.0, opacity_shells=False)})))
    assert a["alpha"].mean() > 0.3, "test scene should cover the image"
    # volprim advances by a fixed 1e-4 after each hit and so drops Gaussians entered within 1e-4 of the previous
    # one (verified against the brute force below); all other pixels agree to float precision.
    close = np.abs(a["interface"] - r[..., :3]).max(-1) < 1e-4
    assert close.mean() > 0.95
    assert np.abs(a["interface"] - r[..., :3]).mean() < 2e-3


def _brute_force(gset, o, d, t_min=0.01, alpha_max=0.9999, extent=3.0, alpha_min=0.0, opacity_shells=False):
    """Independent numpy 3DGRT compositing of one ray: shells sorted by entry, kernel at the peak. With
    ``opacity_shells`` a Gaussian's shell (in sigmas) is where opacity x G = exp(-extent^2 / 2)."""
    from scipy.spatial.transform import Rotation
    act, hits = gset.activated(), []
    for i in range(len(gset)):
        R, s = Rotation.from_quat(act["quats_xyzw"][i]).as_matrix(), act["scales"][i]
        ol, dl = R.T @ (o - act["means"][i]) / s, R.T @ d / s
        r2 = extent ** 2 + 2 * np.log(act["opacity"][i]) if opacity_shells else extent ** 2
        if r2 <= 0:
            continue
        a, b, c = dl @ dl, ol @ dl, ol @ ol - r2
        if b * b - a * c < 0 or (-b - np.sqrt(b * b - a * c)) / a < 0:
            continue
        G = np.exp(-0.5 * np.sum((ol - b / a * dl) ** 2))
        alpha = min(act["opacity"][i] * G, alpha_max)
        if alpha >= alpha_min:
            hits.append(((-b - np.sqrt(b * b - a * c)) / a, alpha,
                         np.maximum(act["sh"][i, 0] * 0.28209479177387814 + 0.5, 0)))
    C, T = np.zeros(3), 1.0
    for _, alpha, col in sorted(hits, key=lambda h: h[0]):
        C, T = C + T * alpha * col, T * (1 - alpha)
        if T < t_min:
            break
    return C


@pytest.mark.parametrize("opacity_shells", [False, True])
def test_interface_matches_brute_force(rng, opacity_shells):
    """Without opacity shells at volprim's cut-offs (no alpha floor); with them at the paper's 1/255 floor, which
    the default 3.33-sigma shell of an opaque Gaussian matches, and opacities down to below the floor."""
    g = random_set(rng, 300, spread=(1, 1, 1), scale=(0.05, 0.2))
    cut = {"alpha_min": 0.0} if not opacity_shells else {}
    if opacity_shells:
        g.logit_opacity[:] = rng.uniform(-7.0, 3.0, len(g))  # opacity 0.001 .. 0.95
    integ = make_integrator({"interface": g}, kernels={"interface": "ellipsoid"}, components="interface",
                            shape_kw={"min_shell_ratio": 0.0, "opacity_shells": opacity_shells}, alpha_max=0.9999,
                            transmittance_min=0.01, **cut)
    o = np.column_stack([rng.uniform(-0.8, 0.8, (40, 2)), np.full(40, -4.0)])
    d = np.column_stack([rng.uniform(-0.1, 0.1, (40, 2)), np.ones(40)])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    got = to_np(integ.trace(rays(o, d), mi.Bool(True))["interface"]).T
    extent = integ.sets["interface"].shape.eval_attribute_1("extent", dr.zeros(mi.SurfaceInteraction3f), True)[0]
    want = np.array([_brute_force(g, o[i], d[i], extent=extent, alpha_min=integ.alpha_min,
                                  opacity_shells=opacity_shells) for i in range(len(o))])
    assert np.abs(want).max() > 0.1, "the rays should hit Gaussians"
    np.testing.assert_allclose(got, want, atol=1e-4)


def _slab(rng, z, n=200, **kw):
    """A dense layer of surfels facing -z at depth z, covering [-1.5, 1.5]^2."""
    xy = rng.uniform(-1.5, 1.5, (n, 2))
    return GaussianSet.from_activated(np.column_stack([xy, np.full(n, z)]), [0.3, 0.3, 0.01], opacities=1.0,
                                      colors=rng.uniform(0.2, 0.8, (n, 3)), **kw)


def test_fresnel_split_at_normal_incidence(rng):
    sets = {"interface": _slab(rng, 0.0, specular=0.0, transparency=1.0),
            "reflection": random_set(rng, 300, center=(0, 0, -2), spread=(2, 2, 0.3), scale=(0.3, 0.5)),
            "transmission": random_set(rng, 300, center=(0, 0, 2), spread=(2, 2, 0.3), scale=(0.3, 0.5))}
    integ = make_integrator(sets, components="all", alpha_max=1 - 1e-7, transmittance_min=1e-9, aovs="weights")
    r = rays(np.column_stack([rng.uniform(-0.3, 0.3, (64, 2)), np.full(64, -3.0)]), [0, 0, 1])
    out = integ.trace(r, mi.Bool(True))
    ks, kt, kd = to_np(out["ks"]), to_np(out["kt"]), to_np(out["kd"])
    np.testing.assert_allclose(ks, 0.04, atol=1e-5)
    np.testing.assert_allclose(kt, 0.96, atol=1e-5)
    np.testing.assert_allclose(kd, 0.0, atol=1e-5)
    rgb, cR, cT = to_np(out["rgb"]), to_np(out["reflection"]), to_np(out["transmission"])
    assert cR.mean() > 0.05 and cT.mean() > 0.05
    np.testing.assert_allclose(rgb, 0.04 * cR + 0.96 * cT, atol=1e-5)


def _weights_reference(cos, beta, tau, ior=1.5, auto=False, reflect_min=0.05, transmit_min=1e-3):
    """The paper's weights (glint-method.md section 2), written out: Schlick F = F0 + (1 - F0)(1 - cos)^5,
    k_s = clamp(beta + (1 - beta) F, F0, 1), k_d = (1 - k_s)(1 - t), k_t = (1 - k_s) t; ``auto`` folds a weight
    under its threshold into k_d."""
    f0 = ((1 - ior) / (1 + ior)) ** 2
    F = f0 + (1 - f0) * (1 - cos) ** 5
    ks = np.clip(beta + (1 - beta) * F, f0, 1.0)
    kd, kt = (1 - ks) * (1 - tau), (1 - ks) * tau
    if auto:
        kd = kd + np.where(ks > reflect_min, 0, ks) + np.where(kt > transmit_min, 0, kt)
        ks, kt = np.where(ks > reflect_min, ks, 0), np.where(kt > transmit_min, kt, 0)
    return kd, ks, kt


@pytest.mark.parametrize("components", ["all", "auto"])
@pytest.mark.parametrize("beta,tau,ior", [(0.0, 0.0, 1.5), (0.0, 0.6, 1.5), (0.3, 1.0, 1.5), (0.0, 0.3, 2.4)])
def test_fresnel_weights_follow_schlick(rng, components, beta, tau, ior):
    """Rays hit one opaque surfel plane (normal +z) at 0-89 degrees: k_d, k_s, k_t equal the written-out Schlick
    weights at every angle (exponent 5, the angle, the beta term, the F0 clamp, ior), auto folding weak weights."""
    plane = GaussianSet.from_activated([[0.0, 0.0, 0.0]], [100.0, 100.0, 0.01], opacities=1.0, colors=[[0.5] * 3],
                                       specular=beta, transparency=tau)
    sets = {"interface": plane, "reflection": random_set(rng, 50, center=(0, 0, -3)),
            "transmission": random_set(rng, 50, center=(0, 0, 3))}
    integ = make_integrator(sets, components=components, alpha_max=1 - 1e-7, ior=ior, aovs="weights")
    angles = np.radians([0.0, 20.0, 45.0, 60.0, 75.0, 85.0, 89.0])
    d = np.column_stack([np.sin(angles), np.zeros_like(angles), np.cos(angles)])
    out = integ.trace(rays(np.column_stack([np.zeros(len(d)), np.zeros(len(d)), np.full(len(d), -0.01)]), d),
                      mi.Bool(True))
    assert np.allclose(to_np(out["alpha"]), 1.0, atol=1e-5)
    kd, ks, kt = _weights_reference(np.cos(angles), beta, tau, ior, auto=components == "auto")
    np.testing.assert_allclose(to_np(out["ks"]), ks, atol=2e-5)
    np.testing.assert_allclose(to_np(out["kt"]), kt, atol=2e-5)
    np.testing.assert_allclose(to_np(out["kd"]), kd, atol=2e-5)


def test_planar_depth_of_a_plane(rng):
    """An opaque wall at z = 1 seen by a camera at z = -4 has planar depth 5 everywhere (not ray distance)."""
    wall = _slab(rng, 1.0, n=600, specular=0.0, transparency=0.0)
    scene = mi.load_dict({"type": "scene", "sensor": camera(24, 16),
                          "integrator": {"type": "glint", "alpha_max": 1 - 1e-6, "interface": make_shape(wall)}})
    b = render_buffers(scene)
    good = b["alpha"][..., 0] > 0.999
    assert good.mean() > 0.5
    d = b["depth"][..., 0][good]
    assert np.ptp(d) < 0.05 * d.mean(), "planar depth of a fronto-parallel wall must be ~constant"
    assert abs(np.median(d) - np.linalg.norm([0.2, 0.1, -4]) * (1 + 1 / 4)) < 0.15
    n = b["normal"][good]
    assert np.all(n[:, 2] < -0.99), "normals face the camera"


# ------------------------------------------------------------------ gradients
def _sphere_dirs():
    """14 directions: the 6 axes and the 8 cube diagonals."""
    diag = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) / np.sqrt(3)
    return np.vstack([np.eye(3), -np.eye(3), diag])


def _grad_setup(rng, kernel, normal_source="axis"):
    def mk(c, k):
        n = len(c)
        return GaussianSet.from_activated(np.array(c), rng.uniform(0.3, 0.5, (n, 3)), rng.normal(size=(n, 4)),
                                          opacities=rng.uniform(0.3, 0.6, n), colors=rng.uniform(0.2, 0.8, (n, 3)),
                                          specular=rng.uniform(0.1, 0.5, n), transparency=rng.uniform(0.2, 0.8, n))
    sets = {"interface": mk([[0, 0, 0], [0.1, 0.05, 0.5]], kernel),
            # six blobs around the interface (a ray starting inside a Gaussian does not see it)
            "reflection": GaussianSet.from_activated(_sphere_dirs() * 2.6, [0.5, 0.5, 0.5], opacities=0.6,
                                                     colors=rng.uniform(0.2, 0.9, (14, 3)), sh_degree=1),
            "transmission": mk([[0.1, 0, 2]], kernel)}
    sets["reflection"].sh[:, 1:] = rng.normal(0, 0.3, (14, 3, 3))
    if normal_source == "attribute":  # normals of their own, away from the surfels' axes
        for role in ("interface", "transmission"):
            sets[role].normals = (sets[role].normals + rng.normal(0, 0.5, sets[role].normals.shape)).astype(np.float32)
    # detach_depth off: AD then gives the total derivative that finite differences measure
    desc = {"type": "glint", "components": "all", "max_order": 2, "detach_depth": False}
    for role, s in sets.items():
        desc[role] = make_shape(s, kernel=kernel if role != "reflection" else "ellipsoid", extent=5.0,
                                normal_source=normal_source if role != "reflection" else "axis")
    integ = mi.load_dict(desc)
    r = rays([[0.05, -0.1, -3], [0.12, 0.02, -3], [-0.05, 0.1, -3]], [[0, 0.02, 1], [0, -0.01, 1], [0.01, 0.02, 1]])
    W = [float(w) for w in rng.uniform(0.5, 1.0, 8)]

    def loss():
        out = integ.trace(r, mi.Bool(True), ad=True, need={"trans_direct"}, forward=mi.Vector3f(0, 0, 1))
        c, n = out["rgb"], out["normal"]
        cd, dd, nd, ad = out["trans_direct"]
        return dr.sum(W[0] * c.x + W[1] * c.y + W[2] * c.z + 0.1 * W[3] * out["depth"] + W[4] * n.x
                      + W[5] * out["transparency"] + W[6] * cd.y + 0.1 * W[7] * dd
                      + 20.0 * W[0] * out["distortion"] + 0.1 * W[1] * out["median"])  # 2DGS terms
    return integ, loss


CASES = [("interface.opacities", [0, 1]), ("interface.data", [0, 1, 2, 6, 8]), ("interface.kernel_scales", [0, 1]),
         ("interface.specular", [0, 1]), ("interface.transparency", [0, 1]), ("interface.sh_coeffs", [0, 4]),
         ("reflection.data", [i * 10 + j for i in range(14) for j in (0, 2, 7)]),
         ("reflection.sh_coeffs", [i * 12 + j for i in range(14) for j in (1, 5)]),
         ("reflection.opacities", list(range(14))),
         ("transmission.data", [0, 1, 2]), ("transmission.opacities", [0]), ("transmission.specular", [0]),
         ("transmission.sh_coeffs", [2])]


NORMAL_CASES = [("interface.normals", list(range(6))), ("transmission.normals", [0, 1, 2])]


@pytest.mark.parametrize("kernel, normal_source", [("surfel", "axis"), ("ellipsoid", "axis"), ("surfel", "attribute")])
def test_gradients_match_finite_differences(rng, kernel, normal_source):
    """normal_source: attribute adds the normals' derivatives (read by Fresnel, the reflection direction and the
    normal AOV); every other parameter is checked in that mode too."""
    integ, loss = _grad_setup(rng, kernel, normal_source)
    params = mi.traverse(integ)
    failures, checked, touched = [], 0, set()
    cases = CASES + (NORMAL_CASES if normal_source == "attribute" else [])
    normal_checked = 0
    for key, idxs in cases:
        if kernel == "ellipsoid" and key.endswith("kernel_scales"):
            idxs = [0, 1, 2]
        dr.enable_grad(params[key])
        params.update()
        dr.backward(loss())
        grad = np.array(dr.grad(params[key])).ravel()
        dr.disable_grad(params[key])

        def value():
            with dr.suspend_grad():
                return float(np.array(loss()).ravel()[0])
        for i in idxs:
            fd = central_difference(params, key, i, value)
            checked += abs(fd) > 1e-3
            normal_checked += key.endswith("normals") and abs(fd) > 1e-3
            touched.add(key.split(".")[0]) if abs(fd) > 1e-3 else None
            if abs(grad[i] - fd) > max(0.02 * abs(fd), 2e-3):
                failures.append(f"{key}[{i}]: AD {grad[i]:+.5f} FD {fd:+.5f}")
    assert not failures, "\n".join(failures)
    assert checked >= 15 and touched == {"interface", "reflection", "transmission"}, \
        f"only {checked} non-zero derivatives in {touched}: the test scene does not exercise every set"
    assert normal_source == "axis" or normal_checked >= 4, f"only {normal_checked} non-zero normal derivatives"


@pytest.mark.parametrize("kernel,detach,normal_source", [("surfel", False, "axis"), ("ellipsoid", False, "axis"),
                                                          ("surfel", True, "axis"), ("surfel", False, "attribute")])
def test_replay_backward_equals_plain_ad(rng, kernel, detach, normal_source):
    """The constant-memory replay gives the same gradients as AD through evaluated loops (rel 1e-3), for every
    parameter of every set (the normals too with normal_source: attribute), with second order, the direct
    transmission pass and all AOV adjoints in the loss."""
    integ, _ = _grad_setup(rng, kernel, normal_source)
    integ.detach_depth = detach
    params = mi.traverse(integ)
    keys = [k for k in params.keys() if k.split(".")[-1] in ("data", "opacities", "kernel_scales", "sh_coeffs",
                                                             "specular", "transparency", "normals")]
    assert any(k.endswith("normals") for k in keys) == (normal_source == "attribute")
    r = rays(rng.normal([0, 0, -3], [0.15, 0.15, 0], (64, 3)), rng.normal([0, 0, 1], [0.03, 0.03, 0], (64, 3)))
    fwd = mi.Vector3f(0, 0, 1)
    adj = {"rgb": mi.Color3f(*[mi.Float(rng.uniform(0.5, 1, 64)) for _ in range(3)]),
           "depth": mi.Float(rng.uniform(-1, 1, 64)), "normal": mi.Vector3f(*[mi.Float(rng.normal(size=64)) for _ in range(3)]),
           "transparency": mi.Float(rng.normal(size=64)), "alpha": mi.Float(rng.normal(size=64)),
           "interface": mi.Color3f(0.3, -0.2, 0.1), "reflection": mi.Color3f(0.2, 0.1, -0.3),
           "trans_direct": (mi.Color3f(0.4, 0.2, 0.1), mi.Float(0.3), mi.Vector3f(0.1, 0.2, -0.1), mi.Float(-0.2)),
           "distortion": mi.Float(rng.uniform(50, 150, 64)), "median": mi.Float(rng.normal(size=64))}
    from glint_mi_plugins.glint_integrator import _adjoint_dot

    def grads():
        out = {k: np.array(dr.grad(params[k])).ravel().copy() for k in keys}
        for k in keys:
            dr.clear_grad(params[k])
        return out
    for k in keys:
        dr.enable_grad(params[k])
    params.update()
    dr.backward(dr.sum(_adjoint_dot(integ.trace(r, mi.Bool(True), ad=True, need={"trans_direct"}, forward=fwd), adj)))
    g_ad = grads()
    out = integ.trace(r, mi.Bool(True), need={"trans_direct"}, forward=fwd)
    integ.backward(r, mi.Bool(True), out, adj, forward=fwd)
    g_rp = grads()
    # the replay over the forward's stored hit lists (no BVH query) is the same computation
    out_l = integ.trace(r, mi.Bool(True), need={"trans_direct"}, forward=fwd, record=True)
    assert sum(x is not None for x in out_l["hit_lists"]) == 5  # interface, reflection, transmission, order 2, direct
    np.testing.assert_array_equal(np.array(out_l["rgb"]), np.array(out["rgb"]))
    integ.backward(r, mi.Bool(True), out_l, adj, forward=fwd)
    g_ls = grads()
    nonzero = 0
    for k in keys:
        scale = max(np.abs(g_ad[k]).max(), 1e-6)
        np.testing.assert_allclose(g_rp[k], g_ad[k], atol=1e-3 * scale, err_msg=k)
        np.testing.assert_allclose(g_ls[k], g_rp[k], rtol=1e-5, atol=1e-6 * scale, err_msg=k)
        nonzero += np.abs(g_ad[k]).max() > 1e-4
    assert nonzero >= 15


def test_distortion_and_median_depth_follow_2dgs(rng):
    """2DGS's depth distortion and median depth from the interface pass, against float64 numpy on the same hits
    (the stored hit list, each hit's alpha and distance from the kernel): the distortion as 2DGS's rasteriser sums
    it, hit by hit, sum_i w_i (m_i^2 A_{i-1} + M2_{i-1} - 2 m_i M1_{i-1}) with m the NDC-mapped distance (near 0.2,
    far 100), and the median as the distance of the last hit composited while T > 0.5 (where T falls below 0.5)."""
    near, far = 0.2, 100.0  # 2DGS's rasteriser planes
    n = 40
    surfels = GaussianSet.from_activated(np.c_[rng.uniform(-0.3, 0.3, (n, 2)), rng.uniform(0.5, 4.0, n)],
                                         np.c_[rng.uniform(0.3, 0.6, (n, 2)), np.full(n, 0.01)],
                                         opacities=rng.uniform(0.05, 0.3, n), colors=rng.uniform(0, 1, (n, 3)))
    integ = make_integrator({"interface": surfels}, components="all", max_hits=64)
    m = 48  # rays through the stack's core (T falls below 0.5) and its fringe (it does not)
    r = rays(np.c_[rng.uniform(-1.0, 1.0, (m, 2)), np.full(m, -1.0)], np.c_[rng.normal(0, 0.05, (m, 2)), np.ones(m)])
    with dr.suspend_grad():
        out = integ.trace(r, mi.Bool(True), forward=mi.Vector3f(0, 0, 1), record=True)
        listed, count = out["hit_lists"][0]
        listed, count = np.array(listed).reshape(m, -1), np.array(count)
        gs = integ.active_set("interface")
        ref_d, ref_med = np.zeros(m), np.zeros(m)
        for k in range(m):
            prims = listed[k, :count[k]]
            o = mi.Point3f(*[float(x) for x in np.array(r.o)[:, k]])
            d = mi.Vector3f(*[float(x) for x in np.array(r.d)[:, k]])
            alpha, t, *_ = integ._eval_kernel(gs, mi.UInt32(prims), o, d, mi.Bool(True))
            alpha, t = np.array(alpha, np.float64), np.array(t, np.float64)
            T = A = M1 = M2 = dist = 0.0
            T = 1.0
            for a, ti in zip(alpha, t):
                if a == 0:
                    continue
                w = T * a
                mm = far / (far - near) * (1 - near / max(ti, near))
                dist += w * (mm * mm * A + M2 - 2 * mm * M1)
                A, M1, M2 = A + w, M1 + w * mm, M2 + w * mm * mm
                if T > 0.5 and T * (1 - a) <= 0.5:
                    ref_med[k] = ti
                T *= 1 - a
            ref_d[k] = dist
    got_d, got_med = np.array(out["distortion"]), np.array(out["median"])
    assert (ref_med > 0).sum() >= 10 and (ref_med == 0).sum() >= 3 and ref_d.max() > 1e-4  # both cases occur
    np.testing.assert_allclose(got_d, ref_d, rtol=2e-3, atol=1e-7)
    np.testing.assert_allclose(got_med, ref_med, rtol=1e-5, atol=1e-6)


def test_mi_render_backward_reaches_aovs(rng):
    """Through mi.render (ADIntegrator.render_backward): a depth-only loss gives interface geometry gradients."""
    sets = examples.display_case_sets(800, seed=2)
    scene = mi.load_dict(examples.scene_dict(sets, width=32, height=18, aovs="depth"))
    params = mi.traverse(scene)
    key = "integrator.interface.data"
    dr.enable_grad(params[key])
    params.update()
    img = mi.render(scene, params)
    dr.backward(dr.sum(img[..., 3], axis=None))
    g = np.array(dr.grad(params[key])).reshape(-1, 10)
    assert np.isfinite(g).all() and np.abs(g[:, :3]).sum() > 0
    assert np.abs(g[:, 3:6]).sum() == 0, "shell scales are a BVH proxy and carry no gradient"
    # the replay over stored hit lists (default) and the re-tracing replay (lists over budget) agree
    scene.integrator().stored_hits_mb = 0.0
    dr.clear_grad(params[key])
    img = mi.render(scene, params)
    dr.backward(dr.sum(img[..., 3], axis=None))
    np.testing.assert_allclose(np.array(dr.grad(params[key])).reshape(-1, 10), g, rtol=1e-4,
                               atol=1e-6 * np.abs(g).max())


# ---------------------------------------------------------------- components
def test_components_are_switchable_and_skipped(rng):
    sets = examples.display_case_sets(1200, seed=4)
    full = render_buffers(mi.load_dict(examples.scene_dict(sets, width=40, height=24, components="all")))
    only = render_buffers(mi.load_dict(examples.scene_dict(sets, width=40, height=24, components="interface")))
    assert np.abs(only["reflection"]).max() == 0 and np.abs(only["transmission"]).max() == 0
    assert np.abs(full["transmission"]).max() > 0.1
    # a transmission set behind opaque surfaces only (t = 0 everywhere) never changes the image in auto mode
    opaque = dict(sets)
    opaque["interface"] = sets["interface"].subset(np.arange(len(sets["interface"])))
    opaque["interface"].logit_transparency[:] = -30.0
    a = render_buffers(mi.load_dict(examples.scene_dict(opaque, width=40, height=24)))
    trans = dict(opaque)
    trans["transmission"] = random_set(rng, 500, spread=(3, 3, 3))
    b = render_buffers(mi.load_dict(examples.scene_dict(trans, width=40, height=24)))
    np.testing.assert_array_equal(a["rgb"], b["rgb"])
    assert np.abs(b["transmission"]).max() == 0


def test_second_order_only_changes_specular_transmission(rng):
    sets = examples.display_case_sets(1200, seed=5)
    sc = lambda s, o: render_buffers(mi.load_dict(examples.scene_dict(s, width=40, height=24, components="all",
                                                                       max_order=o)))["rgb"]
    sets["transmission"].logit_specular[:] = -30.0  # beta_T = 0: second order adds nothing
    np.testing.assert_allclose(sc(sets, 1), sc(sets, 2), atol=1e-6)
    sets["transmission"].logit_specular[:] = 0.0  # beta_T = 0.5
    assert np.abs(sc(sets, 1) - sc(sets, 2)).max() > 1e-2


def test_xml_scene_loads_and_round_trips(tmp_path):
    import glint_mi
    sets = examples.display_case_sets(600, seed=6)
    xml = examples.write_scene(tmp_path, sets, width=32, height=18)
    scene = glint_mi.load_file(xml)
    b = render_buffers(scene)
    assert b["rgb"].shape == (18, 32, 3) and np.isfinite(b["rgb"]).all() and b["rgb"].mean() > 0.05
    keys = set(mi.traverse(scene).keys())
    assert {"integrator.interface.data", "integrator.transmission.transparency", "integrator.reflection.sh_coeffs"} <= keys
    # the file round-trips exactly through the shape plugin's loader
    again = GaussianSet.load_ply(tmp_path / "interface.ply")
    np.testing.assert_array_equal(again.means, sets["interface"].means)


def test_shape_saves_back_to_ply(tmp_path):
    """Scene -> shape parameters -> 3DGS .ply -> scene renders the same image (float32 activation round trip)."""
    import glint_mi
    from glint_mi_plugins.glint_gaussians import save_ply
    sets = examples.display_case_sets(600, seed=8)
    scene = glint_mi.load_file(examples.write_scene(tmp_path / "a", sets, width=32, height=18))
    integ = scene.integrator()
    for role, ref in integ.sets.items():
        save_ply(ref.shape, tmp_path / f"{role}.ply")
        back = GaussianSet.load_ply(tmp_path / f"{role}.ply")
        np.testing.assert_allclose(back.means, sets[role].means, atol=1e-6)
        np.testing.assert_allclose(back.log_scales, sets[role].log_scales, atol=1e-5)
        np.testing.assert_allclose(back.sh, sets[role].sh, atol=1e-6)
    again = {role: GaussianSet.load_ply(tmp_path / f"{role}.ply") for role in sets}
    b1 = render_buffers(scene)
    b2 = render_buffers(glint_mi.load_file(examples.write_scene(tmp_path / "b", again, width=32, height=18)))
    np.testing.assert_allclose(b1["rgb"], b2["rgb"], atol=1e-4)


# ----------------------------------------------------------------- bad input
def test_bad_input_errors(tmp_path, rng):
    g = random_set(rng, 10)
    with pytest.raises(Exception, match="unknown role 'glass'"):
        mi.load_dict({"type": "glint_gaussians", "role": "glass", "centers": mi.TensorXf(np.zeros((3, 3)))})
    with pytest.raises(Exception, match="'scales' has 2 rows but 'centers' has 3"):
        mi.load_dict({"type": "glint_gaussians", "centers": mi.TensorXf(np.zeros((3, 3))),
                      "scales": mi.TensorXf(np.ones((2, 3)))})
    with pytest.raises(Exception, match="'centers' contains NaN"):
        mi.load_dict({"type": "glint_gaussians", "centers": mi.TensorXf(np.full((3, 3), np.nan))})
    with pytest.raises(Exception, match="'opacities' must lie in \\[0, 1\\]"):
        mi.load_dict({"type": "glint_gaussians", "centers": mi.TensorXf(np.zeros((3, 3))),
                      "opacities": mi.TensorXf(np.full((3, 1), 2.0))})
    with pytest.raises(Exception, match="missing.ply: file not found"):
        mi.load_dict({"type": "glint_gaussians", "filename": str(tmp_path / "missing.ply")})
    with pytest.raises(Exception, match="unknown component"):
        make_integrator({"interface": g}, components="interface,mirrors")
    with pytest.raises(Exception, match="needs an 'interface' set"):
        make_integrator({"reflection": g})
    with pytest.raises(Exception, match="unknown AOV group"):
        make_integrator({"interface": g}, aovs="depth,colour")
    with pytest.raises(Exception, match="'ior' must be > 1"):
        make_integrator({"interface": g}, ior=0.5)
    with pytest.raises(Exception, match="kernel 'disc'"):
        make_shape(g, kernel="disc")


def test_traversal_only_pass_visits_the_same_hits(rng):
    """benchmarks/profile_step.py's traversal-only pass (march with budget = a pass's hit counts) stops after the
    same hits per ray and evaluates no kernel; the count is what the pass reports in info["hits"]."""
    g = random_set(rng, 400, spread=(1, 1, 1), scale=(0.05, 0.2))
    integ = make_integrator({"interface": g}, components="interface")
    o = np.column_stack([rng.uniform(-0.8, 0.8, (64, 2)), np.full(64, -4.0)])
    d = np.column_stack([rng.uniform(-0.1, 0.1, (64, 2)), np.ones(64)])
    r = rays(o, d)
    gs = integ.active_set("interface")
    info = {}
    acc = integ.march(gs, r.o, r.d, mi.Bool(True), info=info)
    hits = mi.UInt32(info["hits"])
    dr.eval(acc, hits)
    h = to_np(hits)
    assert h.max() >= 3 and (h == 0).sum() < len(h)
    empty = integ.march(gs, r.o, r.d, mi.Bool(True), budget=hits, info=info)
    np.testing.assert_array_equal(to_np(info["hits"]), h)
    assert float(dr.max(dr.abs(empty.A))[0] if dr.width(empty.A) else 0.0) == 0.0
    integ.march(gs, r.o, r.d, mi.Bool(True), budget=mi.UInt32(np.minimum(h, 2).astype(np.uint32)), info=info)
    np.testing.assert_array_equal(to_np(info["hits"]), np.minimum(h, 2))
    # a recording pass, then passes of another width (the lists must not leak into later loops)
    integ.trace(r, mi.Bool(True), record=True)
    r2 = rays(o[:40], d[:40])
    np.testing.assert_allclose(to_np(integ.trace(r2, mi.Bool(True))["rgb"]), to_np(acc.C)[:, :40], atol=1e-6)


def test_t_raise_drops_only_upward_pushes_on_t(rng):
    """backward(t_raise=...): on rays where t may not rise, a negative adjoint of the interface's t is dropped and a
    positive one kept; equal, exactly, to the ungated replay with the transparency adjoint clamped on those rays."""
    integ, _ = _grad_setup(rng, "surfel")
    params = mi.traverse(integ)
    key = "interface.transparency"
    n = 64
    r = rays(rng.normal([0, 0, -3], [0.15, 0.15, 0], (n, 3)), rng.normal([0, 0, 1], [0.03, 0.03, 0], (n, 3)))
    fwd = mi.Vector3f(0, 0, 1)
    a_t = rng.normal(size=n)
    may = rng.uniform(size=n) < 0.5

    def grad(adj_t, t_raise=None):
        dr.enable_grad(params[key])
        params.update()
        out = integ.trace(r, mi.Bool(True), need={"trans_direct"}, forward=fwd, record=True)
        integ.backward(r, mi.Bool(True), out, {"transparency": mi.Float(adj_t)}, forward=fwd,
                       t_raise=None if t_raise is None else mi.Bool(t_raise))
        g = np.array(dr.grad(params[key])).ravel().copy()
        dr.clear_grad(params[key])
        return g
    gated = grad(a_t, may)
    clamped = grad(np.where(may | (a_t >= 0), a_t, 0.0))
    free = grad(a_t)
    np.testing.assert_allclose(gated, clamped, rtol=1e-6, atol=1e-9)
    assert np.abs(gated - free).max() > 1e-4  # the gate changed something
    # no ray may raise t: every Gaussian's t gradient is >= 0 (descent can only lower t)
    assert (grad(-np.abs(a_t), np.zeros(n, bool)) == 0).all()
    assert (grad(-np.abs(a_t)) < 0).any()


def test_tracing_selects_sets_for_a_block_only():
    """integ.tracing(roles): only those sets inside the block, the former ones after it (also after an error);
    select() refuses a set name that does not exist. A training step traces its stage's sets and leaves the
    integrator as it found it."""
    import pytest

    from glint_mi.model.examples import gaussian_scene_dict

    rng = np.random.default_rng(0)
    sets = {r: random_set(rng, 8) for r in ("interface", "transmission", "reflection")}
    integ = mi.load_dict(gaussian_scene_dict(sets, components="all")).integrator()
    assert integ.enabled == {"interface", "transmission", "reflection"}
    with integ.tracing({"interface"}):
        assert integ.active_set("reflection") is None and integ.active_set("interface") is not None
    assert integ.active_set("reflection") is not None
    with pytest.raises(RuntimeError):
        with integ.tracing({"interface", "transmission"}):
            raise RuntimeError("inside")
    assert integ.enabled == {"interface", "transmission", "reflection"}
    with pytest.raises(ValueError, match="unknown set"):
        integ.select({"glass"})
