"""``python -m glint_mi.benchmark``: every method on every scene with the same budget; the comparison table.

    python -m glint_mi.benchmark --data out/bench_data --preset bench --out docs/results/bench
    python -m glint_mi.benchmark --data DIR --methods glint,envgs --preset tiny --out OUT   # a subset
    python -m glint_mi.benchmark --data DIR --ray ray://head:10001 --out OUT                # runs on a Ray cluster

``--data`` holds generated scenes (``python -m glint_mi.dataset make``; ``--make-data N`` generates N there first).
One run per method x scene (x seed: ``--seeds N``, runs ``<method>@seed<k>`` for k > 0) under
``OUT/runs/<scene>/<method>``; a finished run is skipped, an interrupted one resumes from its checkpoint (an
interrupted evaluation is done again), so the benchmark can be stopped and restarted. Writes ``OUT/results.csv``,
``OUT/table.md`` (the paper's columns per scene and the mean, plus SSIM, glass-only MAE/AbsRel, transparency IoU)
and ``OUT/figures/<scene>.png`` (per-method renders of the first test view side by side).
"""
from __future__ import annotations

import argparse
import csv
import io
import json
import sys
from pathlib import Path

import numpy as np

from glint_mi.evaluation import metrics as M
from glint_mi.config import DEFAULT_VARIANT, PRESETS, VARIANTS
from glint_mi.methods import METHODS, TABLE_METHODS, config_for

COLUMNS = ("fps", "train_s", "psnr", "normal_mae", "absrel", "ssim", "normal_mae_glass", "absrel_glass", "t_iou",
           "t_off_glass", "psnr_glass", "psnr_off_glass")


def scenes_in(data: Path) -> list[Path]:
    """The scenes of ``data``: the folder itself when it is a dataset (a capture: transforms.json or sparse/), else
    its generated scenes (sub-folders with split.json; one still being generated, <name>.partial, is not one)."""
    data = Path(data)
    if (data / "transforms.json").exists() or (data / "sparse").exists():
        return [data]
    found = sorted(p.parent for p in data.glob("*/split.json") if not p.parent.name.endswith(".partial"))
    if not found:
        raise FileNotFoundError(f"{data}: neither a dataset (transforms.json, sparse/) nor a folder of generated "
                                f"scenes (folders with split.json); make them with `python -m glint_mi.dataset make "
                                f"{data} --scenes 5 --preset bench` or pass --make-data 5.")
    return found


PRIORS_ROW = "priors"  # not a method: the dataset's prior maps scored as they are


def aligned_prior_depth(bank, i: int, gt_depth: np.ndarray) -> tuple[np.ndarray, bool]:
    """View ``i``'s depth prior in ``bank`` (``align_depth_priors`` done) as metric depth [H, W], aligned as GLINT's
    loss aligns it: the scale and shift fitted to the SfM points the view sees; where the view has too few points,
    the best affine fit to ``gt_depth`` instead (favours the prior; the bool says it was used). 0 where the prior
    is invalid."""
    h, w = bank.sizes[i]
    P = bank.priors["depth"][bank.offsets[i]:bank.offsets[i + 1], 0].reshape(h, w).astype(np.float64)
    wq, fitted = bank.depth_affine[i], False
    if not np.isfinite(wq[0]):
        m = (P > 0) & (gt_depth > 0)
        x = 1.0 / gt_depth[m] if bank.depth_inverse else gt_depth[m]
        (a, b), *_ = np.linalg.lstsq(np.column_stack([x, np.ones(m.sum())]), P[m], rcond=None)
        wq, fitted = (a, b), True
    z = (P - wq[1]) / wq[0]
    if bank.depth_inverse:
        z = np.where(z > 0, 1.0 / np.maximum(z, 1e-12), 0.0)
    return np.where(P > 0, z, 0.0), fitted


def score_priors(scene_dir: Path, out: Path | None = None) -> dict:
    """The ``priors`` row: each test view's depth and normal priors read straight from the maps, the depth aligned
    as GLINT's loss aligns it (scale and shift fitted to the metric SfM points the view sees; a per-image fit to
    the ground truth where a view has too few points, labelled), normals rotated to world axes; scored with the
    same metrics as a method's renders (no image, no transparency)."""
    from glint_mi.training.batch import RayBank
    from glint_mi.data import load_dataset
    from glint_mi.runs import atomic_write_text

    ds = load_dataset(scene_dir)
    views = ds.test_views
    bank = RayBank(views, ds.root)
    if not {"depth", "normal"} <= bank.has:
        raise FileNotFoundError(f"{scene_dir}: the priors row needs depth and normal priors")
    rep = bank.align_depth_priors(ds.points)
    per_view = {}
    gt_fit = 0
    for i, v in enumerate(views):
        gt = v.load_gt()
        h, w = bank.sizes[i]
        depth, fitted = aligned_prior_depth(bank, i, gt["depth"])
        gt_fit += fitted
        pred = {"depth": depth, "normal": bank.prior_normals_world(i), "transparency": np.zeros((h, w))}
        m = M.view_metrics({**pred, "rgb": np.zeros((h, w, 3))}, gt, np.zeros((h, w, 3)))
        per_view[v.name] = {k: m[k] for k in ("normal_mae", "normal_mae_glass", "absrel", "absrel_glass")}
    metrics = {**M.mean_metrics(list(per_view.values())), "fps": float("nan"), "train_s": 0.0}
    res = {"metrics": metrics, "per_view": per_view, "aligned": rep, "views_fitted_to_ground_truth": gt_fit}
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        atomic_write_text(out / "metrics.json", json.dumps(res, indent=1))
    return res


def run_one(method: str, scene_dir: Path, run: Path, preset: str, variant: str, log=print, missing: str = "error",
            **extra) -> dict:
    """Train (or resume, or skip when finished) one method on one scene and evaluate it; returns the metrics."""
    from glint_mi.evaluate import evaluate
    from glint_mi.runs import finished_metrics, hold_run, train_unless_done
    from glint_mi.scene import read_scene, scene_xml
    from glint_mi.training.trainer import Trainer

    done = finished_metrics(run)
    if done is not None:
        return done
    if method == PRIORS_ROW:
        return score_priors(scene_dir, run)
    lock = hold_run(run)  # before scene.xml is written; the Trainer takes it again (re-entrant in one process)
    cfg = config_for(method, preset, variant, **extra)
    if (run / "checkpoint.npz").exists():
        trainer = Trainer(run, cfg, resume=True, log=log)
    else:
        run.mkdir(parents=True, exist_ok=True)
        xml = run / "scene.xml"
        xml.write_text(scene_xml(scene_dir, missing=missing))
        trainer = Trainer(run, cfg, scene=read_scene(xml), log=log)
    (run / "method.json").write_text(json.dumps({"method": method, "overrides": METHODS[method].overrides_for(preset),
                                                 "differs": METHODS[method].differs}, indent=1))
    res = train_unless_done(trainer)
    out = evaluate(trainer.integ_for_eval(), trainer.eval_views(), run, res["train_s"], **trainer.eval_options())
    del lock  # held until the evaluation is written
    return {k: v for k, v in out.items() if k not in ("per_view", "renders")}


class ClusterError(RuntimeError):
    """A Ray cluster that cannot be used; the message says why and what to do."""


def _job(method, scene, run, preset, variant, seed, extra, missing="error") -> dict:
    """One (method, scene, seed) run, where it is executed (this process or a Ray worker): trains, resumes or skips
    it (run_one), returns its metrics."""
    res = run_one(method, Path(scene), Path(run), preset, variant, log=lambda *a: None, missing=missing, seed=seed,
                  **extra)
    sizes = Path(run) / "report.json"  # the Gaussians at the end (the priors row trains none)
    n = sum(json.loads(sizes.read_text()).get("sizes", {}).values()) if sizes.exists() else 0
    return {"metrics": res["metrics"], "variant": res.get("variant", "unrecorded"),
            "device": res.get("device", "unrecorded"), "gaussians": n}


def run_jobs(jobs: list, preset: str, variant: str, extra: dict, ray_address: str | None = None,
             missing: str = "error") -> list[dict]:
    """Every job (method, scene folder, run folder, seed), locally one after another, or with ``ray_address`` as
    Ray tasks of 2 CPUs each on a cluster (``local``: a Ray instance on this machine; ``auto``: the cluster this
    machine belongs to; else its address). The same run folders, so a sweep resumes the same way either way (the
    folders must be on a filesystem every node sees). Results come back in the jobs' order."""
    if not ray_address:
        out = []
        for m, scene, run, seed in jobs:
            print(f"[{scene.name}] {m} seed {seed} ...", flush=True)
            out.append(_job(m, scene, run, preset, variant, seed, extra, missing))
        return out
    try:
        import ray
    except ImportError:
        raise ClusterError("--ray needs the cluster extra: pip install -e '.[cluster]' (Ray)") from None
    if ray_address not in ("local", "auto"):  # Ray retries an unreachable head for minutes: look first
        import socket

        host, _, port = ray_address.split("://")[-1].rpartition(":")
        try:
            socket.create_connection((host or "127.0.0.1", int(port)), timeout=5).close()
        except (OSError, ValueError) as e:
            raise ClusterError(f"cannot reach the Ray cluster at {ray_address!r}: {e}; start it with `ray start "
                               f"--head` there, or give its address as ray://HOST:10001 or HOST:6379") from None
    try:
        if ray_address == "local":
            ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
        else:
            ray.init(address=ray_address, include_dashboard=False, log_to_driver=False)
    except Exception as e:  # ConnectionError, RuntimeError: say which address failed
        raise ClusterError(f"cannot reach the Ray cluster at {ray_address!r}: {e}") from None
    try:
        task = ray.remote(num_cpus=2)(_job)
        futures = [task.remote(m, str(scene), str(run), preset, variant, seed, extra, missing)
                   for m, scene, run, seed in jobs]
        names = {f: f"[{scene.name}] {m} seed {seed}" for f, (m, scene, _, seed) in zip(futures, jobs)}
        print(f"{len(futures)} run(s) sent to Ray ({ray.cluster_resources().get('CPU', 0):.0f} CPUs)", flush=True)
        pending = list(futures)
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            print(f"{names[done[0]]} done ({len(futures) - len(pending)}/{len(futures)})", flush=True)
        return ray.get(futures)
    finally:
        ray.shutdown()


def figure(scene: str, runs: dict[str, Path], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from PIL import Image

    cols = [("photo", "photo"), ("rgb", "RGB"), ("depth", "depth"), ("normal", "normal"), ("t", "transparency"),
            ("cI", "c_I"), ("cR", "c_R"), ("cT", "c_T")]
    names = [n for n in runs if (runs[n] / "renders").is_dir()]  # rows with renders (not the priors row)
    if not names:
        return
    first = sorted((runs[names[0]] / "renders").glob("*_rgb.png"))
    photo = None
    if first:  # the test photo at the renders' resolution, from the run's own dataset
        from glint_mi.config import TrainConfig
        from glint_mi.runs import load_run_dataset

        try:
            ds = load_run_dataset(runs[names[0]], TrainConfig.load(runs[names[0]] / "config.json"))
            photo = ds.view(first[0].name[:-len("_rgb.png")]).load_image()
        except Exception:  # a figure is not worth failing a benchmark for
            photo = None
    h, w = (photo.shape[:2] if photo is not None else (9, 16))
    size = 2.2 * min(1.0, w / h * 9 / 16) if h > w else 2.2
    fig, ax = plt.subplots(len(names), len(cols), figsize=(size * len(cols), size * h / w * len(names) + 0.4),
                           squeeze=False)
    for i, name in enumerate(names):
        per = sorted((runs[name] / "renders").glob("*_rgb.png"))
        view = per[0].name[:-len("_rgb.png")] if per else None
        for j, (key, title) in enumerate(cols):
            a = ax[i, j]
            a.axis("off")
            f = runs[name] / "renders" / f"{view}_{key}.png"
            if key == "photo" and photo is not None:
                a.imshow(photo)
            elif view and f.exists():
                img = np.asarray(Image.open(f))
                a.imshow(img, cmap="gray" if img.ndim == 2 else None, vmin=0, vmax=255)  # t: 0..1, not rescaled
            if i == 0:
                a.set_title(title, fontsize=8)
        ax[i, 0].text(-0.05, 0.5, name, transform=ax[i, 0].transAxes, ha="right", va="center", fontsize=8)
    fig.suptitle(scene, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def write_results(rows: list[dict], out: Path, header: str = "") -> str:
    """results.csv (one row per method x scene) and table.md (per scene, then the mean per method)."""
    from glint_mi.runs import atomic_write_text

    keys = ["method", "scene", "seed", *COLUMNS, "variant", "device", "gaussians"]
    # Round once, to the CSV's 6 digits, and build the table from those values: rounding the raw value to the
    # table's 4 digits could differ from rounding the CSV's (12.26499 -> 12.26, but 12.265 -> 12.27).
    rows = [{k: (float(f"{v:.6g}") if isinstance(v, float) else v) for k, v in r.items()} for r in rows]
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=keys, extrasaction="ignore")
    w.writeheader()
    for r in rows:
        w.writerow({k: (f"{r[k]:.6g}" if isinstance(r.get(k), float) else r.get(k)) for k in keys})
    atomic_write_text(out / "results.csv", buf.getvalue())
    md = [header] if header else []
    scenes = sorted({r["scene"] for r in rows})
    methods = list(dict.fromkeys(r["method"] for r in rows))
    seeds = sorted({r.get("seed", 0) for r in rows})

    def stat(sel, fn):
        return {k: float(fn([r.get(k) if r.get(k) is not None else np.nan for r in sel])) for k in COLUMNS}

    for s in scenes:
        here = [r for r in rows if r["scene"] == s]
        if len(seeds) == 1:
            md.append(f"### {s}\n")
            md.append(M.table({r["method"]: r for r in here}, COLUMNS))
            continue
        md.append(f"### {s}: mean over seeds {seeds}\n")
        md.append(M.table({m: stat([r for r in here if r["method"] == m], np.nanmean) for m in methods}, COLUMNS))
        md.append(f"### {s}: standard deviation over seeds {seeds} (run-to-run spread)\n")
        md.append(M.table({m: stat([r for r in here if r["method"] == m], np.nanstd) for m in methods}, COLUMNS))
    md.append(f"### mean over {len(scenes)} scene(s)" + (f" and {len(seeds)} seeds" if len(seeds) > 1 else "") + "\n")
    md.append(M.table({m: stat([r for r in rows if r["method"] == m], np.nanmean) for m in methods}, COLUMNS))
    text = "\n".join(md)
    atomic_write_text(out / "table.md", text)
    return text


def job_list(methods, scenes, seeds, out: Path) -> list:
    """(method, scene, run folder, seed) for every run, scene by scene: seed 0's folder is ``OUT/runs/<scene>/<method>``,
    seed k's ``<method>@seed<k>``; the prior maps do not depend on a seed, so ``priors`` runs for the first seed only."""
    return [(m, scene, out / "runs" / scene.name / (m if seed == 0 else f"{m}@seed{seed}"), seed)
            for scene in scenes for seed in seeds for m in methods
            if not (m == PRIORS_ROW and seed != seeds[0])]


def where(rows: list[dict]) -> str:
    """Where the table's runs trained, from their own records (a table rebuilt from finished runs sets no Dr.Jit
    variant, so this process's would say 'none'), and the machine that wrote the table."""
    from glint_mi.machine import describe

    d = describe()
    trained = ", ".join(sorted({f"{r['device']} ({r['variant']})" for r in rows
                                if r["method"] != PRIORS_ROW})) or "no runs"  # the prior maps train nothing
    return f"runs trained on {trained}; table written on {d['cpu']}, {d['cores']} cores, {d['system']}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m glint_mi.benchmark", description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("--data", type=Path, required=True, help="folder of generated scenes")
    ap.add_argument("--make-data", type=int, metavar="N", help="generate N scenes into --data first (if missing)")
    ap.add_argument("--preset", default="bench", choices=sorted(PRESETS))
    ap.add_argument("--variant", default=DEFAULT_VARIANT, choices=sorted(VARIANTS),
                    help="schedule: glint_mi (default: the supplement's without the refine stage), supplement, release")
    ap.add_argument("--methods", default=",".join(TABLE_METHODS), help=f"comma list of {sorted(METHODS)}")
    ap.add_argument("--iterations", type=int,
                    help="override the preset's budget (epochs) with a fixed iteration count (same for every method)")
    which = ap.add_mutually_exclusive_group()
    which.add_argument("--seeds", type=int, default=1,
                       help="train every method x scene with seeds 0..N-1; the table then gives mean and spread")
    which.add_argument("--seed-ids", default=None, metavar="K[,K...]",
                       help="train these seeds only, instead of 0..N-1 (e.g. 1 to add a second seed to a study whose "
                            "seed-0 runs lie elsewhere); the run folders are named as with --seeds")
    ap.add_argument("--set", action="append", metavar="FIELD=VALUE",
                    help="a TrainConfig field for every method (e.g. eval_every=200 for convergence curves)")
    ap.add_argument("--out", type=Path, default=Path("out/benchmark"))
    ap.add_argument("--skip-missing", action="store_true",
                    help="leave out frames whose image is missing (a capture such as the instant-ngp fox)")
    ap.add_argument("--ray", nargs="?", const="auto", default=None, metavar="ADDRESS",
                    help="send each (scene, method, seed) run to a Ray cluster as a 2-CPU task: no ADDRESS or 'auto' "
                         "= the cluster this machine is part of, 'local' = a Ray instance here, else the head's "
                         "address (ray://host:10001 or host:6379); needs pip install -e '.[cluster]'")
    args = ap.parse_args(argv)
    if args.seeds < 1:
        ap.error("--seeds must be >= 1")
    seeds = list(range(args.seeds))
    if args.seed_ids is not None:
        try:
            seeds = sorted({int(k) for k in args.seed_ids.split(",") if k.strip()})
        except ValueError:
            seeds = []
        if not seeds or seeds[0] < 0:
            ap.error(f"--seed-ids {args.seed_ids!r}: give seed numbers >= 0 separated by commas, e.g. --seed-ids 1,2")

    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    bad = [m for m in methods if m not in METHODS and m != PRIORS_ROW]
    if bad:
        print(f"error: unknown method(s) {bad}; choose from {sorted(METHODS)}", file=sys.stderr)
        return 2
    if args.make_data and not list(args.data.glob("*/split.json")):
        from glint_mi.dataset.__main__ import main as dataset_main

        dataset_main(["make", str(args.data), "--scenes", str(args.make_data), "--preset", args.preset])
    try:
        scenes = scenes_in(args.data)
    except FileNotFoundError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    from glint_mi.config import ConfigError
    from glint_mi.optimize import parse_sets
    from glint_mi.runs import RunError

    extra = {"iterations": args.iterations, "epochs": 0.0} if args.iterations else {}
    try:
        extra.update(parse_sets(args.set))
        for m in methods:
            if m != PRIORS_ROW:
                config_for(m, args.preset, args.variant, **extra)  # every override is valid before anything runs
    except ConfigError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    jobs = job_list(methods, scenes, seeds, args.out)
    try:
        results = run_jobs(jobs, args.preset, args.variant, extra, args.ray,
                           missing="skip" if args.skip_missing else "error")
    except (ClusterError, RunError) as e:  # RunError: a run folder another process holds
        print(f"error: {e}", file=sys.stderr)
        return 2
    rows = [{"method": m, "scene": scene.name, "seed": seed, **res["metrics"],
             "variant": res["variant"], "device": res["device"], "gaussians": res.get("gaussians", 0)}
            for (m, scene, _, seed), res in zip(jobs, results)]
    for scene in scenes:
        runs = {}
        for m, sc, run, _ in jobs:
            if sc == scene:
                runs.setdefault(m, run)
        (args.out / "figures").mkdir(exist_ok=True)
        figure(scene.name, runs, args.out / "figures" / f"{scene.name}.png")
    derived = any((s / "priors" / "PRIORS.json").exists() for s in scenes)
    header = (f"Benchmark: `python -m glint_mi.benchmark {' '.join(argv if argv is not None else sys.argv[1:])}`\n\n"
              f"preset {args.preset}, variant {args.variant}; {where(rows)}."
              + (" Priors derived from ground truth (labelled)." if derived else "") + "\n")
    print(write_results(rows, args.out, header))
    curves = convergence_curves(args.out)
    if curves:
        from glint_mi.evaluation.plots import convergence_figure

        convergence_figure(curves, args.out / "convergence.png")
        print(f"convergence curves of {len(curves)} run(s): {args.out / 'convergence.png'}")
    return 0


def convergence_curves(out: Path, method: str = "*", label: str | None = None) -> dict[str, list[dict]]:
    """The in-run test curves (``convergence.csv``) of a benchmark folder's runs of ``method`` (a glob), for
    ``evaluation.plots.convergence_figure``: "METHOD / SCENE" -> rows, or "LABEL / SCENE" with ``label``."""
    curves = {}
    for f in sorted((Path(out) / "runs").glob(f"*/{method}/convergence.csv")):
        with open(f) as fh:
            curves[f"{label or f.parent.name} / {f.parent.parent.name}"] = list(csv.DictReader(fh))
    return curves


if __name__ == "__main__":
    sys.exit(main())
