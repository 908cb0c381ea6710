"""Methods of the comparison table as configurations of the one trainer (glint-method.md section 7).

Each method is a set of :class:`glint_mi.config.TrainConfig` overrides plus the statement of what differs from the
published method on this engine (ray-traced Gaussians, first-order transport, CPU budgets). Nothing here is a copy
of another trainer: a baseline is GLINT's pipeline with components, losses or blending switched.
"""
from __future__ import annotations

import dataclasses

NO_PRIORS = dict(priors="none", w_depth=0.0, w_normal=0.0)
NO_GLASS = dict(w_trans=0.0, w_treg=0.0, w_plausibility=0.0, w_direct=0.0)
NOT_OURS = dict(w_sfm_depth=0.0)  # glint_mi's SfM depth term is no baseline's
PLAIN_PHOTO = dict(w_l1=0.8, w_dssim=0.2)  # 3DGS / 2DGS weights
ALPHA = dict(blend="alpha")  # C = sum T_i alpha_i c_i: no Fresnel weights, no specular, no transparency attribute


@dataclasses.dataclass(frozen=True)
class Method:
    name: str
    overrides: dict
    what: str
    differs: str = ""


METHODS = {m.name: m for m in [
    Method("3dgs", dict(**NOT_OURS, components="interface", kernel="ellipsoid", **ALPHA, w_consistency=0.0, **NO_PRIORS, **NO_GLASS,
                        **PLAIN_PHOTO),
           "one set of 3D Gaussians, plain alpha compositing (3DGRT-style ray tracing)",
           "ray-traced at the 3DGRT peak instead of rasterised; 3DGS's screen-space densification threshold replaced "
           "by our top-fraction rule"),
    Method("2dgs", dict(**NOT_OURS, components="interface", **ALPHA, w_consistency=0.1, **NO_PRIORS, **NO_GLASS, **PLAIN_PHOTO),
           "one set of surfels + depth-normal consistency",
           "no depth distortion loss; ray-traced surfels"),
    Method("pgsr", dict(**NOT_OURS, components="interface", **ALPHA, w_consistency=0.3, **NO_PRIORS, **NO_GLASS, **PLAIN_PHOTO),
           "planar surfels + single-view depth-normal consistency",
           "PGSR's multi-view geometric and photometric consistency terms are NOT implemented (they need pairs of "
           "rendered views per step); only the single-view part, with a higher weight"),
    Method("envgs", dict(**NOT_OURS, components="interface,reflection", blend="envgs", **NO_PRIORS, **NO_GLASS, **PLAIN_PHOTO),
           "interface + reflection set, C = (1 - beta) c_base + beta c_env, no Fresnel, no transmission",
           "the environment set is traced from the interface's expected depth like GLINT's (same as EnvGS); "
           "no normal prior"),
    Method("refgs", dict(**NOT_OURS, components="interface", **ALPHA, sh_degree=3, **NO_PRIORS, **NO_GLASS, **PLAIN_PHOTO),
           "surfels with view-dependent appearance",
           "Ref-GS's directional (split-sum) appearance factorisation is replaced by degree-3 SH colour: only the "
           "view dependence is kept"),
    Method("tsgs", dict(**NOT_OURS, components="interface,transmission", trans_masks="gt", w_plausibility=0.0, t_raise="free",
                        **NO_PRIORS),
           "surfels with a transparency attribute supervised by transparent masks",
           "masks are the GROUND-TRUTH glass masks (labelled so; TSGS uses image segmentation); the first-surface "
           "depth rule (densest window in the first 10 % of weight) is not implemented: depth is the expected depth "
           "of the interface, and what is seen through glass comes from a transmission set"),
    Method("glint", {}, "all three sets, Fresnel first-order transport, L_trans (this project)"),
    # ablations of the supplement
    Method("glint-no-trans", dict(components="interface,reflection"), "GLINT without the transmission set"),
    Method("glint-no-refl", dict(components="interface,transmission"), "GLINT without the reflection set"),
    Method("glint-no-depth", dict(w_depth=0.0), "GLINT without L_depth"),
    Method("glint-no-normal", dict(w_normal=0.0), "GLINT without L_normal"),
    Method("glint-no-priors", dict(**NO_PRIORS), "GLINT without any geometric (or albedo) prior"),
    Method("glint-no-ltrans", dict(w_trans=0.0), "GLINT without L_trans"),
    Method("glint-t-free", dict(t_raise="free"),
           "GLINT with the paper's freedom for t: the photometric terms may raise it wherever their gradient says "
           "(glint_mi's default lets nothing raise t where L_trans's opaque mask votes)"),
    Method("glint-batch-depth", dict(depth_align="batch"),
           "GLINT with the paper's per-batch scale-shift fit of the depth prior (glint_mi's default fits it once per "
           "view to the SfM points)"),
]}
TABLE_METHODS = ("3dgs", "2dgs", "pgsr", "envgs", "refgs", "tsgs", "glint")


def config_for(method: str, preset: str, variant: str = "supplement", **extra):
    from .config import ConfigError, TrainConfig

    if method not in METHODS:
        raise ConfigError(f"unknown method '{method}'; use one of {sorted(METHODS)}.")
    return TrainConfig.for_preset(preset, variant, **{**METHODS[method].overrides, **extra})
