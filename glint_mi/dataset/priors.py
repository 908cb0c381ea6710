"""Imperfect priors derived from ground truth for generated scenes (the readers: :mod:`glint_mi.data.priors`).

Derived priors mimic monocular estimators, so that results made with them are meaningful (and are labelled:
``priors/PRIORS.json`` says ``"derived_from_ground_truth": true`` with every corruption parameter):
unknown per-image scale and shift of depth, multiplicative depth noise, Gaussian blur, angular normal noise, and on
glass the estimator *sees through*: depth and normal of the first opaque surface behind the glass, near-black
albedo (glass has almost no diffuse albedo).
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from glint_mi.data.priors import KINDS, PriorError, load_prior, prior_conventions, priors_are_derived  # noqa: F401


@dataclasses.dataclass
class Corruption:
    depth_scale: tuple = (0.5, 2.0)      # per-image unknown scale (uniform)
    depth_shift: tuple = (-0.3, 0.3)     # per-image unknown shift, in units of the median depth
    depth_noise: float = 0.02            # multiplicative Gaussian noise (std)
    blur_px: float = 1.0                 # Gaussian blur sigma of every map (pixels)
    normal_noise_deg: float = 5.0        # angular noise of normals (std, degrees)
    albedo_noise: float = 0.03
    glass_albedo: float = 0.02           # what the estimator reports on glass
    see_through_glass: float = 1.0       # probability, per view, that depth/normal see through the glass (real
                                         # estimators flicker between the glass and what is behind it)


def _blur(x, sigma):
    from scipy.ndimage import gaussian_filter

    if sigma <= 0:
        return x
    return gaussian_filter(x, sigma=(sigma, sigma) + (0,) * (x.ndim - 2))


def _behind_glass(scene, sensor, max_steps=16):
    """Depth (planar), camera ray distance, world normal and diffuse albedo of the first non-glass surface."""
    import drjit as dr
    import mitsuba as mi

    from glint_mi.render import camera_rays
    from glint_mi_plugins.glint_integrator import first_surface, is_glass

    w, h = sensor.film().crop_size()
    pix = np.stack(np.meshgrid(np.arange(w), np.arange(h)), -1).reshape(-1, 2)
    ray, fwd = camera_rays(sensor, pix)
    o = mi.Point3f(ray.o)
    with dr.suspend_grad():
        si = scene.ray_intersect(ray)
        for _ in range(max_steps):  # a handful of glass layers at most: a Python loop is enough here
            glass = is_glass(si)
            if not dr.any(glass):
                break
            nxt = si.spawn_ray(ray.d)
            ray = mi.Ray3f(dr.select(glass, nxt.o, ray.o), ray.d)
            si2 = scene.ray_intersect(ray)
            si = dr.select(glass, si2, si)
        full = mi.Ray3f(o, ray.d)  # distances from the camera
        si.t = dr.norm(si.p - o)
        s = first_surface(si, full, mi.Bool(True), fwd)
        albedo = si.bsdf().eval_diffuse_reflectance(si, si.is_valid())
    return (np.array(s["depth"]).reshape(h, w), np.array(s["normal"]).T.reshape(h, w, 3),
            np.array(albedo).T.reshape(h, w, 3))


def derive_priors(scene_dir: Path, seed: int = 0, corruption: Corruption | None = None, scene=None,
                  albedo: bool = True) -> Path:
    """Write imperfect priors for every view of a generated scene (``scene``: its loaded scene.xml, loaded here when
    omitted; ``albedo=False``: depth and normal only, like an estimator without intrinsic decomposition); returns
    the priors folder."""
    import glint_mi
    import mitsuba as mi

    from glint_mi.conventions import world_to_opencv_normals
    from glint_mi.data import load_dataset

    c = corruption or Corruption()
    rng = np.random.default_rng(seed)
    scene_dir = Path(scene_dir)
    ds = load_dataset(scene_dir)
    scene = scene if scene is not None else glint_mi.load_file(scene_dir / "scene.xml")
    out = scene_dir / "priors"
    kinds = KINDS if albedo else tuple(k for k in KINDS if k != "albedo")
    for k in KINDS:
        if k not in kinds:
            import shutil

            shutil.rmtree(out / k, ignore_errors=True)
        else:
            (out / k).mkdir(parents=True, exist_ok=True)
    record = {"derived_from_ground_truth": True, "seed": seed, "kinds": list(kinds),
              "corruption": dataclasses.asdict(c), "views": {}}
    for v in ds.views:
        gt = v.load_gt()
        sensor = mi.load_dict(v.sensor_dict())
        z_behind, n_behind, alb = _behind_glass(scene, sensor)
        glass = gt["glass"] > 0.5
        through = bool(rng.random() < float(c.see_through_glass))
        depth = np.where(glass & through, z_behind, gt["depth"])
        normal = np.where((glass & through)[..., None], n_behind, gt["normal"])
        alb_prior = np.where(glass[..., None], c.glass_albedo, alb)
        a, b = rng.uniform(*c.depth_scale), rng.uniform(*c.depth_shift) * np.median(depth[depth > 0])
        valid = depth > 0
        dp = a * depth * (1 + c.depth_noise * rng.normal(size=depth.shape)) + b
        dp = np.where(valid, _blur(dp, c.blur_px), 0.0)
        n_cam = world_to_opencv_normals(normal, v.c2w)
        n_cam = _blur(n_cam + np.radians(c.normal_noise_deg) * rng.normal(size=n_cam.shape), c.blur_px)
        n_cam /= np.maximum(np.linalg.norm(n_cam, axis=-1, keepdims=True), 1e-9)
        alb_prior = np.clip(_blur(alb_prior + c.albedo_noise * rng.normal(size=alb_prior.shape), c.blur_px), 0, 1)
        np.save(out / "depth" / f"{v.name}.npy", dp.astype(np.float32))
        np.save(out / "normal" / f"{v.name}.npy", n_cam.astype(np.float32))
        if albedo:
            np.save(out / "albedo" / f"{v.name}.npy", alb_prior.astype(np.float32))
        record["views"][v.name] = {"depth_scale": float(a), "depth_shift": float(b), "sees_through_glass": through}
    (out / "PRIORS.json").write_text(json.dumps(record, indent=1))
    return out
