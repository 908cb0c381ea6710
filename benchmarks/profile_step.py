"""Where one training step's time goes: a profile of GLINT's training loop, phase by phase (issue 11).

Every phase of Trainer.step and of the structure step that follows it is bracketed by dr.sync_thread(), and the
kernels it launched are read from Dr.Jit's kernel history: wall time, kernel execution time, compile time (codegen +
LLVM backend of kernels that missed the cache), launches. "host" is the rest of the wall time: Python, numpy,
host<->device copies, tracing the kernels' code. Then, on one batch, each ray pass of the forward is timed twice on
the same rays: as it runs (BVH traversal + kernel evaluation + compositing) and as a traversal only (the same BVH
queries and stepping, stopped after the same number of hits per ray, no kernel evaluated), which gives the share of
a step spent in BVH traversal (forward + the replay, which re-traces every pass).

    .venv/bin/python benchmarks/profile_step.py                        # the bundled demo room, fresh init
    .venv/bin/python benchmarks/profile_step.py --run out/demo/run     # a trained run: its config and Gaussians
    .venv/bin/python benchmarks/profile_step.py --scene SCENE.xml [--at 0.3] [--steps 30]
    .venv/bin/python benchmarks/profile_step.py --run RUN --ab [NAME]   # + the exact speed-ups (NAME: those named so) off vs on
    .venv/bin/python benchmarks/profile_step.py --variant cuda_ad_rgb --run RUN --targets   # + issue 43's GPU targets
    .venv/bin/python benchmarks/profile_step.py --run RUN --banks       # + coarse_to_fine's banks against the full one

Syncing between phases removes the overlap of Python with running kernels, so the phases add up to a little more
than an unprofiled step; the table prints both. Results: benchmarks/results/profile_step_<name>.{md,json}.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import statistics
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

import glint_mi  # noqa: E402

if "--variant" in sys.argv[:-1]:  # before Mitsuba loads: e.g. --variant cuda_ad_rgb (else $GLINT_VARIANT or LLVM)
    import os

    os.environ["GLINT_VARIANT"] = sys.argv[sys.argv.index("--variant") + 1]
glint_mi.set_variant()
import drjit as dr  # noqa: E402
import mitsuba as mi  # noqa: E402

from glint_mi.config import TrainConfig  # noqa: E402
from glint_mi.machine import describe, summary  # noqa: E402
from glint_mi.optimize import parse_sets  # noqa: E402
from glint_mi.model.render import floats  # noqa: E402
from glint_mi.scene import read_scene  # noqa: E402
from glint_mi.training.trainer import Trainer  # noqa: E402

PHASES = ("sample", "forward", "objective", "backward", "update", "structure", "bvh")


class Profiler:
    """Trainer.phase: per phase, wall time and the kernels launched (execution, compiles), summed over steps."""

    def __init__(self):
        self.rows = defaultdict(lambda: dict(wall=0.0, exec=0.0, compile=0.0, launches=0, compiles=0))

    @contextlib.contextmanager
    def phase(self, name: str):
        dr.sync_thread()
        dr.kernel_history()  # drop what ran before the phase
        t0 = time.perf_counter()
        yield
        dr.sync_thread()
        r = self.rows[name]
        r["wall"] += time.perf_counter() - t0
        for k in dr.kernel_history():
            r["launches"] += 1
            r["exec"] += k.get("execution_time", 0.0) / 1e3
            if not k.get("cache_hit", 1):
                r["compiles"] += 1
                r["compile"] += (k.get("codegen_time", 0.0) + k.get("backend_time", 0.0)) / 1e3


def steps(tr: Trainer, n: int, profiler: Profiler | None):
    """Run n training steps (each followed by its structure step, as Trainer.train does); wall seconds per step."""
    tr.phase = profiler.phase if profiler else (lambda name: contextlib.nullcontext())
    times = []
    for _ in range(n):
        t0 = time.perf_counter()
        st = tr.stage()
        rec = tr.step(read=READ_EVERY_STEP[0])
        if (tr.it + 1) % tr.cfg.log_every == 0:  # as Trainer.train: the deferred values are read at log lines
            tr.settle([rec])
        tr._structure(st)
        dr.sync_thread()
        times.append(time.perf_counter() - t0)
        tr.it += 1
    tr.phase = lambda name: contextlib.nullcontext()
    return times


# Exact speed-ups that have no config switch, each as (name, what turns it off, what turns it back on): --ab times
# steps with all of them off and on, in alternating blocks of the same run (the model keeps training through both).
def _rebuild_every(n):
    from glint_mi_plugins.glint_composite import GaussianSetRef
    GaussianSetRef.REBUILD_EVERY = n


def _adam(step):
    from glint_mi.training.optim import Adam
    Adam.step = step


def _kbuffer_k(tr, k):
    tr.integ.kbuffer_k = k


READ_EVERY_STEP = [False]


def _read_every_step(on):
    READ_EVERY_STEP[0] = on


def _reuse_lists(on):
    import glint_mi_plugins.glint_march as gm
    gm.REUSE_LISTS = on


def _device_update(tr, on):
    """update: device (on) or host (off), switched in place: the host's sets are brought up to date first."""
    from glint_mi.training.device_step import DeviceUpdate

    if on and tr.dev is None:
        tr.dev = DeviceUpdate(tr.adam, tr.cfg.kernel, tr.extent)
        for role, gs in tr.sets.items():
            tr.dev.load(role, gs, tr.strategy)
    elif not on and tr.dev is not None:
        tr.sync()
        tr.dev = None


from glint_mi.training.optim import Adam as _Adam  # noqa: E402

SPEEDUPS = [("native BVH refit (a build per changed set and step before)", lambda tr: _rebuild_every(0),
             lambda tr: _rebuild_every(100)),
            ("Adam on gathered rows (row masks before)", lambda tr: _adam(_Adam.step_masked),
             lambda tr: _adam(_ADAM_STEP)),
            ("one k-buffer round for the hit budget (64 entries a round before)", lambda tr: _kbuffer_k(tr, 64),
             lambda tr: _kbuffer_k(tr, tr.integ.max_hits)),
            ("k-buffer list arrays kept between queries (new arrays per query before)", lambda tr: _reuse_lists(False),
             lambda tr: _reuse_lists(True)),
            ("Adam's gathered rows in glint_mi.native (numpy before)", lambda tr: setattr(_Adam, "NATIVE", False),
             lambda tr: setattr(_Adam, "NATIVE", True)),
            ("loss terms and batch statistics read back at log lines (every step before)",
             lambda tr: _read_every_step(True), lambda tr: _read_every_step(False)),
            ("update on the device: chain rule, Adam, packing on Dr.Jit arrays (update: host before)",
             lambda tr: _device_update(tr, False), lambda tr: _device_update(tr, True))]
_ADAM_STEP = _Adam.step


def picked(name: str, only: str) -> bool:
    """Whether a speed-up's name holds ``only`` or one of its comma-separated parts ('' picks all)."""
    return any(part in name for part in only.split(","))


def alternating(tr: Trainer, variants: list, steps_per_block: int, blocks: int) -> dict:
    """Median step seconds of each variant ``(name, apply)``: ``apply(tr)`` sets it up, then a block of steps runs from
    the same iteration of the schedule (the model keeps training); the variants alternate, ``blocks`` rounds."""
    times = {name: [] for name, _ in variants}
    it0 = tr.it
    try:
        for _ in range(blocks):
            for name, apply in variants:
                tr.it = it0
                apply(tr)
                times[name] += steps(tr, steps_per_block, None)[1:]  # the first step of a block pays the switch
    finally:
        tr.it = it0
    return {k: statistics.median(v) for k, v in times.items()}


def ab(tr: Trainer, steps_per_block: int, blocks: int = 4, only: str = "") -> dict:
    """Median step seconds with the SPEEDUPS (those whose name holds ``only``, or one of its comma-separated parts)
    off ('before') and on ('after'), in alternating blocks, each from the same iteration of the schedule (the stage of
    the profile above; the model keeps training)."""
    def switch(which):
        def apply(tr):
            for name, off, on in SPEEDUPS:
                if picked(name, only):
                    (off if which == "before" else on)(tr)
        return apply

    return alternating(tr, [(v, switch(v)) for v in ("before", "after")], steps_per_block, blocks)


def banks(tr: Trainer, steps_per_block: int, blocks: int = 3) -> list[dict]:
    """``coarse_to_fine``'s cost: the same model and iteration, steps drawing their patches from each bank (the
    coarse levels and the full-size one) in alternating blocks; median step seconds and, on one batch of each, the
    hits per ray and the forward's traversal time. The rays a step are the same in every bank; what differs is
    the images a patch is cut from (a coarse patch spans more of the view)."""
    pyramid = [f"1/{e['factor']}" for e in tr.report.get("coarse_to_fine", [])]  # the levels the run's banks hold
    named = list(zip(pyramid, (b for _, b in tr.coarse))) + [("full size", tr.bank)]
    try:
        times = alternating(tr, [(name, lambda tr, bank=bank: setattr(tr, "bank_now", lambda: bank))
                                 for name, bank in named], steps_per_block, blocks)
    finally:
        tr.__dict__.pop("bank_now", None)  # the instance's override: Trainer.bank_now again
    rows = []
    for name, bank in named:
        trav = traversal(tr, bank)
        rows.append(dict(bank=name, step_s=times[name],
                         hits_mean=trav[0]["hits_mean"],
                         forward_ms=sum(r["full_ms"] for r in trav), traversal_ms=sum(r["traversal_ms"] for r in trav)))
    return rows


def banks_markdown(tr: Trainer, rows: list[dict]) -> str:
    rays = tr.cfg.patches * tr.cfg.patch ** 2
    full = rows[-1]["step_s"]
    lines = [f"coarse_to_fine's banks ({tr.cfg.coarse_to_fine}), the same model at iteration {tr.it}, alternating "
             f"blocks of steps (hits and traversal: one batch each, timed three times, noisier than the steps):", "",
             "| bank | step ms | rays/s | x full size | interface hits / ray | forward ms "
             "(every pass) | traversal only ms |", "|---|---|---|---|---|---|---|"]
    lines += [f"| {r['bank']} | {1e3 * r['step_s']:.1f} | {rays / r['step_s']:.0f} | {full / r['step_s']:.2f} | "
              f"{r['hits_mean']:.1f} | {r['forward_ms']:.1f} | {r['traversal_ms']:.1f} |" for r in rows]
    return "\n".join(lines + [""])


def timed(fn, reps: int = 3) -> float:
    """Median seconds of fn() (after one call that compiles)."""
    fn()
    out = []
    for _ in range(reps):
        dr.sync_thread()
        t0 = time.perf_counter()
        fn()
        dr.sync_thread()
        out.append(time.perf_counter() - t0)
    return statistics.median(out)


def traversal(tr: Trainer, bank=None) -> list[dict]:
    """Each forward pass of one batch (from ``bank``, the run's by default), as it runs and as a traversal only with
    the same hits per ray."""
    integ, c, st = tr.integ, tr.cfg, tr.stage()
    integ.select(st["traced"])
    b = (bank or tr.bank).sample(np.random.default_rng(123), c.patches, c.patch)
    o, d = mi.Point3f(*floats(b.origin)), mi.Vector3f(*floats(b.direction))
    active = mi.Bool(True)
    intf, refl, trans = (integ.active_set(r) for r in ("interface", "reflection", "transmission"))
    with dr.suspend_grad():
        I = integ.march(intf, o, d, active)
        dr.eval(I)
        kd, ks, kt, do_r, do_t = integ._weights(I, d, active)
        x_i, d_r = integ._secondary(I, o, d)
        dr.eval(x_i, d_r, ks, kt, do_r, do_t)
        passes = [("interface (camera)", intf, o, d, active, None)]
        if refl:
            passes.append(("reflection (from x_I)", refl, x_i, d_r, do_r, ks))
        if trans:
            passes.append(("transmission (from x_I)", trans, x_i, d, do_t, kt))
            passes.append(("transmission (camera, direct)", trans, o, d, active, None))
        rows = []
        for name, gs, oo, dd, act, w in passes:
            info = {}

            def full():
                acc = integ.march(gs, oo, dd, act, weight=w, info=info)
                dr.eval(acc, info["hits"])

            full()
            hits = mi.UInt32(info["hits"])
            dr.eval(hits)

            def walk():
                integ.march(gs, oo, dd, act, weight=w, budget=hits, info=info)
                dr.eval(info["hits"])

            t_full, t_walk = timed(full), timed(walk)
            h = np.array(hits, np.float64)
            rows.append(dict(name=name, gaussians=len(tr.sets[gs.role]), hits_mean=float(h.mean()),
                             hits_max=int(h.max()), full_ms=1e3 * t_full, traversal_ms=1e3 * t_walk))
    return rows


# Issue 43's targets on one H100/H200: training rays/s at >= 1M rays a step, a 480 x 270 view's render rate, and
# the paper's budget (60k iterations of one 480 x 270 image: 7.8 G rays) in minutes.
TARGETS = {"train_rays_per_s": 5e6, "render_fps_480x270": 51.0, "paper_budget_min": 30.0}
PAPER_RAYS = 60000 * 480 * 270


def view_rays(view, width: int, height: int):
    """Rays through the pixel centres of ``view``'s camera at ``width`` x ``height`` (intrinsics scaled)."""
    import dataclasses

    from glint_mi.data.rays import pixel_rays

    K = view.K.copy()
    K[0] *= width / view.width
    K[1] *= height / view.height
    v = dataclasses.replace(view, width=width, height=height, K=K)
    d = pixel_rays(v).astype(np.float32)
    o = np.broadcast_to(view.c2w[:3, 3].astype(np.float32), d.shape)
    return mi.Ray3f(mi.Point3f(*floats(o)), mi.Vector3f(*floats(d))), mi.Vector3f(*[float(x) for x in view.c2w[:3, 2]])


def targets(tr: Trainer, rays: int, steps_n: int = 3) -> dict:
    """The targets measured here: training rays/s with ``rays`` a step (patches of the run's size; Adam, the
    objective and the replay as in training, no structure steps), the render rate of a 480 x 270 view (every
    pass the model has, one kernel sequence per frame, evaluated; the first frame compiles and is not counted),
    and the paper's budget at the training rate measured."""
    c = tr.cfg
    patches = max(1, rays // (c.patch * c.patch))
    tr.cfg = c.replace(patches=patches)
    it0 = tr.it
    times = steps(tr, steps_n + 1, None)[1:]  # the first step compiles the kernels of this batch size
    tr.it, tr.cfg = it0, c
    step_s = statistics.median(times)
    n_rays = patches * c.patch * c.patch
    integ = tr.integ_for_eval()
    view = (tr.ds.test_views or tr.ds.train_views)[0]
    ray, fwd = view_rays(view, 480, 270)

    def frame():
        with dr.suspend_grad():
            out = integ.trace(ray, mi.Bool(True), forward=fwd)
            dr.eval(out["rgb"])
        dr.sync_thread()

    frame_s = timed(frame, reps=5)
    rate = n_rays / step_s
    return {"rays_per_step": n_rays, "step_s": step_s, "train_rays_per_s": rate, "render_fps_480x270": 1.0 / frame_s,
            "paper_budget_min": PAPER_RAYS / rate / 60.0}


def targets_markdown(t: dict) -> str:
    rows = [("training rays/s", f"{t['train_rays_per_s'] / 1e6:.3f} M at {t['rays_per_step']:,} rays a step "
             f"({1e3 * t['step_s']:.0f} ms)", ">= 5 M at >= 1M rays a step",
             t["train_rays_per_s"] >= TARGETS["train_rays_per_s"] and t["rays_per_step"] >= 2 ** 20),
            ("render, one 480 x 270 view", f"{t['render_fps_480x270']:.2f} fps", ">= 51 fps",
             t["render_fps_480x270"] >= TARGETS["render_fps_480x270"]),
            ("the paper's budget (7.8 G rays) at that rate", f"{t['paper_budget_min']:.0f} min", "<= 30 min",
             t["paper_budget_min"] <= TARGETS["paper_budget_min"])]
    lines = [f"Issue 43's targets on this machine ({summary()}):", "", "| | measured | target | met |",
             "|---|---|---|---|"]
    lines += [f"| {a} | {b} | {c} | {'yes' if ok else 'no'} |" for a, b, c, ok in rows]
    return "\n".join(lines + [""])


def markdown(name, tr, plain, prof, n, trav, before_after=None, only: str = "") -> str:
    rays = tr.cfg.patches * tr.cfg.patch ** 2
    step = statistics.median(plain)
    prof_total = sum(r["wall"] for r in prof.rows.values()) / n
    lines = [f"### {name}", "",
             f"{rays} rays per step; Gaussians: " + ", ".join(f"{r} {len(s)}" for r, s in tr.sets.items()
                                                               if r not in tr.dropped)
             + f"; stage '{tr.stage()['name']}' (iteration {tr.it} of {tr.cfg.iterations}). Machine: {summary()}.", "",
             f"Unprofiled step: **{1e3 * step:.0f} ms** (median of {len(plain)}) = **{rays / step:.0f} rays/s**; "
             f"profiled (a sync between phases): {1e3 * prof_total:.0f} ms.", "",
             "| phase | ms / step | share | kernels ms | compile ms | host ms | launches / step |",
             "|---|---|---|---|---|---|---|"]
    for ph in PHASES:
        r = prof.rows.get(ph)
        if r is None:
            continue
        host = r["wall"] - r["exec"] - r["compile"]
        lines.append(f"| {ph} | {1e3 * r['wall'] / n:.1f} | {100 * r['wall'] / n / prof_total:.1f} % | "
                     f"{1e3 * r['exec'] / n:.1f} | {1e3 * r['compile'] / n:.1f} | {1e3 * host / n:.1f} | "
                     f"{r['launches'] / n:.1f} |")
    lines += ["", "| forward pass | Gaussians | hits / ray (mean, max) | as run ms | traversal only ms | traversal share |",
              "|---|---|---|---|---|---|"]
    for r in trav:
        lines.append(f"| {r['name']} | {r['gaussians']} | {r['hits_mean']:.1f}, {r['hits_max']} | {r['full_ms']:.1f} | "
                     f"{r['traversal_ms']:.1f} | {100 * r['traversal_ms'] / max(r['full_ms'], 1e-9):.0f} % |")
    walk = sum(r["traversal_ms"] for r in trav) / 1e3
    fwd = prof.rows["forward"]["wall"] / n
    passes = 1 if tr.cfg.stored_hits else 2
    how = ("the replay walks the stored hit lists (stored_hits)" if tr.cfg.stored_hits
           else "forward + replay, which re-traces every pass (stored_hits false)")
    lines += ["", f"BVH traversal: {1e3 * walk:.0f} ms in the forward ({100 * walk / max(fwd, 1e-9):.0f} % of it); "
              f"{how}: {1e3 * passes * walk:.0f} ms = **{100 * passes * walk / prof_total:.0f} % of the step**. "
              f"(Traversal-only timings run on their own and can exceed the pass as run by the timing noise.)", ""]
    if before_after:
        b, a = before_after["before"], before_after["after"]
        lines += ["Exact speed-ups without a config switch, off (before) and on (after), alternating blocks of steps in "
                  "this run: " + "; ".join(n for n, _, _ in SPEEDUPS if picked(n, only)) + ".", "",
                  "| | step ms | rays/s | x |", "|---|---|---|---|",
                  f"| before | {1e3 * b:.1f} | {rays / b:.0f} | 1.00 |",
                  f"| after | {1e3 * a:.1f} | {rays / a:.0f} | {b / a:.2f} |", ""]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default=str(ROOT / "scenes" / "glass_room" / "optimize.xml"))
    ap.add_argument("--run", help="profile a trained run folder (its checkpoint and config) instead of a fresh init")
    ap.add_argument("--preset", default="quick")
    ap.add_argument("--at", type=float, default=0.25, help="fresh init: profile from this fraction of the schedule "
                    "(0.25: joint stage, all sets traced, densifying)")
    ap.add_argument("--warm", type=int, default=3, help="steps run first (they compile the kernels)")
    ap.add_argument("--steps", type=int, default=20, help="steps timed unprofiled, and again profiled")
    ap.add_argument("--name", help="results name (default: the scene's or run's folder)")
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE", help="TrainConfig override")
    ap.add_argument("--ab", nargs="?", const="", default=None, metavar="NAME",
                    help="also time the exact speed-ups without a config switch (those whose name holds NAME, e.g. "
                    "'k-buffer', or several: 'list arrays,Adam'; all without it) off and on, in alternating blocks "
                    "of --steps steps")
    ap.add_argument("--banks", action="store_true", help="also time steps drawn from each of coarse_to_fine's banks "
                    "against the full-size one (the run's config must have coarse_to_fine, or give --set "
                    "coarse_to_fine=4:0.2,2:0.2)")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results"), help="results folder")
    ap.add_argument("--variant", help="Mitsuba variant (e.g. cuda_ad_rgb; default $GLINT_VARIANT or llvm_ad_rgb)")
    ap.add_argument("--targets", action="store_true", help="also measure issue 43's GPU targets (training rays/s "
                    "at --target-rays a step, a 480 x 270 view's fps, the paper's budget in minutes)")
    ap.add_argument("--target-rays", type=int, default=2 ** 20, help="rays a step for --targets (default 1,048,576)")
    args = ap.parse_args(argv)
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    quiet = lambda *a, **k: None
    tmp = tempfile.TemporaryDirectory()
    overrides = parse_sets(args.set)
    cfg = (TrainConfig.load(Path(args.run) / "config.json").replace(**overrides) if args.run
           else TrainConfig.for_preset(args.preset, **overrides))
    if args.banks and not cfg.pyramid():
        ap.error(f"--banks: the config has no coarse_to_fine ({cfg.coarse_to_fine!r}); add --set "
                 f"coarse_to_fine=4:0.2,2:0.2")
    if args.run:
        tr = Trainer(args.run, cfg, resume=True, log=quiet)
        name = args.name or Path(args.run).name
    else:
        spec = read_scene(args.scene)
        tr = Trainer(Path(tmp.name) / "run", cfg, scene=spec, log=quiet)
        tr.it = tr.cfg.at(args.at)
        name = args.name or Path(spec.dataset).name
    t0 = time.perf_counter()
    steps(tr, args.warm, None)
    print(f"{name}: {args.warm} warm-up steps (compiles) in {time.perf_counter() - t0:.1f} s", flush=True)
    it0 = tr.it
    plain = steps(tr, args.steps, None)
    tr.it = it0
    prof = Profiler()
    steps(tr, args.steps, prof)
    trav = traversal(tr)
    tr.it = it0
    before_after = ab(tr, args.steps, only=args.ab) if args.ab is not None else None
    text = markdown(name, tr, plain, prof, args.steps, trav, before_after, only=args.ab or "")
    bank_rows = banks(tr, args.steps) if args.banks else None
    if bank_rows is not None:
        text += "\n" + banks_markdown(tr, bank_rows)
    tgt = targets(tr, args.target_rays) if args.targets else None
    if tgt is not None:
        text += "\n" + targets_markdown(tgt)
    print(text)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / f"profile_step_{name}.md").write_text(text + "\n")
    (out / f"profile_step_{name}.json").write_text(json.dumps(
        {"name": name, **{k: v for k, v in describe().items() if k in ("variant", "device", "cpu", "cores")},
         "rays_per_step": tr.cfg.patches * tr.cfg.patch ** 2, "step_s": plain,
         "phases": {k: dict(v) for k, v in prof.rows.items()}, "steps": args.steps, "traversal": trav,
         "before_after_step_s": before_after, "targets": tgt, "banks": bank_rows,
         "gaussians": {r: len(s) for r, s in tr.sets.items() if r not in tr.dropped}}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
