"""The benchmark CLI on a tiny scene (two methods, table + CSV + figures that agree, no silent fallback) and the
benchmark and experiment scripts on trained tiny runs."""
import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import KBUFFER
from glint_mi.data import load_dataset
from glint_mi.dataset.generate import Preset, make_scene
from glint_mi.config import TrainConfig, flatten
from glint_mi.methods import METHODS, config_for
from glint_mi.scene import read_scene
from glint_mi.training.trainer import Trainer

from conftest import tiny_cfg

ROOT = Path(__file__).resolve().parent.parent


def test_methods_are_configurations():
    for name, m in METHODS.items():
        cfg = config_for(name, "tiny")
        for path, v in m.overrides.items():  # by path: layer.field
            layer, k = path.split(".")
            assert getattr(getattr(cfg, layer), k) == v, (name, path)
    assert config_for("3dgs", "tiny").kernel == "ellipsoid" and config_for("envgs", "tiny").blend == "envgs"
    # a method is checked when it is defined, not when it first runs
    from glint_mi.config import ConfigError
    from glint_mi.methods import Method
    with pytest.raises(ConfigError, match=r"method 'typo': unknown field\(s\) w_l2 \(did you mean w_l1\?\)"):
        Method("typo", {"w_l2": 1.0}, "a misspelled weight")
    with pytest.raises(ConfigError, match=r"method 'bad': 'max_hits' = 0: must be >= 1"):
        Method("bad", {"max_hits": 0}, "an impossible budget")


def test_prior_parity_rows_take_glints_inputs_and_weights():
    """3dgs-priors and 2dgs-priors (issue 44): their base method plus GLINT's prior terms with GLINT's weights,
    photometric ones included (the priors weigh as much against the photos as in GLINT); nothing else differs."""
    from glint_mi.config import TrainConfig

    glint = TrainConfig.for_preset("tiny")
    for row, base in (("3dgs-priors", "3dgs"), ("2dgs-priors", "2dgs")):
        a, b = config_for(row, "tiny"), config_for(base, "tiny")
        differ = {k for k, v in a.flat().items() if v != getattr(b, k)}
        assert differ == {"priors", "w_depth", "w_normal", "w_l1", "w_dssim", "prior_decay", "depth_prior_ref"}, \
            (row, differ)
        for k in differ:
            assert getattr(a, k) == getattr(glint, k), (row, k)


def test_benchmark_tiny(tmp_path):
    data = tmp_path / "data"
    make_scene(data / "scene_000", seed=1, preset=Preset.named("tiny", views=6, spp=16), sfm="none")
    out = tmp_path / "bench"
    cmd = [sys.executable, "-m", "glint_mi.benchmark", "--data", str(data), "--preset", "tiny", "--methods",
           "2dgs,envgs", "--iterations", "12", "--set", "eval_every=6", "--out", str(out)]
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    rows = list(csv.DictReader(open(out / "results.csv")))
    assert [(x["method"], x["scene"]) for x in rows] == [("2dgs", "scene_000"), ("envgs", "scene_000")]
    from glint_mi.machine import describe
    assert {(x["variant"], x["device"]) for x in rows} == {(describe()["variant"], describe()["device"])}
    table = (out / "table.md").read_text()
    assert f"runs trained on {describe()['device']} ({describe()['variant']});" in table  # from the runs' records
    for x in rows:  # the markdown table shows the CSV's numbers
        assert f"| {x['method']} | {float(x['fps']):.4g} | {float(x['train_s']):.4g} | {float(x['psnr']):.4g} |" \
            in table
    assert (out / "figures" / "scene_000.png").stat().st_size > 1000
    # no silent fallback: each run trained the sets its method asks for, with its blending
    for method, sets in (("2dgs", {"interface"}), ("envgs", {"interface", "reflection"})):
        run = out / "runs" / "scene_000" / method
        cfg = TrainConfig.load(run / "config.json").flat()
        for k, v in flatten(METHODS[method].overrides).items():
            assert cfg[k] == v, (method, k)
        assert set(json.loads((run / "report.json").read_text())["sizes"]) == sets
    # --set reaches every method: convergence curves at 6 and 12 iterations
    for method in ("2dgs", "envgs"):
        conv = list(csv.DictReader(open(out / "runs" / "scene_000" / method / "convergence.csv")))
        assert [int(c["iteration"]) for c in conv] == [6, 12]
    assert (out / "convergence.png").stat().st_size > 1000
    from glint_mi.benchmark import convergence_curves
    assert set(convergence_curves(out)) == {"2dgs / scene_000", "envgs / scene_000"}
    assert {k: len(v) for k, v in convergence_curves(out, "envgs", "x").items()} == {"x / scene_000": 2}
    bad = subprocess.run(cmd[:-2] + ["--set", "no_such_field=1", "--out", str(tmp_path / "x")], capture_output=True,
                         text=True, cwd=ROOT, timeout=600)
    assert bad.returncode == 2 and "no_such_field" in bad.stderr and not (tmp_path / "x" / "runs").exists()
    # finished runs are skipped on a rerun (resumable benchmark)
    mtime = (out / "runs" / "scene_000" / "envgs" / "metrics.json").stat().st_mtime
    r2 = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert r2.returncode == 0
    assert (out / "runs" / "scene_000" / "envgs" / "metrics.json").stat().st_mtime == mtime
    # an evaluation killed after one view leaves metrics.json marked interrupted: the rerun evaluates that run again
    # (every view) from its finished checkpoint without training it again, and the CSV holds the full mean
    run = out / "runs" / "scene_000" / "2dgs"
    full = json.loads((run / "metrics.json").read_text())
    part = {**full, "metrics": {**full["metrics"], "psnr": 1.0}, "views": full["views"][:1], "views_done": 1,
            "interrupted": True}
    (run / "metrics.json").write_text(json.dumps(part))
    conv = (run / "convergence.csv").read_text()
    r3 = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert r3.returncode == 0, r3.stderr[-3000:]
    again = json.loads((run / "metrics.json").read_text())
    assert "interrupted" not in again and again["views_done"] == again["views_total"] == full["views_total"]
    assert abs(again["metrics"]["psnr"] - full["metrics"]["psnr"]) < 0.05 and again["train_s"] == full["train_s"]
    assert (run / "convergence.csv").read_text() == conv  # not trained again
    row = next(x for x in csv.DictReader(open(out / "results.csv")) if x["method"] == "2dgs")
    assert abs(float(row["psnr"]) - full["metrics"]["psnr"]) < 0.05
    bad = subprocess.run(cmd[:-1] + [str(out), "--methods", "nerf"], capture_output=True, text=True, cwd=ROOT)
    assert bad.returncode == 2 and "unknown method" in bad.stderr


def test_results_with_seeds_give_mean_and_spread(tmp_path):
    """--seeds N: the CSV keeps one row per seed; the table shows the mean and the standard deviation per method."""
    from glint_mi.benchmark import COLUMNS, write_results

    rows = [{"method": m, "scene": "s", "seed": k, **{c: base + k for c in COLUMNS}}
            for m, base in (("glint", 10.0), ("3dgs", 20.0)) for k in (0, 1, 2)]
    text = write_results(rows, tmp_path)
    assert len(list(csv.DictReader(open(tmp_path / "results.csv")))) == 6
    assert "mean over seeds [0, 1, 2]" in text and "standard deviation over seeds" in text
    assert "| glint | 11 | 11 |" in text and "| 3dgs | 21 | 21 |" in text  # means of base + 0, 1, 2
    assert f"| glint | {0.8165:.4g} |" in text                              # population std of (0, 1, 2)
    one = write_results([r for r in rows if r["seed"] == 0], tmp_path)
    assert "standard deviation" not in one and "| glint | 10 |" in one


def test_seed_ids_add_seeds_to_a_study(tmp_path):
    """--seed-ids 1 trains seed 1 alone, in the folder --seeds 2 gives it, so its runs merge with seed 0's kept
    elsewhere; the prior maps are scored once; a bad list stops before anything is written."""
    from glint_mi.benchmark import job_list

    a, b = Path("d/scene_a"), Path("d/scene_b")
    jobs = job_list(["glint", "priors"], [a, b], [1], tmp_path)
    assert [(m, s.name, r.relative_to(tmp_path).as_posix(), k) for m, s, r, k in jobs] == [
        ("glint", "scene_a", "runs/scene_a/glint@seed1", 1), ("priors", "scene_a", "runs/scene_a/priors@seed1", 1),
        ("glint", "scene_b", "runs/scene_b/glint@seed1", 1), ("priors", "scene_b", "runs/scene_b/priors@seed1", 1)]
    two = job_list(["glint", "priors"], [a], [0, 1], tmp_path)
    assert [(m, r.name) for m, _, r, _ in two] == [("glint", "glint"), ("priors", "priors"), ("glint", "glint@seed1")]
    for spec in (["x"], [","], ["-1"], ["1", "--seeds", "2"]):  # the last: which seeds would be ambiguous
        r = subprocess.run([sys.executable, "-m", "glint_mi.benchmark", "--data", str(tmp_path), "--seed-ids", *spec,
                            "--out", str(tmp_path / "o")], capture_output=True, text=True, cwd=ROOT, timeout=120)
        assert r.returncode == 2 and "--seed-ids" in r.stderr and not (tmp_path / "o").exists(), (spec, r.stderr)


def test_table_shows_the_csv_numbers(tmp_path):
    """The table is rounded from the CSV's values, not from the raw ones: a value whose 4-digit rounding differs
    between the two (12.264996 -> CSV 12.265 -> 12.27, raw -> 12.26) failed a CI run."""
    from glint_mi.benchmark import COLUMNS, write_results

    write_results([{"method": "m", "scene": "s", "seed": 0, **{c: 12.264996 for c in COLUMNS}}], tmp_path)
    got = float(next(csv.DictReader(open(tmp_path / "results.csv")))["fps"])
    assert got == 12.265
    assert f"| m | {got:.4g} |" in (tmp_path / "table.md").read_text()


def test_mesh_reference_trade_error_falls_with_spp():
    """path's error against the high-spp reference must fall with spp (a warm-up render once left every timed render
    at 1 spp), and time must grow with it."""
    from glint_mi.tradeoff import mesh_reference_trade

    rows = mesh_reference_trade(spps=(1, 64), ref_spp=256, width=24, height=18, depths=(64,))
    path = {r["spp"]: r for r in rows if r["renderer"] == "path"}
    assert path[64]["rel_error"] < 0.6 * path[1]["rel_error"], path
    mesh = {r["spp"]: r for r in rows if r["renderer"] == "glint mesh mode"}
    assert mesh[64]["rel_error"] < mesh[1]["rel_error"], mesh


def test_pareto_front():
    from glint_mi.tradeoff import pareto
    rows = [{"train_s": 1, "psnr": 20}, {"train_s": 2, "psnr": 25}, {"train_s": 3, "psnr": 24},
            {"train_s": 2, "psnr": 25}, {"train_s": 0.5, "psnr": 10}]
    assert pareto(rows) == [True, True, False, True, True]
    mae = [{"train_s": 1, "normal_mae": 30}, {"train_s": 2, "normal_mae": 35}]
    assert pareto(mae, quality="normal_mae", higher_is_better=False) == [True, False]


@pytest.mark.slow
def test_tradeoff_script_tiny(tmp_path):
    r = subprocess.run([sys.executable, "benchmarks/bench_tradeoff.py", "--tiny", "--out", str(tmp_path)],
                       capture_output=True, text=True, cwd=ROOT, timeout=1800)
    assert r.returncode == 0, r.stderr[-3000:]
    rows = list(csv.DictReader(open(tmp_path / "training.csv")))
    by = {x["variant"]: x for x in rows}
    assert set(by) >= {"base", "iters x0.5", "iters x1", "train 1/1 res", "train 1/2 res"}
    # the base configuration appears in both groups and is trained once, first
    for v in ("iters x1", "train 1/1 res"):
        assert by[v]["trained_as"] == "base" and by[v]["psnr"] == by["base"]["psnr"]
    assert by["train 1/2 res"]["trained_as"] == "train 1/2 res"
    runs = tmp_path / "runs" / "glass_room" / "seed0"
    assert (runs / "base" / "metrics.json").exists() and not (runs / "resolution" / "train_1_1_res").exists()
    md = (tmp_path / "tradeoff.md").read_text()
    assert (tmp_path / "tradeoff.png").exists() and "glint mesh mode" in md and "| path | 3 |" in md
    assert md.count("| iters x1 |") == 0  # a reused run is not a row of its own in the summary


def test_tradeoff_summary_pairs_each_variant_with_its_own_base():
    """The change against the base is taken per (room, seed) - the room-to-room spread cancels - and a variant on a
    room without a base run (the glass-free twin) gets no change."""
    from glint_mi.tradeoff import summarise

    rows = [{"group": "base", "variant": "base", "room": "a", "seed": 0, "psnr": 30.0, "train_s": 100.0},
            {"group": "base", "variant": "base", "room": "b", "seed": 0, "psnr": 20.0, "train_s": 50.0},
            {"group": "g", "variant": "v", "room": "a", "seed": 0, "psnr": 29.0, "train_s": 50.0},
            {"group": "g", "variant": "v", "room": "b", "seed": 0, "psnr": 21.0, "train_s": "25"},
            {"group": "ng", "variant": "w", "room": "c", "seed": 0, "psnr": 10.0, "train_s": 1.0}]
    s = {x["variant"]: x for x in summarise(rows, keys=("psnr", "train_s"))}
    assert s["v"]["runs"] == 2 and s["v"]["psnr"] == 25.0 and (s["v"]["psnr_min"], s["v"]["psnr_max"]) == (21, 29)
    assert s["v"]["d_psnr"] == 0.0 and (s["v"]["d_psnr_min"], s["v"]["d_psnr_max"]) == (-1.0, 1.0)
    assert s["v"]["d_train_s"] == -37.5 and s["base"]["d_psnr"] == 0.0
    assert s["w"]["d_psnr"] != s["w"]["d_psnr"] and s["w"]["psnr"] == 10.0


def test_benchmark_on_a_local_ray_instance(tmp_path):
    """--ray local: the same runs as Ray tasks (2 CPUs each) on a Ray instance started here; results gathered in
    the same CSV, finished runs skipped on a rerun, an unreachable cluster refused in one line."""
    pytest.importorskip("ray")
    data = tmp_path / "data"
    make_scene(data / "scene_000", seed=1, preset=Preset.named("tiny", views=6, spp=16), sfm="none")
    out = tmp_path / "bench"
    cmd = [sys.executable, "-m", "glint_mi.benchmark", "--data", str(data), "--preset", "tiny", "--methods",
           "2dgs,3dgs", "--iterations", "6", "--out", str(out), "--ray", "local"]
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-3000:]
    assert "2 run(s) sent to Ray" in r.stdout
    rows = list(csv.DictReader(open(out / "results.csv")))
    assert [(x["method"], x["scene"]) for x in rows] == [("2dgs", "scene_000"), ("3dgs", "scene_000")]
    assert all(float(x["psnr"]) > 0 for x in rows)
    mtime = (out / "runs" / "scene_000" / "3dgs" / "metrics.json").stat().st_mtime
    assert subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=600).returncode == 0
    assert (out / "runs" / "scene_000" / "3dgs" / "metrics.json").stat().st_mtime == mtime
    bad = subprocess.run(cmd[:-1] + ["127.0.0.1:1"], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert bad.returncode == 2 and "cannot reach the Ray cluster at '127.0.0.1:1'" in bad.stderr


def test_budget_curve_compares_like_with_like(tmp_path):
    """benchmarks/budget_curve.py: per method, only the (room, seed) runs present at every budget count; a run found
    in two folders of one budget is taken from the first; the summary's mean and spread are those runs'."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import budget_curve

    head = "method,scene,seed,fps,train_s,psnr,normal_mae,absrel,ssim,normal_mae_glass,absrel_glass,t_iou,t_off_glass\n"
    row = lambda m, s, seed, psnr: f"{m},{s},{seed},1,100,{psnr},10,0.1,0.8,20,0.2,0.5,0.01\n"
    for name, text in {"a": row("glint", "r1", 0, 20) + row("glint", "r1", 1, 22) + row("glint", "r2", 0, 30),
                       "b": row("glint", "r1", 0, 99) + row("3dgs", "r1", 0, 21),
                       "c": row("glint", "r1", 0, 25) + row("glint", "r1", 1, 27) + row("3dgs", "r1", 0, 23)}.items():
        (tmp_path / name).mkdir()
        (tmp_path / name / "results.csv").write_text(head + text)
    assert budget_curve.main([f"3={tmp_path / 'a'},{tmp_path / 'b'}", f"10={tmp_path / 'c'}",
                              "--out", str(tmp_path / "o")]) == 0
    rows = list(csv.DictReader(open(tmp_path / "o" / "budget.csv")))
    assert sorted((r["method"], r["epochs"], r["scene"], r["seed"]) for r in rows) == [
        ("3dgs", "10.0", "r1", "0"), ("3dgs", "3.0", "r1", "0"), ("glint", "10.0", "r1", "0"), ("glint", "10.0", "r1", "1"),
        ("glint", "3.0", "r1", "0"), ("glint", "3.0", "r1", "1")]  # r2 only at 3 epochs; b's glint r1 is a's
    md = (tmp_path / "o" / "budget.md").read_text()
    assert "| glint | 3 | 2 | 21.00 (20.00-22.00) |" in md and "| 3dgs | 10 | 1 | 23.00 |" in md
    assert (tmp_path / "o" / "budget.png").stat().st_size > 0


def test_converge_table_finds_where_each_method_stopped_gaining():
    """benchmarks/converge_table.py's stopping rule: the smallest point within tol of its next doubling and its next
    capacity; a point flat in epochs whose next capacity was not run is taken as undecided in capacity (not called
    'still gaining'); a method whose every doubling gained is still gaining (at its largest budget, the smallest
    capacity flat to the next); without any doubling, undecided."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import converge_table

    caps = ["default", "grow", "wide"]
    pts = lambda d: {k: [{"psnr": v}] for k, v in d.items()}
    # flat in epochs and in capacity at (120, grow): stopped there, not at 60 (which still gains 1 dB)
    e, c, why = converge_table.stopped(pts({(60, "grow"): 30.0, (120, "grow"): 31.0, (240, "grow"): 31.1,
                                             (120, "wide"): 31.15}), caps, 0.2)
    assert (e, c) == (120, "grow") and why.startswith("stopped gaining") and "+0.10" in why and "wide +0.15" in why
    # a longer run ends lower (the 9801 baselines), the next capacity not run: undecided, at the point, said
    e, c, why = converge_table.stopped(pts({(120, "grow"): 34.21, (240, "grow"): 33.06}), caps, 0.2)
    assert (e, c) == (120, "grow") and why.startswith("undecided") and "-1.15" in why and "(wide) not run" in why
    # the largest capacity needs no next one: decided by its doubling alone
    e, c, why = converge_table.stopped(pts({(120, "wide"): 34.0, (240, "wide"): 34.1}), caps, 0.2)
    assert (e, c) == (120, "wide") and why.startswith("stopped gaining")
    # every doubling gains: still gaining, the best point taken
    e, c, why = converge_table.stopped(pts({(60, "wide"): 30.0, (120, "wide"): 31.0}), caps, 0.2)
    assert (e, c) == (120, "wide") and why.startswith("still gaining")
    e, c, why = converge_table.stopped(pts({(120, "grow"): 35.0}), caps, 0.2)
    assert (e, c) == (120, "grow") and why.startswith("undecided: no point")
    # still gaining in epochs, flat in capacity at the largest budget (glint-paper on 9801-9802): that budget at the
    # smaller capacity, not the larger one for its 0.07 dB; a capacity that still gains is not taken
    e, c, why = converge_table.stopped(pts({(60, "grow"): 35.76, (120, "grow"): 36.23, (120, "wide"): 36.30}), caps,
                                       0.2)
    assert (e, c) == (120, "grow") and why.startswith("still gaining in epochs") and "(wide) +0.07" in why
    e, c, why = converge_table.stopped(pts({(60, "grow"): 35.76, (120, "grow"): 36.23, (120, "wide"): 36.50}), caps,
                                       0.2)
    assert (e, c) == (120, "wide") and why.startswith("still gaining at every point")


def test_converge_table_only_reads_a_method_from_its_folders(tmp_path):
    """converge_table.gather with --only: GLINT's runs come from the named folders alone (its runs at a former default
    in the shared folders are left out, every other method's kept); a folder named in --only but in no spec is
    refused rather than silently missing."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import converge_table

    def run(folder, scene, method, psnr):
        d = tmp_path / folder / "runs" / scene / method
        d.mkdir(parents=True)
        (d / "metrics.json").write_text(json.dumps({"metrics": {"psnr": psnr}}))

    run("old", "r1", "glint", 30.0)
    run("old", "r1", "3dgs", 31.0)
    run("old", "r2", "glint", 29.0)
    run("new", "r1", "glint", 32.0)
    run("old120", "r1", "glint", 28.0)
    specs = [f"60:grow={tmp_path / 'new'},{tmp_path / 'old'}", f"120:grow={tmp_path / 'old120'}"]
    got = sorted((r["epochs"], r["method"], r["scene"], r["psnr"]) for r in converge_table.gather(specs))
    assert got == [(60.0, "3dgs", "r1", 31.0), (60.0, "glint", "r1", 32.0), (60.0, "glint", "r2", 29.0),
                   (120.0, "glint", "r1", 28.0)]
    only = converge_table.parse_only([f"glint={tmp_path / 'new'}"])
    got = sorted((r["epochs"], r["method"], r["scene"], r["psnr"]) for r in converge_table.gather(specs, only))
    assert got == [(60.0, "3dgs", "r1", 31.0), (60.0, "glint", "r1", 32.0)]
    with pytest.raises(SystemExit, match="in no EPOCHS:CAPACITY"):
        converge_table.gather(specs, converge_table.parse_only([f"glint={tmp_path / 'elsewhere'}"]))
    with pytest.raises(SystemExit, match="METHOD=FOLDER"):
        converge_table.parse_only(["glint"])


def test_converge_table_compares_glint_seed_by_seed():
    """converge_table.compare pairs GLINT with a method on (room, seed), gives the difference by seed and its paired
    standard error; seed_spread is how far a room moves with the seed alone. Hand-computed figures."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import converge_table

    row = lambda sc, sd, p: {"scene": sc, "seed": sd, "psnr": p, "psnr_glass": p - 3, "psnr_off_glass": p + 1,
                             "normal_mae": 10.0}
    g = [row("a", 0, 30.0), row("b", 0, 32.0), row("a", 1, 31.0), row("b", 1, 31.0)]
    o = [row("a", 0, 30.5), row("b", 0, 31.0), row("a", 1, 30.0), row("c", 1, 40.0)]  # c: GLINT has no such run
    c = converge_table.compare(g, o)
    assert c["n"] == 3 and c["wins"] == 2
    assert c["per_seed"] == {0: (0.25, 2), 1: (1.0, 1)}
    assert abs(c["mean"]["psnr"] - 0.5) < 1e-12 and abs(c["mean"]["psnr_glass"] - 0.5) < 1e-12
    assert abs(c["se"] - 0.8660254037844386 / 3 ** 0.5) < 1e-9  # stdev of (-0.5, 1, 1) over sqrt(3)
    assert converge_table.compare(g, [row("z", 0, 1.0)]) is None
    one = converge_table.compare(g, [{**row("a", 1, 30.0), "psnr_glass": 30.0}])  # higher overall, lower on glass
    assert (one["wins"], one["wins_glass"]) == (1, 0) and c["wins_glass"] == 2
    assert abs(converge_table.seed_spread(g) - 1.0) < 1e-12  # |31-30| and |31-32|
    assert converge_table.seed_spread([row("a", 0, 30.0)]) != converge_table.seed_spread([row("a", 0, 30.0)])  # nan


def test_profile_step_measures_the_gpu_targets(tmp_path):
    """benchmarks/profile_step.py --targets (issue 43's figures; the GPU runs it with --variant cuda_ad_rgb): the
    training rate at a given batch, a 480 x 270 view's render rate and the paper's budget at that rate, in the
    table and the JSON with the variant that ran them. With --banks, a row per coarse_to_fine bank (coarsest first)
    and the full-size one; without coarse_to_fine, --banks is refused before any step."""
    cmd = [sys.executable, str(ROOT / "benchmarks" / "profile_step.py"), "--preset", "tiny", "--steps", "2",
           "--warm", "1", "--targets", "--target-rays", "4096", "--variant", "llvm_ad_rgb", "--name", "t",
           "--out", str(tmp_path), "--banks", "--set", "coarse_to_fine=2:0.5"]
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    res = json.loads((tmp_path / "profile_step_t.json").read_text())
    t = res["targets"]
    assert res["variant"] == "llvm_ad_rgb" and t["rays_per_step"] == 4096
    assert t["train_rays_per_s"] == pytest.approx(4096 / t["step_s"])
    assert t["paper_budget_min"] == pytest.approx(60000 * 480 * 270 / t["train_rays_per_s"] / 60)
    assert 0 < t["render_fps_480x270"] < 1e4
    assert "| render, one 480 x 270 view |" in (tmp_path / "profile_step_t.md").read_text()
    assert [b["bank"] for b in res["banks"]] == ["1/2", "full size"]
    assert all(b["step_s"] > 0 and b["hits_mean"] > 0 and b["traversal_ms"] > 0 for b in res["banks"])
    assert "| 1/2 |" in (tmp_path / "profile_step_t.md").read_text()
    r = subprocess.run(cmd[:-2], capture_output=True, text=True, cwd=ROOT, timeout=900)
    assert r.returncode == 2 and "coarse_to_fine=" in r.stderr and "Traceback" not in r.stderr, r.stderr[-2000:]


def test_render_tradeoff_benchmark_on_a_trained_run(room, tmp_path):
    """benchmarks/bench_render_tradeoff.py renders one trained run with render-time variants: one row per variant,
    the base as `evaluate` renders it, Mitsuba's queries (the CUDA path) the same image model, dropping sets a
    different image; the summary's base is 1.00x and +0 dB."""
    import csv
    import sys as _sys

    _sys.path.insert(0, str(ROOT / "benchmarks"))
    import bench_render_tradeoff as brt

    tr = Trainer(tmp_path / "run", tiny_cfg(iterations=4, patches=4, components="all"),
                 scene=read_scene(room.parent / "scene.xml"), log=lambda *a: None)
    tr.train(progress=False)
    assert brt.main([str(tmp_path / "run"), "--reps", "1", "--variants", "2,7,8", "--out", str(tmp_path / "o")]) == 0
    rows = {r["variant"]: r for r in csv.DictReader(open(tmp_path / "o" / "render_tradeoff.csv"))}
    names = [v[0] for i, v in enumerate(brt.VARIANTS) if i in (0, 2, 7, 8)]
    assert list(rows) == names
    base, bvh, alone = (float(rows[n]["psnr"]) for n in (names[0], names[3], names[2]))
    assert abs(bvh - base) < 0.05 and abs(alone - base) > 0.01, (base, bvh, alone)
    assert float(rows[names[1]]["max_hits"]) == 64 and rows[names[3]]["traversal"] == "bvh"
    text = (tmp_path / "o" / "render_tradeoff.md").read_text()
    assert "| base (run's budget, all sets) |" in text and "| 1.00 |" in text and "+0.00" in text
    assert (tmp_path / "o" / "render_tradeoff.png").stat().st_size > 0
    (tmp_path / "o" / "render_tradeoff.md").unlink()
    assert brt.main(["--from-csv", "--out", str(tmp_path / "o")]) == 0  # re-summarised from the CSV alone
    assert (tmp_path / "o" / "render_tradeoff.md").read_text() == text


@pytest.mark.skipif(not KBUFFER, reason="counts the native k-buffer's lists: needs it built and an LLVM variant")
def test_list_use_counts_listed_and_composited_entries(room, tmp_path):
    """benchmarks/list_use.py: per set, the native lists' entries and the hits composited from them; a hit budget of
    2 composites fewer, and lists fewer (the k-buffer holds the budget)."""
    import sys as _sys

    _sys.path.insert(0, str(ROOT / "benchmarks"))
    import list_use

    tr = Trainer(tmp_path / "run", tiny_cfg(iterations=4, patches=4, components="all"),
                 scene=read_scene(room.parent / "scene.xml"), log=lambda *a: None)
    tr.train(progress=False)
    full = list_use.count_lists(tmp_path / "run", views=1)
    assert set(full) == {"interface", "transmission", "reflection"}, full
    for s in full.values():
        assert 0 < s["composited"] <= s["listed"] and s["rounds"] >= 1, full
    cfg = json.loads((tmp_path / "run" / "config.json").read_text())
    cfg["render"]["max_hits"] = 2
    (tmp_path / "run" / "config.json").write_text(json.dumps(cfg))
    cut = list_use.count_lists(tmp_path / "run", views=1)
    assert cut["interface"]["composited"] < full["interface"]["composited"], (cut, full)
    assert cut["interface"]["listed"] < full["interface"]["listed"], (cut, full)


def test_shell_mesh_walks_the_same_gaussians_on_triangles(room, tmp_path):
    """benchmarks/bench_shell_mesh.py: one row per set; the triangle shells (an icosahedron around each shell) are
    entered by at least the rays that enter the exact shells, and list most of the same Gaussians."""
    import sys as _sys

    _sys.path.insert(0, str(ROOT / "benchmarks"))
    import bench_shell_mesh

    tr = Trainer(tmp_path / "run", tiny_cfg(iterations=2, patches=4, components="all"),
                 scene=read_scene(room.parent / "scene.xml"), log=lambda *a: None)
    tr.train(progress=False)
    assert bench_shell_mesh.main(["--run", str(tmp_path / "run"), "--res", "24x16", "--reps", "1",
                                  "--name", "t", "--out", str(tmp_path / "o")]) == 0
    text = (tmp_path / "o" / "shell_mesh_t.md").read_text()
    rows = {r.split("|")[1].strip(): [c.strip() for c in r.split("|")[2:-1]] for r in text.splitlines()
            if r.startswith("| ") and "---" not in r and "set" not in r}
    assert set(rows) == {"interface", "transmission", "reflection"}, text
    for role, c in rows.items():
        exact, tri = (float(v) for v in c[4].split(","))
        assert exact > 0 and tri >= 0.95 * exact, (role, c)
        assert float(c[5].rstrip(" %")) >= 50.0, (role, c)


def test_glass_pixels_splits_the_glass_by_the_runs_transparency(room, tmp_path):
    """benchmarks/glass_pixels.py: on synthetic glass pixels, the run's and the prior's normal errors, the depth
    against the pane's and the share behind it, per subset (t > 0.5 and the rest); on a trained and evaluated run
    it reads the saved renders and counts every glass pixel of the test views once (``off_glass``: every other
    valid pixel once)."""
    import sys as _sys

    _sys.path.insert(0, str(ROOT / "benchmarks"))
    import glass_pixels

    from glint_mi.evaluate import evaluate

    z = np.array([0.0, 0.0, 1.0])
    tilt = np.array([np.sin(np.radians(30)), 0.0, np.cos(np.radians(30))])
    px = {"normal": np.array([z, z, tilt, tilt]), "prior": np.array([tilt, tilt, z, np.zeros(3)]),
          "gt_normal": np.array([z] * 4), "depth": np.array([1.0, 1.0, 1.5, 1.2]), "gt_depth": np.ones(4),
          "t": np.array([0.9, 0.6, 0.1, 0.5])}
    s = glass_pixels.glass_split(px)
    assert s["t>0.5"]["share"] == 0.5 and s["t<=0.5"]["share"] == 0.5
    assert s["t>0.5"]["normal"] == pytest.approx(0.0, abs=1e-4) and s["t<=0.5"]["normal"] == pytest.approx(30.0)
    assert s["t>0.5"]["prior_normal"] == pytest.approx(30.0)  # the pixel without a prior does not count
    assert s["t<=0.5"]["prior_normal"] == pytest.approx(0.0, abs=1e-4)
    assert s["t>0.5"]["behind"] == 0.0 and s["t<=0.5"]["behind"] == 1.0
    assert s["all"]["depth_ratio"] == pytest.approx(1.1)
    assert s["all"]["normal"] == pytest.approx(15.0)
    tr = Trainer(tmp_path / "run", tiny_cfg(iterations=2, patches=4, components="all"),
                 scene=read_scene(room.parent / "scene.xml"), log=lambda *a: None)
    tr.train(progress=False)
    evaluate(tr.integ_for_eval(), tr.eval_views(), tmp_path / "run", 0.0, **tr.eval_options())
    got = glass_pixels.run_pixels(tmp_path / "run")
    n_glass = sum(int(((v.load_gt()["glass"] > 0.5) & (v.load_gt()["depth"] > 0)).sum()) for v in tr.eval_views())
    assert n_glass > 0 and all(len(a) == n_glass for a in got.values())
    assert "| run/run | t>0.5 |" in glass_pixels.table([("run/run", glass_pixels.glass_split(got))])
    off = glass_pixels.run_pixels(tmp_path / "run", off_glass=True)  # the rest of the valid pixels, each once
    n_valid = sum(int((v.load_gt()["depth"] > 0).sum()) for v in tr.eval_views())
    assert all(len(a) == n_valid - n_glass for a in off.values()) and n_valid > n_glass
    # --reflection: k_s solved from the saved buffers; the image model holds in them (a small residual)
    ref = glass_pixels.reflection_share(tmp_path / "run")
    assert ref["glass"]["pixels"] == n_glass and ref["off"]["pixels"] == n_valid - n_glass
    for x in ref.values():
        assert x["residual"] < 0.05 and -0.05 <= x["median"] <= 1.05 and 0 <= x["over_0.1"] <= 1, ref
    assert "| run/run | off the glass (" in glass_pixels.reflection_table([("run/run", ref)])
    rng = np.random.default_rng(0)  # solve_ks on synthetic pixels: the k_s that made them, NaN where c_R = base
    c_i, c_r, c_t = (rng.uniform(0, 1, (5, 3)) for _ in range(3))
    t, ks = rng.uniform(0, 1, 5), np.array([0.0, 0.04, 0.3, 0.9, 0.5])
    base = (1 - t[:, None]) * c_i + t[:, None] * c_t
    c_r[4] = base[4]
    got, res = glass_pixels.solve_ks((1 - ks[:, None]) * base + ks[:, None] * c_r, c_i, c_r, c_t, t)
    assert np.allclose(got[:4], ks[:4], atol=1e-9) and np.isnan(got[4]) and np.abs(res[:4]).max() < 1e-9
    import contact_sheet  # benchmarks/contact_sheet.py on the same evaluated run: one row per test view

    sheet = contact_sheet.contact_sheet(tmp_path / "run", tmp_path / "sheet.png")
    from PIL import Image
    w, h = Image.open(sheet).size
    assert w > 800 and h > 100 * len(tr.eval_views()) * 0.5


def test_trade_off_variants_resume_finished_and_interrupted_runs(room, tmp_path):
    """evaluation.tradeoff.run_variants: a finished variant is read back, not trained; one whose evaluation was killed
    (metrics.json marked interrupted) is evaluated again from its finished checkpoint, not trained again."""
    from glint_mi.tradeoff import run_variants

    xml = room.parent / "scene.xml"
    kw = dict(iterations=4, patches=4, log_every=1000, eval_every=0)
    first = run_variants(xml, tmp_path / "o", {"base": {}}, "tiny", log=lambda *a: None, **kw)
    run = tmp_path / "o" / "base"
    ckpt = (run / "checkpoint.npz").stat().st_mtime_ns
    again = run_variants(xml, tmp_path / "o", {"base": {}}, "tiny", log=lambda *a: None, **kw)
    assert again == first and (run / "checkpoint.npz").stat().st_mtime_ns == ckpt
    m = json.loads((run / "metrics.json").read_text())
    (run / "metrics.json").write_text(json.dumps({**m, "metrics": {**m["metrics"], "psnr": 1.0}, "interrupted": True}))
    redone = run_variants(xml, tmp_path / "o", {"base": {}}, "tiny", log=lambda *a: None, **kw)
    assert redone[0]["psnr"] == pytest.approx(first[0]["psnr"], abs=0.05)
    assert redone[0]["train_s"] == first[0]["train_s"]
    assert "interrupted" not in json.loads((run / "metrics.json").read_text())
    assert (run / "checkpoint.npz").stat().st_mtime_ns == ckpt  # not trained again
    # killed after the last checkpoint, before the model was saved: the end of the run is finished, nothing trained
    (run / "model" / "scene.xml").unlink()
    (run / "metrics.json").write_text(json.dumps({**m, "interrupted": True}))
    ended = run_variants(xml, tmp_path / "o", {"base": {}}, "tiny", log=lambda *a: None, **kw)
    assert (run / "model" / "scene.xml").exists() and ended[0]["psnr"] == pytest.approx(first[0]["psnr"], abs=0.05)
    assert int(np.load(run / "checkpoint.npz")["iteration"]) == 4


def test_priors_row_scores_the_prior_maps_as_the_dataset_measured_them(room, tmp_path):
    """The benchmark's `priors` row: the normal prior read back into world space scores, per test view, the error
    that PRIORS.json recorded when the maps were written (measured in camera space, another code path); a wrong
    camera-to-world rotation would not."""
    from glint_mi.benchmark import score_priors

    res = score_priors(room, tmp_path / "priors")
    rec = json.loads((room / "priors" / "PRIORS.json").read_text())["views"]
    assert res["per_view"] and json.loads((tmp_path / "priors" / "metrics.json").read_text())["per_view"]
    for name, m in res["per_view"].items():
        assert m["normal_mae"] == pytest.approx(rec[name]["measured"]["normal_mae_deg"], abs=1e-3), name


def test_cue_accuracy_counts_the_cue_against_the_glass(room, rng):
    """benchmarks/cue_accuracy.py: with features seen through every glass pixel they land on (1.5x behind the
    surface the prior sees) and on the surface elsewhere, the cue is "seen through" on the glass and "opaque"
    off it, and the SfM depth term keeps none of the glass features; with every feature on the surface, the glass
    is "opaque" too (what a see-through estimator does to the cue)."""
    import json
    import sys

    from glint_mi.data.rays import pixel_rays

    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
    from cue_accuracy import cue_accuracy

    ds = load_dataset(room)
    rec = json.loads((room / "priors" / "PRIORS.json").read_text())["views"]
    affine = [[rec[v.name]["depth_scale"], rec[v.name]["depth_shift"]] for v in ds.train_views]

    def observations(behind: float):
        obs = {}
        for v in ds.train_views:
            gt = v.load_gt()
            ys, xs = np.nonzero(gt["depth"] > 0)
            k = rng.choice(len(xs), min(60, len(xs)), replace=False)
            xs, ys = xs[k], ys[k]
            d = pixel_rays(v, np.stack([xs, ys], -1))
            dist = gt["depth"][ys, xs] / (d @ (v.c2w[:3, :3] @ np.array([0, 0, 1.0])))
            dist = np.where(gt["glass"][ys, xs] > 0.5, behind * dist, dist)
            obs[v.name] = (np.stack([xs + 0.5, ys + 0.5], -1), v.c2w[:3, 3] + d * dist[:, None])
        return obs

    r = cue_accuracy(room, 0.05, 0.04, observations(1.5), affine)
    assert r["glass_share"] > 0.01
    assert r["through_on_glass"] > 3 * r["through_off_glass"] and r["opaque_off_glass"] > r["opaque_on_glass"]
    assert r["sfm_depth_behind_pane"] == 0 or r["sfm_depth_behind_pane"] < 0.2 * r["sfm_depth_glass_pixels"]
    flat = cue_accuracy(room, 0.05, 0.04, observations(1.0), affine)
    assert flat["through_on_glass"] < 0.1 and flat["opaque_on_glass"] > 0.5 * flat["opaque_off_glass"] > 0.1
    assert flat["opaque_on_glass"] > 5 * r["opaque_on_glass"]
    # --photo q: the shares above the q-quantile of the scored pixels, on and off the glass, add up to at most 1 - q
    q = cue_accuracy(room, 0.05, 0.04, observations(1.5), affine, photo=0.75)
    g = q["glass_share"]
    above = g * q["photo_above_on_glass"] + (1 - g) * q["photo_above_off_glass"]
    assert 0.1 < above <= 0.25 + 1e-3 and "photo_above_on_glass" not in r


def test_case_coverage_from_the_layout():
    """benchmarks/case_coverage.py (how the tuning room 7310 was chosen): shares in (0, 1], deterministic per seed
    (build_room and trajectory, the generator's own functions, with its seeds), and a case seen from 0.97 m (9503)
    fills more of the view than one from 2.2 m (7301): 0.76 and 0.14 measured."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from case_coverage import case_coverage
    near, far = case_coverage(9503), case_coverage(7301)
    assert 0 < far["coverage"] < near["coverage"] <= 1
    assert near["distance"] < far["distance"]
    assert case_coverage(9503) == near
    assert 0.6 < near["coverage"] and far["coverage"] < 0.3


def test_tuning_rule_judges_a_switch_by_the_written_rule(tmp_path):
    """benchmarks/tuning_rule.py: a room's figure is the mean over the seeds both folders finished; a PSNR gain of
    0.3 dB in all but one room passes only while the geometry stays within the bounds; a 0.6 deg normal gain in two
    of three rooms passes the geometry rule; one room decides nothing; an interrupted evaluation is not read; a room
    missing on one side is left out and named."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import tuning_rule

    base = dict(psnr=28.0, normal_mae=30.0, absrel=0.2, normal_mae_glass=40.0, absrel_glass=0.3, t_iou=0.3)

    def write(folder, room, seed, **delta):
        m = {k: v + delta.get(k, 0.0) for k, v in base.items()}
        d = tmp_path / folder / "runs" / f"scene_{room}" / ("glint" if seed == 0 else f"glint@seed{seed}")
        d.mkdir(parents=True)
        (d / "metrics.json").write_text(json.dumps({"metrics": m}))

    for room in ("1", "2", "3"):
        write("base", room, 0)
        write("base", room, 1, psnr=-1.0)                          # seed 1 only in the base: must not count
        write("gain", room, 0, psnr=0.4 if room != "3" else 0.35)
        write("costly", room, 0, psnr=0.5, normal_mae=0.6)          # PSNR bought with 0.6 deg of normals
        write("normals", room, 0, normal_mae=-0.9 if room != "3" else 0.1)
    write("base", "4", 0)                                           # no switch run in room 4
    write("gain", "1", 1, psnr=5.0)                                 # an interrupted evaluation: must not count
    (tmp_path / "gain" / "runs" / "scene_1" / "glint@seed1" / "evaluation_partial").mkdir()
    pairs = {r: tuning_rule.room_pair(tmp_path / "base", tmp_path / "gain", r, "glint") for r in "123"}
    assert all(p[2] == [0] for p in pairs.values()) and tuning_rule.room_pair(
        tmp_path / "base", tmp_path / "gain", "4", "glint") is None
    v = tuning_rule.judge(pairs, agree=2)
    assert v["psnr_rule"] and v["adopted"] and not v["geometry_rule"] and abs(v["dpsnr"] - 0.3833) < 1e-3
    costly = {r: tuning_rule.room_pair(tmp_path / "base", tmp_path / "costly", r, "glint") for r in "123"}
    assert not tuning_rule.judge(costly, agree=2)["adopted"]
    normals = {r: tuning_rule.room_pair(tmp_path / "base", tmp_path / "normals", r, "glint") for r in "123"}
    v = tuning_rule.judge(normals, agree=2)
    assert v["geometry_rule"] and v["improving"] == ["normal_mae"] and not v["psnr_rule"]
    assert not tuning_rule.judge(normals, agree=3)["geometry_rule"]
    one = tuning_rule.judge({"1": pairs["1"]}, agree=1)          # one room passes the PSNR rule but decides nothing
    assert one["psnr_rule"] and not one["enough"] and not one["adopted"]
    out = tmp_path / "rule.md"
    assert tuning_rule.main(["--rooms", "1,2,3,4", "--base", str(tmp_path / "base"), "--switch",
                             f"gain={tmp_path / 'gain'}", "--out", str(out)]) == 0
    text = out.read_text()
    assert "**Adopted.**" in text and "Left out (no seed finished in both folders): 4." in text
    # the check rule (--confirm): an adopted switch stays unless worse than the default it replaced by more than the
    # bounds; 0.6 deg of normals is over them, whatever the PSNR, and 0.1 dB lower with the geometry equal is not
    assert not tuning_rule.judge(costly, agree=2)["stays"] and tuning_rule.judge(normals, agree=2)["stays"]
    for r in "123":
        write("level", r, 0, psnr=-0.1)
        write("lower", r, 0, psnr=-0.35)
    assert tuning_rule.main(["--confirm", "--rooms", "1,2,3", "--base", str(tmp_path / "base"),
                             "--switch", f"level={tmp_path / 'level'}", "--switch", f"lower={tmp_path / 'lower'}",
                             "--out", str(out)]) == 0
    level, lower = out.read_text().split("### lower")
    assert "**Stays.**" in level and "**Reverts.**" in lower and "Adopted" not in level + lower
    # room-levels (ROOM@LEVEL fills {level}) and the floor: the priors' row in the base folder; the switch passes the
    # PSNR rule but its normals end over the priors' in one room-level, and a room-level without the floor's run fails
    for r, lvl in (("1", "a"), ("2", "a"), ("1", "b")):
        write(f"sw_{lvl}", r, 0)
        write(f"sw_{lvl}_on", r, 0, psnr=0.5)
        d = tmp_path / f"sw_{lvl}" / "runs" / f"scene_{r}" / "priors"
        d.mkdir(parents=True)
        worse = lvl == "b"  # the priors' normals better than the switch's there
        (d / "metrics.json").write_text(json.dumps({"metrics": {**base, "normal_mae": 25.0 if worse else 35.0}}))
    args = ["--rooms", "1@a,2@a,1@b", "--base", str(tmp_path / "sw_{level}"), "--switch",
            f"on={tmp_path / 'sw_{level}_on'}", "--out", str(out)]
    assert tuning_rule.main(args) == 0 and "**Adopted.**" in out.read_text() and "| 1@b |" in out.read_text()
    assert tuning_rule.main(args + ["--floor", "priors"]) == 0
    assert "**Not adopted.**" in out.read_text() and "**not met** in 1@b." in out.read_text()
    write("sw_b", "2", 0)
    write("sw_b_on", "2", 0, psnr=0.5)  # 2@b: no priors row there
    tuning_rule.main(["--rooms", "1@a,2@a,2@b", "--base", str(tmp_path / "sw_{level}"), "--switch",
                      f"on={tmp_path / 'sw_{level}_on'}", "--floor", "priors", "--out", str(out)])
    assert "**No `priors` run** for 2@b" in out.read_text() and "**Not adopted.**" in out.read_text()
    tuning_rule.main(["--confirm", "--rooms", "1@a,2@a,1@b", "--base", str(tmp_path / "sw_{level}"), "--switch",
                      f"on={tmp_path / 'sw_{level}_on'}", "--floor", "priors", "--out", str(out)])
    assert "**Reverts.**" in out.read_text()  # the check rule reads the floor too: over the priors in 1@b
    # --floor-mode no-farther: in 1@b the switch is over the priors (30 against 25) but no farther over them than the
    # base (30): met, the `under` reading named beside it; a switch farther over them there (30.2) is not
    nf = ["--floor", "priors", "--floor-mode", "no-farther"]
    assert tuning_rule.main(args + nf) == 0
    text = out.read_text()
    assert "**Adopted.**" in text and "met. Over `priors` at all (the `under` reading): 1@b." in text
    tuning_rule.main(["--confirm"] + args + nf)
    assert "**Stays.**" in out.read_text()
    for r, lvl in (("1", "a"), ("2", "a"), ("1", "b")):
        write(f"sw_{lvl}_far", r, 0, psnr=0.5, normal_mae=0.2)  # within the geometry bound: the PSNR rule passes
    tuning_rule.main(["--rooms", "1@a,2@a,1@b", "--base", str(tmp_path / "sw_{level}"), "--switch",
                      f"far={tmp_path / 'sw_{level}_far'}", "--out", str(out)] + nf)
    assert "**Not adopted.**" in out.read_text() and "**not met** in 1@b." in out.read_text()
    with pytest.raises(ValueError, match="--floor-mode 'over'"):
        tuning_rule.apply_floor({"adopted": True, "stays": True}, {}, {}, "priors", "over")
    with pytest.raises(SystemExit):  # a floor mode without a floor is refused, not ignored
        tuning_rule.main(args + ["--floor-mode", "no-farther"])


def test_gpu_budget_command_dry_run(tmp_path):
    """benchmarks/gpu_budget.py, the one-call GPU command of issue 65 (here on LLVM, a tiny room): the room rendered
    with the SfM points of the same room made elsewhere, a calibration that sets one epoch budget for every method,
    the three methods trained on it, and a table that names the variant, the budget and each run's Gaussians."""
    src = tmp_path / "sfm"
    r = subprocess.run([sys.executable, "-m", "glint_mi.dataset", "make", str(src), "--seed", "21", "--preset", "tiny",
                        "--size", "40x24", "--views", "6", "--spp", "2", "--priors", "none"], capture_output=True,
                       text=True, cwd=ROOT, timeout=600)
    assert r.returncode == 0, r.stderr
    scene = src / "scene_021"
    meta = json.loads((scene / "meta.json").read_text())
    # a stand-in for --sfm known (pycolmap takes a minute): points inside the room, the mode recorded
    rng = np.random.default_rng(0)
    lo, hi = np.array(meta["case_lo"]) - 1.0, np.array(meta["case_hi"]) + 1.0
    pts = rng.uniform(lo, hi, (300, 3))
    (scene / "sparse" / "0" / "points3D.txt").write_text(
        "".join(f"{i + 1} {x:.4f} {y:.4f} {z:.4f} 128 128 128 0.5\n" for i, (x, y, z) in enumerate(pts)))
    (scene / "meta.json").write_text(json.dumps({**meta, "sfm": {"mode": "known", "points3D": 300}}))
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "benchmarks/gpu_budget.py", "--sfm", str(src), "--seed", "21", "--scenes", "1",
                        "--size", "40x24", "--views", "6", "--spp", "4", "--minutes", "1.5", "--calibrate", "4",
                        "--preset", "tiny", "--methods", "glint,3dgs", "--out", str(out)], capture_output=True,
                       text=True, cwd=ROOT, timeout=600)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    md = (out / "gpu_budget.md").read_text()
    assert "variant llvm_ad_rgb" in md and "epochs** a run" in md
    rows = list(csv.DictReader(open(out / "results.csv")))
    assert {x["method"] for x in rows} == {"glint", "3dgs"} and all(int(x["gaussians"]) > 0 for x in rows)
    cfg = json.loads((out / "bench" / "runs" / "scene_021" / "glint" / "config.json").read_text())
    budget = float(md.split("**")[1].split()[0])
    assert cfg["run"]["epochs"] == budget and cfg["densify"]["densify_top"] == 0.12


def test_sweep_table_labels_levels_and_folders(tmp_path):
    """benchmarks/sweep_table.py: one row per level and run label (a folder given with :SUFFIX labels its runs
    METHOD+SUFFIX), the mean over the rooms that run finished, seeds other than 0 and rooms not asked for left out."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import sweep_table

    def write(folder, room, method, **m):
        d = tmp_path / folder / "runs" / f"scene_{room}" / method
        d.mkdir(parents=True)
        (d / "metrics.json").write_text(json.dumps({"metrics": m}))

    write("a", 1, "glint", psnr=30.0, t_iou=0.5)
    write("a", 2, "glint", psnr=32.0, t_iou=0.7)
    write("a", 3, "glint", psnr=99.0)                        # a room not asked for
    write("a", 1, "glint@seed1", psnr=99.0)                  # another seed
    write("a", 1, "priors", normal_mae=20.0)
    write("a_pp", 1, "glint", psnr=31.0)
    data = sweep_table.gather([f"1.0={tmp_path / 'a'},{tmp_path / 'a_pp'}:pp"], ["scene_1", "scene_2"])
    assert sorted(data["1.0"]) == ["glint", "glint+pp", "priors"]
    text = sweep_table.table(data)
    assert "| 1.0 | glint | 2 | 31.00 |" in text and "| 1.0 | glint+pp | 1 | 31.00 |" in text
    assert "| 1.0 | priors | 1 | - |" in text and "0.60" in text  # t IoU: the mean of 0.5 and 0.7
    rows = sweep_table.table(data, by_room=True)
    assert "| 1.0 scene_1 | glint | 1 | 30.00 |" in rows and "| 1.0 scene_2 | glint | 1 | 32.00 |" in rows
    assert "| 1.0 scene_2 | glint+pp |" not in rows
    with pytest.raises(SystemExit, match="LEVEL=FOLDER"):
        sweep_table.gather(["1.0"], None)
    missing = []  # a folder not there yet: named, not read
    assert sweep_table.gather([f"1.0={tmp_path / 'later'}:x,{tmp_path / 'a'}"], None, missing)["1.0"]["glint"]
    assert missing == [str(tmp_path / "later")]
    with pytest.raises(SystemExit, match="holds neither"):
        sweep_table.gather([f"1.0={tmp_path / 'later'}"], None)
    # the floor plot: each run's geometry against the priors row's, per room and level (the priors' copies left out)
    write("a_pp", 1, "priors", normal_mae=20.0)
    data = sweep_table.gather([f"1.0={tmp_path / 'a'},{tmp_path / 'a_pp'}:pp"], ["scene_1"])
    data["1.0"]["glint"]["scene_1"]["normal_mae"] = 18.0
    pts = sweep_table.floor_plot(data, tmp_path / "floor.png")
    assert pts["normal_mae"]["glint"] == [(20.0, 18.0)] and "priors+pp" not in pts["normal_mae"]
    del data["1.0"]["priors"]  # every folder given with a suffix: the reference is its copy
    assert sweep_table.floor_plot(data, tmp_path / "floor.png")["normal_mae"]["glint"] == [(20.0, 18.0)]
    assert (tmp_path / "floor.png").stat().st_size > 10_000
    # the floor count under the table: at or under in how many room-levels, and which are over
    data = sweep_table.gather([f"1.0={tmp_path / 'a'}"], ["scene_1"])
    data["1.0"]["glint"]["scene_1"].update(normal_mae=20.0, absrel=0.06)  # at the priors' normals: not over
    data["1.0"]["priors"]["scene_1"]["absrel"] = 0.05
    line = sweep_table.floor_summary(data)
    assert "normals at or under in 1 of 1;" in line and "AbsRel at or under in 0 of 1, over at 1.0 scene_1 " \
        "(0.0600 against 0.0500)" in line and "priors`:" in line and "- `priors`" not in line
    data["1.0"]["glint"]["scene_1"]["absrel"] = 0.04
    assert sweep_table.floor_summary(data).endswith("AbsRel at or under in 1 of 1")


def test_densify_bump_reads_the_loss_around_densify_steps_and_leaves_resets_out(tmp_path):
    """benchmarks/densify_bump.py: the mean loss of the window after each densify step against the window up to it;
    a step next to an opacity reset is left out."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from densify_bump import densify_rises, main

    loss = np.full(60, 1.0)
    loss[10:20] = 1.5  # after the step at iteration 9 (iterations 10..19)
    loss[40:50] = 3.0  # after the step at 39, which sits next to a reset at 41
    with open(tmp_path / "log.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["iteration", "total"])
        w.writerows([i, loss[i]] for i in range(60))
    events = [{"iteration": 9, "what": "densify"}, {"iteration": 39, "what": "densify"},
              {"iteration": 41, "what": "reset"}]
    (tmp_path / "report.json").write_text(json.dumps({"events": events}))
    assert densify_rises(tmp_path, window=10) == [(9, 1.0, 1.5)]
    assert main([str(tmp_path)]) == 0
    assert main([str(tmp_path / "missing")]) == 2


def test_step_rate_reads_a_runs_own_step_times_from_its_log(tmp_path):
    """benchmarks/step_rate.py: the median rays/s over an iteration range, the steps' seconds summed (rays a step
    from config.json over rays_per_s), the loss at the last iteration; a run without its files is refused."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from step_rate import main, read_rates, summary

    (tmp_path / "config.json").write_text(json.dumps({"run": {"patches": 4, "patch": 5}}))
    with open(tmp_path / "log.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["iteration", "total", "rays_per_s"])
        w.writerows([i, 1.0 / (i + 1), 100.0 if i < 5 else 50.0] for i in range(10))  # 1 s, then 2 s a step
    rates = read_rates(tmp_path)
    assert rates[0] == (100.0, 1.0, 100)
    s = summary(rates, 3, 9, split=5)
    assert s["median_rays_per_s"] == 50.0  # iterations 3..9: two at 100, five at 50
    assert s["step_s"] == 5 * 1.0 + 5 * 2.0 and s["step_s_split"] == 5 * 2.0
    assert s["loss"] == 0.1
    with pytest.raises(ValueError, match="no logged iteration"):
        summary(rates, 20, 30)
    assert main([str(tmp_path), "--from", "3", "--split", "5"]) == 0
    assert main([str(tmp_path)]) == 2  # --from 300 past the last iteration (9): refused, not an empty median
    assert main([str(tmp_path / "missing")]) == 2


def test_train_view_depth_scores_a_run_against_the_priors_it_read(room, tmp_path, monkeypatch):
    """benchmarks/train_view_depth.py: a finished run rendered at its training views, scored with the benchmark's
    AbsRel against the same views' depth priors aligned as the priors row aligns them (a helper the row shares).
    With each view's affine the generator recorded, the prior's figure is that of the map file inverted by hand;
    a run whose depth is the aligned prior ties it in every view; one whose
    depth is the ground truth scores 0 and is worse nowhere; a view without an SfM fit is left out, not fitted to
    the truth."""
    import glint_mi.evaluation.renders as E
    from glint_mi.benchmark import aligned_prior_depth
    from glint_mi.training.batch import RayBank

    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
    import train_view_depth as T

    rec = json.loads((room / "priors" / "PRIORS.json").read_text())["views"]

    def recorded(self, points, nan_first=False, **kw):  # the tiny room has too few SfM points a view for the fit
        self.depth_affine = np.array([[rec[v.name]["depth_scale"], rec[v.name]["depth_shift"]] for v in self.views])
        if nan_first:
            self.depth_affine[0] = np.nan

    run = tmp_path / "run"
    Trainer(run, tiny_cfg(iterations=4, patches=4), scene=read_scene(room.parent / "scene.xml"),
            log=lambda *a: None).train(progress=False)
    monkeypatch.setattr(RayBank, "align_depth_priors", recorded)
    got = T.train_view_depth(run)
    ds = load_dataset(room)
    assert [r["view"] for r in got["views"]] == [v.name for v in ds.train_views] and not got["left_out"]
    for r in got["views"]:
        assert np.isfinite(r["run"]["absrel"])
        p = np.load(room / "priors" / "depth" / f"{r['view']}.npy").astype(np.float64)  # the map as written
        gt = next(v for v in ds.train_views if v.name == r["view"]).load_gt()["depth"]
        z = (p - rec[r["view"]]["depth_shift"]) / rec[r["view"]]["depth_scale"]
        m = (gt > 0) & (p > 0)
        assert r["prior"]["absrel"] == pytest.approx(np.mean(np.abs(z[m] - gt[m]) / gt[m]), rel=1e-6), r
    assert "| " + str(run) + " | 7 (0 without an SfM fit) | " in T.table([(str(run), got)])
    # planted depths: the run's renders replaced by the aligned prior, then by the ground truth
    bank = RayBank(ds.train_views, ds.root)
    bank.align_depth_priors(ds.points)
    by_name = {v.name: i for i, v in enumerate(ds.train_views)}
    real = E.render_view

    def planted(kind):
        def render(integ, view, **kw):
            out = real(integ, view, **kw)
            gt = view.load_gt()
            out["depth"] = aligned_prior_depth(bank, by_name[view.name], gt["depth"])[0] if kind == "prior" \
                else gt["depth"]
            return out
        return render

    monkeypatch.setattr(E, "render_view", planted("prior"))
    same = T.train_view_depth(run)
    assert same["worse"] == 0 and all(r["run"]["absrel"] == r["prior"]["absrel"] for r in same["views"])
    monkeypatch.setattr(E, "render_view", planted("truth"))
    exact = T.train_view_depth(run)
    assert exact["run"]["absrel"] == 0 and exact["worse"] == 0 and exact["prior"]["absrel"] > 0
    monkeypatch.setattr(RayBank, "align_depth_priors", lambda self, pts: recorded(self, pts, nan_first=True))
    assert T.train_view_depth(run)["left_out"] == [ds.train_views[0].name]
    # --photo: the photometric fit at the training views (every one; the photos planted, off by 0.01 off the glass and
    # 0.1 on it: 40 and 20 dB, no pixel of the tiny room clipping) beside the test views' figures (metrics.json)
    test = {"psnr": 20.0, "psnr_glass": 18.0, "psnr_off_glass": 21.0}
    (run / "metrics.json").write_text(json.dumps({"metrics": test}))
    seen = []

    def photo(err):
        def render(integ, view, **kw):
            out = real(integ, view, **kw)
            seen.append(view.name)
            out["rgb"] = view.load_image() + np.where(view.load_gt()["glass"] > 0.5, err, 0.01)[..., None]
            return out
        return render

    monkeypatch.setattr(E, "render_view", photo(0.1))
    fit = T.train_view_photo(run)
    assert seen == [v.name for v in ds.train_views] and fit["views"] == len(ds.train_views)
    assert fit["test"] == test
    assert fit["train"]["psnr_off_glass"] == pytest.approx(40.0), fit
    assert fit["train"]["psnr_glass"] == pytest.approx(20.0), fit
    assert fit["train"]["psnr_off_glass"] > fit["train"]["psnr"] > fit["train"]["psnr_glass"]
    row = T.photo_table([("r", fit)]).splitlines()[-1]
    assert f"| {fit['train']['psnr_glass']:.2f} / 18.00 |" in row
    assert f"| {fit['train']['psnr_glass'] - 18:.2f} / " in row
