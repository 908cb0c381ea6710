"""Imperfect priors derived from ground truth for generated scenes (the readers: :mod:`glint_mi.data.priors`).

Three models, each labelled in ``priors/PRIORS.json`` (``"derived_from_ground_truth": true``, the model, every
parameter, what was drawn, and the *measured* error of the written maps, overall, off glass and on glass, the glass
masks' IoU and how much the albedo marks the glass):

- ``realistic`` (:class:`Realistic`, the default): errors as an estimator makes them, drawn and never tuned against
  the ground truth. Smooth error fields in world space (the same mistake on the same surface in every view: fusing
  views does not average it out) plus per-view image-space jitter, pixel noise, edge blur, an unknown depth scale and
  shift. On glass the depth and normal see through where a field on the pane (plus per-view jitter) says so; the
  albedo is the far surface's, darkened and tinted, with part of the photo itself (shading, reflections, highlights)
  baked in everywhere: never the glass BSDF's. Glass masks with a segmenter's failures: panes missed (the same panes
  tend to be missed, and flicker between views), holes, ragged edges, false positives on glossy and dark surfaces.
- ``realistic-v1`` (:class:`PerViewRealistic`, the default until 2026-11-26): errors calibrated per view against the
  ground truth and independent between views; on glass the glass BSDF's own albedo where the estimator does not see
  through (a dark patch that follows the glass); masks that are the truth with ragged edges.
- ``ideal`` (:class:`Corruption`): near ground truth (2 % depth noise, 1 px blur, 5 deg normal noise; on glass a
  constant near-black albedo): results made with it say little about real estimators.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from glint_mi.data.priors import KINDS, PriorError, load_prior, prior_conventions, priors_are_derived  # noqa: F401
from glint_mi.evaluation.metrics import angles_deg as _angle_deg


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


def _behind_glass(scene, sensor, max_steps=16, points=False):
    """Planar depth, world normal and diffuse albedo of the first non-glass surface ([H, W], [H, W, 3] x 2), and
    with ``points`` its world point [H, W, 3]."""
    import drjit as dr
    import mitsuba as mi

    from glint_mi.model.render import camera_rays
    from glint_mi_plugins.glint_integrator import first_surface, is_glass

    w, h = sensor.film().crop_size()
    ray, fwd = camera_rays(sensor)
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
        p = np.nan_to_num(np.array(si.p).T.reshape(h, w, 3))
    out = (np.array(s["depth"]).reshape(h, w), np.array(s["normal"]).T.reshape(h, w, 3),
           np.array(albedo).T.reshape(h, w, 3))
    return (*out, p) if points else out


@dataclasses.dataclass
class PerViewRealistic:
    """``realistic-v1``, the former default (kept so that results can be compared): a monocular estimator's errors
    calibrated per view against the ground truth (bisection), drawn independently in every view; on glass the glass
    BSDF's own albedo where the estimator does not see through, and masks that are the truth with ragged edges."""

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


def realistic_view(rng, c: PerViewRealistic, gt: dict, behind: dict, first_albedo, c2w) -> tuple[dict, dict]:
    """One view's priors under :class:`PerViewRealistic`: ({'depth' [H,W], 'normal' [H,W,3] OpenCV, 'albedo' [H,W,3]},
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
           "see_through_share_of_glass": float(m[glass].mean()) if glass.any() else None,
           "target_normal_mae_deg": target_n, "target_depth_absrel": target_d,
           "depth_scale": float(a), "depth_shift": float(shift)}
    return {"depth": depth.astype(np.float32), "normal": normal.astype(np.float32),
            "albedo": albedo.astype(np.float32), "glass": mask.astype(np.float32)}, rec


@dataclasses.dataclass
class Realistic:
    """``realistic``, the default: an estimator's errors drawn, never tuned against the ground truth, and the same
    for a surface in every view. Amplitudes are drawn per room (the world-space part) and per view (the jitter) from
    these ranges (uniform); what they amount to is measured afterwards and written to PRIORS.json."""

    world_length_m: float = 0.8          # correlation length of the world-space error fields (metres)
    normal_world_deg: tuple = (8.0, 14.0)  # rms tilt of the world-space normal error (per room)
    normal_view_deg: tuple = (3.0, 8.0)  # rms tilt of the per-view, image-space normal error (per view)
    pixel_noise_deg: float = 2.0         # per-pixel normal noise (std)
    depth_world: tuple = (0.03, 0.07)    # rms of the world-space log-depth warp (per room)
    depth_view: tuple = (0.015, 0.035)   # rms of the per-view log-depth warp
    depth_noise: float = 0.005           # per-pixel multiplicative depth noise (std)
    view_sigma: float = 0.25             # smoothness of the per-view fields (Gaussian sigma, x image width)
    blur: float = 0.008                  # edge blur (sigma, x image width): estimators smooth across discontinuities
    depth_scale: tuple = (0.5, 2.0)      # per-image unknown scale ...
    depth_shift: tuple = (-0.3, 0.3)     # ... and shift (x the median depth)
    see_through_glass: float = 0.6       # expected share of glass pixels where depth and normal see through ...
    see_through_jitter: float = 0.7      # ... decided by a world-space field on the pane plus this much per-view field
    see_through_view_sd: float = 0.5     # ... and a per-view offset (the estimator flickers between views)
    glass_darkening: tuple = (0.7, 1.0)  # albedo seen through glass: the far surface's x this (per view) ...
    glass_tint: float = 0.08             # ... x a per-room tint (per-channel gain 1 +- this)
    photo_leak: tuple = (0.1, 0.35)      # share of the albedo that is the photo itself (shading, reflections and
    #                                      highlights baked in), per view, brightness matched; the same everywhere
    albedo_gain: tuple = (0.8, 1.2)      # per-image brightness error
    albedo_field: float = 0.15           # smooth multiplicative albedo error (std of log gain)
    albedo_noise: float = 0.02
    # glass masks (a segmenter's, TSGS's input): panes missed, holes, ragged edges, flicker, false positives on
    # glossy and dark surfaces. Set (on the tuning room 7301, not per view) for a mean IoU on glass of ~0.6 (measured
    # 0.61 at the quick preset, 0.59 at bench):
    # GDNet reports 0.876 on the GDD test set it was trained for (Mei et al., CVPR 2020, Table 2); a segmenter off
    # its training domain does worse (GLINT's supplement, Fig. 7, shows fragmented masks missing whole panes)
    pane_miss: float = 0.22              # probability that a pane is missed in a view (a per-room difficulty per
    pane_difficulty_sd: float = 1.0      # pane, this spread, plus per-view noise: the same panes tend to be missed)
    pane_view_sd: float = 0.6
    mask_holes: float = 0.15             # share of a detected pane lost to holes (a world-space field + jitter)
    mask_edge: float = 0.015             # boundary error (x image width, smooth along the edge)
    mask_false: float = 0.35             # probability per view of false positives ...
    mask_false_share: float = 0.25       # ... covering this share of the view's glossy and dark pixels (blobs)
    mask_dark_quantile: float = 0.1      # "dark": the view's darkest pixels, this share


class WorldField:
    """A smooth random field on R^3 with zero mean and unit variance per output (random Fourier features of a
    Gaussian kernel with correlation length ``length``): evaluated at a surface point it gives the same value in
    every view, so an error drawn from it is the same mistake on the same surface from view to view."""

    def __init__(self, rng, outputs: int, length: float, features: int = 64):
        self.omega = rng.normal(size=(outputs, features, 3)) / max(length, 1e-6)
        self.phase = rng.uniform(0, 2 * np.pi, size=(outputs, features))

    def __call__(self, p):
        """p [..., 3] -> [..., outputs]."""
        arg = np.einsum("...k,ofk->...of", p, self.omega) + self.phase
        return np.sqrt(2.0 / self.omega.shape[1]) * np.cos(arg).sum(-1)


def _room_draws(rng, c: Realistic) -> dict:
    """What a room's estimator gets wrong the same way in every view (drawn once per room)."""
    return {"normal_field": WorldField(rng, 3, c.world_length_m), "depth_field": WorldField(rng, 1, c.world_length_m),
            "see_field": WorldField(rng, 1, c.world_length_m), "hole_field": WorldField(rng, 1, 0.5 * c.world_length_m),
            "normal_world_deg": float(rng.uniform(*c.normal_world_deg)),
            "depth_world": float(rng.uniform(*c.depth_world)),
            "tint": (1 + c.glass_tint * rng.uniform(-1, 1, size=3)).round(4).tolist(),
            "pane_difficulty": {}, "pane_rng": np.random.default_rng(rng.integers(2**63))}


def _panes(normal_world, glass):
    """Integer pane keys [H, W] (-1 off glass): the glass's dominant normal axis and its sign (the case's panels)."""
    axis = np.abs(normal_world).argmax(-1)
    sign = np.take_along_axis(normal_world, axis[..., None], -1)[..., 0] > 0
    return np.where(glass, 2 * axis + sign, -1)


def _inverse_normal_cdf(p):
    from scipy.special import ndtri

    return float(ndtri(np.clip(p, 1e-9, 1 - 1e-9)))


def estimator_view(rng, c: Realistic, room: dict, gt: dict, tr: dict, c2w) -> tuple[dict, dict]:
    """One view's priors under :class:`Realistic`: ({'depth', 'normal' (OpenCV), 'albedo', 'glass'}, record).
    ``gt``: the view's ground truth (its 'rgb' is the photo an estimator sees); ``tr``: what the view's rays hit
    (:func:`_trace_view`); ``room``: :func:`_room_draws`. Nothing is calibrated against the ground truth here."""
    from glint_mi.conventions import world_to_opencv_normals

    h, w = gt["depth"].shape
    sig = c.view_sigma * w
    blur = c.blur * w
    valid = gt["depth"] > 0
    glass = valid & (gt["glass"] > 0.5)
    photo = np.clip(np.nan_to_num(gt["rgb"]), 0, None)
    # where on the glass the estimator sees through: a field on the pane (the same in every view), per-view jitter and
    # a per-view offset around the expected share
    m = np.zeros((h, w))
    if glass.any() and c.see_through_glass > 0:
        if c.see_through_glass >= 1:
            m = glass.astype(np.float64)
        else:
            spread = np.sqrt(1 + c.see_through_jitter ** 2)
            off = _inverse_normal_cdf(c.see_through_glass) * spread + c.see_through_view_sd * rng.normal()
            s = room["see_field"](tr["first_p"])[..., 0] + c.see_through_jitter * _field(rng, (h, w), sig) + off
            m = _blur((s > 0).astype(np.float64), 2.0) * glass
    mg = m[..., None]
    z_s = np.where(glass, m * tr["behind_depth"] + (1 - m) * gt["depth"], gt["depth"])
    n_s = np.where(glass[..., None], _unit(mg * tr["behind_normal"] + (1 - mg) * gt["normal"]), gt["normal"])
    p_s = np.where(glass[..., None], mg * tr["behind_p"] + (1 - mg) * tr["first_p"], tr["first_p"])
    # normals: a world-space tilt (same surface, same error), a per-view image-space tilt, pixel noise, edge blur
    a_view = np.radians(rng.uniform(*c.normal_view_deg))
    rot_w = np.radians(room["normal_world_deg"]) * room["normal_field"](p_s)
    n_cam = _unit(world_to_opencv_normals(_rotate(n_s, rot_w), c2w))
    rot_v = a_view * np.stack([_field(rng, (h, w), sig) for _ in range(3)], -1)
    rot_v = rot_v + np.radians(c.pixel_noise_deg) * rng.normal(size=(h, w, 3))
    normal = np.where(valid[..., None], _unit(_blur(_rotate(n_cam, rot_v), blur)), 0.0)
    # depth: world-space and per-view log warps, pixel noise, edge blur, an unknown scale and shift
    d_view = rng.uniform(*c.depth_view)
    warp = room["depth_world"] * room["depth_field"](p_s)[..., 0] + d_view * _field(rng, (h, w), sig)
    z = np.where(valid, _blur(z_s * np.exp(warp) * (1 + c.depth_noise * rng.normal(size=(h, w))), blur), 0.0)
    a = rng.uniform(*c.depth_scale)
    shift = rng.uniform(*c.depth_shift) * np.median(z_s[valid]) if valid.any() else 0.0
    depth = np.where(valid, a * z + shift, 0.0)
    depth = np.where(valid & (depth <= 0), 1e-6, depth)  # keep every valid pixel positive (0 = invalid)
    # albedo: the surface seen (through glass: the far surface, darkened and tinted), part of the photo itself baked
    # in (shading, reflections, highlights: the same rule on and off glass), a gain, a smooth error and noise
    dark = rng.uniform(*c.glass_darkening)
    seen = np.where(glass[..., None], dark * np.asarray(room["tint"]) * tr["behind_albedo"], tr["first_albedo"])
    leak = rng.uniform(*c.photo_leak)
    k = seen[valid].mean() / max(photo[valid].mean(), 1e-6) if valid.any() else 1.0
    gain = rng.uniform(*c.albedo_gain) * np.exp(c.albedo_field * _field(rng, (h, w), sig))[..., None]
    alb = (1 - leak) * seen * gain + leak * k * photo + c.albedo_noise * rng.normal(size=(h, w, 3))
    albedo = np.where(valid[..., None], np.clip(_blur(alb, blur), 0, 1), 0.0)
    # glass masks: whole panes missed (a per-room difficulty per pane: the same panes, flickering), holes from a field
    # on the surface, ragged edges, false positives on glossy and dark surfaces
    panes = _panes(gt["normal"], glass)
    det = np.zeros((h, w), bool)
    missed, seen_panes = [], []
    base = _inverse_normal_cdf(1 - c.pane_miss) * np.sqrt(c.pane_difficulty_sd ** 2 + c.pane_view_sd ** 2)
    for key in np.unique(panes[panes >= 0]):
        sel = panes == key
        if sel.sum() < 4:
            continue
        diff = room["pane_difficulty"].setdefault(int(key), float(room["pane_rng"].normal(0, c.pane_difficulty_sd)))
        lost = diff + c.pane_view_sd * rng.normal() > base
        (missed if lost else seen_panes).append(int(key))
        if not lost:
            det |= sel
    holes = room["hole_field"](tr["first_p"])[..., 0] + 0.5 * _field(rng, (h, w), 0.1 * w)
    if det.any():
        det &= holes < np.quantile(holes[det], 1 - c.mask_holes)
    edge = _blur(det.astype(np.float64), max(c.mask_edge * w, 0.5))
    mask = (edge > 0.5 + 0.35 * np.tanh(_field(rng, (h, w), sig))) & valid
    lum = photo.mean(-1)
    cand = valid & ~glass & (tr["first_glossy"] | (lum <= np.quantile(lum[valid], c.mask_dark_quantile)))
    false_px = 0
    if cand.any() and rng.random() < c.mask_false:
        blob = _field(rng, (h, w), 0.05 * w)
        fp = cand & (blob >= np.quantile(blob[cand], 1 - c.mask_false_share))
        mask |= _blur(fp.astype(np.float64), 1.0) > 0.5
        false_px = int((mask & ~glass).sum())
    union = (mask | glass).sum()
    rec = {"mask_iou": float((mask & glass).sum() / union) if glass.any() else None,
           "panes_missed": missed, "panes_detected": seen_panes, "mask_false_pixels": false_px,
           "see_through_share_of_glass": float(m[glass].mean()) if glass.any() else None,
           "normal_view_deg": float(np.degrees(a_view)), "depth_view": float(d_view), "glass_darkening": float(dark),
           "photo_leak": float(leak), "depth_scale": float(a), "depth_shift": float(shift)}
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


def _diffuse_albedo(si, h: int, w: int) -> np.ndarray:
    """Diffuse albedo [H, W, 3] of the surfaces ``si`` hit (their BSDF's own; a glass BSDF's is ~0), 0 on a miss."""
    albedo = si.bsdf().eval_diffuse_reflectance(si, si.is_valid())
    return np.nan_to_num(np.array(albedo).T.reshape(h, w, 3))


def _first_albedo(scene, sensor):
    """Diffuse albedo [H, W, 3] of the first surface along each pixel's ray, glass included (its BSDF's own)."""
    import drjit as dr

    from glint_mi.model.render import camera_rays

    w, h = sensor.film().crop_size()
    ray, _ = camera_rays(sensor)
    with dr.suspend_grad():
        return _diffuse_albedo(scene.ray_intersect(ray), h, w)


def _trace_view(scene, sensor) -> dict:
    """What one view's rays hit ([H, W, ...] numpy): the first surface's world point, diffuse albedo (its BSDF's) and
    whether it is glossy; the first opaque surface behind any glass: planar depth, world normal, albedo, point."""
    import drjit as dr
    import mitsuba as mi

    from glint_mi.model.render import camera_rays

    w, h = sensor.film().crop_size()
    ray, _ = camera_rays(sensor)
    with dr.suspend_grad():  # the first hit once, for all three
        si = scene.ray_intersect(ray)
        glossy = mi.has_flag(si.bsdf().flags(), mi.BSDFFlags.Glossy) & si.is_valid()
        first_p = np.array(si.p).T.reshape(h, w, 3)
        first_albedo = _diffuse_albedo(si, h, w)
    z, n, alb, p = _behind_glass(scene, sensor, points=True)
    return {"first_p": np.nan_to_num(first_p), "first_albedo": first_albedo,
            "first_glossy": np.array(glossy).reshape(h, w), "behind_depth": z, "behind_normal": n,
            "behind_albedo": alb, "behind_p": p}


MODELS = {"realistic": Realistic, "realistic-v1": PerViewRealistic, "ideal": Corruption}

# What an error scale multiplies, per model: the normal and depth error amplitudes (not the see-through share, the
# glass masks, the albedo or the unknown per-image depth scale and shift, which a loss removes anyway)
ERROR_FIELDS = {"realistic": ("normal_world_deg", "normal_view_deg", "pixel_noise_deg", "depth_world", "depth_view",
                              "depth_noise"),
                "realistic-v1": ("normal_mae_deg", "normal_spread_deg", "pixel_noise_deg", "depth_absrel",
                                 "depth_spread", "depth_noise"),
                "ideal": ("normal_noise_deg", "depth_noise")}


def scale_errors(c, scale: float):
    """The model ``c`` with its normal and depth error amplitudes times ``scale`` (a sweep of prior quality: issue
    66's 8-30 deg). The levels are the sweep's variable, drawn as any model's are; what they amount to is measured
    in PRIORS.json as always."""
    if not (scale > 0 and np.isfinite(scale)):
        raise ValueError(f"the prior error scale must be a positive number (got {scale})")
    out = dataclasses.replace(c)
    for f in ERROR_FIELDS[model_name(c)]:
        v = getattr(out, f)
        setattr(out, f, tuple(scale * x for x in v) if isinstance(v, tuple) else scale * v)
    if isinstance(out, PerViewRealistic) and out.normal_mae_deg >= 89.0:  # refused, not clipped
        raise ValueError(f"scale {scale} asks realistic-v1 for a {out.normal_mae_deg:.0f} deg normal error; the most it "
                         f"can draw is < 89 deg (scale < {89.0 / c.normal_mae_deg:.2f})")
    return out


def model_name(c) -> str:
    """The name a prior model is recorded under in PRIORS.json."""
    for name, cls in MODELS.items():
        if type(c) is cls:
            return name
    raise TypeError(f"not a prior model: {type(c).__name__}; use one of {sorted(MODELS)}")


def _albedo_cue(albedo, gt, dark: float = 0.05) -> dict:
    """How much the albedo prior marks the glass: the share of pixels darker than ``dark`` on and off glass, and the
    share of dark pixels that are glass (a prior copied from the glass BSDF makes these large)."""
    valid = gt["depth"] > 0
    glass = valid & (gt["glass"] > 0.5)
    low = valid & (albedo.mean(-1) < dark)
    return {"albedo_dark_share_glass": float(low[glass].mean()) if glass.any() else float("nan"),
            "albedo_dark_share_off_glass": float(low[valid & ~glass].mean()),
            "albedo_dark_pixels_on_glass": float(glass[low].mean()) if low.any() else float("nan")}


def derive_priors(scene_dir: Path, seed: int = 0, corruption=None, scene=None, albedo: bool = True) -> Path:
    """Write imperfect priors for every view of a generated scene (``scene``: its loaded scene.xml, loaded here when
    omitted; ``albedo=False``: depth and normal only, like an estimator without intrinsic decomposition); returns
    the priors folder."""
    import glint_mi
    import mitsuba as mi

    from glint_mi.conventions import world_to_opencv_normals
    from glint_mi.data import load_dataset

    c = corruption if corruption is not None else Realistic()
    model = model_name(c)
    rng = np.random.default_rng(seed)
    room = _room_draws(rng, c) if model == "realistic" else None
    scene_dir = Path(scene_dir)
    ds = load_dataset(scene_dir)
    scene = scene if scene is not None else glint_mi.load_file(scene_dir / "scene.xml")
    out = scene_dir / "priors"
    kinds = tuple(k for k in KINDS if (albedo or k != "albedo") and (model != "ideal" or k != "glass"))
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
        if model == "realistic":
            tr = _trace_view(scene, sensor)
            maps, rec = estimator_view(rng, c, room, gt, tr, v.c2w)
            err = {**measure_priors(maps, gt, v.c2w, tr["first_albedo"] if albedo else None),
                   **(_albedo_cue(maps["albedo"], gt) if albedo else {})}
            for k in ("depth", "normal", "glass") + (("albedo",) if albedo else ()):
                np.save(out / k / f"{v.name}.npy", maps[k])
            record["views"][v.name] = {**rec, "measured": err}
            errors.append(err)
            continue
        z_behind, n_behind, alb = _behind_glass(scene, sensor)
        first = _first_albedo(scene, sensor)
        if model == "realistic-v1":
            maps, rec = realistic_view(rng, c, gt, {"depth": z_behind, "normal": n_behind, "albedo": alb}, first,
                                       v.c2w)
            err = {**measure_priors(maps, gt, v.c2w, first if albedo else None),
                   **(_albedo_cue(maps["albedo"], gt) if albedo else {})}
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
        err = {**measure_priors(maps, gt, v.c2w, first if albedo else None),
               **(_albedo_cue(alb_prior, gt) if albedo else {})}
        record["views"][v.name] = {"depth_scale": float(a), "depth_shift": float(b), "sees_through_glass": through,
                                   "measured": err}
        errors.append(err)
    keys = sorted({k for e in errors for k in e})
    record["measured"] = {k: float(np.nanmean([e.get(k, np.nan) for e in errors])) for k in keys}
    ious = [r["mask_iou"] for r in record["views"].values() if r.get("mask_iou") is not None]
    if ious:  # over the views that show glass
        record["measured"]["glass_mask_iou"] = float(np.nanmean(ious))
    if room is not None:
        record["drawn"] = {k: v for k, v in room.items() if isinstance(v, (int, float, list, dict))}
    (out / "PRIORS.json").write_text(json.dumps(record, indent=1))
    return out
