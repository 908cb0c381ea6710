"""``python -m glint_mi.dataset make OUT --scenes 5 --seed 0 --preset bench``: generate rooms with a glass case."""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

PRIOR_MODELS = ["realistic", "realistic-v1", "ideal"]  # glint_mi.dataset.priors.MODELS (tested equal)
SUMMARY_KEYS = ("total_seconds", "gt_noise_psnr_db", "glass_pixel_fraction", "case_support")  # per scene


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m glint_mi.dataset", description=__doc__)
    sub = ap.add_subparsers(dest="cmd", required=True)
    mk = sub.add_parser("make", help="generate scenes with path-traced ground truth")
    mk.add_argument("out", type=Path, help="output folder (one sub-folder per scene)")
    mk.add_argument("--scenes", type=int, default=1)
    mk.add_argument("--seed", type=int, default=0, help="scene i uses seed + i")
    mk.add_argument("--preset", default="quick", choices=["tiny", "quick", "bench", "gpu"])
    mk.add_argument("--views", type=int, help="override the preset's number of views")
    mk.add_argument("--spp", type=int, help="override the preset's samples per pixel")
    mk.add_argument("--size", metavar="WxH", help="override the preset's image size (e.g. 320x180)")
    mk.add_argument("--sfm", choices=["known", "full", "none"], default=None,
                    help="SfM points: triangulate with the known poses (default; 'none' for the tiny preset), "
                         "'full' also runs SfM without poses and reports its pose error")
    mk.add_argument("--sfm-from", type=Path, metavar="DIR",
                    help="take each scene's SfM points from DIR/<scene>, the same scene generated elsewhere with "
                         "--sfm known (same seed, preset, views and size; checked): for a machine without pycolmap, "
                         "e.g. a GPU that renders the ground truth. Copies sparse/0; no SfM is run here")
    mk.add_argument("--priors", choices=["derived", "none"], default="derived",
                    help="write imperfect depth/normal/albedo priors derived from ground truth (labelled as such)")
    mk.add_argument("--no-glass", action="store_true",
                    help="the same rooms without the case's glass panels (frame and objects stay): a control scene")
    mk.add_argument("--renderer", choices=["mitsuba", "cycles"], default="mitsuba",
                    help="ground truth from Mitsuba's volpath (default) or from Blender Cycles (needs `make "
                         "cycles-env`): images and every gt pass rendered by Cycles")
    mk.add_argument("--no-albedo-prior", action="store_true", help="derive depth and normal priors only")
    mk.add_argument("--prior-model", choices=PRIOR_MODELS, default="realistic",
                    help="derived priors: an estimator's errors, the same on a surface in every view (default); "
                         "realistic-v1, the former model (calibrated per view, the glass BSDF's albedo); or near "
                         "ground truth (ideal)")
    mk.add_argument("--see-through", type=float, default=None, metavar="P",
                    help="how often derived depth/normal priors see through the glass instead of its surface (realistic: "
                         "the expected share of glass pixels, default 0.6; realistic-v1: the probability per view, "
                         "0.75; ideal: 1; 0: they see the glass surface)")
    mk.add_argument("--prior-error-scale", type=float, default=None, metavar="F",
                    help="multiply the prior model's normal and depth error amplitudes by F (a sweep of prior "
                         "quality; PRIORS.json measures what they amount to)")
    mk.add_argument("--overwrite", action="store_true",
                    help="regenerate scenes that are already complete (default: skip them, so an interrupted "
                         "multi-scene run resumes where it stopped)")
    pr = sub.add_parser("priors", help="(re)derive imperfect priors for a generated scene")
    pr.add_argument("scene", type=Path)
    pr.add_argument("--seed", type=int, default=0)
    pr.add_argument("--model", choices=PRIOR_MODELS, default="realistic",
                    help="realistic (default): an estimator's errors, drawn (not tuned per view), the same on a "
                         "surface in every view, segmenter-like glass masks; realistic-v1: the former model; ideal: "
                         "near ground truth. PRIORS.json records what each measures")
    pr.add_argument("--see-through", type=float, default=None, metavar="P",
                    help="how often the depth/normal priors see through the glass instead of its surface (default: "
                         "the model's; see `make --help`; 0: they see the glass)")
    pr.add_argument("--error-scale", type=float, default=None, metavar="F",
                    help="multiply the model's normal and depth error amplitudes by F (a sweep of prior quality)")
    pr.add_argument("--no-albedo", action="store_true",
                    help="depth and normal only (default: as the scene's current priors, else with albedo)")
    cy = sub.add_parser("cycles", help="render a generated scene with Blender Cycles (the optional cycles extra)")
    cy.add_argument("scene", type=Path)
    cy.add_argument("--views", help="comma list of view names (default: the test split)")
    cy.add_argument("--spp", type=int, default=256)
    tr = sub.add_parser("tracks", help="re-triangulate a generated scene from its sfm/images and rewrite sparse/0 "
                        "with the SfM tracks (scenes made before tracks were written)")
    tr.add_argument("scene", type=Path)
    args = ap.parse_args(argv)
    if args.cmd == "tracks":
        from glint_mi.dataset.generate import retriangulate

        st = retriangulate(args.scene)
        print(f"wrote {args.scene / 'sparse' / '0'}: {st['points3D']} points, {st['observations']} observations")
        return 0
    if args.cmd == "cycles":
        from glint_mi.dataset.cycles_render import CyclesUnavailable, render_cycles

        try:
            out = render_cycles(args.scene, args.views.split(",") if args.views else None, args.spp)
        except CyclesUnavailable as e:
            print(f"error: {e}", file=sys.stderr)
            return 3
        meta = json.loads((out / "meta.json").read_text())
        print(f"wrote {out} ({len(meta['views'])} views at {args.spp} spp in {meta['seconds']:.1f} s); compare with "
              f"`python -m glint_mi.crosscheck {args.scene}`")
        return 0
    if args.cmd == "make" and args.renderer == "cycles":
        from glint_mi.dataset.cycles_render import CyclesUnavailable, find_bpy

        try:
            find_bpy()
        except CyclesUnavailable as e:
            print(f"error: {e}", file=sys.stderr)
            return 3
    if args.cmd == "priors":
        from glint_mi.dataset.priors import MODELS, derive_priors, prior_conventions, scale_errors

        c = MODELS[args.model]()
        if args.error_scale is not None:
            try:
                c = scale_errors(c, args.error_scale)
            except ValueError as e:
                print(f"error: --error-scale: {e}", file=sys.stderr)
                return 2
        if args.see_through is not None:
            c.see_through_glass = args.see_through
        kinds = prior_conventions(args.scene)["record"].get("kinds")
        albedo = not args.no_albedo and (kinds is None or "albedo" in kinds)
        out = derive_priors(args.scene, args.seed, c, albedo=albedo)
        m = json.loads((out / "PRIORS.json").read_text())["measured"]
        print(f"wrote {out} ({args.model} model, derived from ground truth): normal error {m['normal_mae_deg']:.1f} "
              f"deg ({m['normal_mae_deg_off_glass']:.1f} off glass, {m['normal_mae_deg_glass']:.1f} on glass), depth "
              f"AbsRel {m['depth_absrel']:.3f} after a per-image affine fit ({m['depth_absrel_off_glass']:.3f} / "
              f"{m['depth_absrel_glass']:.3f})" + (f"; glass masks IoU {m['glass_mask_iou']:.2f}"
                                                      if "glass_mask_iou" in m else ""))
        return 0

    from tqdm import tqdm

    from glint_mi.dataset.generate import Preset, make_scene

    size = {}
    if args.size:
        try:
            w, h = (int(v) for v in args.size.lower().split("x"))
            assert w >= 8 and h >= 8
        except (ValueError, AssertionError):
            ap.error(f"--size {args.size}: give WIDTHxHEIGHT, each >= 8 (e.g. 320x180)")
        size = dict(width=w, height=h)
    if args.prior_error_scale is not None:
        from glint_mi.dataset.priors import MODELS, scale_errors
        try:  # before any rendering
            scale_errors(MODELS[args.prior_model](), args.prior_error_scale)
        except ValueError as e:
            ap.error(f"--prior-error-scale {args.prior_error_scale}: {e} (1: the model's own errors)")
    if args.sfm_from is not None and not args.sfm_from.is_dir():
        ap.error(f"--sfm-from {args.sfm_from}: not a folder (it holds scene_<seed>/ folders generated with --sfm known)")
    if args.sfm_from is not None and args.sfm not in (None, "known"):
        ap.error(f"--sfm-from takes known-pose points from elsewhere: it cannot be combined with --sfm {args.sfm}")
    preset = Preset.named(args.preset, views=args.views, spp=args.spp, **size)
    args.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    summary, refused = [], None
    for i in range(args.scenes):
        name = f"scene_{args.seed + i:03d}"
        done = args.out / name / "meta.json"
        if done.exists() and not args.overwrite:
            meta = json.loads(done.read_text())
            print(f"{name}: already complete ({meta['views']} views), skipped; --overwrite regenerates it")
            summary.append({"scene": name, "skipped": True, **{k: meta.get(k) for k in SUMMARY_KEYS}})
            continue
        with tqdm(total=preset.views, desc=name, unit="view", file=sys.stderr) as bar:
            def progress(done, total):
                bar.n = done
                bar.refresh()
            try:
                meta = make_scene(args.out / name, args.seed + i, preset, progress,
                                  sfm=args.sfm or ("none" if args.preset == "tiny" else "known"),
                                  priors=args.priors == "derived", glass=not args.no_glass, renderer=args.renderer,
                                  albedo_prior=not args.no_albedo_prior, see_through=args.see_through,
                                  prior_model=args.prior_model, prior_error_scale=args.prior_error_scale,
                                  sfm_from=None if args.sfm_from is None else args.sfm_from / name)
            except ValueError as exc:
                if "--sfm-from" not in str(exc):
                    raise
                refused = exc
        if refused is not None:
            print(f"error: {refused}", file=sys.stderr)
            return 2
        summary.append({"scene": name, **{k: meta[k] for k in SUMMARY_KEYS}})
        pts = meta["sfm"].get("points3D", 0)
        noise = meta["gt_noise_psnr_db"]
        print(f"{name}: {meta['views']} views in {meta['total_seconds']:.1f} s ({meta['renderer']}), GT noise PSNR "
              f"{'n/a' if noise is None else f'{noise:.1f}'} dB, glass pixels {100 * meta['glass_pixel_fraction']:.1f} %, "
              f"case on {meta['case_support']}, {pts} SfM points ({meta['sfm']['mode']})")
        if "full_sfm" in meta["sfm"]:
            print(f"  full SfM: {json.dumps(meta['sfm']['full_sfm'])}")
    total = time.perf_counter() - t0
    (args.out / "summary.json").write_text(json.dumps({"preset": args.preset, "total_seconds": total,
                                                       "scenes_seconds": sum(s["total_seconds"] or 0 for s in summary),
                                                       "scenes": summary}, indent=1))
    print(f"{args.scenes} scene(s) in {total:.1f} s -> {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
