#!/bin/bash
# Item 2 of issue 66 (README here): glint at the bench preset with and without coarse_to_fine on the tuning rooms,
# seed 0. Lane A runs the defaults, lane B the switch, the same room side by side:
#   bash drive.sh A   and   bash drive.sh B   (DATA73: folder of r7301/, r7302/, r7303/; RUNS: output root)
# A finished run is skipped (the benchmark reads its metrics.json), so a lane restarts where it stopped.
set -u
cd "$(dirname "$0")/../../.."
PY=${PY:-.venv/bin/python}; DATA73=${DATA73:-/work/data73}; RUNS=${RUNS:-/work/runs73}
B="--preset bench --methods glint --set threads=1 --set eval_every=1000"
for room in 7301 7302 7303; do
  while [ ! -d "$DATA73/r$room/scene_$room" ]; do sleep 30; done   # the generator renames scene_*.partial when done
  case ${1:?A or B} in
    A) $PY -m glint_mi.benchmark $B --data "$DATA73/r$room" --out "$RUNS/c2f_base" ;;
    B) $PY -m glint_mi.benchmark $B --set coarse_to_fine=4:0.2,2:0.2 --data "$DATA73/r$room" --out "$RUNS/c2f_4_2" ;;
  esac
done
