"""GLINT at a GPU's budget on rooms declared before generation (issue 65, item 3): one prepared command for a device
call of at most ~9 minutes.

1. The declared rooms are rendered on the device (Mitsuba's volpath under the variant in force), with their
   known-pose SfM points taken from the same rooms generated on a CPU machine with pycolmap (``--sfm-from``: the
   device has no pycolmap; only ``sparse/``, ``transforms.json`` and ``meta.json`` travel, a few hundred kB).
2. A calibration: the slowest method (``glint``) trains a few iterations on the first room; its seconds an
   iteration set the budget: the epochs that let every (method, room) run fit in what is left, with a margin.
3. Every method trains every room on that same number of epochs (the same rays), with densification that lets
   the sets grow (``densify_top=0.12 densify_grad_rel=0.05``), and is evaluated: ``python -m glint_mi.benchmark``.
4. ``OUT/gpu_budget.md``: the variant, the device, the epochs, each run's minutes and Gaussians, and the
   benchmark's table; ``OUT/results.csv``.

Here (a CPU machine with pycolmap), once, the rooms' SfM points:

    .venv/bin/python -m glint_mi.dataset make out/gpu_rooms_sfm --scenes 2 --seed 9811 --preset gpu --size 320x180 \\
        --views 48 --spp 8 --priors none
    tar czf .gpu_carry/rooms_sfm.tgz -C out/gpu_rooms_sfm $(cd out/gpu_rooms_sfm && ls -d scene_*/sparse \\
        scene_*/transforms.json scene_*/meta.json)

On the device (``benchmarks/gpu_check.sh budget`` unpacks the wheels and calls this):

    python3 benchmarks/gpu_budget.py --sfm .gpu_carry/rooms_sfm.tgz --seed 9811 --scenes 2 --minutes 8.5 --out $OUT

A dry run on the CPU (LLVM, a tiny room, a minute): ``GLINT_VARIANT=llvm_ad_rgb .venv/bin/python
benchmarks/gpu_budget.py --sfm DIR --seed S --scenes 1 --size 64x36 --views 8 --spp 16 --minutes 2
--calibrate 5 --out OUT``.
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import os
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
GROW = ["--set", "densify_top=0.12", "--set", "densify_grad_rel=0.05"]


def sh(cmd: list[str], timeout: float, log: Path) -> tuple[int, float]:
    """Run a command with its output appended to log; (return code, seconds); 124 when it ran out of time."""
    t = time.perf_counter()
    with open(log, "a") as f:
        f.write(f"\n$ {' '.join(cmd)}\n")
        f.flush()
        try:
            rc = subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT, cwd=ROOT, timeout=max(1.0, timeout)).returncode
        except subprocess.TimeoutExpired:
            rc = 124
    return rc, time.perf_counter() - t


def device_name() -> str:
    try:
        out = subprocess.run(["nvidia-smi", "--query-gpu=name", "--format=csv,noheader"], capture_output=True,
                             text=True, timeout=20).stdout.strip()
        return out.splitlines()[0] if out else "no NVIDIA GPU"
    except (OSError, subprocess.TimeoutExpired):
        return "no NVIDIA GPU (nvidia-smi absent)"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0], epilog=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sfm", type=Path, required=True, help="the rooms' SfM points: a folder or a .tgz of scene_<seed>/")
    ap.add_argument("--seed", type=int, default=9811)
    ap.add_argument("--scenes", type=int, default=2)
    ap.add_argument("--size", default="320x180")
    ap.add_argument("--views", type=int, default=48)
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--methods", default="glint,3dgs-priors,3dgs")
    ap.add_argument("--preset", default="gpu", help="the training preset (gpu: 2025 patches of 8 x 8 a step)")
    ap.add_argument("--minutes", type=float, default=8.5, help="the whole command's wall-clock budget")
    ap.add_argument("--calibrate", type=int, default=20, help="iterations of glint that time a step")
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                    help="more TrainConfig fields for every method (e.g. traversal=shellbvh)")
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    t_end = time.perf_counter() + 60 * args.minutes
    args.out.mkdir(parents=True, exist_ok=True)
    log = args.out / "gpu_budget_log.txt"
    py = sys.executable
    work = Path(tempfile.mkdtemp(prefix="glint_gpu_budget_"))
    sfm = args.sfm
    if sfm.is_file():
        with tarfile.open(sfm) as tf:
            tf.extractall(work / "sfm", filter="data")
        sfm = work / "sfm"
    if not sfm.is_dir():
        print(f"error: --sfm {args.sfm}: neither a folder nor a .tgz of scene_<seed>/ folders", file=sys.stderr)
        return 2
    data = work / "rooms"
    rc, gen_s = sh([py, "-m", "glint_mi.dataset", "make", str(data), "--scenes", str(args.scenes), "--seed",
                    str(args.seed), "--preset", "gpu", "--size", args.size, "--views", str(args.views), "--spp",
                    str(args.spp), "--sfm-from", str(sfm)], t_end - time.perf_counter() - 60, log)
    if rc != 0:
        print(f"error: generating the rooms failed (rc {rc}); see {log}", file=sys.stderr)
        return 1
    extra = [x for kv in args.set for x in ("--set", kv)]
    bench = [py, "-m", "glint_mi.benchmark", "--data", str(data), "--preset", args.preset, "--set", "w_sfm_depth=0",
             *GROW, *extra]
    # calibration: glint, the slowest method, for a few iterations on the first room (its kernels compiled first)
    first = sorted(p.name for p in data.iterdir() if (p / "split.json").exists())[0]
    cal = work / "calibrate"
    (cal_data := work / "cal_data").mkdir()
    os.symlink(data / first, cal_data / first)
    rc, cal_s = sh([*bench[:4], str(cal_data), *bench[5:], "--methods", "glint", "--iterations", str(args.calibrate),
                "--set", "log_every=1",
                "--out", str(cal)], t_end - time.perf_counter() - 60, log)
    if rc != 0:
        print(f"error: the calibration run failed (rc {rc}); see {log}", file=sys.stderr)
        return 1
    from glint_mi.config import DEFAULT_VARIANT
    from glint_mi.methods import config_for
    rays_per_it = config_for("glint", args.preset, DEFAULT_VARIANT).rays_per_iteration()
    with open(cal / "results.csv") as f:
        cal_row = next(csv.DictReader(f))
    s_cold = float(cal_row["train_s"]) / args.calibrate  # compilation included: an upper bound
    with open(cal / "runs" / first / "glint" / "log.csv") as f:  # the steps' own speed, the later half
        speeds = sorted(float(r["rays_per_s"]) for r in list(csv.DictReader(f))[args.calibrate // 2:])
    # 1.5x: the sets grow with densification (the calibration's are the initial ones)
    s_per_it = min(s_cold, 1.5 * rays_per_it / speeds[len(speeds) // 2]) if speeds else s_cold
    overhead = max(0.0, cal_s - float(cal_row["train_s"]))  # a run's start, loading and evaluation
    meta = json.loads((data / first / "meta.json").read_text())
    split = json.loads((data / first / "split.json").read_text())
    w, h = meta["preset"]["width"], meta["preset"]["height"]
    train_px = len(split["train"]) * w * h
    methods = [m for m in args.methods.split(",") if m]
    runs = len(methods) * args.scenes
    left = t_end - time.perf_counter()
    # per run: the calibration's fixed cost (start, loading, evaluation) and 80 % of the rest in training; the
    # other methods are at most as slow as glint
    per_run = max(0.0, (left - 15) / runs - overhead) * 0.8
    its = max(1, int(per_run / s_per_it))
    epochs = math.floor(10 * its * rays_per_it / train_px) / 10
    if epochs <= 0:
        print(f"error: no time left to train ({left:.0f} s for {runs} runs at {s_per_it:.2f} s an iteration)",
              file=sys.stderr)
        return 1
    rc, bench_s = sh([*bench, "--methods", ",".join(methods), "--set", f"epochs={epochs}", "--out",
                      str(args.out / "bench")], t_end - time.perf_counter(), log)
    rows = []
    if (args.out / "bench" / "results.csv").exists():
        with open(args.out / "bench" / "results.csv") as f:
            rows = list(csv.DictReader(f))
    import glint_mi
    glint_mi.set_variant()
    import mitsuba as mi
    lines = [f"# GLINT at a GPU's budget: rooms {args.seed}-{args.seed + args.scenes - 1} (`benchmarks/gpu_budget.py`)",
             "", f"Device: {device_name()}; variant {mi.variant()}; {' '.join(sys.argv[1:]) if argv is None else ' '.join(argv)}",
             "", f"- rooms: {args.scenes} x {args.views} views at {w} x {h}, {args.spp} spp (Mitsuba volpath on this "
             f"device), SfM points from `{args.sfm.name}`; generated in {gen_s:.0f} s",
             f"- calibration: glint {args.calibrate} iterations of {rays_per_it} rays on {first}: {s_cold:.2f} s an "
             f"iteration with compilation, budgeted at {s_per_it:.2f} s ({rays_per_it / s_per_it / 1e6:.2f} M rays/s: "
             f"the later steps' median speed, 1.5x for the sets' growth), {overhead:.0f} s "
             f"a run besides training (start, loading, evaluation)",
             f"- budget: **{epochs} epochs** a run ({its} iterations of glint's time; {epochs * train_px / 1e6:.1f} M "
             f"rays) for {', '.join(methods)}; densification that lets the sets grow ({' '.join(GROW[1::2])})",
             f"- benchmark: rc {rc} in {bench_s:.0f} s" + (" (ran out of time: the rows below are the runs that "
                                                          "finished)" if rc == 124 else ""), "",
             "| method | room | train min | Gaussians | PSNR | normal MAE | AbsRel | t IoU |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['method']} | {r['scene']} | {float(r['train_s']) / 60:.1f} | {r.get('gaussians', '?')} | "
                     f"{float(r['psnr']):.2f} | {float(r['normal_mae']):.1f} | {float(r['absrel']):.3f} | "
                     f"{float(r['t_iou']):.2f} |")
    if (args.out / "bench" / "table.md").exists():
        lines += ["", "## The benchmark's table", "", (args.out / "bench" / "table.md").read_text()]
    (args.out / "gpu_budget.md").write_text("\n".join(lines) + "\n")
    if rows:
        (args.out / "results.csv").write_text((args.out / "bench" / "results.csv").read_text())
    print("\n".join(lines))
    return 0 if rows else 1


if __name__ == "__main__":
    sys.exit(main())
