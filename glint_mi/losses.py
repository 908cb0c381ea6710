"""GLINT's geometric losses and transparency-bootstrapping masks (glint-method.md sections 3 and 4).

Differentiable terms take Dr.Jit arrays over a batch of rays, with ``view`` [M] the image each ray belongs to (the
scale-shift fit of the depth loss is per image). Masks are computed without gradient, on whole images (numpy).
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np


def depth_fit(depth, prior, mask, view, n_views: int):
    """Per-image closed form (w, q) = argmin sum_mask (w D + q - P)^2, gathered back per ray (detached).

    Detaching is exact for the gradient of the minimised loss (envelope theorem: d/dD of min_{w,q} equals the
    partial derivative at the optimum).
    """
    D, P = dr.detach(depth), dr.detach(prior)
    m = dr.select(mask, 1.0, 0.0)
    sums = [dr.zeros(mi.Float, n_views) for _ in range(5)]
    for acc, val in zip(sums, (m, m * D, m * D * D, m * P, m * D * P)):
        dr.scatter_reduce(dr.ReduceOp.Add, acc, val, view)
    s1, sd, sdd, sp, sdp = sums
    det = s1 * sdd - sd * sd
    ok = dr.abs(det) > 1e-12 * dr.maximum(s1 * sdd, 1e-30)
    w = dr.select(ok, (s1 * sdp - sd * sp) / dr.select(ok, det, 1.0), 1.0)
    q = dr.select(ok, (sp - w * sd) / dr.maximum(s1, 1.0), 0.0)
    return dr.gather(mi.Float, w, view), dr.gather(mi.Float, q, view)


def depth_loss(depth, prior, mask, view, n_views: int):
    """Scale-shift-invariant depth loss (MonoSDF): mean over valid rays of (w D + q - P)^2."""
    w, q = depth_fit(depth, prior, mask, view, n_views)
    r = dr.select(mask, dr.square(w * depth + q - prior), 0.0)
    return dr.sum(r) / dr.maximum(dr.count(mask), 1)


def normal_loss(normal, prior, tau_n: float = 0.3, valid=True):
    """Normal prior with the cosine mask [<n, n_prior> >= tau_n]: mean of |n - p|_1 + (1 - <n, p>) over the mask.

    ``normal`` and ``prior`` are unit vectors in the same (camera) frame; the mask is detached.
    """
    cos = dr.dot(normal, prior)
    mask = mi.Bool(valid) & (dr.detach(cos) >= tau_n)
    d = normal - prior
    term = dr.abs(d.x) + dr.abs(d.y) + dr.abs(d.z) + (1.0 - cos)
    return dr.sum(dr.select(mask, term, 0.0)) / dr.maximum(dr.count(mask), 1), mask


def bce(t, target: float, weight):
    """Binary cross-entropy of transparency t against a constant target, weighted mean (weights detached)."""
    t = dr.clip(t, 1e-6, 1.0 - 1e-6)
    w = dr.detach(weight)
    loss = -(target * dr.log(t) + (1.0 - target) * dr.log(1.0 - t))
    return dr.sum(w * loss) / dr.maximum(dr.sum(w), 1e-12)


def _erode(mask: np.ndarray) -> np.ndarray:
    from scipy.ndimage import binary_erosion

    return binary_erosion(mask, structure=np.ones((3, 3), bool), border_value=0)


def transparency_masks(depth_t, depth_i, tau_delta: float, albedo=None, base=None, cos_view=None,
                       low_a: float = 0.05, high_a: float = 0.10, high_b: float = 0.25):
    """L_trans masks of one image (numpy, no gradient): returns (weight_transparent, weight_opaque), [H, W] float.

    ``depth_t``/``depth_i``: planar depth of the transmission set (straight from the camera) and of the interface
    (0 = invalid). Delta z = D_T - D_I: "behind" if > tau_delta, "same" otherwise. With a diffuse-albedo prior
    (``albedo`` [H,W] mean RGB) and the interface base colour (``base`` [H,W]): transparent = LowA & HighB & valid &
    behind; opaque = HighA | (LowA & ~HighB) | same. Without: transparent = valid & behind, opaque = same.
    Both are eroded 3x3 and weighted by the view angle (1 up to 70 deg, 0 beyond 80 deg, linear between).
    """
    valid = (depth_t > 0) & (depth_i > 0)
    dz = depth_t - depth_i
    behind, same = valid & (dz > tau_delta), valid & (dz <= tau_delta)
    if albedo is not None and base is not None:
        low, high, bright = albedo < low_a, albedo > high_a, base > high_b
        m_t = low & bright & behind
        m_o = valid & (high | (low & ~bright) | same)
    else:
        m_t, m_o = behind, same
    w = np.ones_like(depth_i, dtype=np.float64)
    if cos_view is not None:
        ang = np.degrees(np.arccos(np.clip(cos_view, -1, 1)))
        w = np.clip((80.0 - ang) / 10.0, 0.0, 1.0)
    return _erode(m_t) * w, _erode(m_o & ~m_t) * w
