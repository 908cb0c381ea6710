"""Small measurements of the image model used by notebooks and docs: everything goes through the integrator."""
from __future__ import annotations

import time

import numpy as np


def fresnel_weights_vs_angle(angles_deg, beta: float = 0.0, tau: float = 0.5, ior: float = 1.5) -> dict:
    """k_d, k_s, k_t of the glint integrator for rays hitting an interface slab at ``angles_deg`` from its normal.

    The slab is a dense layer of opaque surfels (beta, tau given); the weights are read from ``trace()``.
    """
    import mitsuba as mi

    from glint_mi.model.gaussians import GaussianSet
    from glint_mi.model.shapes import make_shape

    rng = np.random.default_rng(0)
    n = 2000
    xy = rng.uniform(-6, 6, (n, 2))
    slab = GaussianSet.from_activated(np.column_stack([xy, np.zeros(n)]), [0.4, 0.4, 0.01], opacities=1.0,
                                      colors=0.5, specular=beta, transparency=tau)
    # the reflection and transmission sets must be present for their weights to exist (an absent set gives its weight
    # to the diffuse term): one far Gaussian each
    far = lambda z: GaussianSet.from_activated([[0.0, 0.0, z]], 0.5, opacities=0.5)
    integ = mi.load_dict({"type": "glint", "components": "all", "ior": ior, "alpha_max": 1 - 1e-7,
                          "transmittance_min": 1e-9, "interface": make_shape(slab, role="interface"),
                          "reflection": make_shape(far(-50.0), role="reflection"),
                          "transmission": make_shape(far(50.0), role="transmission")})
    th = np.radians(np.asarray(angles_deg, float))
    d = np.column_stack([np.sin(th), np.zeros_like(th), np.cos(th)])  # towards +z, the slab faces -z
    o = -2.0 * d
    ray = mi.Ray3f(mi.Point3f(*[mi.Float(o[:, i]) for i in range(3)]), mi.Vector3f(*[mi.Float(d[:, i]) for i in range(3)]))
    out = integ.trace(ray, mi.Bool(True))
    k = {w: np.broadcast_to(np.array(out[w]), th.shape).copy() for w in ("kd", "ks", "kt")}
    return {"angle_deg": np.asarray(angles_deg, float), **k, "f0": integ.f0}


def mesh_mode_vs_path(width=48, height=36, spp=64, seed=7) -> dict:
    """The first-order glass reference (glint mesh mode) against Mitsuba's full path tracer on a small glass room."""
    import mitsuba as mi

    from glint_mi.model.mesh_room import glass_room_dict
    from glint_mi.model.render import render_buffers

    path_scene = mi.load_dict(glass_room_dict({"type": "path", "max_depth": 64}, True, width, height, spp))
    fo_scene = mi.load_dict(glass_room_dict({"type": "glint", "max_depth": 64}, True, width, height, spp))
    # compile both renderers' kernels first, at the timed spp (it is part of the kernel): the timings below are warm.
    # mi.render(spp=k) leaves the sensor's sampler at k, so every render names its spp.
    mi.render(path_scene, spp=spp, seed=seed + 1)
    render_buffers(fo_scene, spp=spp, seed=seed + 1)
    t0 = time.perf_counter()
    ref = np.array(mi.render(path_scene, spp=spp, seed=seed))
    t1 = time.perf_counter()
    fo = render_buffers(fo_scene, spp=spp, seed=seed)
    t2 = time.perf_counter()
    glass = fo["transparency"][..., 0] > 0.5
    err = np.abs(fo["rgb"] - ref)
    return {"path": ref, "first_order": fo, "abs_error": err, "glass": glass,
            "rel_error": float(err.mean() / ref.mean()), "rel_error_glass": float(err[glass].mean() / ref[glass].mean()),
            "path_seconds": t1 - t0, "first_order_seconds": t2 - t1}
