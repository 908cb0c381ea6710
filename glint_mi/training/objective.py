"""The training objective as a table of terms (glint-method.md section 3): each :class:`Term` names its loss, the
config field that weighs it, the schedule field it starts at, the buffers it reads and the function that computes it
on one ray batch. :func:`batch_objective` builds what the terms share (:class:`Inputs`), runs the terms the stage
switches on in the table's order and returns their values and the adjoints of the traced buffers. A new term is a
function and a row of :data:`TERMS` here, its weight field in the config's ``losses`` layer and its name in
``LOSS_NAMES`` (config.py); the trainer's stage switches it on while weighted, from its schedule field.

The terms' math is in :mod:`glint_mi.training.losses`.
"""
from __future__ import annotations

import dataclasses
from typing import Callable

import drjit as dr
import mitsuba as mi

from glint_mi.config import LOSS_NAMES
from glint_mi.training import losses as L
from glint_mi.training.losses import read_values

__all__ = ["Inputs", "Term", "TERMS", "batch_objective", "read_values"]  # read_values: the trainer's


@dataclasses.dataclass
class Inputs:
    """What the terms of one batch share: the losses layer ``c``, the batch ``b`` (its photos and priors), the traced
    buffers ``out`` and their differentiable leaves, the stage ``st``, and values several terms read."""

    c: object
    b: object
    out: dict
    st: dict
    ray: object
    fwd: object
    n_views: int
    extent: float
    nb: object                   # each ray's patch neighbours
    rgb: object
    depth: object                # the interface's planar depth (leaf)
    normal: object
    t: object
    A: object                    # the interface's accumulated alpha (detached)
    leaves: dict                 # buffer name -> leaf (the adjoints returned for the replay)
    stats: dict
    near_c: bool                 # the release's near-to-far weight on the consistency ...
    near_p: bool                 # ... and on the normal prior
    w_near: object               # that weight from the interface's depth (None when no term reads it)
    trans: tuple | None          # the transmission set's direct buffers (Dc, Dd, Dn, DA) as leaves, when traced
    behind_ok: object            # prior_layer: nearer - rays whose priors may describe the transmitted surface
    prior_w: object              # the prior terms' schedule (prior_decay)
    decays: tuple                # the terms it scales (prior_decay_terms)
    _masks: tuple | None = None

    def decay(self, term: str):
        """The factor on the prior term ``term``: its schedule (prior_decay, for the terms prior_decay_terms names)
        times its share from the priors' agreement with SfM (prior_weight_ref; a constant from prior_weight_from of the
        run, 1 before it)."""
        share = self.st.get("prior_weight", {}).get(term, 1.0)
        return (self.prior_w if term in self.decays else 1.0) * share

    @property
    def traced_t(self) -> bool:
        return self.trans is not None

    def masks(self):
        """L_trans's depth-gap masks (w_t, w_o), computed once per batch for the terms that read them; their coverage
        and the depth gaps go to the statistics, and with the t gate on the rays where t may rise."""
        if self._masks is None:
            c, st = self.c, self.st
            w_t, w_o, self.stats["mask_t"], allowed = L.batch_transparency_masks(c, self.b, self.out, self.extent,
                                                                                  st["t_gate"])
            self.stats.update(L.depth_gap_stats(c, self.out, self.extent))
            if st["t_gate"]:  # t_raise: masks - nothing may raise t where the gate's opaque votes fall (replay)
                self.stats["t_raise"] = allowed
            self._masks = (w_t, w_o)
        return self._masks


@dataclasses.dataclass(frozen=True)
class Term:
    name: str                    # its entry of LOSS_NAMES (and the stage's switch of the same name, if any)
    weight: str                  # the config field that weighs it (0 switches it off)
    starts: str | None           # the schedule field (a fraction of the run) it starts at; None: from the start
    needs: tuple                 # the traced buffers it reads besides rgb / depth / normal / alpha
    when: Callable               # (Inputs) -> whether it runs on this batch
    fn: Callable                 # (Inputs) -> its weighted value


# ------------------------------------------------------------------ the terms
def _l1(x):
    return x.c.w_l1 * L.l1(x.rgb, x.b.rgb)


def _dssim(x):
    return x.c.w_dssim * L.dssim(x.rgb, x.b.rgb, x.b.patch)


def _consistency(x):
    """Depth-normal consistency of the interface (expected depth, or 2DGS's median) and, where the transmission set
    is traced with its direct image, of that set too (the release scales it by G_trans's own depth)."""
    c = x.c
    if c.consistency_depth == "median":  # 2DGS: normals of the median depth (where T falls to 0.5)
        dist = x.leaves["median"] = L._leaf(x.out["median"])
    else:
        dist = x.depth / dr.dot(x.ray.d, x.fwd)
    # its pull on the depth: none (consistency_grad: normal), else the share prior_weight_ref gives it (1: the paper)
    pull = 0.0 if c.consistency_grad == "normal" else x.st.get("prior_weight", {}).get("consistency", 1.0)
    if c.prior_weight_where == "off_glass":  # the glass keeps the whole pull, per ray
        pull = L.glass_pull(pull, x.t, x.b.cue, c.prior_weight_glass_t)
    value = c.w_consistency * L.depth_normal_consistency(x.ray.o, x.ray.d, dist, x.normal, x.A > 0.5, x.nb, x.w_near,
                                                         pull)
    if x.traced_t and x.st["direct"]:
        _, Dd, Dn, DA = x.trans
        w_t_near = L.near_weight(Dd, dr.detach(DA) > 0.5) if x.near_c else None
        value = value + c.w_consistency * L.depth_normal_consistency(
            x.ray.o, x.ray.d, Dd / dr.dot(x.ray.d, x.fwd), Dn, dr.detach(DA) > 0.5, x.nb, w_t_near, pull)
    return value


def _distortion(x):
    """2DGS's depth distortion of the interface's hits, mean over the rays."""
    x.leaves["distortion"] = L._leaf(x.out["distortion"])
    return x.c.w_dist * dr.mean(x.leaves["distortion"])


def _depth(x):
    """The depth prior, fitted per view (to the SfM points, the whole image, or the batch); with prior_layer nearer
    on whichever layer it agrees with where the interface is transparent."""
    c, b = x.c, x.b
    depth, prior = x.depth, b.depth_prior
    mask = (prior > 0) & (x.A > 0.5)
    d_behind = x.trans[1] if x.behind_ok is not None else None
    if b.depth_inverse:  # a disparity prior (MiDaS, Depth Anything): the fit is affine in 1 / depth
        mask &= depth > 1e-6
        depth = 1.0 / dr.maximum(depth, 1e-6)
        if d_behind is not None:
            d_behind = 1.0 / dr.maximum(d_behind, 1e-6)
    behind = (d_behind, x.behind_ok) if d_behind is not None else None
    if c.depth_align in ("sfm", "image") and b.depth_affine is not None:
        w_v, q_v = b.depth_affine
        fit = dr.isfinite(w_v)  # views without a fit keep the per-batch fit
        vid = dr.select(fit, x.n_views, b.view)  # fitted views: a spare slot
        w_b, q_b = L.depth_fit(depth, prior, mask & ~fit, vid, x.n_views + 1)
        return c.w_depth * x.decay("depth") * L.depth_loss_aligned(depth, prior, mask, dr.select(fit, w_v, w_b),
                                                           dr.select(fit, q_v, q_b), behind, b.depth_weight)
    return c.w_depth * x.decay("depth") * L.depth_loss(depth, prior, mask, b.view, x.n_views, behind, b.depth_weight)


def _sfm_depth(x):
    """glint_mi's: |D - z| / z at pixels with a tracked SfM feature's depth z."""
    z = x.b.sfm_depth
    m = (z > 0) & (x.A > 0.5)
    r = dr.select(m, dr.abs(x.depth - z) / dr.maximum(z, 1e-6), 0.0)
    return x.c.w_sfm_depth * dr.sum(r) / dr.maximum(dr.count(m), 1)


def _normal(x):
    c, b, normal = x.c, x.b, x.normal
    axes = b.axes
    n_cv = mi.Vector3f(dr.dot(axes[0], normal), dr.dot(axes[1], normal), dr.dot(axes[2], normal))
    prior = b.normal_prior
    valid = (dr.squared_norm(prior) > 0.25) & (x.A > 0.5)
    behind = None
    if x.behind_ok is not None:
        Dn = x.trans[2]
        behind = (mi.Vector3f(dr.dot(axes[0], Dn), dr.dot(axes[1], Dn), dr.dot(axes[2], Dn)), x.behind_ok)
    return c.w_normal * x.decay("normal") * L.normal_loss(n_cv, prior, c.tau_n, valid, c.normal_loss,
                                                          x.st["normal_masked"], behind,
                                                          x.w_near if x.near_p else None)[0]


def _direct(x):
    """The transmission set's direct image against the photo (x w_l1, w_dssim)."""
    c, Dc = x.c, x.trans[0]
    return c.w_direct * (c.w_l1 * L.l1(Dc, x.b.rgb) + c.w_dssim * L.dssim(Dc, x.b.rgb, x.b.patch))


def _trans_depth_gap(x):
    """L_trans on GLINT's masks (the depth gap, or the see-through cue)."""
    w_t, w_o = x.masks()
    return x.c.w_trans * (L.bce(x.t, 0.98, w_t) + L.bce(x.t, 0.02, w_o))


def _plausibility(x):
    c = x.c
    _, Dd, Dn, _ = x.trans
    w_p = x.masks()[1] if c.plausibility_mask == "opaque" else L.plausibility_weight(x.t, x.A, c.trans_min_alpha)
    return c.w_plausibility * L.plausibility(Dd, x.out["depth"], Dn, x.out["normal"], w_p, x.extent)


def _treg(x):
    return x.c.w_treg * L.transparency_regulariser(x.t, L.photo_edges(x.b.rgb, x.nb) * 10.0, x.nb)


def _trans_given_masks(x):
    """TSGS: L_trans supervised by given glass masks (a segmenter's, or the ground truth's, labelled)."""
    p = x.b.patch
    g = x.b.glass > 0.5
    w_t, w_o = (dr.select(L.erode_blocks(m, p, p), 1.0, 0.0) for m in (g, ~g))
    x.stats["mask_t"] = mi.Float(dr.count(w_t > 0)) / dr.width(w_t)
    return x.c.w_trans * (L.bce(x.t, 0.98, w_t) + L.bce(x.t, 0.02, w_o))


# In the order the total sums them (a term's place changes the total's float rounding, not its value).
TERMS = (
    Term("l1", "w_l1", None, (), lambda x: True, _l1),
    Term("dssim", "w_dssim", None, (), lambda x: True, _dssim),
    Term("consistency", "w_consistency", "consistency_from", ("median", "trans_direct"),
         lambda x: x.st["consistency"], _consistency),
    Term("distortion", "w_dist", "dist_from", ("distortion",), lambda x: x.st.get("distortion", False), _distortion),
    Term("depth", "w_depth", None, ("trans_direct",), lambda x: x.st["depth"], _depth),
    Term("sfm_depth", "w_sfm_depth", None, (), lambda x: x.st["sfm_depth"] and x.b.sfm_depth is not None, _sfm_depth),
    Term("normal", "w_normal", "normal_from", ("trans_direct",), lambda x: x.st["normal"], _normal),
    Term("direct", "w_direct", "transmission_from", ("trans_direct",), lambda x: x.traced_t and x.st["direct"],
         _direct),
    Term("trans", "w_trans", "trans_from", ("transparency", "trans_direct"),
         lambda x: x.traced_t and x.st["trans"] and x.c.trans_masks == "depth_gap", _trans_depth_gap),
    Term("plausibility", "w_plausibility", "plausibility_from", ("transparency", "trans_direct"),
         lambda x: x.traced_t and x.st["plausibility"], _plausibility),
    Term("treg", "w_treg", "treg_from", ("transparency",), lambda x: x.traced_t and x.st["treg"], _treg),
    Term("trans", "w_trans", "trans_from", ("transparency",),
         lambda x: x.st["trans"] and x.c.trans_masks in ("gt", "prior"), _trans_given_masks),
)


def batch_objective(c, b, out: dict, st: dict, ray, fwd, n_views: int, extent: float, read: bool = True):
    """The training objective on one ray batch: every term of :data:`TERMS` that the stage ``st`` switches on,
    weighted by ``c``, the config's ``losses`` layer (every field the terms read is there; a whole TrainConfig reads
    through), on the buffers ``out`` traced for the batch ``b``.

    Returns (terms: weighted value per name of LOSS_NAMES, adjoints: per traced buffer, for the integrator's
    replay, stats: L_trans mask coverage and each component's share of the image energy, and with ``t_raise:
    masks`` the rays where t may rise, for the replay).

    The terms and the statistics are reduced on the device. ``read`` (default) returns them as floats; with
    ``read=False`` they stay width-1 Dr.Jit arrays, scheduled for the next evaluation (the backward's), so a training
    step reads nothing back until it is logged (:func:`glint_mi.training.losses.read_values`)."""
    from glint_mi.training.batch import DeviceBatch, device_neighbours, to_device

    if not isinstance(b, DeviceBatch):
        b = to_device(b)
    terms = {k: 0.0 for k in LOSS_NAMES}
    stats = {}
    with dr.resume_grad():
        rgb = L._leaf(mi.Color3f(out["rgb"]))
        depth, normal, t = L._leaf(out["depth"]), L._leaf(out["normal"]), L._leaf(out["transparency"])
        leaves = {"rgb": rgb, "depth": depth, "normal": normal, "transparency": t}
        A = dr.detach(out["alpha"])
        # the release's depth scale, from the interface's depth: on the consistency (near, near_consistency) and on
        # the normal prior (near only; under near_consistency the prior keeps every pixel)
        near_c, near_p = c.normal_weight in ("near", "near_consistency"), c.normal_weight == "near"
        w_near = L.near_weight(out["depth"], A > 0.5) if (near_c and st["consistency"]) or (
            near_p and st["normal"]) else None
        trans = behind_ok = None
        if "transmission" in st["traced"]:
            trans = leaves["trans_direct"] = tuple(L._leaf(mi.Color3f(v) if i == 0 else v)
                                                   for i, v in enumerate(out["trans_direct"]))
            if c.prior_layer == "nearer":  # where the interface is transparent the priors may describe G_trans
                _, Dd, _, DA = trans
                behind_ok = (dr.detach(t) > 0.5) & (dr.detach(DA) > 0.5) & (dr.detach(Dd) > 0)
        # the prior terms' schedule (prior_decay): an opaque scalar, so the kernels stay the same while it falls
        prior_w = dr.opaque(mi.Float, st.get("prior_scale", 1.0)) if c.prior_decay < 1.0 else 1.0
        x = Inputs(c, b, out, st, ray, fwd, n_views, extent, device_neighbours(b.patches, b.patch), rgb, depth,
                   normal, t, A, leaves, stats, near_c, near_p, w_near, trans, behind_ok, prior_w,
                   tuple(c.prior_decay_terms.split(",")))
        parts = {term.name: term.fn(x) for term in TERMS if term.when(x)}
        total = sum(parts.values())
        dr.backward(total)
        adjoints = {}
        for k, v in leaves.items():
            adjoints[k] = tuple(dr.grad(y) for y in v) if isinstance(v, tuple) else dr.grad(v)
        for k, v in parts.items():
            terms[k] = dr.detach(v)
        terms["total"] = dr.detach(total)
    stats.update(L.component_stats(out, b.rgb))  # what each component contributes (evidence for components: auto)
    values = {**terms, **{k: v for k, v in stats.items() if k != "t_raise"}}
    if read:
        for k, v in read_values(values).items():
            (terms if k in terms else stats)[k] = v
    else:
        dr.schedule(*[v for v in values.values() if isinstance(v, dr.ArrayBase)])
    return terms, adjoints, stats
