"""What a run trains on besides the photos: the ray bank's priors (aligned to the SfM points), the SfM see-through cue
and the SfM depth term, each reported (``report.json``) and logged as it is set up. The trainer's constructor calls
:func:`training_inputs` once, after the sets exist (the cue is built only when a transmission set does)."""
from __future__ import annotations

import numpy as np

from glint_mi.config import TrainConfig
from glint_mi.data import Dataset
from glint_mi.training.batch import RayBank, inverse_variance_share


def training_inputs(ds: Dataset, cfg: TrainConfig, has_transmission: bool, report: dict, log=print,
                    resume_affine: np.ndarray | None = None) -> RayBank:
    """The run's ray bank with every input its losses read set up; ``report`` gains what each step found.
    ``resume_affine``: the image-space depth alignment a resumed run had refitted (``depth_align: image``)."""
    bank = RayBank(ds.train_views, ds.root, use_priors=cfg.priors == "all", glass_masks=cfg.trans_masks)
    if cfg.trans_albedo == "off" and bank.priors.pop("albedo", None) is not None:
        # the albedo prior's one reader is L_trans's mask rule (and components: auto's glass cue): left out, the run
        # is the run of a capture without one
        report["albedo_prior"] = "not read (trans_albedo: off)"
        log("albedo prior not read (trans_albedo: off): the transparency comes from the SfM see-through cue; "
            "trans_albedo: masks reads it as the paper does")
    report["priors"] = sorted(bank.has)
    if not bank.has and has_transmission:
        log(f"no priors ({ds.root}/priors holds no depth, normal or albedo maps"
            + (", priors: none" if cfg.priors == "none" else "") + "): geometry comes from the photos, "
            "depth-normal consistency and the SfM points' depth; nothing tells glass from a wall, so "
            "components: auto keeps the interface alone (priors/PRIORS.json and the README say how to add "
            "an estimator's maps)")
    if cfg.depth_align == "image" and resume_affine is not None:
        bank.depth_affine = resume_affine
    if cfg.depth_align == "sfm" and "depth" in bank.has:
        report["depth_align"] = bank.align_depth_priors(ds.points, seed=cfg.seed)
        log(f"depth prior aligned to the SfM points in {report['depth_align']['aligned_views']} of "
            f"{len(bank.views)} views (the others keep the per-batch fit)")
    if cfg.depth_prior_ref > 0 and "depth" in bank.has:
        loss_fit = bank.depth_affine
        if cfg.depth_align != "sfm":  # measured against the SfM fit; the loss keeps its own alignment
            bank.align_depth_priors(ds.points, seed=cfg.seed)
        dw = report["depth_prior_weights"] = bank.depth_prior_weights(ds.observations(), cfg.depth_prior_ref)
        if cfg.depth_align != "sfm":
            bank.depth_affine = loss_fit
        log(f"depth prior weighed per view by its agreement with the SfM points (depth_prior_ref "
            f"{cfg.depth_prior_ref:g}): " + (dw["why"] if "why" in dw else
            f"median residual {dw['residual_median']:.4f}, weights median {dw['weight_median']:.2f}, "
            f"min {dw['weight_min']:.2f}, {dw['full_weight_views']} of {dw['views']} views at full weight"))
    if cfg.trans_cue != "none" and has_transmission:  # only L_trans and plausibility read it
        cue = bank.see_through_cue(ds.observations(), cfg.cue_margin, cfg.cue_radius, cfg.cue_votes,
                                   cfg.cue_point_share, cfg.cue_photo)
        report["trans_cue"] = cue
        log(f"L_trans SfM see-through cue: {cue.get('seen_through_observations', 0)} features seen through, "
            f"{cue.get('opaque_observations', 0)} on opaque surfaces in {cue['views']} views"
            + (f" ({cue['why']})" if "why" in cue else ""))
    if cfg.prior_photo > 0 and bank.has & {"depth", "normal"}:  # after the cue and the alignment: both read it whole
        pp = bank.drop_priors_by_photo(cfg.prior_photo)
        report["prior_photo"] = pp
        log(f"prior_photo {cfg.prior_photo}: depth and normal priors left out on {100 * pp['dropped']:.1f} % of "
            "the training pixels (their colour moves with the view at the prior's depth)"
            + (f" ({pp['why']})" if "why" in pp else ""))
    if cfg.w_sfm_depth > 0:
        sd = bank.set_sfm_depth(ds.observations())
        report["sfm_depth"] = sd
        log(f"SfM depth: {sd['pixels']} training pixels carry a tracked feature's depth"
            + (f" ({sd['why']})" if "why" in sd else ""))
    return bank


def normal_prior_schedule(bank: RayBank, ds: Dataset, cfg: TrainConfig, report: dict,
                          log=print) -> tuple[float, dict]:
    """The run's floor for the falling normal prior (:func:`normal_prior_floor`) and each prior term's factor
    through the run (:func:`prior_weight_scale`), from the normal prior's agreement with the SfM points' planes
    measured once on the run's bank (not on coarse_to_fine's); each goes to ``report`` (``normal_prior_sfm``,
    ``prior_floor``, ``prior_weight``) and the log."""
    ag = None
    if "normal" in bank.has:
        ag = bank.normal_prior_sfm_agreement(ds.observations(), ds.points)
        report["normal_prior_sfm"] = ag
        log(f"normal prior against the SfM points' planes: median {ag['median_deg']:.1f} deg over "
            f"{ag['observations']} tracked features" if ag["median_deg"] is not None else
            f"normal prior against the SfM points' planes: not measured ({ag['why']})")
    floor, why = normal_prior_floor(cfg, ag)
    report["prior_floor"] = {"floor": floor, "why": why}
    if cfg.prior_decay < 1.0:
        log(why)
    scale, why = prior_weight_scale(cfg, ag)
    if cfg.prior_weight_ref > 0:
        report["prior_weight"] = {"scale": scale, "why": why}
        log(why)
    return floor, scale


def normal_prior_floor(cfg: TrainConfig, agreement: dict | None) -> tuple[float, str]:
    """The share of its weight the falling normal prior keeps at the end of the run (``prior_decay_ref``):
    min(1, (ref / a)^2), a the median angle between the normal prior and the SfM points' planes - the weight of a
    measurement whose error is a, against one whose error is ref (inverse variance). 0 with prior_decay_ref 0, and
    where a was not measured (then said). Returns (floor, why)."""
    if cfg.prior_decay >= 1.0 or "normal" not in cfg.prior_decay_terms.split(","):
        return 0.0, "the normal prior's weight does not fall"
    if cfg.prior_decay_ref <= 0:
        return 0.0, "prior_decay_ref 0: the normal prior falls to 0"
    a = (agreement or {}).get("median_deg")
    if a is None:
        why = (agreement or {}).get("why", "no normal prior")
        return 0.0, f"the normal prior's agreement with the SfM points was not measured ({why}): it falls to 0"
    f = float(inverse_variance_share(cfg.prior_decay_ref, a))
    return f, (f"the normal prior falls to {f:.2f} of its weight: it agrees with the SfM points' planes to {a:.1f} "
               f"deg, prior_decay_ref {cfg.prior_decay_ref:g} deg")


def prior_weight_scale(cfg: TrainConfig, agreement: dict | None) -> tuple[dict, str]:
    """Each prior term's factor through the run (``prior_weight_ref``): min(1, (ref / a)^2) on the terms
    ``prior_weight_terms`` names, a the mean angle between the normal prior and the SfM points' planes; 1 on the
    others, and on all of them with prior_weight_ref 0 or where a was not measured (then said). Returns
    ({term: factor}, why)."""
    if cfg.prior_weight_ref <= 0:
        return {}, "prior_weight_ref 0: the prior terms keep their weights"
    a = (agreement or {}).get("mean_deg")
    if a is None:
        why = (agreement or {}).get("why", "no normal prior")
        return {}, (f"the prior terms keep their weights: the normal prior's agreement with the SfM points was not "
                    f"measured ({why})")
    f = float(inverse_variance_share(cfg.prior_weight_ref, a))
    terms = cfg.prior_weight_terms.split(",")
    priors = [t for t in terms if t != "consistency"]
    names = [f"the {' and '.join(priors)} prior{'s' if len(priors) > 1 else ''}"] if priors else []
    full = f", whole from t {cfg.prior_weight_glass_t:g}" if cfg.prior_weight_glass_t < 1.0 else ""
    where = f" off the glass (prior_weight_where: off_glass{full})" if cfg.prior_weight_where == "off_glass" else ""
    names += [f"the depth-normal consistency's pull on the depth{where}"] if "consistency" in terms else []
    many = len(priors) > 1 or len(names) > 1
    which = f"{' and '.join(names)} weigh{'' if many else 's'} {f:.2f} of {'their' if many else 'its'} weight"
    which += f" from {cfg.prior_weight_from:.0%} of the run" if cfg.prior_weight_from > 0 else ""
    return {t: f for t in terms}, (f"{which}: the normal prior agrees with the SfM points' planes to {a:.1f} deg on "
                                   f"the mean, prior_weight_ref {cfg.prior_weight_ref:g} deg")
