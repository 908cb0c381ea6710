"""Mesh mode of the glint integrator (:func:`trace_meshes`): a first-order reference of a mesh scene with real
glass: one exact-Fresnel split at the first glass surface, radiance beyond from Mitsuba's ``path`` integrator.
Also the ground-truth helpers :func:`is_glass` and :func:`first_surface` (the dataset generator uses them)."""
from __future__ import annotations

import drjit as dr
import mitsuba as mi


@dr.syntax
def through_glass(scene, ray, active, max_steps: int):
    """Advance rays past every glass surface they meet; returns rays whose first hit is opaque (or none)."""
    ray = mi.Ray3f(ray)
    active = mi.Bool(active)
    steps = mi.UInt32(0)
    while dr.hint(active, label="glint skip glass"):
        si = scene.ray_intersect(ray, active)
        glass = active & is_glass(si)
        ray[glass] = si.spawn_ray(ray.d)
        steps += 1
        active = glass & (steps < max_steps)
    return ray


def trace_meshes(path, scene, sampler, ray, active, forward, max_steps: int) -> dict:
    """First-order reference on a mesh scene: one Fresnel split at the first glass surface (primal only); ``path``
    is the ``path`` integrator that gives the radiance of opaque surfaces, ``forward`` the camera's axis (depth),
    ``max_steps`` the most glass surfaces a secondary ray passes."""
    si = scene.ray_intersect(ray, active)
    glass = active & is_glass(si)
    # Non-glass pixels first, so they consume the sampler exactly like a plain `path` render.
    L_direct, _, _ = path.sample(scene, sampler, ray, None, active & ~glass)

    ctx = mi.BSDFContext()
    bsdf = si.bsdf()
    # sample1 = 0 always picks the reflection lobe and 1 the transmission lobe; pdf is then F resp. 1 - F.
    bs_r, w_r = bsdf.sample(ctx, si, 0.0, mi.Point2f(0.5), glass)
    bs_t, w_t = bsdf.sample(ctx, si, 1.0 - 1e-6, mi.Point2f(0.5), glass)
    ok_r = glass & (bs_r.pdf > 0) & mi.has_flag(bs_r.sampled_type, mi.BSDFFlags.Reflection)
    ok_t = glass & (bs_t.pdf > 0) & (mi.has_flag(bs_t.sampled_type, mi.BSDFFlags.Transmission)
                                     | mi.has_flag(bs_t.sampled_type, mi.BSDFFlags.Null))
    F = dr.select(ok_r, bs_r.pdf, 0.0)
    ray_r = through_glass(scene, si.spawn_ray(si.to_world(bs_r.wo)), ok_r, max_steps)
    ray_t = through_glass(scene, si.spawn_ray(si.to_world(bs_t.wo)), ok_t, max_steps)
    L_r, _, _ = path.sample(scene, sampler, ray_r, None, ok_r)
    L_t, _, _ = path.sample(scene, sampler, ray_t, None, ok_t)
    L_r = dr.select(ok_r, mi.Spectrum(w_r) * L_r, 0.0)
    L_t = dr.select(ok_t, mi.Spectrum(w_t) * L_t, 0.0)
    kt = dr.select(ok_t, bs_t.pdf, 0.0)
    rgb = dr.select(glass, F * L_r + kt * L_t, L_direct)

    surf = first_surface(si, ray, active, forward)
    zero3 = mi.Color3f(0.0)
    kd = dr.select(glass, 0.0, 1.0)
    return {"rgb": rgb, "kd": kd, "ks": F, "kt": kt, "distance": surf["distance"], "depth": surf["depth"],
            "normal": surf["normal"], "transparency": surf["glass"], "alpha": surf["alpha"],
            "interface": dr.select(glass, zero3, mi.Color3f(L_direct)),
            "reflection": mi.Color3f(L_r), "transmission": mi.Color3f(L_t), "weights": (kd, F, kt),
            "trans_direct": (zero3, mi.Float(0.0), mi.Vector3f(0.0), mi.Float(0.0))}


def is_glass(si):
    """Hits on glass: ``dielectric`` (delta transmission) or ``thindielectric`` (delta reflection + Null lobe)."""
    flags = si.bsdf().flags()
    thin = mi.has_flag(flags, mi.BSDFFlags.Null) & mi.has_flag(flags, mi.BSDFFlags.DeltaReflection)
    return si.is_valid() & (mi.has_flag(flags, mi.BSDFFlags.DeltaTransmission) | thin)


def first_surface(si, ray, active, forward) -> dict:
    """Ground-truth buffers of the first surface along rays (glass included), in the project's conventions:
    ``depth`` planar camera z, ``normal`` world shading normal facing the ray, ``glass`` mask, ``alpha`` hit mask."""
    valid = active & si.is_valid()
    dist = dr.select(valid, si.t, 0.0)
    n = si.sh_frame.n
    n = dr.select(valid, dr.select(dr.dot(n, ray.d) > 0, -n, n), mi.Vector3f(0.0))
    return {"distance": dist, "depth": dist * dr.dot(ray.d, forward), "normal": n,
            "glass": dr.select(valid & is_glass(si), 1.0, 0.0), "alpha": dr.select(valid, 1.0, 0.0)}
