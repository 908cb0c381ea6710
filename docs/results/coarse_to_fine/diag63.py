"""The sixty-third session's diagnosis table (README, "What costs GLINT against `3dgs` at 40 epochs of 96 x 54"):
each arm of s63d.sh against GLINT at today's preset (the committed base runs) and `3dgs` (groups/w62_3dgs_p27), per
tuning room and as the mean; the share of the base's gap to `3dgs` each arm closes.

    python docs/results/coarse_to_fine/diag63.py RUNS [--arms copy,noterms,el,iface] [--tag d63] [--out FILE]
    python docs/results/coarse_to_fine/diag63.py RUNS --check [--out FILE]
    python docs/results/coarse_to_fine/diag63.py RUNS --ladder i_el,i_copy,i_photo,i_cons [--out FILE]
    python docs/results/coarse_to_fine/diag63.py RUNS --check-arm el [--tag d63] [--out FILE]
    python docs/results/coarse_to_fine/diag63.py RUNS --weights [--plot PNG] [--out FILE]
    python docs/results/coarse_to_fine/diag63.py RUNS --seeds agree_n --tag d66 [--check-rooms] [--out FILE]
    python docs/results/coarse_to_fine/diag63.py RUNS --trade [--plot PNG] [--out FILE]

RUNS holds the arms' folders d63_<arm>/ (--tag: another session's prefix; the benchmark's output, or groups/ here,
their small files); a missing run is reported as not run. --check: on the check rooms 9801-9803, GLINT at today's
preset (groups/t61_min27) against `3dgs` (RUNS/d63_3dgs). --ladder: the sixty-fourth session's steps (RUNS/d64_<step>,
cumulative) from GLINT's interface alone (RUNS/d63_iface) to `3dgs`, each step's gain over the one before it and its
share of the interface's gap to `3dgs`; the last row, the step from the ladder's last rung to `3dgs`. --check-arm ARM:
on 9801-9803, an arm (RUNS/d63_<arm>) against GLINT at today's preset and `3dgs` there. --weights: the sixty-fifth
session's curve of the prior terms' weight (0: RUNS/d63_noterms, 0.25: RUNS/d65_quarter, 0.5: RUNS/d65_half, 1: the
base) per tuning room, against the base, `3dgs` and the priors (RUNS/d63_priors); --plot draws it. --seeds ARM: the
sixty-sixth session's second seed, an arm beside the base and `3dgs` at seeds 0 and 1 (--check-rooms: on 9801-9803,
the sixty-ninth session's). --trade: every arm run on the
whole of GLINT at seed 0 on the three tuning rooms (TRADE), its mean PSNR against its mean normals and AbsRel, beside
`3dgs` and the priors; --plot draws it."""
import argparse
import json
from pathlib import Path

from glint_mi.runs import finished_metrics

HERE = Path(__file__).resolve().parent
ROOMS = ("7301", "7302", "7303")
BASE = {"7301": HERE.parent / "prior_sweep/groups/b62_realistic_e1_7301",
        "7302": HERE.parent / "prior_sweep/groups/b62_realistic_e1_7302",
        "7303": HERE / "groups/t56_min27"}
REF = HERE / "groups/w62_3dgs_p27"
CHECK_ROOMS = ("9801", "9802", "9803")
COLS = ("psnr", "psnr_glass", "psnr_off_glass", "normal_mae", "absrel", "t_iou")


def read(folder: Path, room: str, method: str) -> dict | None:
    """One seed-0 run's metrics, Gaussians per set and minutes; None where its evaluation has not finished."""
    run = folder / "runs" / f"scene_{room}" / method
    m = finished_metrics(run)
    if m is None:
        return None
    report = run / "report.json"  # a priors row trains nothing and has none
    sizes = json.loads(report.read_text()).get("sizes", {}) if report.exists() else {}
    return {**{k: m["metrics"].get(k) for k in COLS}, "sizes": sizes, "minutes": m.get("train_s", 0) / 60}


def fmt(r: dict | None) -> str:
    if r is None:
        return "not run | | | | | |"
    t = "-" if r["t_iou"] is None or list(r["sizes"]) == ["interface"] else f"{r['t_iou']:.2f}"  # no t to find
    sizes = "/".join(f"{v / 1000:.1f}" for v in r["sizes"].values())
    return (f"{r['psnr']:.2f} / {r['psnr_glass']:.2f} / {r['psnr_off_glass']:.2f} | {r['normal_mae']:.2f} | "
            f"{r['absrel']:.4f} | {t} | {sizes}k | {r['minutes']:.1f}")


def per_room(rooms, rows: dict, what: str = "run", sizes: str = "Gaussians (sets)") -> list[str]:
    """The per-room table: each room, each row of ``rows`` ({name: {room: read(...)}})."""
    lines = [f"| room | {what} | PSNR all / glass / off | normals | AbsRel | t IoU | {sizes} | minutes |",
             "|---|---|---|---|---|---|---|---|"]
    for room in rooms:
        lines += [f"| {room} | {name} | {fmt(runs[room])} |" for name, runs in rows.items()]
    return lines


def tagged(a) -> str:
    """The --tag flag as the printed command gives it (none for the default d63)."""
    return f" --tag {a.tag}" if a.tag != "d63" else ""


def over_priors(runs: dict, priors: dict, rooms, key: str) -> int:
    """How many of ``rooms`` the run ends over its priors' row in ``key`` (normal_mae, absrel)."""
    return sum(priors[r] is not None and runs[r][key] > priors[r][key] for r in rooms)


def emit(a, flag: str, lines: list[str]) -> None:
    """Print the table and, with --out, write it under the command that made it."""
    text = "\n".join(lines) + "\n"
    print(text, end="")
    if a.out:
        a.out.write_text(f"`python docs/results/coarse_to_fine/diag63.py {a.runs} {flag}`\n\n" + text)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", type=Path)
    ap.add_argument("--arms", default="copy,noterms,el,iface")
    ap.add_argument("--out", type=Path)
    ap.add_argument("--tag", default="d63", help="the arms' folder prefix for --arms and --check-arm (RUNS/<tag>_<arm>;"
                    " the sixty-sixth session's: d66)")
    ap.add_argument("--check", action="store_true", help="GLINT against `3dgs` on 9801-9803")
    ap.add_argument("--ladder", help="the ladder's steps in order, e.g. i_el,i_copy,i_photo,i_cons")
    ap.add_argument("--check-arm", help="an arm on 9801-9803 against GLINT at today's preset and `3dgs`")
    ap.add_argument("--weights", action="store_true", help="the prior terms' weight curve on the tuning rooms")
    ap.add_argument("--seeds", help="an arm (RUNS/<tag>_<arm>) at seeds 0 and 1 beside the base (seed 1: "
                    "RUNS/d66_base) and `3dgs` (seed 1: RUNS/d63_3dgs), each seed and their mean")
    ap.add_argument("--check-rooms", action="store_true", help="with --seeds: on 9801-9803 (seed 0 of the base: "
                    "groups/t61_min27; of `3dgs`: RUNS/d63_3dgs)")
    ap.add_argument("--trade", action="store_true", help="every whole-GLINT arm's PSNR against its geometry")
    ap.add_argument("--plot", type=Path, help="with --weights or --trade: draw it into this PNG")
    a = ap.parse_args()
    if a.check:
        return check(a)
    if a.check_arm:
        return check_arm(a)
    if a.weights:
        return weights(a)
    if a.seeds:
        return seeds(a)
    if a.trade:
        return trade(a)
    if a.ladder:
        return ladder(a)
    arms = a.arms.split(",")
    rows = {"`3dgs` (today's preset)": {r: read(REF, r, "3dgs") for r in ROOMS},
            "GLINT, today's preset": {r: read(BASE[r], r, "glint") for r in ROOMS}}
    rows.update({f"`{arm}`": {r: read(a.runs / f"{a.tag}_{arm}", r, "glint") for r in ROOMS} for arm in arms})
    lines = per_room(ROOMS, rows)
    lines += ["", "| mean of the rooms each ran | PSNR all / glass / off | against the base | share of the gap to "
              "`3dgs` closed | normals | AbsRel | rooms |", "|---|---|---|---|---|---|---|"]
    ref, base = rows["`3dgs` (today's preset)"], rows["GLINT, today's preset"]
    for name, runs in rows.items():
        done = [r for r in ROOMS if runs[r] is not None and base[r] is not None and ref[r] is not None]
        if not done:
            lines.append(f"| {name} | not run | | | | | 0 |")
            continue
        mean = {k: sum(runs[r][k] for r in done) / len(done) for k in COLS[:5]}
        d = {k: sum(runs[r][k] - base[r][k] for r in done) / len(done) for k in COLS[:3]}
        gap = sum(ref[r]["psnr"] - base[r]["psnr"] for r in done) / len(done)
        share = f"{d['psnr'] / gap:+.0%}" if abs(gap) > 1e-9 else "-"
        lines.append(f"| {name} | {mean['psnr']:.2f} / {mean['psnr_glass']:.2f} / {mean['psnr_off_glass']:.2f} | "
                     f"{d['psnr']:+.2f} / {d['psnr_glass']:+.2f} / {d['psnr_off_glass']:+.2f} | {share} | "
                     f"{mean['normal_mae']:.2f} | {mean['absrel']:.4f} | {len(done)} |")
    emit(a, f"--arms {a.arms}" + tagged(a), lines)


def ladder(a) -> None:
    steps = a.ladder.split(",")
    rungs = {"`iface` (GLINT's interface alone)": {r: read(a.runs / "d63_iface", r, "glint") for r in ROOMS}}
    rungs.update({f"`{s}`": {r: read(a.runs / f"d64_{s}", r, "glint") for r in ROOMS} for s in steps})
    rungs["`3dgs`"] = {r: read(REF, r, "3dgs") for r in ROOMS}
    lines = per_room(ROOMS, rungs, what="rung", sizes="Gaussians")
    names = list(rungs)
    first, last = rungs[names[0]], rungs[names[-1]]
    lines += ["", "| step to | PSNR all / glass / off over the rung before | per room | share of `iface`'s gap to "
              "`3dgs` | normals | AbsRel | rooms |", "|---|---|---|---|---|---|---|"]
    for before, name in zip(names, names[1:]):
        prev, runs = rungs[before], rungs[name]
        done = [r for r in ROOMS if runs[r] is not None and prev[r] is not None]
        if not done:
            lines.append(f"| {name} | not run | | | | | 0 |")
            continue
        d = {k: sum(runs[r][k] - prev[r][k] for r in done) / len(done) for k in COLS[:3]}
        gap = sum(last[r]["psnr"] - first[r]["psnr"] for r in done) / len(done)
        share = f"{d['psnr'] / gap:+.0%}" if abs(gap) > 1e-9 else "-"
        per = ", ".join(f"{runs[r]['psnr'] - prev[r]['psnr']:+.2f}" for r in done)
        geo = {k: sum(runs[r][k] for r in done) / len(done) for k in ("normal_mae", "absrel")}
        lines.append(f"| {name} | {d['psnr']:+.2f} / {d['psnr_glass']:+.2f} / {d['psnr_off_glass']:+.2f} | {per} | "
                     f"{share} | {geo['normal_mae']:.2f} | {geo['absrel']:.4f} | {len(done)} |")
    emit(a, f"--ladder {a.ladder}", lines)


def check_arm(a) -> None:
    rows = {"GLINT, today's preset": {r: read(HERE / "groups/t61_min27", r, "glint") for r in CHECK_ROOMS},
            f"`{a.check_arm}`": {r: read(a.runs / f"{a.tag}_{a.check_arm}", r, "glint") for r in CHECK_ROOMS},
            "`3dgs` (today's preset)": {r: read(a.runs / "d63_3dgs", r, "3dgs") for r in CHECK_ROOMS}}
    lines = per_room(CHECK_ROOMS, rows)
    base, arm, ref = rows.values()
    done = [r for r in CHECK_ROOMS if all(x[r] is not None for x in (base, arm, ref))]
    lines += ["", f"| mean of the rooms `{a.check_arm}` ran | PSNR all / glass / off | against the base | per room | "
              "against `3dgs` | normals | AbsRel | rooms |", "|---|---|---|---|---|---|---|---|"]
    if done:
        mean = lambda runs, k: sum(runs[r][k] for r in done) / len(done)
        for name, runs in rows.items():
            lines.append(f"| {name} | " + " / ".join(f"{mean(runs, k):.2f}" for k in COLS[:3]) + " | "
                         + " / ".join(f"{mean(runs, k) - mean(base, k):+.2f}" for k in COLS[:3]) + " | "
                         + ", ".join(f"{runs[r]['psnr'] - base[r]['psnr']:+.2f}" for r in done) + " | "
                         + " / ".join(f"{mean(runs, k) - mean(ref, k):+.2f}" for k in COLS[:3]) + " | "
                         + f"{mean(runs, 'normal_mae'):.2f} | {mean(runs, 'absrel'):.4f} | {len(done)} |")
    else:
        lines.append("| not run | | | | | | | 0 |")
    emit(a, f"--check-arm {a.check_arm}" + tagged(a), lines)


def seeds(a) -> None:
    """The sixty-sixth session's second seed: GLINT at today's preset, an arm and `3dgs` at seeds 0 and 1 on the
    tuning rooms (--check-rooms: on 9801-9803, where `3dgs` has seed 0 alone); each seed's change of the arm over
    the base and of GLINT against `3dgs` (said not run where `3dgs` has no run), and their mean."""
    check = a.check_rooms
    rooms_ = CHECK_ROOMS if check else ROOMS
    base0 = {r: read(HERE / "groups/t61_min27" if check else BASE[r], r, "glint") for r in rooms_}
    ref0 = {r: read(a.runs / "d63_3dgs" if check else REF, r, "3dgs") for r in rooms_}
    rows = {"GLINT, today's preset": (base0, {r: read(a.runs / "d66_base", r, "glint@seed1") for r in rooms_}),
            f"`{a.seeds}`": ({r: read(a.runs / f"{a.tag}_{a.seeds}", r, "glint") for r in rooms_},
                             {r: read(a.runs / f"{a.tag}_{a.seeds}", r, "glint@seed1") for r in rooms_}),
            "`3dgs`": (ref0, {r: read(a.runs / "d63_3dgs", r, "3dgs@seed1") for r in rooms_})}
    lines = per_room(rooms_, {f"{name}, seed {k}": runs[k] for name, runs in rows.items() for k in (0, 1)})
    base, arm, ref = rows.values()
    lines += ["", "| room | seed | `3dgs` over GLINT (PSNR all / glass / off) | the arm over GLINT | the arm's normals "
              "against GLINT's | its AbsRel against GLINT's |", "|---|---|---|---|---|---|"]
    diff = lambda x, y, k: x[k] - y[k]
    for room in rooms_ + ("mean",):
        for k in (0, 1, "both"):
            seeds_ = (0, 1) if k == "both" else (k,)
            rooms = rooms_ if room == "mean" else (room,)
            pairs = [(s, r) for s in seeds_ for r in rooms]
            if any(x[s][r] is None for s, r in pairs for x in (base, arm)):
                lines.append(f"| {room} | {k} | not run | | | |")
                continue
            mean = lambda f: sum(f(s, r) for s, r in pairs) / len(pairs)
            gap = ("not run" if any(ref[s][r] is None for s, r in pairs) else  # `3dgs` has no run at that seed
                   " / ".join(f"{mean(lambda s, r: diff(ref[s][r], base[s][r], c)):+.2f}" for c in COLS[:3]))
            gain = " / ".join(f"{mean(lambda s, r: diff(arm[s][r], base[s][r], c)):+.2f}" for c in COLS[:3])
            dn = mean(lambda s, r: diff(arm[s][r], base[s][r], "normal_mae"))
            da = mean(lambda s, r: diff(arm[s][r], base[s][r], "absrel") / base[s][r]["absrel"])
            lines.append(f"| {room} | {k} | {gap} | {gain} | {dn:+.2f} deg | {da:+.1%} |")
    emit(a, f"--seeds {a.seeds}" + tagged(a) + (" --check-rooms" if check else ""), lines)


WEIGHTS = {0.0: "d63_noterms", 0.25: "d65_quarter", 0.5: "d65_half"}  # 1.0: the base


def weights(a) -> None:
    curve = {w: {r: read(a.runs / d, r, "glint") for r in ROOMS} for w, d in WEIGHTS.items()}
    curve[1.0] = {r: read(BASE[r], r, "glint") for r in ROOMS}
    ref = {r: read(REF, r, "3dgs") for r in ROOMS}
    priors = {r: read(a.runs / "d63_priors", r, "priors") for r in ROOMS}
    lines = per_room(ROOMS, {**{f"weight {w:g}": curve[w] for w in sorted(curve)}, "`3dgs`": ref})
    lines += ["", "| priors | normals | AbsRel |", "|---|---|---|"]
    lines += [f"| {r} | " + ("not run | |" if priors[r] is None else
                             f"{priors[r]['normal_mae']:.2f} | {priors[r]['absrel']:.4f} |") for r in ROOMS]
    base = curve[1.0]
    lines += ["", "| prior terms' weight | PSNR all / glass / off | against weight 1 | per room | against `3dgs` | "
              "normals | AbsRel | rooms over the priors (normals, AbsRel) | rooms |",
              "|---|---|---|---|---|---|---|---|---|"]
    for w in sorted(curve):
        runs = curve[w]
        done = [r for r in ROOMS if all(x[r] is not None for x in (runs, base, ref))]
        if not done:
            lines.append(f"| {w:g} | not run | | | | | | | 0 |")
            continue
        mean = lambda rs, k: sum(rs[r][k] for r in done) / len(done)
        over = lambda k: over_priors(runs, priors, done, k)
        lines.append(f"| {w:g} | " + " / ".join(f"{mean(runs, k):.2f}" for k in COLS[:3]) + " | "
                     + " / ".join(f"{mean(runs, k) - mean(base, k):+.2f}" for k in COLS[:3]) + " | "
                     + ", ".join(f"{runs[r]['psnr'] - base[r]['psnr']:+.2f}" for r in done) + " | "
                     + " / ".join(f"{mean(runs, k) - mean(ref, k):+.2f}" for k in COLS[:3]) + " | "
                     + f"{mean(runs, 'normal_mae'):.2f} | {mean(runs, 'absrel'):.4f} | "
                     + f"{over('normal_mae')}, {over('absrel')} | {len(done)} |")
    emit(a, "--weights" + (f" --plot {a.plot}" if a.plot else ""), lines)
    if a.plot:
        plot_weights(a.plot, curve, ref, priors)


def plot_weights(path: Path, curve: dict, ref: dict, priors: dict) -> None:
    """Each tuning room's PSNR (all, on the glass), normal MAE and AbsRel against the prior terms' weight; `3dgs`
    (PSNR) and the priors (geometry) as dashed lines in the room's colour."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = (("psnr", "PSNR (dB)", ref), ("psnr_glass", "PSNR on the glass (dB)", ref),
              ("normal_mae", "normal MAE (deg)", priors), ("absrel", "depth AbsRel", priors))
    fig, axes = plt.subplots(1, 4, figsize=(16, 3.8))
    ws = sorted(curve)
    for (key, label, line), ax in zip(panels, axes):
        for room, colour in zip(ROOMS, ("C0", "C1", "C2")):
            pts = [(w, curve[w][room][key]) for w in ws if curve[w][room] is not None]
            if pts:
                ax.plot(*zip(*pts), "o-", color=colour, label=room)
            if line[room] is not None and line[room].get(key) is not None:
                ax.axhline(line[room][key], color=colour, ls="--", lw=1)
        ax.set_xlabel("prior terms' weight (x today's w_depth, w_normal)")
        ax.set_title(label + (" - dashed: `3dgs`" if line is ref else " - dashed: the priors"), fontsize=9)
        ax.set_xticks(ws)
    axes[0].legend(fontsize=8)
    fig.suptitle("GLINT at 40 epochs of 96 x 54, seed 0, tuning rooms: the prior terms' weight", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


# Every arm run on the whole of GLINT (not the ladder's interface alone) on 7301-7303 at seed 0: folder, what it sets.
TRADE = {"d63_copy": "3DGS's clones", "d63_el": "ellipsoids", "d63_noterms": "no prior term",
         "d65_half": "prior terms x 0.5", "d65_quarter": "prior terms x 0.25",
         "d66_agree_n": "normal prior x SfM share", "d66_agree_dn": "prior terms x SfM share",
         "d64_nocons": "no consistency term",
         "d67_freesf": "no geometry term", "d67_free": "no geometry term, ellipsoids"}


def trade(a) -> None:
    """What each arm gives up in geometry for its PSNR: the mean of the three tuning rooms at seed 0."""
    rows = {"GLINT, today's preset": {r: read(BASE[r], r, "glint") for r in ROOMS}}
    rows.update({f"`{d.split('_', 1)[1]}` ({what})": {r: read(a.runs / d, r, "glint") for r in ROOMS}
                 for d, what in TRADE.items()})
    ref = {r: read(REF, r, "3dgs") for r in ROOMS}
    priors = {r: read(a.runs / "d63_priors", r, "priors") for r in ROOMS}
    full = lambda runs: all(runs[r] is not None for r in ROOMS)
    mean = lambda runs, k: sum(runs[r][k] for r in ROOMS) / len(ROOMS)
    lines = ["| run (seed 0, 7301-7303) | PSNR all / glass / off | against `3dgs` | normals | AbsRel | "
             "rooms over the priors (normals, AbsRel) |", "|---|---|---|---|---|---|"]
    points = {}
    for name, runs in {**rows, "`3dgs`": ref}.items():
        if not full(runs):
            lines.append(f"| {name} | not run on the three rooms | | | | |")
            continue
        over = lambda k: over_priors(runs, priors, ROOMS, k)
        lines.append(f"| {name} | " + " / ".join(f"{mean(runs, k):.2f}" for k in COLS[:3]) + " | "
                     + (" / ".join(f"{mean(runs, k) - mean(ref, k):+.2f}" for k in COLS[:3]) if full(ref) else "-")
                     + f" | {mean(runs, 'normal_mae'):.2f} | {mean(runs, 'absrel'):.4f} | "
                     + f"{over('normal_mae')}, {over('absrel')} |")
        points[name] = {k: mean(runs, k) for k in ("psnr", "normal_mae", "absrel")}
    if full(priors):
        lines.append(f"| the priors | - | - | {mean(priors, 'normal_mae'):.2f} | {mean(priors, 'absrel'):.4f} | |")
    emit(a, "--trade" + (f" --plot {a.plot}" if a.plot else ""), lines)
    if a.plot:
        plot_trade(a.plot, points, {k: mean(priors, k) for k in ("normal_mae", "absrel")} if full(priors) else None)


def plot_trade(path: Path, points: dict, priors: dict | None) -> None:
    """Mean PSNR against mean normal MAE and AbsRel, one point a run; the priors' geometry as a dashed line."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(13, 5))
    for (key, label), ax in zip((("normal_mae", "normal MAE (deg)"), ("absrel", "depth AbsRel")), axes):
        for name, p in points.items():
            colour = "C3" if name == "`3dgs`" else "C0" if name.startswith("GLINT") else "C7"
            ax.plot(p[key], p["psnr"], "o", color=colour)
            ax.annotate(name.split(" (")[0].strip("`"), (p[key], p["psnr"]), fontsize=7, xytext=(3, 3),
                        textcoords="offset points")
        if priors is not None:
            ax.axvline(priors[key], color="k", ls="--", lw=1, label="the priors")
            ax.legend(fontsize=8)
        ax.set_xlabel(label + " (lower is better)")
        ax.set_ylabel("PSNR (dB)")
    fig.suptitle("40 epochs of 96 x 54, seed 0, mean of 7301-7303: each arm's PSNR against its geometry", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def check(a) -> None:
    glint = {r: read(HERE / "groups/t61_min27", r, "glint") for r in CHECK_ROOMS}
    ref = {r: read(a.runs / "d63_3dgs", r, "3dgs") for r in CHECK_ROOMS}
    lines = ["| room | GLINT, today's preset: PSNR all / glass / off, normals, AbsRel | `3dgs`, today's preset | "
             "GLINT - `3dgs`: all / glass / off |",
             "|---|---|---|---|"]
    done = [r for r in CHECK_ROOMS if glint[r] is not None and ref[r] is not None]
    short = lambda r: ("not run" if r is None else
                       f"{r['psnr']:.2f} / {r['psnr_glass']:.2f} / {r['psnr_off_glass']:.2f}, {r['normal_mae']:.2f}, "
                       f"{r['absrel']:.4f}")
    for r in CHECK_ROOMS:
        d = (" / ".join(f"{glint[r][k] - ref[r][k]:+.2f}" for k in COLS[:3])) if r in done else "not run"
        lines.append(f"| {r} | {short(glint[r])} | {short(ref[r])} | {d} |")
    if done:
        mean = lambda runs, k: sum(runs[r][k] for r in done) / len(done)
        lines.append(f"| mean of {len(done)} | " + " / ".join(f"{mean(glint, k):.2f}" for k in COLS[:3]) + " | "
                     + " / ".join(f"{mean(ref, k):.2f}" for k in COLS[:3]) + " | "
                     + " / ".join(f"{mean(glint, k) - mean(ref, k):+.2f}" for k in COLS[:3]) + " |")
    emit(a, "--check", lines)


if __name__ == "__main__":
    main()
