#!/bin/bash
# The declared check of c2f (README here) on rooms 9801-9803: lane A the defaults, lane B the switch, the same bench
# command as the tuning runs:  bash check.sh A  /  bash check.sh B  (after gen98.sh has made each room's folder)
set -u
cd "$(dirname "$0")/../../.."
PY=${PY:-.venv/bin/python}; DATA=${DATA:-/work/data98_r}; RUNS=${RUNS:-/work/runs98c}
B="--preset bench --methods glint --set threads=1 --set eval_every=1000"
for room in 9801 9802 9803; do
  while [ ! -e "$DATA/r$room/scene_$room" ]; do sleep 30; done
  case ${1:?A or B} in
    A) $PY -m glint_mi.benchmark $B --data "$DATA/r$room" --out "$RUNS/c2f_base" ;;
    B) $PY -m glint_mi.benchmark $B --set coarse_to_fine=4:0.2,2:0.2 --data "$DATA/r$room" --out "$RUNS/c2f_4_2" ;;
  esac
done
