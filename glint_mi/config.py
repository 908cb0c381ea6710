"""Training configuration: layers (run, model, render, optim, losses, schedule, densify, evaluation; :data:`LAYERS`)
composed into one :class:`TrainConfig`, presets sized for 2 CPU cores (and ``gpu``, the paper's budget), the schedule
variants (the paper's two and glint_mi's), and the migrations of older run folders (:data:`MIGRATIONS`). A field's
comment says what it is; why a default is what it is, with the measurement behind it, is in docs/decisions.md.

Iteration-dependent settings are *fractions of the run* (the paper's 60k-iteration schedule, rescaled): e.g. the
transparency bootstrapping starts at 5k/60k = 0.083 of the run. ``variant`` picks the schedule: the supplement's,
the authors' release (glint-method.md section 5), or glint_mi's default, the supplement's without its refine stage
(the interface trains to the end; docs/decisions.md); any field can still be overridden.
"""
from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import glint_mi.conventions as cv

PAPER_ITERS = 60_000.0
# the weighted terms of the objective (glint_mi.training.objective.TERMS), each switched by its w_<name> weight
LOSS_NAMES = ("total", "l1", "dssim", "direct", "depth", "sfm_depth", "normal", "consistency", "distortion", "trans",
              "treg", "plausibility")


DEFAULT_VARIANT = "glint_mi"  # the schedule of VARIANTS that every entry point uses unless told otherwise


class ConfigError(ValueError):
    """Bad configuration; the message names the field and the fix."""


@dataclasses.dataclass
class RunConfig:
    """The run: preset and schedule variant, seed, the budget (rays per iteration = patches x patch^2, drawn across
    the training views; iterations or epochs), the dataset's scale, checkpoints and logs."""

    preset: str = "quick"
    variant: str = DEFAULT_VARIANT       # glint_mi | supplement | release (glint-method.md section 5; VARIANTS)
    seed: int = 0
    iterations: int = 1500
    epochs: float = 0.0                  # > 0: the budget in rays per training pixel; a run sets ``iterations`` from
    #                                      the training set's size (so a 192 x 108 room gets the per-pixel budget of a
    #                                      96 x 54 one); 0: ``iterations`` as given. An explicit --iterations sets 0.
    patches: int = 32
    patch: int = 8
    downscale: int = 1                   # read the dataset at 1/k of its resolution (area filter, or a capture's
    #                                      images_<k>/): photos, priors, training and evaluation alike
    checkpoint_every: int = 200
    log_every: int = 10
    threads: int = 0                     # Dr.Jit's LLVM worker threads (0: every core). 1 makes a run, and a resumed
    #                                      one, the same bit for bit; with more, the gradients' atomic sums add in
    #                                      the order the threads finish: runs differ by float rounding that grows


@dataclasses.dataclass
class ModelConfig:
    """The model: which Gaussian sets, their kernel and colour, the priors they read, their initialisation (method
    section 1) and what ``components: auto`` keeps."""

    kernel: str = "surfel"
    normal_source: str = "axis"          # a Gaussian's normal (read by the priors, the depth-normal consistency,
    #                                      Fresnel and the reflection direction): axis = its surfel's thin axis (the
    #                                      paper) | attribute = a normal of its own, trained, the surfel's shape
    #                                      then free for appearance (surfels only)
    sh_degree: int = 1                   # highest SH degree; raised one band every sh_every of the run
    components: str = "auto"             # auto | all | comma list of interface,transmission,reflection
    priors: str = "all"                  # all | none: use the dataset's depth / normal / albedo priors
    init_opacity: float = 0.1
    grid_n: int = 32                     # reflection grid N^3 cells ...
    grid_k: int = 5                      # ... with K random points each (paper: 32, 5)
    init_min_points: int = 2000          # fewer SfM points than this: add random points in the scene box
    auto_trans_min: float = 0.001        # keep the transmission set if L_trans's transparent mask covers this
    #                                      share of the sampled pixels (mean since L_trans started)
    auto_contrib_min: float = 0.005      # drop the reflection set if its share of the image energy is below this
    #                                      (the transmission set: its mask alone, auto_trans_min)
    no_glass: str = "3dgs"               # when components: auto drops both secondary sets before training (no glass
    #                                      cue), the interface alone is a radiance field: 3dgs = train it exactly as
    #                                      the 3dgs method does (3D Gaussians, its loss weights 0.8 / 0.2, no
    #                                      depth-normal consistency, no SfM depth term); 3dgs+sfm = the same with
    #                                      glint_mi's SfM depth term; glint = GLINT's surfels and weights


@dataclasses.dataclass
class RenderConfig:
    """The image model (the integrator's properties, glint_mi.model.files.integrator_props) and how rays are traced."""

    max_order: int = 1
    max_hits: int = 256                  # hit budget per ray and pass (the paper: stop at T < 1e-4 "or a budget"); a
    #                                      ray that spends it is cut short (its share: log.csv budget_full)
    opacity_shells: bool = True          # each Gaussian's BVH shell ends where its alpha reaches the 1/255 cut-off
    #                                      (glint_gaussians' opacity_shells); false: 3.33 sigma for every opacity
    blend: str = "fresnel"               # fresnel (GLINT) | envgs: (1 - beta) c_I + beta c_R | alpha: plain compositing
    #                                      | refgs: Ref-GS's deferred srgb(c_I + s(reflect(d, N), beta as roughness))
    env_levels: int = 7                  # refgs: mip levels of its directional grid, 2^L x 2^(L+1) texels at level 0
    env_init: float = 0.001              # refgs: the specular radiance s the grid starts at, everywhere
    traversal: str = "auto"              # kbuffer (glint_mi.native's Embree k-buffer, LLVM only) | shellbvh (the same
    #                                      lists from our own BVH: host, or a CUDA device through CuPy) | bvh
    #                                      (Mitsuba's queries, one per hit) | auto: kbuffer where it builds, else bvh
    stored_hits: bool = True             # the replay walks the forward's stored hit lists instead of re-running
    #                                      the BVH queries (exact: same hits and arithmetic; rays x max_hits x 4 B
    #                                      per pass); false = re-trace (benchmarks/profile_step.py compares)
    stored_hits_mb: float = 1024.0       # cap on a batch's stored lists (rays x max_hits x 4 B x 5 passes): a larger
    #                                      batch re-traces in the replay instead (the same gradients)


@dataclasses.dataclass
class OptimConfig:
    """The optimiser (method section 5): Adam's learning rates (the position's is multiplied by the scene extent and
    decays to lr_position_final), its variant, and where the update runs."""

    lr_env: float = 0.002                # refgs: the grid's learning rate (Ref-GS's encoding_lr)
    lr_position: float = 1.6e-4
    lr_position_final: float = 1.6e-6
    lr_position_until: float = 1.0       # the fraction of the run where the position rate reaches lr_position_final
    #                                      (log-linear from lr_position) and holds; 1.0: it falls over the whole run
    lr_scale: float = 5e-3
    lr_rotation: float = 1e-3
    lr_normal: float = 2e-3              # normal_source: attribute; twice lr_rotation (a unit quaternion turns its
    #                                      axes by twice its own change)
    lr_opacity: float = 0.05
    lr_sh_dc: float = 2.5e-3
    lr_sh_rest: float = 1.25e-4
    lr_specular: float = 0.01
    lr_transparency: float = 0.05
    adam_eps: float = 1e-15
    adam: str = "selective"              # selective (touched rows only, per-row bias correction) | dense
    update: str = "device"               # device: chain rule, Adam and packing on Dr.Jit arrays (nothing goes to the
    #                                      host between structure steps) | host: numpy / native C++ (the reference)
    lr_multiplier: float = 1.0           # x every learning rate (ray batches see each Gaussian less often)


@dataclasses.dataclass
class LossConfig:
    """The objective (method section 3): weights (0 switches a term off) and each term's rules."""

    trans_masks: str = "depth_gap"       # depth_gap (GLINT's L_trans) | prior (a segmentation model's masks in
    #                                      priors/glass/: the TSGS baseline) | gt (ground-truth glass masks, labelled)
    w_l1: float = 1.2
    w_dssim: float = 0.4
    w_direct: float = 1.0                # photometric loss of the transmission set's direct image (x w_l1, w_dssim)
    w_depth: float = 0.1
    w_sfm_depth: float = 0.1             # glint_mi's: the interface's depth at pixels with a tracked SfM feature,
    #                                      |D - z| / z (not where the see-through cue says the feature lies behind
    #                                      glass); the capture's own metric geometry, with or without priors
    depth_align: str = "sfm"             # sfm: the prior's scale and shift fitted once per view to the metric SfM
    #                                      points (anchors the depth; views without points fall back); image: the
    #                                      paper's per-image fit (MonoSDF) over each whole view, refitted every
    #                                      depth_refit of the run on a grid of <= 2048 of its pixels; batch: per
    #                                      view over the view's rays in each batch (~2.5 patches)
    depth_refit: float = 0.02
    depth_prior_ref: float = 0.02        # > 0: each view's depth prior weighs min(1, (ref / r)^2) of w_depth, r the
    #                                      25th percentile of |z_prior - z| / z over the SfM points the view tracks
    #                                      (z a point's depth, z_prior the SfM-aligned prior's at its pixel;
    #                                      RayBank.depth_prior_weights, in report.json): the inverse-variance weight,
    #                                      full for a view whose prior agrees with its points to ref. The lower
    #                                      quartile: points seen through glass or hidden behind a surface make the
    #                                      upper tail, the prior's own error moves all of it. Views with < 12 such
    #                                      points take the median view's weight. 0: every view at w_depth (the paper).
    #                                      Measured with the SfM fit whatever depth_align the loss uses. Decided on the
    #                                      tuning rooms' prior levels, checked on 9801-9804 (docs/decisions.md)
    w_normal: float = 0.3
    prior_decay: float = 0.5             # from this fraction of the run the prior terms prior_decay_terms names fall
    #                                      linearly to 0 at its end; 1.0 = constant weights (the paper, every baseline)
    prior_decay_terms: str = "normal"    # which prior terms prior_decay lets fall: normal (glint_mi's: the depth prior
    #                                      keeps its weight) | depth,normal | depth. With near-exact priors the normal
    #                                      prior cost 3DGS 0.43 dB on room 7301 and the depth prior gained 0.31;
    #                                      decided on the tuning rooms (docs/results/prior_sweep, docs/decisions.md)
    prior_decay_ref: float = 8.0         # deg; > 0: the falling normal prior falls to min(1, (ref / a)^2) of its
    #                                      weight, a the median angle between the normal prior and the planes of the
    #                                      SfM points (RayBank.normal_prior_sfm_agreement, in report.json): the
    #                                      inverse-variance weight, the full weight for priors that agree with SfM
    #                                      to ref deg. 0, or a not measurable (no SfM tracks; said in the log and
    #                                      report): it falls to 0. Needs prior_decay_terms: normal. Decided on the
    #                                      tuning rooms at three levels of prior error (docs/results/prior_sweep)
    prior_weight_ref: float = 0.0        # deg; > 0: the prior terms prior_weight_terms names weigh min(1, (ref / a)^2)
    #                                      of their weight through the whole run (prior_decay's fall multiplies
    #                                      it), a the MEAN angle between the normal prior and the SfM points'
    #                                      planes (RayBank.normal_prior_sfm_agreement; the floor reads its median, which
    #                                      under-reads a prior whose error sits in a few regions: 7303's 30-deg priors
    #                                      read 14.5 median, 26.4 mean). Not measurable (no normal prior, < 50 planar
    #                                      tracks): full weight, said in the log and report (prior_weight). 0: off
    #                                      (the paper's constant weights). docs/results/coarse_to_fine, 66th session
    prior_weight_terms: str = "normal"   # which terms prior_weight_ref scales, comma-separated: normal, depth, and
    #                                      consistency = the depth-normal consistency's pull on the depth (its pull
    #                                      on the normals, and its value, stay; consistency_grad: normal is that
    #                                      pull at 0). E.g. normal | depth,normal | consistency. consistency at
    #                                      ref 10 gained 0.39 dB on 7301-7303, 0.08 on 9801-9803, but cut the pull
    #                                      where the photos had corrected a 30-deg prior and lost glass there (t IoU
    #                                      0.59 -> 0.36): not a default (coarse_to_fine, prior_sweep/errors69_cpull.md)
    prior_weight_where: str = "all"      # where prior_weight_terms: consistency cuts the pull to its share s: all
    #                                      (every pixel) or off_glass: per ray s + (1 - s) g, g = max(the interface's
    #                                      rendered transparency (detached), 1 where the SfM see-through cue says
    #                                      seen through), so the glass keeps the whole pull (the cut's gain on 7303 was
    #                                      off the glass, its losses at 30-deg priors on it). +0.28 dB on 7301-7303,
    #                                      +0.20 on 9801-9803, 7302's glass kept at x2, but glass GLINT has not found
    #                                      is still lost (7301 x2: +7 deg of glass normals): not a default
    #                                      (coarse_to_fine, 70th session)
    prior_weight_glass_t: float = 1.0    # with prior_weight_where: off_glass, the rendered transparency from which a
    #                                      ray counts as glass wholly: g = min(1, t / this). 1: g = t (gpull). Lower
    #                                      gives glass GLINT has partly found (t ~0.7 on found glass, mid-range while
    #                                      it forms) the whole pull; off the glass t is mostly ~0 (mean 0.01-0.16).
    #                                      0.5 and 0.25 halve gpull's glass loss at realistic-v1 x2 (+7.8 -> +3.5
    #                                      deg) but keep +4-5 deg at 7301 x2: not a default (coarse_to_fine, 72nd)
    prior_weight_from: float = 0.0       # the fraction of the run from which prior_weight_ref's factors apply; before
    #                                      it every term it names keeps its whole weight (with prior_weight_where:
    #                                      off_glass the glass is then found under the whole pull, and t, which
    #                                      keeps it there, has formed). 0: from the start. 0.5 with off_glass
    #                                      (dpull): +0.19 dB on 7301-7303, +0.08 on 9801-9803, no depth gain, 7302's
    #                                      glass lost at x2: not a default (coarse_to_fine, 71st session)
    prior_layer: str = "nearer"          # which layer the depth and normal priors describe: nearer (glint_mi's):
    #                                      where the interface is transparent (t > 0.5) and the transmission set a
    #                                      surface, whichever of the two agrees better with the prior (an estimator
    #                                      sees through the glass in some views, the pane in others; the choice per
    #                                      ray is detached, losses.nearer_layer), elsewhere the interface; interface
    #                                      = the paper's
    w_consistency: float = 0.1
    consistency_depth: str = "expected"  # the depth whose normals the consistency term compares: expected (GLINT) or
    #                                      median (2DGS's depth_ratio 1: the distance where T falls to 0.5)
    consistency_grad: str = "both"       # what the depth-normal consistency moves: both (2DGS, GLINT: the Gaussians'
    #                                      normals toward the rendered depth's surface and that depth toward the
    #                                      normals) or normal (the depth's normals detached: the term turns the
    #                                      normals to the depth's surface and cannot bend the depth toward normals a
    #                                      bad normal prior set; issue 66, docs/results/coarse_to_fine, 68th session;
    #                                      prior_weight_terms: consistency scales that pull by the priors' agreement)
    normal_weight: str = "near_consistency"  # per-pixel weight of the normal prior and depth-normal consistency
    #                                      terms: uniform (the supplement's formulas; every baseline's) or near =
    #                                      the release's use_dpt_scale_(gs_)norm_loss: 1 - (D - near) / (far - near)
    #                                      clipped to [0, 1], near / far the 1 % / 99 % quantiles of the rendered
    #                                      depth (the release: of the image; here: of the batch, whose patches span
    #                                      views), so the far end of a view (a window, the far wall) is barely
    #                                      constrained;
    #                                      near_consistency (glint_mi's since 2026-11-27, tuning_73xx section 6):
    #                                      that weight on the consistency term only, the normal prior keeping every
    #                                      pixel (the far walls' normals stay the prior's)
    w_dist: float = 0.0                  # 2DGS's depth distortion, mean over rays of sum_{i<j} w_i w_j (m_i - m_j)^2
    #                                      on NDC-mapped distances (near 0.2, far 100); GLINT has none
    w_trans: float = 0.01
    w_treg: float = 0.01
    w_plausibility: float = 0.05
    plausibility_mask: str = "opaque"    # where G_trans is pulled to the interface: opaque = L_trans's opaque mask
    #                                      (the paper); interface = 1 - t where the interface is a surface
    trans_cue: str = "auto"              # L_trans's masks: auto = glint_mi's 3D cue from the SfM tracks
    #                                      (RayBank.see_through_cue) in place of the paper's depth gap D_T - D_I:
    #                                      transparent only near features seen behind the SfM-aligned depth prior,
    #                                      opaque near features on it (with an albedo prior its votes stay); none =
    #                                      the paper's masks. Without an albedo prior (and, for auto, without the cue)
    #                                      components: auto drops the transmission set (the depth gap of two sets
    #                                      fitting one surface is no glass cue)
    t_raise: str = "masks"               # where the objective may raise t: masks = from the end of densification,
    #                                      not where L_trans's opaque mask votes (which votes: t_gate_votes;
    #                                      glint_mi's: off glass a blend of c_I and c_T, two fits of the same
    #                                      surface, beats either, and once the resets stop the photometric terms
    #                                      made t a veil over the room); free = wherever the gradient says (paper)
    t_gate_votes: str = "geometric"      # which opaque votes close the t_raise: masks gate: geometric = L_trans's
    #                                      opaque mask without its dark-surface vote (LowA & ~HighB), which glass
    #                                      with a dark background also casts; all = the whole opaque mask
    trans_albedo: str = "off"            # the albedo prior in L_trans's masks: off (glint_mi's) = not read at all: the
    #                                      transparency comes from the SfM cue (trans_cue: auto), as on a capture
    #                                      with no albedo prior; masks = the paper's LowA & HighB rule (transparent
    #                                      needs albedo < 0.05). An estimator reports the surface behind clear glass,
    #                                      not ~0: on the tuning rooms 7301-7303 reading it left t IoU 0.07, the
    #                                      cue alone 0.50 (docs/results/tuning_73xx)
    cue_margin: float = 0.1              # an SfM feature this fraction of its depth behind the prior is seen through
    cue_radius: float = 0.04             # a pixel takes the label of its nearest feature within this x image width
    cue_votes: str = "point"             # view: each observation labelled by its view's prior; point: a 3D point is
    #                                      seen through in every view when cue_point_share of its views say so
    cue_point_share: float = 0.2
    cue_photo: float = 0.0               # 0: off; q in (0, 1): no opaque vote on the pixels whose colour disagrees with
    #                                      their nearest views at the prior's depth more than the q-quantile of the
    #                                      training pixels (RayBank.photo_inconsistency; untuned, issue 66)
    prior_photo: float = 0.0             # 0: off; q in (0, 1): the depth and normal priors are not read at the pixels
    #                                      whose colour disagrees with their nearest views at the prior's depth more
    #                                      than the q-quantile of the training pixels (a prior seeing through a pane
    #                                      or off its surface places the point where the photos do not agree; the
    #                                      photos alone decide there; untuned, issue 66)
    tau_n: float = 0.3                   # normal prior mask: supplement 0.3, release 0.5
    normal_loss: str = "cos"             # cos: the supplement's 1 - <n, p>; l1_cos: + |n - p|_1 (glint_mi's until
    #                                      2026-11-26)
    normal_early: str = "unmasked"       # before normal_from: unmasked (the paper: the mask starts at 10k/60k, the
    #                                      loss at 0) or off (glint_mi's until 2026-11-26). Together, on the tuning
    #                                      rooms 7301-7303: normal MAE 18.7 against 24.0 deg (docs/decisions.md)
    tau_delta: float = 0.005             # L_trans depth gap, x scene extent
    trans_min_alpha: float = 0.5         # L_trans: a depth is valid where its set's accumulated alpha reaches this


@dataclasses.dataclass
class ScheduleConfig:
    """When each stage and term starts: fractions of the run (paper iteration / 60k)."""

    warmup: float = 5 / 60               # interface only until here (supplement)
    transmission_from: float = 5 / 60    # release: 1k
    reflection_from: float = 5 / 60      # release: 3k
    refine_from: float = 40 / 60         # interface frozen after this (supplement); 1.0 = never (release)
    secondary_until: float = 1.0         # the transmission and reflection sets frozen after this, the interface
    #                                      trained on (the refine stage's mirror image; issue 66: the glass pixels'
    #                                      test views lose with epochs while their training views gain); 1.0 = never
    normal_from: float = 10 / 60
    consistency_from: float = 0.0        # depth-normal consistency from here (GLINT: the start; 2DGS: 7k of 30k)
    dist_from: float = 0.1               # depth distortion from here (2DGS: 3k of 30k)
    trans_from: float = 5 / 60
    treg_from: float = 7 / 60
    plausibility_from: float = 5 / 60
    sh_every: float = 1 / 60
    coarse_to_fine: str = ""             # patches drawn from coarser images early: "4:0.2,2:0.2" = the first 20 % of
    #                                      the iterations from images at 1/4 of the run's size, the next 20 % at
    #                                      1/2, the rest at full size ("": full size throughout; the bench preset
    #                                      sets "4:0.2,2:0.2" for every method; issue 66)
    coarse_min_side: int = 0             # coarse_to_fine's levels at which the smallest training view's shorter side
    #                                      would be under this many pixels are left out, the next finer level
    #                                      starting in their place (27, the bench preset's: none smaller than its
    #                                      1/4 of 192 x 108, where the coarse start was tuned); 0: every level


@dataclasses.dataclass
class DensifyConfig:
    """Densification, pruning and opacity resets (one strategy object, glint_mi.training.strategy) and the Gaussian
    budget."""

    densify_from: float = 0.5 / 60
    densify_until: float = 21 / 60       # the end of the structure phase: densification, the opacity resets, the
    #                                      t gate's start and the secondary sets' decisions (components: auto)
    grow_until: float = -1.0             # densification alone ends here instead (-1: at densify_until): growth
    #                                      moved apart from the resets, the t gate and the decisions (issue 66)
    densify_every: float = 0.02
    reset_every: float = 3 / 60
    densify_grad_rel: float = 0.12       # floor on a Gaussian's mean |dL/d position| x extent over the interval (the
    #                                      steps that saw it), as a fraction of the interface's median: a floor
    #                                      that holds at any batch size (the statistic itself falls as batches grow)
    densify_grad: float = 0.0            # an absolute floor on the same statistic as well (runs before the relative
    #                                      floor had 2e-4; right only at their batch size)
    densify_top: float = 0.05            # ... and only the top fraction of the set by that gradient, per step
    percent_dense: float = 0.01          # clone below this x extent, split above
    clone_opacity: str = "copy"          # a clone and its parent: "copy" keep the parent's opacity a (3DGS: where
    #                                      they overlap they cover 1 - (1 - a)^2), "shared" each get 1 - sqrt(1 - a)
    #                                      so that the pair covers a (Rota Bulo et al. 2024, "Revising Densification")
    split_mode: str = "sample"           # a split: "sample" (3DGS) two children drawn from the parent, scales / 1.6;
    #                                      "axis" two children at +-(sqrt(3)/2) s along the parent's largest axis,
    #                                      that scale halved, the rest and the opacity kept: the pair's mean,
    #                                      covariance and integrated opacity are the parent's (its footprint kept)
    prune_opacity: float = 0.005         # 3DGS's; the paper lists 0.08 / 0.05, which after a reset to 0.01 prunes
                                         # most of a set unless thousands of steps separate reset and pruning
    prune_scale: float = 0.1             # prune Gaussians larger than this x extent (after the first reset)
    max_gaussians: int = 30_000          # every set together: one budget per method (GLINT's three sets share
    #                                      what a one-set baseline gets)
    cap_schedule: str = "fixed"          # the budget over the growth window: "fixed" max_gaussians from the start
    #                                      (3DGS's); "linear" a cap rising from the count at the first densify
    #                                      step to max_gaussians at the end of growth, so that the sets cannot
    #                                      spend the budget before the model has learnt where it is needed


@dataclasses.dataclass
class EvalConfig:
    """Evaluation: the resolution, the depth a method reports, and how often."""

    eval_full: bool = False              # evaluate at the dataset's full resolution instead of the training one
    eval_depth: str = "expected"         # the depth a method reports (training.depth_rules): expected (GLINT, 3DGS),
    #                                      median (2DGS, depth_ratio 1) or first_surface (TSGS, with priors/glass)
    eval_every: int = 0                  # > 0: evaluate the test views every this many iterations and at the end
    #                                      (convergence.csv in the run folder; evaluation time is not training time)


LAYERS = {"run": RunConfig, "model": ModelConfig, "render": RenderConfig, "optim": OptimConfig,  # name -> layer,
          "losses": LossConfig, "schedule": ScheduleConfig, "densify": DensifyConfig,  # in reading order
          "evaluation": EvalConfig}


FIELD_LAYER = {f.name: name for name, cls in LAYERS.items() for f in dataclasses.fields(cls)}  # field -> its layer


@dataclasses.dataclass(init=False)
class TrainConfig:
    """A run's configuration: one instance of each layer (``cfg.losses``, ``cfg.render``, ...; :data:`LAYERS`). A
    field is set by its path (``losses.w_normal``; ``--set losses.w_normal=0.1``) or, as every name is unique, by its
    bare name (``w_normal``), which resolves to its layer; reading ``cfg.w_normal`` is ``cfg.losses.w_normal``. A run
    folder's config.json holds the layers as objects; a flat one (runs before 2026-11-28) loads through the
    migrations."""

    run: RunConfig = dataclasses.field(default_factory=RunConfig)
    model: ModelConfig = dataclasses.field(default_factory=ModelConfig)
    render: RenderConfig = dataclasses.field(default_factory=RenderConfig)
    optim: OptimConfig = dataclasses.field(default_factory=OptimConfig)
    losses: LossConfig = dataclasses.field(default_factory=LossConfig)
    schedule: ScheduleConfig = dataclasses.field(default_factory=ScheduleConfig)
    densify: DensifyConfig = dataclasses.field(default_factory=DensifyConfig)
    evaluation: EvalConfig = dataclasses.field(default_factory=EvalConfig)

    def __init__(self, run: RunConfig | None = None, model: ModelConfig | None = None,
                 render: RenderConfig | None = None, optim: OptimConfig | None = None, losses: LossConfig | None = None,
                 schedule: ScheduleConfig | None = None, densify: DensifyConfig | None = None,
                 evaluation: EvalConfig | None = None, **fields):
        """Layers (the others at their defaults) and fields by bare name or path, unchecked (:meth:`from_dict`
        checks)."""
        given = dict(run=run, model=model, render=render, optim=optim, losses=losses, schedule=schedule,
                     densify=densify, evaluation=evaluation)
        for name, cls in LAYERS.items():  # copies: a config never shares a layer (dataclasses.replace passes them)
            object.__setattr__(self, name, dataclasses.replace(given[name]) if given[name] is not None else cls())
        for key, value in flatten(fields, "TrainConfig").items():
            if key not in FIELD_LAYER:
                raise TypeError(f"TrainConfig has no field '{key}'")
            setattr(getattr(self, FIELD_LAYER[key]), key, value)

    def __getattr__(self, name: str):
        """A field by its bare name, from its layer (only called when the name is not a layer)."""
        layer = FIELD_LAYER.get(name)
        if layer is None:
            raise AttributeError(f"TrainConfig has no field '{name}'")
        return getattr(object.__getattribute__(self, layer), name)

    def __setattr__(self, name: str, value) -> None:
        if name in FIELD_LAYER:  # a bare field name writes into its layer (no field is ever set on the top level)
            setattr(getattr(self, FIELD_LAYER[name]), name, value)
        else:
            object.__setattr__(self, name, value)

    # -------------------------------------------------------------- layers
    def layer(self, name: str):
        """One layer's values (e.g. ``cfg.layer('losses')``, a :class:`LossConfig`; a copy)."""
        if name not in LAYERS:
            raise ConfigError(f"unknown config layer '{name}'; the layers are {', '.join(LAYERS)}.")
        return dataclasses.replace(getattr(self, name))

    @classmethod
    def compose(cls, *layers, source: str = "config") -> "TrainConfig":
        """A config from layer instances (the others at their defaults), checked like any other."""
        values = {}
        for part in layers:
            if type(part) not in LAYERS.values():
                kinds = ", ".join(c.__name__ for c in LAYERS.values())
                raise ConfigError(f"{source}: {type(part).__name__} is not a config layer; use {kinds}.")
            values.update(dataclasses.asdict(part))
        return cls.from_dict(values, source=source)

    def flat(self) -> dict:
        """Every field by its bare name (the layers' order)."""
        return {k: v for name in LAYERS for k, v in dataclasses.asdict(getattr(self, name)).items()}

    def replace(self, **changes) -> "TrainConfig":
        """A checked copy with ``changes`` (bare names or paths)."""
        return type(self).from_dict({**self.flat(), **flatten(changes)})

    # -------------------------------------------------------------- helpers
    @classmethod
    def for_preset(cls, preset: str, variant: str = DEFAULT_VARIANT, **overrides) -> "TrainConfig":
        if preset not in PRESETS:
            raise ConfigError(f"unknown preset '{preset}'; use one of {sorted(PRESETS)}.")
        if variant not in VARIANTS:
            raise ConfigError(f"unknown variant '{variant}'; use one of {sorted(VARIANTS)}.")
        overrides = flatten(overrides)
        if "iterations" in overrides and "epochs" not in overrides:  # an explicit count is a fixed budget
            overrides = {**overrides, "epochs": 0.0}
        values = {**flatten(PRESETS[preset]), **flatten(VARIANTS[variant]), "preset": preset, "variant": variant,
                  **overrides}
        return cls.from_dict(values)

    @classmethod
    def from_dict(cls, values: dict, source: str = "config") -> "TrainConfig":
        """A checked config from bare names, paths (``losses.w_normal``) or layer objects (``{"losses": {...}}``)."""
        values = flatten(values, source)
        unknown = sorted(set(values) - set(FIELD_LAYER))
        if unknown:
            import difflib

            hints = [f"{u} (did you mean {near[0]}?)" if (near := difflib.get_close_matches(u, FIELD_LAYER, n=1))
                     else u for u in unknown]
            raise ConfigError(f"{source}: unknown field(s) {', '.join(hints)}; a field is named by its path "
                              f"(losses.w_normal) or its bare name; the layers: "
                              + "; ".join(f"{n}: {', '.join(f.name for f in dataclasses.fields(c))}"
                                          for n, c in LAYERS.items()) + ".")
        values = {k: _typed(source, k, v, type(getattr(_DEFAULTS, k))) for k, v in values.items()}
        cfg = cls(**{name: layer_cls(**{k: v for k, v in values.items() if FIELD_LAYER[k] == name})
                     for name, layer_cls in LAYERS.items()})
        cfg.validate(source)
        return cfg

    @classmethod
    def load(cls, path: str | Path) -> "TrainConfig":
        path = Path(path)
        try:
            values = json.loads(path.read_text())
        except (OSError, json.JSONDecodeError) as e:
            raise ConfigError(f"{path}: cannot read the config ({e}); it must be a JSON object of TrainConfig fields.")
        if not isinstance(values, dict):
            raise ConfigError(f"{path}: holds a JSON {type(values).__name__}, not an object; write the fields as "
                              f'{{"layer": {{"field": value}}}} or {{"layer.field": value}}, e.g. '
                              f'{{"model": {{"components": "all"}}, "losses.w_trans": 0}}.')
        values = flatten(values, str(path))
        for key in ("preset", "variant"):
            if key in values and not isinstance(values[key], str):
                raise ConfigError(f"{path}: '{key}' = {values[key]!r}: must be a string.")
        base = cls.for_preset(values.get("preset", "quick"), values.get("variant", "supplement"))
        values = migrate(values)
        return cls.from_dict({**base.flat(), **values}, source=str(path))

    def to_dict(self) -> dict:
        """The layers as objects, as config.json holds them."""
        return {name: dataclasses.asdict(getattr(self, name)) for name in LAYERS}

    def save(self, path: str | Path) -> None:
        Path(path).write_text(json.dumps(self.to_dict(), indent=1))

    def validate(self, source: str = "config") -> None:
        def need(ok, field, what):
            if not ok:
                raise ConfigError(f"{source}: '{field}' = {getattr(self, field)!r}: {what}.")

        need(self.iterations >= 1, "iterations", "must be >= 1")
        need(0 <= self.seed < 2 ** 63, "seed", "must be an integer in [0, 2^63) (numpy's generators take no negative "
                                               "seed)")
        for name, v in self.flat().items():  # weights, learning rates and schedule fractions
            if name.startswith(("w_", "lr_")):
                need(v >= 0, name, "must be >= 0")
            fraction = name.endswith(("_from", "_until", "_every")) and isinstance(v, float)
            if fraction and name != "grow_until" or name in ("warmup", "depth_refit", "prior_decay", "densify_top"):
                need(0 <= v <= 1, name, "is a fraction of the run (or of a set), between 0 and 1")
        for name, low in (("max_hits", 1), ("max_gaussians", 1), ("log_every", 1), ("checkpoint_every", 0),
                          ("threads", 0), ("eval_every", 0), ("grid_n", 1), ("grid_k", 1), ("init_min_points", 0),
                          ("env_levels", 1)):
            need(getattr(self, name) >= low, name, f"must be >= {low}")
        need(0 < self.init_opacity < 1 and 0 <= self.prune_opacity < 1, "init_opacity",
             "init_opacity must be in (0, 1) and prune_opacity in [0, 1)")
        need(self.tau_delta >= 0 and self.percent_dense > 0, "tau_delta",
             "tau_delta must be >= 0 and percent_dense > 0 (fractions of the scene extent)")
        comps = self.components.replace(" ", "")
        need(comps in ("auto", "all") or (comps and set(comps.split(",")) <= set(cv.ROLES)), "components",
             f"use auto, all or a comma list of {', '.join(cv.ROLES)}")
        need(isinstance(self.epochs, (int, float)) and self.epochs >= 0, "epochs",
             "must be >= 0 (rays per training pixel; 0 = use iterations)")
        need(self.patches >= 1, "patches", "must be >= 1")
        need(self.stored_hits_mb >= 0, "stored_hits_mb", "must be >= 0 MiB (0: the replay always re-traces)")
        need(isinstance(self.downscale, int) and self.downscale >= 1, "downscale",
             "must be an integer >= 1 (4 = a quarter of the width and height)")
        need(self.patch >= 3, "patch", "must be >= 3 (D-SSIM and normal consistency work on patches)")
        need(self.kernel in cv.KERNELS, "kernel", f"use one of {cv.KERNELS}")
        need(self.normal_source in cv.NORMAL_SOURCES, "normal_source", f"use one of {cv.NORMAL_SOURCES}")
        need(self.normal_source == "axis" or self.kernel == "surfel", "normal_source",
             f"'attribute' needs kernel: surfel (an ellipsoid's normal is the axis its ray meets); with kernel: "
             f"{self.kernel} use normal_source: axis")
        need(self.lr_normal >= 0, "lr_normal", "must be >= 0")
        need(0 <= self.sh_degree <= 3, "sh_degree", "must be 0..3")
        need(self.max_order in (1, 2), "max_order", "must be 1 or 2")
        need(self.priors in ("all", "none"), "priors", "use all or none")
        need(self.traversal in ("auto", "kbuffer", "shellbvh", "bvh"), "traversal", "use auto, kbuffer, shellbvh or bvh")
        need(self.adam in ("selective", "dense"), "adam", "use selective or dense")
        need(self.update in ("device", "host"), "update", "use device or host")
        need(self.densify_grad_rel >= 0 and self.densify_grad >= 0, "densify_grad_rel",
             "the densification floors densify_grad_rel and densify_grad must be >= 0")
        need(self.trans_masks in ("depth_gap", "prior", "gt"), "trans_masks", "use depth_gap, prior or gt")
        need(self.depth_align in ("batch", "sfm", "image"), "depth_align", "use sfm, image or batch")
        try:
            levels = self.pyramid()
        except ValueError as e:
            levels = None
            need(False, "coarse_to_fine", str(e))
        need(not levels or self.depth_align != "image", "coarse_to_fine",
             "depth_align image refits the full-size images' priors only: use depth_align sfm or batch with it, "
             "or --set coarse_to_fine= (full size throughout; the bench preset sets it)")
        need(isinstance(self.coarse_min_side, int) and self.coarse_min_side >= 0, "coarse_min_side",
             "is a number of pixels (an integer >= 0; 0 keeps every coarse_to_fine level)")
        need(self.normal_loss in ("cos", "l1_cos"), "normal_loss", "use cos (the paper) or l1_cos")
        need(self.normal_early in ("off", "unmasked"), "normal_early", "use off or unmasked (the paper)")
        need(self.eval_depth in ("expected", "median", "first_surface"), "eval_depth",
             "use expected, median (2DGS) or first_surface (TSGS; needs priors/glass masks)")
        need(self.consistency_depth in ("expected", "median"), "consistency_depth",
             "use expected (GLINT) or median (2DGS)")
        need(self.consistency_grad in ("both", "normal"), "consistency_grad",
             "use both (2DGS, GLINT) or normal (the depth's normals detached)")
        need(self.normal_weight in ("uniform", "near", "near_consistency"), "normal_weight",
             "use near_consistency (glint_mi: the release's depth scale on the depth-normal consistency only), "
             "near (the release: on the normal prior too) or uniform (the baselines)")
        need(self.plausibility_mask in ("interface", "opaque"), "plausibility_mask", "use interface or opaque")
        need(self.trans_cue in ("auto", "none"), "trans_cue", "use auto or none (the paper's masks)")
        need(self.cue_votes in ("view", "point"), "cue_votes", "use view or point")
        need(self.trans_albedo in ("off", "masks"), "trans_albedo", "use off (glint_mi) or masks (the paper)")
        need(0 < self.cue_point_share <= 1, "cue_point_share", "is a share of a point's views: (0, 1]")
        need(0 <= self.cue_photo < 1, "cue_photo", "is 0 (off) or a quantile in (0, 1)")
        need(0 <= self.prior_photo < 1, "prior_photo", "is 0 (off) or a quantile in (0, 1)")
        for field in ("cue_photo", "prior_photo"):  # the measure places each pixel's point by the SfM-aligned prior
            need(getattr(self, field) == 0 or self.depth_align == "sfm", field,
                 "reads the depth prior aligned to the SfM points: use depth_align sfm, or set it to 0")
        need(self.t_raise in ("masks", "free"), "t_raise", "use masks (glint_mi) or free (the paper)")
        need(self.prior_layer in ("interface", "nearer"), "prior_layer", "use interface (the paper) or nearer")
        need(self.no_glass in ("3dgs", "3dgs+sfm", "glint"), "no_glass", "use 3dgs, 3dgs+sfm or glint")
        need(self.t_gate_votes in ("all", "geometric"), "t_gate_votes", "use all (L_trans's opaque mask) or geometric")
        need(self.blend in ("fresnel", "envgs", "alpha", "refgs"), "blend",
             "use fresnel (GLINT), envgs, refgs or alpha (plain alpha compositing, the 3DGS-family baselines)")
        need(0 < self.env_init <= 1, "env_init", "use a radiance in (0, 1]")
        need(1 <= self.env_levels <= 10, "env_levels", "use 1..10 mip levels (7: a 128 x 256 grid)")
        need(self.blend != "refgs" or self.components.replace(" ", "") == "interface", "components",
             "blend refgs shades the interface alone: use components interface")
        comps = self.components.replace(" ", "")
        need(comps in ("auto", "all") or set(comps.split(",")) <= set(cv.ROLES), "components",
             f"use auto, all or a comma list of {cv.ROLES}")
        need(comps in ("auto", "all") or "interface" in comps.split(","), "components",
             "the interface set is always needed")
        for name, v in self.flat().items():
            if name.startswith(("w_", "lr_")):
                need(isinstance(v, (int, float)) and v >= 0, name, "must be a number >= 0")
        need(0.0 < self.lr_position_until <= 1.0, "lr_position_until",
             "is the fraction of the run (0, 1] where the position rate reaches lr_position_final (1.0: the run's end)")
        need(self.prior_decay_terms in ("depth,normal", "normal", "depth"), "prior_decay_terms",
             "use depth,normal, normal or depth")
        need(math.isfinite(self.depth_prior_ref) and self.depth_prior_ref >= 0, "depth_prior_ref",
             "must be a finite relative depth error >= 0 (0: every view's depth prior at w_depth)")
        need(math.isfinite(self.prior_decay_ref) and self.prior_decay_ref >= 0, "prior_decay_ref",
             "is an angle in degrees, >= 0 (0: the falling prior falls to 0)")
        need(self.prior_decay_ref == 0 or self.prior_decay_terms == "normal", "prior_decay_ref",
             "sets the normal prior's floor from its agreement with the SfM points: use it with prior_decay_terms: "
             "normal, or set prior_decay_ref=0 to let the depth prior fall too")
        need(math.isfinite(self.prior_weight_ref) and self.prior_weight_ref >= 0, "prior_weight_ref",
             "is an angle in degrees, >= 0 (0: the prior terms keep their weights)")
        terms = self.prior_weight_terms.split(",")
        need(len(terms) == len(set(terms)) and set(terms) <= {"depth", "normal", "consistency"}, "prior_weight_terms",
             "name each of depth, normal and consistency at most once, comma-separated (e.g. normal or depth,normal)")
        need(not (self.consistency_grad == "normal" and self.prior_weight_ref > 0 and "consistency" in terms),
             "prior_weight_terms", "names consistency, whose pull on the depth consistency_grad: normal already sets "
             "to 0: drop consistency from prior_weight_terms, or set consistency_grad=both to scale the pull")
        need(self.prior_weight_where in ("all", "off_glass"), "prior_weight_where",
             f"is {self.prior_weight_where!r}: use all or off_glass")
        need(self.prior_weight_where == "all" or ("consistency" in terms and self.prior_weight_ref > 0),
             "prior_weight_where",
             "is off_glass, which places the consistency's pull only: add consistency to prior_weight_terms "
             "(and prior_weight_ref > 0), or set prior_weight_where=all")
        need(0.0 < self.prior_weight_glass_t <= 1.0, "prior_weight_glass_t", "is a transparency in (0, 1] (1: g = t)")
        need(self.prior_weight_glass_t == 1.0 or self.prior_weight_where == "off_glass", "prior_weight_glass_t",
             f"shapes prior_weight_where: off_glass's g, but prior_weight_where is {self.prior_weight_where}: set "
             f"prior_weight_where=off_glass, or prior_weight_glass_t=1")
        need(self.prior_weight_from == 0.0 or self.prior_weight_ref > 0, "prior_weight_from",
             f"is {self.prior_weight_from:g}, which delays prior_weight_ref's factors, but prior_weight_ref is 0 (no "
             f"factor): set prior_weight_ref > 0, or prior_weight_from=0")
        for f in ("warmup", "transmission_from", "reflection_from", "refine_from", "secondary_until", "normal_from",
                  "trans_from", "treg_from", "plausibility_from", "densify_from", "densify_until", "consistency_from",
                  "dist_from", "prior_decay"):
            need(0.0 <= getattr(self, f) <= 1.0, f, "is a fraction of the run: 0..1")
        need(self.refine_from >= 1.0 or self.secondary_until >= 1.0, "secondary_until",
             "freezes the transmission and reflection sets, refine_from the interface: with both, the end of the run "
             "trains nothing; set one of them to 1.0")
        need(self.clone_opacity in ("copy", "shared"), "clone_opacity",
             "use copy (a clone keeps its parent's opacity, 3DGS) or shared (the pair covers what the parent did)")
        need(self.cap_schedule in ("fixed", "linear"), "cap_schedule",
             "use fixed (max_gaussians from the start) or linear (a cap rising to max_gaussians over the growth "
             "window)")
        need(self.split_mode in ("sample", "axis"), "split_mode",
             "use sample (children drawn from the parent, 3DGS) or axis (two children along its largest axis that "
             "keep its mean, covariance and integrated opacity)")
        need(self.grow_until == -1 or self.densify_from < self.grow_until <= 1.0, "grow_until",
             f"is a fraction of the run after densify_from ({self.densify_from:g}) and <= 1, or -1 (densification "
             f"ends at densify_until)")

    def rays_per_iteration(self) -> int:
        return self.patches * self.patch ** 2

    def pyramid(self) -> list[tuple[int, float]]:
        """``coarse_to_fine`` as [(factor, until), ...]: patches come from images at 1/factor of the run's size
        until that fraction of the run (factors decreasing, each an integer >= 2; the rest at full size)."""
        text = self.coarse_to_fine.replace(" ", "")
        if not text:
            return []
        out, end = [], 0.0
        for part in text.split(","):
            f, sep, share = part.partition(":")
            try:
                f, share = int(f), float(share)
            except ValueError:
                raise ValueError(f"'{part}' is not FACTOR:SHARE (e.g. 4:0.2,2:0.2)") from None
            if not sep or f < 2 or not 0 < share < 1 or (out and f >= out[-1][0]):
                raise ValueError(f"'{part}': factors are integers >= 2, decreasing, each with a share of the run in "
                                 f"(0, 1) (e.g. 4:0.2,2:0.2)")
            end += share
            out.append((f, end))
        if end >= 1:
            raise ValueError(f"the coarse levels' shares add up to {end:g}: leave part of the run at full size (< 1)")
        return out

    def coarse_levels(self, width: int, height: int) -> tuple[list[tuple[int, float]], list[int]]:
        """``pyramid()`` for training views whose smallest is ``width`` x ``height``: (the levels kept, the factors
        left out by ``coarse_min_side``). Coarser levels are smaller, so those left out are the first ones; the first
        level kept draws from the run's start (the ``until`` of each level is unchanged)."""
        kept, out = [], []
        for f, until in self.pyramid():
            (out.append(f) if min(width // f, height // f) < self.coarse_min_side else kept.append((f, until)))
        return kept, out

    def with_budget(self, train_pixels: int) -> "TrainConfig":
        """This config with ``iterations`` = epochs x train_pixels / rays per iteration (unchanged when epochs is 0);
        the schedule's fractions follow."""
        if self.epochs <= 0:
            return self
        its = max(1, int(math.ceil(self.epochs * train_pixels / self.rays_per_iteration())))
        return self.replace(iterations=its)

    def at(self, fraction: float) -> int:
        """The iteration at ``fraction`` of the run."""
        return int(round(fraction * self.iterations))

    def every(self, fraction: float) -> int:
        return max(1, int(round(fraction * self.iterations)))

    def roles(self) -> list[str]:
        comps = self.components.replace(" ", "")
        return list(cv.ROLES) if comps in ("auto", "all") else [r for r in cv.ROLES if r in comps.split(",")]


# Run folders written by earlier versions: (what changed, whether a saved config predates it, how to read it). Each
# keeps the old run's meaning, so that it resumes as it trained (tests/test_train.py resumes one of each).
MIGRATIONS = (
    ("budgets in epochs", lambda v: "iterations" in v and "epochs" not in v,
     lambda v: {**v, "epochs": 0.0}),  # a fixed iteration count
    ("the dataset's downscale", lambda v: "train_downsample" in v,
     lambda v: {**{k: x for k, x in v.items() if k != "train_downsample"}, "downscale": v["train_downsample"],
                "eval_full": True}),  # the same meaning for training; it evaluated at full size
    ("trans_cue 'sfm' renamed 'auto'", lambda v: v.get("trans_cue") == "sfm", lambda v: {**v, "trans_cue": "auto"}),
    ("the relative densification floor", lambda v: "densify_grad_rel" not in v,
     lambda v: {**v, "densify_grad_rel": 0.0, "densify_grad": v.get("densify_grad", 2e-4)}),  # its absolute floor
    ("prior_layer", lambda v: "prior_layer" not in v,
     lambda v: {**v, "prior_layer": "interface"}),  # its priors supervised the interface everywhere
    ("the defaults of 2026-11-26's tuning", lambda v: "trans_albedo" not in v,
     lambda v: {**v, "trans_albedo": "masks", "cue_margin": v.get("cue_margin", 0.05),
                "cue_votes": v.get("cue_votes", "view"), "normal_loss": v.get("normal_loss", "l1_cos"),
                "normal_early": v.get("normal_early", "off")}),  # it read the albedo, voted per view, margin 0.05
    ("the blend option", lambda v: "fresnel" in v and "blend" not in v,
     lambda v: {**{k: x for k, x in v.items() if k != "fresnel"}, "blend": "fresnel" if v["fresnel"] else "envgs"}),
    ("the normal prior's floor", lambda v: "prior_decay_ref" not in v,
     lambda v: {**v, "prior_decay_ref": 0.0}),  # a falling prior fell to 0
    # two options whose preset value is not the former behaviour (the bench preset has both on): without these an
    # older bench run would read, and resume, with the coarse start and shared clones it never had
    ("the coarse start", lambda v: "coarse_to_fine" not in v,
     lambda v: {**v, "coarse_to_fine": ""}),  # it drew its patches from full-size images throughout
    ("the clones' coverage", lambda v: "clone_opacity" not in v,
     lambda v: {**v, "clone_opacity": "copy"}),  # a clone copied its parent's opacity (3DGS's)
    ("the depth prior's weight per view", lambda v: "depth_prior_ref" not in v,
     lambda v: {**v, "depth_prior_ref": 0.0}),  # every view's depth prior weighed w_depth
    ("the coarse start's floor", lambda v: "coarse_min_side" not in v,
     lambda v: {**v, "coarse_min_side": 0}),  # a bench run kept every coarse level, however small
)


def flatten(values: dict, source: str = "config") -> dict:
    """Bare field names from any mix of bare names, paths (``losses.w_normal``) and layer objects
    (``{"losses": {"w_normal": 0.1}}``); a path whose layer does not hold the field is refused, naming its layer."""
    out = {}
    for key, value in values.items():
        if key in LAYERS and isinstance(value, dict):
            items = [(f"{key}.{k}", v) for k, v in value.items()]
        else:
            items = [(key, value)]
        for path, v in items:
            if "." in path:
                layer, name = path.split(".", 1)
                if layer not in LAYERS:
                    raise ConfigError(f"{source}: '{path}': no layer '{layer}'; the layers are {', '.join(LAYERS)}.")
                if FIELD_LAYER.get(name, layer) != layer:
                    raise ConfigError(f"{source}: '{path}': {name} is in the {FIELD_LAYER[name]} layer; write "
                                      f"{FIELD_LAYER[name]}.{name}.")
                path = name
            if path in out and out[path] != v:
                raise ConfigError(f"{source}: '{path}' is given twice ({out[path]!r} and {v!r}); keep one.")
            out[path] = v
    return out


def by_path(values: dict) -> dict:
    """``values`` keyed by path (``losses.w_normal``): how presets, variants and methods name what they override."""
    return {f"{FIELD_LAYER[k]}.{k}": v for k, v in flatten(values).items()}


def migrate(values: dict) -> dict:
    """A saved config's values in today's fields (:data:`MIGRATIONS`, in order)."""
    for _, applies, change in MIGRATIONS:
        if applies(values):
            values = change(values)
    return values


def _typed(source: str, key: str, value, kind: type):
    """``value`` as the type of field ``key`` (an int may be given as 3.0, a float as 3), or a ConfigError."""
    what = {bool: "true or false", int: "an integer", float: "a number", str: "a string"}.get(kind, kind.__name__)
    if kind is bool:
        ok = isinstance(value, bool)
    elif kind is int:
        ok = isinstance(value, (int, float)) and not isinstance(value, bool) and float(value).is_integer()
        value = int(value) if ok else value
    elif kind is float:
        ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
        value = float(value) if ok else value
    else:
        ok = isinstance(value, kind)
    if not ok:
        raise ConfigError(f"{source}: '{key}' = {value!r}: must be {what}.")
    return value


# Presets of protocol.md ("tiny" for tests, "quick" for make demo, "bench" for the benchmark), CPU-sized, "converged"
# (a CPU's run to where the methods stop gaining), and "gpu", the paper's budget.
PRESETS = {
    # Adam moves a logit by about lr per step, so opacity resets and densification intervals are set in iterations
    # that let opacities recover (the paper's 3k / 100 iterations are 5 % / 0.17 % of 60k, far fewer steps here).
    "tiny": dict(iterations=300, patches=16, patch=8, sh_degree=0, grid_n=8, grid_k=2, init_min_points=1500,
                 max_gaussians=10000, checkpoint_every=100, densify_every=0.1, reset_every=0.3, lr_multiplier=3.0),
    # quick: 15 epochs = the 800 iterations x 2048 rays that the bundled 96 x 54 room (21 training views) had
    "quick": dict(iterations=800, epochs=15.0, patches=32, patch=8, sh_degree=1, grid_n=12, grid_k=2, init_min_points=3000,
                  max_gaussians=30000, densify_every=0.05, reset_every=0.15, lr_multiplier=2.0),
    # bench: 10 epochs = 14 min of GLINT on the 48-view 192 x 108 tuning room 7301 on 2 cores (opacity shells); every
    # method but glint-paper draws its patches from 1/4-, then 1/2-size images for the first 20 % + 20 % of the run:
    # decided for GLINT on tuning rooms 7301-7303, checked on 9801-9803; 3DGS gains too (docs/results/coarse_to_fine).
    # No coarse image under 27 pixels on its shorter side (coarse_min_side: at 96 x 54 the 1/4 level, 24 x 13, is
    # left out; nothing changes at 192 x 108 and above): tuned on 7301-7303, checked on 9801-9803 (coarse_to_fine,
    # "The coarse-start floor checked on 9801-9803"). A clone and its parent share its coverage (clone_opacity:
    # shared; decided for GLINT there too; the baselines and glint-paper keep 3DGS's copy, methods.NOT_OURS and PAPER)
    "bench": dict(iterations=4000, epochs=10.0, patches=48, patch=8, sh_degree=1, grid_n=16, grid_k=2, init_min_points=6000,
                  max_gaussians=60000, checkpoint_every=500, densify_every=0.025, reset_every=0.1,
                  lr_multiplier=1.5, coarse_to_fine="4:0.2,2:0.2", coarse_min_side=27, clone_opacity="shared"),
    # gpu: the paper's budget - 60k iterations of one 480 x 270 image's worth of rays (129,600 = 2,025 patches of
    # 8 x 8, drawn across views), densification every 100 iterations and opacity resets every 3,000 as in 3DGS, SH
    # degree 3, the paper's learning rates and its SfM-grid initialisation; for a GPU (GLINT_VARIANT=cuda_ad_rgb)
    "gpu": dict(iterations=60000, epochs=0.0, patches=2025, patch=8, sh_degree=3, grid_n=32, grid_k=5,
                init_min_points=20000, max_gaussians=500_000, checkpoint_every=5000, log_every=100,
                densify_every=100 / 60000, reset_every=3000 / 60000, lr_multiplier=1.0, stored_hits_mb=8192.0),
}
# converged: a CPU's run to where GLINT stops gaining on the 48-view rooms at 96 x 54 (docs/results/converge_98xx):
# bench's settings, 60 epochs (GLINT is flat past them: 120 gave +0.14 dB on 9801-9802), full-size patches throughout
# (the coarse start gained nothing there, coarse_to_fine "At 96 x 54 and the converged budget"), and the capacity that
# lets the sets grow to the Gaussian cap (densify_top 0.25, densify_grad_rel 0.02: +0.61 dB on the tuning rooms,
# decided there by the PSNR rule; kept by the check rule on 9801-9804 at two seeds, where it gave +0.03 dB for a
# little geometry lost, converge_98xx "wide at the converged preset"; under the priors at 13 of 14 prior-error
# room-levels, AbsRel 1.4 % over at realistic-v1 x2 without the SfM depth term until depth_prior_ref, prior_sweep).
# ~16 minutes of GLINT a 96 x 54 room on one core (epochs are rays per pixel: 4x that at 192 x 108). Every
# baseline keeps the capacity where it stopped (methods.BASELINE_AT).
# GLINT's kernel there is 3DGS's ellipsoid: surfels' cost grows with the budget (on 9803 they cost 3DGS 0.97 dB at
# this point, 0.28 at bench's); decided on the tuning rooms at this point (geometry rule: AbsRel -7 %, +0.10 dB),
# checked on 9801-9803 (coarse_to_fine, "Ellipsoids at the converged point"); surfel methods keep theirs (SURFELS)
# coarse_min_side 0: inert without a coarse start, and the value the headline's runs were saved with
PRESETS["converged"] = {**PRESETS["bench"], "epochs": 60.0, "densify_top": 0.25, "densify_grad_rel": 0.02,
                        "coarse_to_fine": "", "coarse_min_side": 0, "kernel": "ellipsoid"}
SUPPLEMENT = dict(warmup=5 / 60, transmission_from=5 / 60, reflection_from=5 / 60, refine_from=40 / 60, tau_n=0.3)
VARIANTS = {
    # glint_mi (default): the supplement's warm-up and tau_n, but no refine stage (the supplement freezes the
    # interface for the last third, 40k-60k of a run whose interface has converged by then)
    "glint_mi": {**SUPPLEMENT, "refine_from": 1.0},
    "supplement": SUPPLEMENT,
    "release": dict(warmup=1 / 60, transmission_from=1 / 60, reflection_from=3 / 60, refine_from=1.0, tau_n=0.5),
}


PRESETS = {name: by_path(values) for name, values in PRESETS.items()}  # what each overrides, by path
VARIANTS = {name: by_path(values) for name, values in VARIANTS.items()}
_DEFAULTS = TrainConfig()  # each field's type, for from_dict's checks
