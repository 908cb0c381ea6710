"""GLINT's losses and transparency-bootstrapping masks (glint-method.md sections 3 and 4); their assembly into one
batch objective is the table of terms in :mod:`glint_mi.training.objective`.

Differentiable terms take Dr.Jit arrays over a batch of rays, with ``view`` [M] the image each ray belongs to (the
scale-shift fit of the depth loss is per image). L_trans's masks are computed without gradient on the batch's
patches, on the device (:func:`batch_transparency_masks`); :func:`transparency_masks` is their definition on a whole
image (numpy), which the device version is tested against.
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


def depth_loss(depth, prior, mask, view, n_views: int, behind=None, weight=None):
    """Scale-shift-invariant depth loss (MonoSDF): mean over valid rays of (w D + q - P)^2. ``behind``, ``weight``:
    see depth_loss_aligned (the fit itself is unweighted)."""
    w, q = depth_fit(depth, prior, mask, view, n_views)
    return depth_loss_aligned(depth, prior, mask, w, q, behind, weight)


def depth_loss_aligned(depth, prior, mask, w, q, behind=None, weight=None):
    """The same loss with (w, q) given per ray (fitted once per view to the metric SfM points): the interface's
    depth is then anchored in metres, not only up to a per-image scale and shift. ``weight`` (per ray, detached;
    e.g. its view's depth_prior_ref weight) scales each ray's term; the mean still divides by the valid rays.

    ``behind`` = (D_behind, ok): a second layer the prior may describe instead (``prior_layer: nearer``): where
    ``ok``, each ray's residual is the smaller of the two layers' (nearer_layer)."""
    r = dr.square(w * depth + q - prior)
    if behind is not None:
        r = nearer_layer(r, dr.square(w * behind[0] + q - prior), behind[1])
    if weight is not None:
        r = r * dr.detach(weight)
    r = dr.select(mask, r, 0.0)
    return dr.sum(r) / dr.maximum(dr.count(mask), 1)


def nearer_layer(err_i, err_t, ok):
    """Per ray, the error of the layer a prior describes: the interface's (``err_i``) or, where ``ok`` (the
    interface is transparent and the transmission set a surface), the transmitted surface's (``err_t``) when that
    one agrees better. The choice is detached; the gradient reaches only the chosen layer. A monocular estimator
    sees through glass in some views and the pane in others: the views that see through then shape what lies
    behind the glass instead of pulling the pane onto it."""
    return dr.select(takes_behind(err_i, err_t, ok), err_t, err_i)


def takes_behind(err_i, err_t, ok):
    """The rays where the layer behind takes a prior term (nearer_layer's choice, detached): ``ok`` and a smaller
    error there."""
    return mi.Bool(ok) & (dr.detach(err_t) < dr.detach(err_i))


def normal_loss(normal, prior, tau_n: float = 0.3, valid=True, form: str = "l1_cos", masked: bool = True,
                behind=None, weight=None):
    """Normal prior: mean over the valid pixels of (1 - <n, p>) (``form`` "cos", the supplement's) or
    |n - p|_1 + (1 - <n, p>) ("l1_cos", glint_mi's), with the cosine mask [<n, p> >= tau_n] when ``masked``.

    ``normal`` and ``prior`` are unit vectors in the same (camera) frame; the mask is detached. ``behind`` =
    (n_behind, ok): where ``ok``, the layer whose normal agrees better with the prior takes the term
    (nearer_layer; the cosine mask then reads that layer's cosine). ``weight`` (detached, per pixel; e.g.
    :func:`near_weight`) scales each pixel's term; the mean still divides by the number of masked pixels.
    """
    def term_of(n):
        cos = dr.dot(n, prior)
        term = 1.0 - cos
        if form == "l1_cos":
            d = n - prior
            term += dr.abs(d.x) + dr.abs(d.y) + dr.abs(d.z)
        return term, cos

    term, cos = term_of(normal)
    if behind is not None:
        term_t, cos_t = term_of(behind[0])
        use_t = takes_behind(-cos, -cos_t, behind[1])  # the term and its cosine mask follow one choice
        term, cos = dr.select(use_t, term_t, term), dr.select(use_t, cos_t, cos)
    mask = mi.Bool(valid) & dr.isfinite(dr.detach(cos))  # (as wide as the rays)
    if masked:
        mask &= dr.detach(cos) >= tau_n
    if weight is not None:
        term = term * dr.detach(weight)
    return dr.sum(dr.select(mask, term, 0.0)) / dr.maximum(dr.count(mask), 1), mask


def bce(t, target: float, weight):
    """Binary cross-entropy of transparency t against a constant target, weighted mean (weights detached)."""
    t = dr.clip(t, 1e-6, 1.0 - 1e-6)
    w = dr.detach(weight)
    loss = -(target * dr.log(t) + (1.0 - target) * dr.log(1.0 - t))
    return dr.sum(w * loss) / dr.maximum(dr.sum(w), 1e-12)


def transparency_masks(depth_t, depth_i, tau_delta: float, albedo=None, base=None, cos_view=None,
                       low_a: float = 0.05, high_a: float = 0.10, high_b: float = 0.25, alpha_t=None, alpha_i=None,
                       min_alpha: float = 0.5, cue=None, dark_votes: bool = True):
    """L_trans masks of one image (numpy in and out, no gradient): returns (weight_transparent, weight_opaque),
    [H, W] float (or [B, H, W] for a stack of images). Computed by :func:`block_transparency_masks`, the definition
    training uses on its patches.

    ``depth_t``/``depth_i``: planar depth of the transmission set (straight from the camera) and of the interface
    (0 = invalid). A depth is valid where it is > 0 and, when the accumulated alphas ``alpha_t``/``alpha_i`` are
    given, where they reach ``min_alpha``: an expected depth is normalised by the alpha, so a faint layer (a
    floater, or an interface that has become a translucent veil) has a depth but is no surface, and must not vote.
    Delta z = D_T - D_I: "behind" if > tau_delta, "same" otherwise. With a diffuse-albedo prior
    (``albedo`` [H,W] mean RGB) and the interface base colour (``base`` [H,W]): transparent = LowA & HighB & valid &
    behind; opaque = HighA | (LowA & ~HighB) | same. Without: transparent = valid & behind, opaque = same.
    With the SfM see-through ``cue`` ([H,W]: +1 seen through, -1 opaque, 0 none; RayBank.see_through_cue), the cue
    takes the place of the depth gap: "behind" = the interface is a surface and the cue says seen through, "same" =
    the cue says opaque; pixels without evidence vote for nothing. The depth gap of two half-trained
    sets does not separate glass from a room (measured on a Cycles room at 400 iterations: "behind" on 85 % of the
    glass pixels and 64 % of the others); the cue's labels are right on 79 % (seen through) and 97 % (opaque) of
    the pixels they cover there.
    ``dark_votes=False`` leaves the dark-surface vote (LowA & ~HighB) out of the opaque mask: a glass pane has a
    near-black albedo prior too, and its interface colour is dark wherever what lies behind it is dark.
    Both are eroded 3x3 and weighted by the view angle (1 up to 70 deg, 0 beyond 80 deg, linear between).
    """
    shape = np.shape(depth_i)
    dev = lambda x: None if x is None else mi.Float(np.ascontiguousarray(np.broadcast_to(x, shape), np.float32).ravel())
    w_t, w_o = block_transparency_masks(dev(depth_t), dev(depth_i), shape[-2:], tau_delta, dev(albedo), dev(base),
                                        dev(cos_view), low_a, high_a, high_b, dev(alpha_t), dev(alpha_i), min_alpha,
                                        dev(cue), dark_votes)
    return np.array(w_t, np.float64).reshape(shape), np.array(w_o, np.float64).reshape(shape)


# ------------------------------------------------------------ patch terms
C1, C2 = 0.01 ** 2, 0.03 ** 2


def l1(pred, target):
    d = pred - target
    return dr.mean(dr.abs(d.x) + dr.abs(d.y) + dr.abs(d.z)) / 3.0


def dssim(pred, target, p: int):
    """1 - SSIM with one window per p x p patch (rays of a patch contiguous), channels averaged.

    Whole-image SSIM uses sliding 11x11 windows; on ray patches each patch is one window (uniform weights).
    """
    n = p * p
    total = mi.Float(0.0)
    for ch in range(3):
        x, y = pred[ch], target[ch]
        mx, my = dr.block_sum(x, n) / n, dr.block_sum(y, n) / n
        sxx = dr.block_sum(x * x, n) / n - mx * mx
        syy = dr.block_sum(y * y, n) / n - my * my
        sxy = dr.block_sum(x * y, n) / n - mx * my
        s = ((2 * mx * my + C1) * (2 * sxy + C2)) / ((mx * mx + my * my + C1) * (sxx + syy + C2))
        total += dr.mean(s)
    return 1.0 - total / 3.0


def take(v, idx):
    """Gather rows ``idx`` of a Dr.Jit value (Float or a 3-vector), differentiably."""
    if dr.size_v(v) == 3:
        return type(v)(*[dr.gather(mi.Float, v[k], idx) for k in range(3)])
    return dr.gather(type(v), v, idx)


def near_weight(depth, valid, p: float = 0.01):
    """The release's depth scale of its normal terms (``normalize_depth``): 1 - (D - near) / (far - near) clipped
    to [0, 1], near 1 and far 0, with near / far the ``p`` / 1 - ``p`` quantiles of ``depth`` over the ``valid``
    rays (the release: of every pixel of the image; its quantile is the k-th smallest and k-th largest value,
    k = int(p N)). Detached; the sort and the two gathers stay on the device (no read-back)."""
    D = dr.detach(mi.Float(depth))
    ok = mi.Bool(valid) & dr.isfinite(D)
    s = dr.sort(dr.select(ok, D, dr.inf))  # the valid depths first, ascending
    n = mi.UInt32(dr.count(ok))
    k = mi.UInt32(dr.floor(mi.Float(n) * p))
    k1 = dr.maximum(k, 1)
    last = dr.maximum(n, 1) - 1
    near = dr.gather(mi.Float, s, dr.minimum(k1 - 1, last))
    far = dr.gather(mi.Float, s, dr.select(n > k1, n - k1, 0))  # (unsigned: no n - k1 when n <= k1)
    w = 1.0 - (D - near) / dr.maximum(far - near, 1e-12)
    return dr.select(ok, dr.clip(w, 0.0, 1.0), 0.0)


def depth_normal_consistency(origin, d, dist, normal, valid, nb, weight=None, depth_grad: float = 1.0):
    """2DGS normal consistency on patches: 1 - <n, n_depth>, n_depth from the cross product of the 3D points of
    a pixel and its right and lower neighbours (oriented to face the camera). ``nb`` = patch_neighbours(...).
    ``weight`` (detached, per ray; e.g. :func:`near_weight`) scales each pixel's term; the mean still divides by the
    number of pixels where the term is defined. ``depth_grad`` scales the gradient that reaches the depth (its pull
    toward the normals): 1 differentiates n and n_depth alike (2DGS), 0 detaches n_depth, so that the term moves only
    the normals; the value is the same (between 0 and 1, to float rounding). A Float (detached, per ray) scales each
    ray's depth by its own share (:func:`glass_pull`)."""
    i, r, b = (mi.UInt32(x) for x in nb)
    per_ray = isinstance(depth_grad, dr.ArrayBase)
    if not per_ray and depth_grad <= 0.0:
        dist = dr.detach(dist)
    elif per_ray or depth_grad < 1.0:  # the value of dist, a share of its gradient
        g = dr.detach(mi.Float(depth_grad)) if per_ray else depth_grad
        dist = g * dist + (1.0 - g) * dr.detach(dist)
    pts = origin + d * dist
    P0, Pr, Pb = (take(pts, k) for k in (i, r, b))
    n_d = dr.cross(Pr - P0, Pb - P0)
    n_d = dr.normalize(n_d)
    di = take(mi.Vector3f(d), i)
    n_d = dr.select(dr.dot(n_d, di) > 0, -n_d, n_d)
    n0 = take(mi.Vector3f(normal), i)
    ok = take(mi.Bool(valid), i) & take(mi.Bool(valid), r) & take(mi.Bool(valid), b)
    ok &= dr.isfinite(n_d.x)
    term = dr.select(ok, 1.0 - dr.dot(n0, n_d), 0.0)
    if weight is not None:
        term = term * take(dr.detach(mi.Float(weight)), i)
    return dr.sum(term) / dr.maximum(dr.count(ok), 1)


def glass_pull(share: float, t, cue=None, t_full: float = 1.0):
    """``prior_weight_where: off_glass``: the consistency's pull on the depth per ray, share + (1 - share) g, with
    g = max(clip(t / t_full, 0, 1), 1 where the SfM see-through ``cue`` > 0): the whole pull on the glass (the rendered
    transparency ``t`` reaches ``t_full``, prior_weight_glass_t, or the cue says seen through), the share elsewhere.
    Detached; a share >= 1 stays 1.0."""
    if share >= 1.0:
        return 1.0
    g = dr.clip(dr.detach(mi.Float(t)) / t_full, 0.0, 1.0)
    if cue is not None:
        g = dr.select(mi.Float(cue) > 0, 1.0, g)
    return share + (1.0 - share) * g


def transparency_regulariser(t, image_grad, nb):
    """Entropy + L1 + edge-aware TV (weights exp(-|grad I|), computed from the photo) of the transparency t."""
    tc = dr.clip(t, 1e-6, 1.0 - 1e-6)
    entropy = dr.mean(-(tc * dr.log(tc) + (1.0 - tc) * dr.log(1.0 - tc)))
    i, r, b = (mi.UInt32(x) for x in nb)
    t0, tr, tb = (take(t, k) for k in (i, r, b))
    w = dr.exp(-(image_grad if isinstance(image_grad, mi.Float) else mi.Float(image_grad)))
    tv = dr.mean(w * (dr.abs(tr - t0) + dr.abs(tb - t0)))
    return entropy + dr.mean(t) + tv


def plausibility(depth_t, depth_i, n_t, n_i, weight, extent: float):
    """Pull the transmission set to the interface where it is opaque: |D_T - D_I| / extent + (1 - <n_T, n_I>)."""
    w = dr.detach(weight)
    term = dr.abs(depth_t - dr.detach(depth_i)) / extent + (1.0 - dr.dot(n_t, dr.detach(n_i)))
    return dr.sum(w * term) / dr.maximum(dr.sum(w), 1e-12)


def plausibility_weight(t, alpha_i, min_alpha: float):
    """Where the plausibility term pulls G_trans to the interface (``plausibility_mask: interface``): 1 - t where the
    interface is a surface (accumulated alpha >= ``min_alpha``), 0 elsewhere; detached. It reads only the interface,
    so a transmission set that floats behind an opaque interface is pulled back instead of voting "transparent"."""
    return dr.select(dr.detach(alpha_i) >= min_alpha, 1.0 - dr.clip(dr.detach(t), 0.0, 1.0), 0.0)


# ------------------------------------------------------- the batch objective
def _leaf(x):
    """A detached copy of a traced buffer with gradients enabled: the losses' AD input, whose adjoint the replay
    back-propagates."""
    y = type(x)(dr.detach(x))
    dr.enable_grad(y)
    return y


def read_values(values: dict) -> dict:
    """Width-1 Dr.Jit values (and plain numbers) -> floats, evaluated together."""
    arrays = [v for v in values.values() if isinstance(v, dr.ArrayBase)]
    if arrays:
        dr.eval(*arrays)
    return {k: (float(v[0]) if dr.width(v) else 0.0) if isinstance(v, dr.ArrayBase) else float(v)
            for k, v in values.items()}


def component_stats(out: dict, gt) -> dict:
    """On the device (width-1 Dr.Jit arrays, nothing read back): each secondary set's share of the image energy,
    share_X = mean(k_X lum(c_X)) / mean(lum(C)), and its gain, how much it improves the batch's photometric fit: the
    relative increase of the mean L1 error when its weight went to the interface instead (what dropping it would do,
    before the interface adapts), gain_X = (E without X - E) / E, E = mean |C - photo| over the rays where the
    interface is a surface (accumulated alpha >= 0.5; right after an opacity reset the 4 % Fresnel floor lets c_R
    brighten a dark, uncovered image); NaN where no ray is a surface. Only traced sets have a gain. Equal to the
    float64 numpy definitions in tests/test_objective.py to float32 rounding."""
    w = out["weights"]
    C = mi.Color3f(out["rgb"])
    img_e = dr.maximum(dr.mean(_mean3(C)), 1e-6)
    stats = {"share_reflection": dr.mean(w[1] * _mean3(out["reflection"])) / img_e,
             "share_transmission": dr.mean(w[2] * _mean3(out["transmission"])) / img_e}
    surface = dr.detach(out["alpha"]) >= 0.5
    n = dr.maximum(mi.Float(dr.count(surface)), 1.0) * 3.0
    l1 = lambda x: dr.sum(dr.select(surface, dr.sum(dr.abs(x - gt)), 0.0)) / n
    e = dr.maximum(l1(C), 1e-6)
    none = dr.count(surface) == 0
    cI = mi.Color3f(out["interface"])
    for k, name in ((1, "reflection"), (2, "transmission")):
        if dr.width(w[k]) <= 1:  # not traced: a constant weight
            continue
        without = C - w[k] * (mi.Color3f(out[name]) - cI)
        stats[f"gain_{name}"] = dr.select(none, dr.nan, (l1(without) - e) / e)
    return stats


def _mean3(c):
    """Per ray, the mean of a colour's channels, summed in numpy's order (float32; a scalar 0 for a pass that was
    not traced)."""
    c = mi.Color3f(c)
    return ((c.x + c.y) + c.z) / 3.0


def erode_blocks(mask, h: int, w: int):
    """3x3 erosion of a Dr.Jit Bool on h x w blocks (patches, or whole images) laid out one after the other
    (row-major): a pixel stays set where it and its 8 neighbours are, and nowhere on a block's border (a binary
    erosion with border value 0, per block)."""
    i = dr.arange(mi.UInt32, dr.width(mask))
    local = i % (h * w)
    y, x = local // w, local % w
    inner = (y > 0) & (y < h - 1) & (x > 0) & (x < w - 1)
    out = mask & inner
    base = mi.Int32(i)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if dy or dx:
                out &= dr.gather(mi.Bool, mask, mi.UInt32(dr.select(inner, base + dy * w + dx, base)))
    return out


def photo_edges(gt, nb):
    """The photo's edge strength at the patch pixels ``nb`` (patch_neighbours' pixels with a right and a lower
    neighbour): mean over channels of |right - pixel| plus that of |below - pixel|."""
    i, right, down = nb
    at = lambda idx: dr.gather(mi.Color3f, gt, idx)
    c = at(i)
    return _mean3(dr.abs(at(right) - c)) + _mean3(dr.abs(at(down) - c))


def block_transparency_masks(depth_t, depth_i, block: tuple, tau_delta: float, albedo=None, base=None,
                             cos_view=None, low_a: float = 0.05, high_a: float = 0.10, high_b: float = 0.25,
                             alpha_t=None, alpha_i=None, min_alpha: float = 0.5, cue=None, dark_votes: bool = True):
    """The L_trans masks (the rules of :func:`transparency_masks`) on Dr.Jit arrays, per pixel of h x w ``block``s
    laid out one after the other (a batch's patches, or whole images), eroded within each block: returns
    (weight_transparent, weight_opaque) as Float. Tested against a numpy/scipy implementation of the same rules
    (tests/test_losses.py): the masks exactly, the view-angle weights to float32 rounding."""
    valid = (depth_t > 0) & (depth_i > 0)
    if alpha_t is not None and alpha_i is not None:
        valid &= (alpha_t >= min_alpha) & (alpha_i >= min_alpha)
    dz = depth_t - depth_i
    behind, same = valid & (dz > tau_delta), valid & (dz <= tau_delta)
    if cue is not None:  # the SfM cue replaces the depth gap
        valid_i = (depth_i > 0) if alpha_i is None else (depth_i > 0) & (alpha_i >= min_alpha)
        behind, same = valid_i & (cue > 0), cue < 0
    if albedo is not None and base is not None:
        low, high, bright = albedo < low_a, albedo > high_a, base > high_b
        m_t = low & bright & behind
        votes = (high | (low & ~bright)) if dark_votes else high
        m_o = (valid & votes) | same
    else:
        m_t, m_o = behind, same
    w = mi.Float(1.0)
    if cos_view is not None:
        ang = dr.acos(dr.clip(cos_view, -1.0, 1.0)) * mi.Float(180.0 / np.pi)
        w = dr.clip((80.0 - ang) / 10.0, 0.0, 1.0)
    one = lambda m: dr.select(erode_blocks(m, *block), w, 0.0)
    return one(m_t), one(m_o & ~m_t)


def batch_transparency_masks(c, b, out: dict, extent: float, gate: bool = False):
    """L_trans masks of the batch on the p x p patches, on the device: (weight_transparent, weight_opaque, coverage,
    gate), coverage = the share of the batch's pixels in the transparent mask (before the improvement weight; what
    components: auto reads; a width-1 Float); gate (with ``gate``, else None) = the rays where t may rise under
    ``t_raise: masks``: outside the opaque mask, read with or without its dark-surface vote (``t_gate_votes``).
    ``b``: a :class:`glint_mi.training.batch.DeviceBatch`."""
    _, Dd, _, DA = out["trans_direct"]
    dI, dT = dr.detach(mi.Float(out["depth"])), dr.detach(mi.Float(Dd))
    aI, aT = dr.detach(mi.Float(out["alpha"])), dr.detach(mi.Float(DA))
    albedo = _mean3(b.albedo_prior) if b.albedo_prior is not None else None
    base = _mean3(dr.detach(mi.Color3f(out["interface"]))) if albedo is not None else None
    n = dr.detach(mi.Vector3f(out["normal"]))
    d = b.direction
    cos = -((n.x * d.x + n.y * d.y) + n.z * d.z)
    cos = dr.select(dr.squared_norm(n) > 0, cos, 1.0)
    masks = lambda dark: block_transparency_masks(dT, dI, (b.patch, b.patch), c.tau_delta * extent, albedo, base,
                                                  cos, alpha_t=aT, alpha_i=aI, min_alpha=c.trans_min_alpha,
                                                  cue=b.cue, dark_votes=dark)
    w_t, w_o = masks(True)
    allowed = None
    if gate:
        g_o = w_o if c.t_gate_votes == "all" or albedo is None else masks(False)[1]  # no prior: no dark vote
        allowed = g_o <= 0
    coverage = mi.Float(dr.count(w_t > 0)) / dr.width(w_t)
    # weight M_t by how much seeing through improves the photometric fit
    return w_t * see_through_gain(b, out), w_o, coverage, allowed


def depth_gap_stats(c, out: dict, extent: float) -> dict:
    """Where both sets are surfaces (accumulated alpha >= trans_min_alpha): the share of the batch's pixels whose
    transmission depth lies more than tau_delta behind the interface's (``gap_behind``, what L_trans's depth rule
    calls glass) and in front of it (``gap_front``, impossible for glass: the depth gap's noise). Width-1 Dr.Jit
    arrays, reduced on the device."""
    _, Dd, _, DA = out["trans_direct"]
    dI, dT = dr.detach(out["depth"]), dr.detach(Dd)
    valid = ((dI > 0) & (dT > 0) & (dr.detach(out["alpha"]) >= c.trans_min_alpha)
             & (dr.detach(DA) >= c.trans_min_alpha))
    tau = c.tau_delta * extent
    share = lambda m: mi.Float(dr.count(m)) / dr.width(m)
    return {"gap_behind": share(valid & (dT - dI > tau)), "gap_front": share(valid & (dT - dI < -tau))}


def see_through_gain(b, out: dict):
    """Per ray, how much seeing through improves the photometric fit (Dr.Jit Float in [0, 1]): the L1 error of the
    pixel at t = 1 (the colour transmitted from x_I) against the pixel at t = 0 (the interface's own colour), both
    with the current specular part; gain = clip((e_0 - e_1) / e_0, 0, 1): L_trans's weight on M_t."""
    gt = b.rgb
    ks = dr.detach(mi.Float(out["weights"][1]))
    spec = ks * dr.detach(mi.Color3f(out["reflection"]))
    e_0 = _mean3(dr.abs((1.0 - ks) * dr.detach(mi.Color3f(out["interface"])) + spec - gt))
    e_1 = _mean3(dr.abs((1.0 - ks) * dr.detach(mi.Color3f(out["transmission"])) + spec - gt))
    return dr.clip((e_0 - e_1) / dr.maximum(e_0, 1e-3), 0.0, 1.0)
