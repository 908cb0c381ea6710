"""Apply the tuning rule of ``docs/results/tuning_73xx`` to a switch: does it become a default?

Each configuration is a benchmark output folder per room (``--base`` and each ``--switch`` take a pattern with
``{room}``). A room's figure is the mean over the seeds that both the base and the switch have for it (seed 0 is the
run folder ``METHOD``, seed k ``METHOD@seedk``); rooms missing either side are left out and named. The rule, written
before the runs it judges (sections 1 and 5 of that README), on the mean of the rooms:

- geometry rule: an improvement of at least 0.5 deg of normal MAE, or 5 % of AbsRel, or 2 deg of glass normal MAE,
  or 10 % of glass AbsRel; at most 0.3 dB of PSNR lost and none of the four worse by more than those amounts; the
  improving column better in at least ``--agree`` rooms;
- PSNR rule: at least +0.3 dB of PSNR, higher in at least ``--agree`` rooms, none of the four geometry columns worse
  by more than those amounts.

A room may carry a level, ``ROOM@LEVEL`` (a room under one setting of a sweep, e.g. ``7301@1.0``), which fills
``{level}`` in the patterns; each room-level counts as a room.

``--floor METHOD`` (e.g. ``priors``, the benchmark's row of the priors themselves, read from the base folder): the
switch is adopted only where its normal MAE and AbsRel are at or under that row's in every room (GLINT never ends
worse than its priors). ``--floor-mode no-farther`` (declared in ``docs/results/coarse_to_fine``, sixtieth session)
also passes a room where a column of the switch is over the floor but no farther over it than the base's: a floor
must not keep a default that ends worse than the priors over a switch that ends nearer them (``under``, the default,
is the former reading).

``--agree`` defaults to all rooms but one (two of three, three of four, four of five); fewer than ``--min-rooms``
(3) rooms decide nothing.

``--confirm`` judges a switch already adopted on rooms it was not tuned on (the check rooms of that README): the
base is the default it replaced, and it stays if, on the rooms' mean, it is worse than the base by no more than
those amounts (0.3 dB of PSNR, and each geometry column's bound); otherwise it reverts.

    .venv/bin/python benchmarks/tuning_rule.py --rooms 7301,7302,7303,7310,7340 --base 'runs/q{room}/base' \\
        --switch near='runs/q{room}/near' --switch cfrom='runs/q{room}/cfrom' [--method glint] [--out rule.md]
    .venv/bin/python benchmarks/tuning_rule.py --confirm --rooms 9601,9602,9603,9604 --base 'former' \\
        --switch near_consistency='new'
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

COLUMNS = ("psnr", "normal_mae", "absrel", "normal_mae_glass", "absrel_glass", "t_iou")
# (column, threshold, relative?): an improvement lowers the column
GEOMETRY = (("normal_mae", 0.5, False), ("absrel", 0.05, True), ("normal_mae_glass", 2.0, False),
            ("absrel_glass", 0.10, True))
PSNR_COST, PSNR_GAIN = 0.3, 0.3


def seed_runs(folder: Path, room: str, method: str, max_seed: int = 64) -> dict[int, dict]:
    """{seed: metrics} of one method's finished runs in a benchmark output folder: the benchmark's own run folders
    (``job_list``) and its test of a finished evaluation (``finished_metrics``: an interrupted one is not read)."""
    from glint_mi.benchmark import job_list
    from glint_mi.runs import finished_metrics

    jobs = job_list([method], [Path(f"scene_{room}")], list(range(max_seed)), Path(folder))
    done = {seed: finished_metrics(run) for _, _, run, seed in jobs}
    return {seed: res["metrics"] for seed, res in done.items() if res is not None}


def room_pair(base: Path, switch: Path, room: str, method: str):
    """Per-room means over the seeds both folders have: (base, switch, seeds), or None."""
    b, s = seed_runs(base, room, method), seed_runs(switch, room, method)
    seeds = sorted(set(b) & set(s))
    if not seeds:
        return None
    mean = lambda runs: {c: float(np.mean([runs[k][c] for k in seeds])) for c in COLUMNS}
    return mean(b), mean(s), seeds


def change(col: str, base: float, new: float, relative: bool) -> float:
    """Improvement (positive = better) in the column's unit: deg, or a fraction of the base for AbsRel."""
    d = base - new
    return d / base if relative else d


def judge(pairs: dict[str, tuple], agree: int, min_rooms: int = 3) -> dict:
    """The rule on the rooms' pairs {room: (base, switch, seeds)}; fewer than ``min_rooms`` rooms decide nothing."""
    rooms = sorted(pairs)
    mb = {c: float(np.mean([pairs[r][0][c] for r in rooms])) for c in COLUMNS}
    ms = {c: float(np.mean([pairs[r][1][c] for r in rooms])) for c in COLUMNS}
    gain = {c: change(c, mb[c], ms[c], rel) for c, _, rel in GEOMETRY}
    within = all(gain[c] >= -thr for c, thr, _ in GEOMETRY)
    dpsnr = ms["psnr"] - mb["psnr"]
    per_room = {c: sum(change(c, pairs[r][0][c], pairs[r][1][c], rel) > 0 for r in rooms) for c, _, rel in GEOMETRY}
    psnr_rooms = sum(pairs[r][1]["psnr"] > pairs[r][0]["psnr"] for r in rooms)
    improving = [c for c, thr, _ in GEOMETRY if gain[c] >= thr and per_room[c] >= agree]
    geometry_rule = bool(improving) and within and dpsnr >= -PSNR_COST
    psnr_rule = dpsnr >= PSNR_GAIN and psnr_rooms >= agree and within
    return dict(base=mb, switch=ms, gain=gain, dpsnr=dpsnr, within=within, per_room=per_room,
                psnr_rooms=psnr_rooms, improving=improving, geometry_rule=geometry_rule, psnr_rule=psnr_rule,
                enough=len(rooms) >= min_rooms, adopted=(geometry_rule or psnr_rule) and len(rooms) >= min_rooms,
                stays=within and dpsnr >= -PSNR_COST)


FLOOR_MODES = ("under", "no-farther")


def apply_floor(verdict: dict, pairs: dict, floors: dict, method: str, mode: str = "under") -> dict:
    """``--floor``: the rooms where the switch's normal MAE or AbsRel is over the floor method's (with ``no-farther``:
    over it and farther over than the base's), or where the floor's run is missing (``floor_missed``); with any, the
    switch is neither adopted nor, under ``--confirm``, kept. ``floor_over`` names the rooms over the floor at all
    (the ``under`` reading), whatever the mode, so a report can give both."""
    if mode not in FLOOR_MODES:
        raise ValueError(f"--floor-mode {mode!r}: use one of {', '.join(FLOOR_MODES)}")
    cols = ("normal_mae", "absrel")
    over_cols = lambda r: [c for c in cols if pairs[r][1][c] > floors[r][c]]
    farther = lambda r: any(pairs[r][1][c] > max(floors[r][c], pairs[r][0][c]) for c in cols)
    present = [r for r in sorted(pairs) if r in floors]
    over = [r for r in present if over_cols(r)]
    fails = over if mode == "under" else [r for r in present if farther(r)]
    missed = sorted([r for r in pairs if r not in floors] + fails)
    return {**verdict, "floor_method": method, "floor_mode": mode, "floor_missed": missed, "floor_over": over,
            "floor_absent": [r for r in missed if r not in floors],
            "adopted": verdict["adopted"] and not missed, "stays": verdict["stays"] and not missed}


def report(name: str, pairs: dict, verdict: dict, agree: int, confirm: bool = False) -> str:
    rooms = sorted(pairs)
    lines = [f"### {name}", "", "| room | seeds | " + " | ".join(f"{c} (base -> switch)" for c in COLUMNS) + " |",
             "|---|---|" + "---|" * len(COLUMNS)]
    for r in rooms:
        b, s, seeds = pairs[r]
        lines.append(f"| {r} | {','.join(map(str, seeds))} | "
                     + " | ".join(f"{b[c]:.4g} -> {s[c]:.4g}" for c in COLUMNS) + " |")
    v = verdict
    lines.append("| mean | | " + " | ".join(f"{v['base'][c]:.4g} -> {v['switch'][c]:.4g}" for c in COLUMNS) + " |")
    geo = ", ".join(f"{c} {v['gain'][c] * (100 if rel else 1):+.2f}{' %' if rel else ''} (better in {v['per_room'][c]})"
                    for c, _, rel in GEOMETRY)
    lines += ["", f"PSNR {v['dpsnr']:+.2f} dB (higher in {v['psnr_rooms']} of {len(rooms)} rooms); improvements "
              f"(positive = better): {geo}; geometry within bounds: {'yes' if v['within'] else 'no'}.",
              (f"Check rule (the adopted switch worse than the default it replaced by at most {PSNR_COST} dB and the "
               f"geometry bounds): " + (f"**{'Stays' if v['stays'] else 'Reverts'}.**" if v["enough"]
                                        else f"**Too few rooms to decide** ({len(rooms)}).")) if confirm else
              f"Geometry rule: {'passes' if v['geometry_rule'] else 'fails'}; PSNR rule (+{PSNR_GAIN} dB, "
              f"{agree} of {len(rooms)} rooms): {'passes' if v['psnr_rule'] else 'fails'}. "
              + (f"**{'Adopted' if v['adopted'] else 'Not adopted'}.**" if v["enough"]
                 else f"**Too few rooms to decide** ({len(rooms)})."), ""]
    if "floor_method" in v:
        absent, m = v["floor_absent"], v["floor_method"]
        failed = [r for r in v["floor_missed"] if r not in absent]
        farther = v.get("floor_mode") == "no-farther"
        what = ("normals and AbsRel at or under it, or no farther over it than the base's, in every room" if farther
                else "normals and AbsRel at or under it in every room")
        lines.insert(-1, f"Floor (`{m}`: {what}): "
                     + (f"**not met** in {', '.join(failed)}. " if failed else "")
                     + (f"**No `{m}` run** for {', '.join(absent)} in the base folder (add it: `python -m "
                        f"glint_mi.benchmark --methods {m}` with the base's --data and --out)." if absent else "")
                     + ("" if v["floor_missed"] else "met.")
                     + (f" Over `{m}` at all (the `under` reading): {', '.join(v['floor_over']) or 'none'}."
                        if farther else ""))
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rooms", required=True, help="comma-separated room ids, the {room} in the patterns")
    ap.add_argument("--base", required=True, help="benchmark output folder of the defaults, with {room}")
    ap.add_argument("--switch", action="append", required=True, metavar="NAME=PATTERN")
    ap.add_argument("--method", default="glint")
    ap.add_argument("--agree", type=int, default=None, help="rooms that must agree (default: all but one)")
    ap.add_argument("--min-rooms", type=int, default=3, help="fewer rooms than this decide nothing (default 3)")
    ap.add_argument("--out", type=Path, default=None, help="also write the report here (markdown)")
    ap.add_argument("--floor", default=None, metavar="METHOD",
                    help="a method of the base folder (e.g. priors) whose normals and AbsRel the switch must not exceed")
    ap.add_argument("--floor-mode", default="under", choices=FLOOR_MODES,
                    help="under: the switch at or under the floor in every room (default); no-farther: or no farther "
                         "over it than the base")
    ap.add_argument("--confirm", action="store_true",
                    help="the check rule: the switch is an adopted default, the base the one it replaced")
    a = ap.parse_args(argv)
    if a.floor_mode != "under" and not a.floor:
        ap.error(f"--floor-mode {a.floor_mode} reads a floor: add --floor METHOD (e.g. --floor priors)")
    rooms = [r.strip() for r in a.rooms.split(",") if r.strip()]
    fill = lambda pattern, r: pattern.format(room=r.partition("@")[0], level=r.partition("@")[2])
    args = list(argv if argv is not None else sys.argv[1:])
    out = [f"Tuning rule: `{' '.join(['python benchmarks/tuning_rule.py'] + args)}`", ""]
    for spec in a.switch:
        if "=" not in spec:
            ap.error(f"--switch {spec!r}: expected NAME=PATTERN, e.g. near='runs/q{{room}}/near'")
        name, pattern = spec.split("=", 1)
        pairs, missing = {}, []
        floors = {}
        for r in rooms:
            p = room_pair(Path(fill(a.base, r)), Path(fill(pattern, r)), r.partition("@")[0], a.method)
            (missing.append(r) if p is None else pairs.__setitem__(r, p))
            if a.floor and p is not None:
                f = seed_runs(Path(fill(a.base, r)), r.partition("@")[0], a.floor)
                if 0 in f:
                    floors[r] = f[0]
        if not pairs:
            absent = [f for r in rooms for f in (fill(a.base, r), fill(pattern, r)) if not Path(f).is_dir()]
            out.append(f"### {name}\n\nno room has a finished run in both folders"
                       + (f" (no such folder: {', '.join(sorted(set(absent)))})" if absent else "") + "\n")
            continue
        agree = a.agree if a.agree is not None else max(len(pairs) - 1, 1)
        verdict = judge(pairs, agree, a.min_rooms)
        if a.floor:
            verdict = apply_floor(verdict, pairs, floors, a.floor, a.floor_mode)
        out.append(report(name, pairs, verdict, agree, a.confirm))
        if missing:
            out.append(f"Left out (no seed finished in both folders): {', '.join(missing)}.\n")
    text = "\n".join(out)
    print(text)
    if a.out:
        a.out.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
