"""Imperfect priors derived from ground truth for generated scenes (the readers: :mod:`glint_mi.data.priors`).

Two models, both labelled in ``priors/PRIORS.json`` (``"derived_from_ground_truth": true``, the model, every
parameter, and the *measured* error of the written maps, overall, off glass and on glass):

- ``realistic`` (:class:`Realistic`, the default): errors with the shape of a monocular estimator's. Wrong mostly in
  low frequencies: a smooth tilt field rotates the normals and a smooth warp bends the depth, calibrated per view so
  that off glass the normals measure ~15 deg mean error (DSINE ~16, Metric3D v2 ~13, StableNormal ~17-19 on indoor
  scenes) and the depth AbsRel ~0.05 after a per-image affine fit; plus pixel noise, edge blur, an unknown depth
  scale and shift. On glass the estimator sees through in most views, over part of the glass (a smooth mask), to
  the first opaque surface behind it; the albedo is that of the surface it sees (the glass's own diffuse albedo from
  its BSDF where it sees the glass), with a per-image gain and a smooth shading leak.
- ``ideal`` (:class:`Corruption`): near ground truth (2 % depth noise, 1 px blur, 5 deg normal noise; on glass a
  constant near-black albedo): results made with it say little about real estimators.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from glint_mi.data.priors import KINDS, PriorError, load_prior, prior_conventions, priors_are_derived  # noqa: F401
from glint_mi.metrics import angles_deg as _angle_deg


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


@dataclasses.dataclass
class Realistic:
    """A monocular estimator's errors (see the module docstring); targets are drawn per view around the means."""

    normal_mae_deg: float = 15.0         # mean angular error off glass, per view ~ N(mean, spread)
    normal_spread_deg: float = 3.0
    depth_absrel: float = 0.05           # AbsRel off glass after the per-image affine fit, per view ~ N(mean, spread)
    depth_spread: float = 0.015
    field_sigma: float = 0.25            # smoothness of the error fields (Gaussian sigma, x image width)
    pixel_noise_deg: float = 2.0         # per-pixel normal noise (std, degrees)
    depth_noise: float = 0.005           # per-pixel multiplicative depth noise (std)
    blur: float = 0.008                  # edge blur (Gaussian sigma, x image width; 1.5 px at 192 px): estimators
    #                                      smooth across discontinuities
    depth_scale: tuple = (0.5, 2.0)      # per-image unknown scale ...
    depth_shift: tuple = (-0.3, 0.3)     # ... and shift (x the median depth)
    see_through_glass: float = 0.75      # probability per view that the estimator sees through the glass ...
    see_through_part: float = 0.7        # ... over this share of the view's glass pixels (a smooth mask)
    albedo_gain: tuple = (0.8, 1.2)      # per-image brightness error of the albedo estimator
    albedo_field: float = 0.15           # smooth multiplicative albedo error (shading leak, std of log gain)
    albedo_noise: float = 0.02
    mask_miss: float = 0.15              # glass masks (a segmentation model's, for TSGS): a view's glass missed ...
    mask_false: float = 0.2              # ... a false blob elsewhere, with these probabilities per view
    mask_edge: float = 0.015             # boundary error (x image width, smooth along the edge)


MODELS = {"realistic": Realistic, "ideal": Corruption}


def _field(rng, shape, sigma_px):
    """A smooth random field [H, W] with zero mean and unit std (low frequencies only)."""
    from scipy.ndimage import gaussian_filter

    f = gaussian_filter(rng.normal(size=shape), sigma_px, mode="wrap")
    return (f - f.mean()) / max(f.std(), 1e-12)


def _rotate(n, rotvec):
    """Rodrigues: rotate unit vectors n [..., 3] by rotation vectors [..., 3] (radians)."""
    theta = np.linalg.norm(rotvec, axis=-1, keepdims=True)
    k = rotvec / np.maximum(theta, 1e-12)
    return (n * np.cos(theta) + np.cross(k, n) * np.sin(theta)
            + k * np.sum(k * n, axis=-1, keepdims=True) * (1 - np.cos(theta)))


def _unit(n):
    return n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)


def affine_depth_error(prior, z_gt, fit_mask, score_mask, inverse: bool = False) -> float:
    """AbsRel of a relative depth prior after the per-image affine fit prior ~ w z + q (least squares over
    ``fit_mask``; for a disparity prior, ~ w / z + q), scored over ``score_mask``; NaN without pixels."""
    x = np.where(z_gt > 0, 1.0 / np.maximum(z_gt, 1e-12), 0.0) if inverse else z_gt
    m = fit_mask & (prior > 0) & (z_gt > 0)
    s = score_mask & (prior > 0) & (z_gt > 0)
    if m.sum() < 2 or not s.any():
        return float("nan")
    A = np.column_stack([x[m], np.ones(m.sum())])
    (w, q), *_ = np.linalg.lstsq(A, prior[m], rcond=None)
    if abs(w) < 1e-12:
        return float("nan")
    est = (prior[s] - q) / w
    est = 1.0 / np.maximum(est, 1e-12) if inverse else est
    return float(np.mean(np.abs(est - z_gt[s]) / z_gt[s]))


def _calibrate(make, measure, target, lo=0.0, hi=2.0, steps=18):
    """The amplitude in [lo, hi] whose ``measure(make(amplitude))`` is ``target`` (bisection; monotone)."""
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        if measure(make(mid)) < target:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def realistic_view(rng, c: Realistic, gt: dict, behind: dict, first_albedo, c2w) -> tuple[dict, dict]:
    """One view's priors under :class:`Realistic`: ({'depth' [H,W], 'normal' [H,W,3] OpenCV, 'albedo' [H,W,3]},
    record). ``gt``: the view's ground truth; ``behind``: depth, normal, albedo of the first opaque surface behind
    the glass; ``first_albedo``: the diffuse albedo of the first surface (glass included) from its BSDF."""
    from glint_mi.conventions import world_to_opencv_normals

    h, w = gt["depth"].shape
    sig = c.field_sigma * w
    valid = gt["depth"] > 0
    glass = valid & (gt["glass"] > 0.5)
    off = valid & ~glass
    # what the estimator sees on the glass: the surface behind, over a smooth part of it, in most views
    m = np.zeros((h, w))
    sees_through = bool(glass.any() and rng.random() < c.see_through_glass)
    if sees_through:
        f = _field(rng, (h, w), sig)
        thr = np.quantile(f[glass], 1.0 - c.see_through_part)
        m = _blur((f > thr).astype(np.float64), 2.0) * glass
    z_s = np.where(glass, m * behind["depth"] + (1 - m) * gt["depth"], gt["depth"])
    n_s = np.where(glass[..., None], _unit(m[..., None] * behind["normal"] + (1 - m[..., None]) * gt["normal"]),
                   gt["normal"])
    alb_s = np.where(glass[..., None], m[..., None] * behind["albedo"] + (1 - m[..., None]) * first_albedo,
                     first_albedo)
    n_cam = _unit(world_to_opencv_normals(n_s, c2w))
    n_gt = _unit(world_to_opencv_normals(gt["normal"], c2w))
    # normals: a smooth tilt field + pixel noise + edge blur, the tilt calibrated to the view's target
    tilt = np.stack([_field(rng, (h, w), sig) for _ in range(3)], -1)
    noise = np.radians(c.pixel_noise_deg) * rng.normal(size=(h, w, 3))
    blur = c.blur * w
    make_n = lambda a: _unit(_blur(_rotate(n_cam, a * tilt + noise), blur))
    target_n = float(np.clip(rng.normal(c.normal_mae_deg, c.normal_spread_deg), 5.0, 30.0))
    amp = _calibrate(make_n, lambda n: _angle_deg(n[off], n_gt[off]).mean() if off.any() else 0.0,
                     target_n, 0.0, 1.5)
    normal = np.where(valid[..., None], make_n(amp), 0.0)
    # depth: a smooth multiplicative warp + pixel noise + edge blur, then an unknown scale and shift
    warp = _field(rng, (h, w), sig)
    px = c.depth_noise * rng.normal(size=(h, w))
    make_d = lambda b: np.where(valid, _blur(z_s * np.exp(b * warp) * (1 + px), blur), 0.0)
    target_d = float(np.clip(rng.normal(c.depth_absrel, c.depth_spread), 0.01, 0.15))
    bw = _calibrate(make_d, lambda d: affine_depth_error(d, gt["depth"], valid, off), target_d, 0.0, 1.0)
    a = rng.uniform(*c.depth_scale)
    shift = rng.uniform(*c.depth_shift) * np.median(z_s[valid]) if valid.any() else 0.0
    depth = np.where(valid, a * make_d(bw) + shift, 0.0)
    depth = np.where(valid & (depth <= 0), 1e-6, depth)  # keep every valid pixel positive (0 = invalid)
    # albedo: the seen surface's, with a per-image gain and a smooth shading leak
    gain = rng.uniform(*c.albedo_gain) * np.exp(c.albedo_field * _field(rng, (h, w), sig))[..., None]
    albedo = np.clip(_blur(alb_s * gain + c.albedo_noise * rng.normal(size=(h, w, 3)), blur), 0, 1)
    # glass mask (segmentation): ragged boundary, whole panes missed in some views, false blobs in others
    edge = _blur(glass.astype(np.float64), max(c.mask_edge * w, 0.5))
    mask = (edge > 0.5 + 0.35 * np.tanh(_field(rng, (h, w), sig))) & valid
    missed = bool(rng.random() < c.mask_miss)
    if missed:
        mask[:] = False
    if rng.random() < c.mask_false:
        blob = _field(rng, (h, w), 0.1 * w)
        mask |= (blob > np.quantile(blob, 0.97)) & valid & ~glass
    union = (mask | glass).sum()
    rec_mask = {"mask_missed": missed, "mask_iou": float((mask & glass).sum() / union) if union else float("nan")}
    rec = {**rec_mask, "sees_through_glass": sees_through,
           "see_through_share_of_glass": float(m[glass].mean()) if glass.any() else None, "target_normal_mae_deg": target_n, "target_depth_absrel": target_d,
           "depth_scale": float(a), "depth_shift": float(shift)}
    return {"depth": depth.astype(np.float32), "normal": normal.astype(np.float32),
            "albedo": albedo.astype(np.float32), "glass": mask.astype(np.float32)}, rec


def measure_priors(maps: dict, gt: dict, c2w, first_albedo=None) -> dict:
    """The error of one view's prior maps against ground truth (the first surface, glass included): normal mean
    angle (deg) and depth AbsRel after the per-image affine fit over every valid pixel (as a loss without SfM
    points would fit it), albedo mean absolute error against the first surface's albedo when given; overall, off
    glass and on glass (NaN where a set is empty)."""
    from glint_mi.conventions import world_to_opencv_normals

    valid = gt["depth"] > 0
    glass = valid & (gt["glass"] > 0.5)
    n_gt = _unit(world_to_opencv_normals(gt["normal"], c2w))
    out = {}
    for name, sel in (("", valid), ("_off_glass", valid & ~glass), ("_glass", glass)):
        ok = sel & (np.linalg.norm(maps["normal"], axis=-1) > 0.5)
        out[f"normal_mae_deg{name}"] = float(_angle_deg(_unit(maps["normal"][ok]), n_gt[ok]).mean()) if ok.any() \
            else float("nan")
        out[f"depth_absrel{name}"] = affine_depth_error(maps["depth"], gt["depth"], valid, sel)
        if first_albedo is not None and maps.get("albedo") is not None:
            out[f"albedo_mae{name}"] = float(np.abs(maps["albedo"][sel] - first_albedo[sel]).mean()) if sel.any() \
                else float("nan")
    return out


def _first_albedo(scene, sensor):
    """Diffuse albedo [H, W, 3] of the first surface along each pixel's ray, glass included (its BSDF's own)."""
    import drjit as dr

    from glint_mi.render import camera_rays

    w, h = sensor.film().crop_size()
    pix = np.stack(np.meshgrid(np.arange(w), np.arange(h)), -1).reshape(-1, 2)
    ray, _ = camera_rays(sensor, pix)
    with dr.suspend_grad():
        si = scene.ray_intersect(ray)
        albedo = si.bsdf().eval_diffuse_reflectance(si, si.is_valid())
    return np.nan_to_num(np.array(albedo).T.reshape(h, w, 3))


def derive_priors(scene_dir: Path, seed: int = 0, corruption=None, scene=None, albedo: bool = True) -> Path:
    """Write imperfect priors for every view of a generated scene (``scene``: its loaded scene.xml, loaded here when
    omitted; ``albedo=False``: depth and normal only, like an estimator without intrinsic decomposition); returns
    the priors folder."""
    import glint_mi
    import mitsuba as mi

    from glint_mi.conventions import world_to_opencv_normals
    from glint_mi.data import load_dataset

    c = corruption if corruption is not None else Realistic()
    model = "realistic" if isinstance(c, Realistic) else "ideal"
    rng = np.random.default_rng(seed)
    scene_dir = Path(scene_dir)
    ds = load_dataset(scene_dir)
    scene = scene if scene is not None else glint_mi.load_file(scene_dir / "scene.xml")
    out = scene_dir / "priors"
    kinds = tuple(k for k in KINDS if (albedo or k != "albedo") and (model == "realistic" or k != "glass"))
    for k in KINDS:
        if k not in kinds:
            import shutil

            shutil.rmtree(out / k, ignore_errors=True)
        else:
            (out / k).mkdir(parents=True, exist_ok=True)
    record = {"derived_from_ground_truth": True, "model": model, "seed": seed, "kinds": list(kinds),
              "depth": {"type": "depth"}, "normal": {"frame": "opencv"}, "albedo": {"space": "linear"},
              "corruption": dataclasses.asdict(c), "views": {}}
    errors = []
    for v in ds.views:
        gt = v.load_gt()
        sensor = mi.load_dict(v.sensor_dict())
        z_behind, n_behind, alb = _behind_glass(scene, sensor)
        first = _first_albedo(scene, sensor)
        if model == "realistic":
            maps, rec = realistic_view(rng, c, gt, {"depth": z_behind, "normal": n_behind, "albedo": alb}, first,
                                       v.c2w)
            err = measure_priors(maps, gt, v.c2w, first if albedo else None)
            np.save(out / "depth" / f"{v.name}.npy", maps["depth"])
            np.save(out / "normal" / f"{v.name}.npy", maps["normal"])
            np.save(out / "glass" / f"{v.name}.npy", maps["glass"])
            if albedo:
                np.save(out / "albedo" / f"{v.name}.npy", maps["albedo"])
            record["views"][v.name] = {**rec, "measured": err}
            errors.append(err)
            continue
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
        maps = {"depth": dp, "normal": n_cam, "albedo": alb_prior}
        err = measure_priors(maps, gt, v.c2w, first if albedo else None)
        record["views"][v.name] = {"depth_scale": float(a), "depth_shift": float(b), "sees_through_glass": through,
                                   "measured": err}
        errors.append(err)
    record["measured"] = {k: float(np.nanmean([e[k] for e in errors])) for k in errors[0]} if errors else {}
    ious = [r["mask_iou"] for r in record["views"].values() if r.get("mask_iou") is not None]
    if ious:
        record["measured"]["glass_mask_iou"] = float(np.nanmean(ious))
    (out / "PRIORS.json").write_text(json.dumps(record, indent=1))
    return out
