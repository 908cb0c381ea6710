#!/bin/bash
# Does the schedule help 3DGS too (README here: whom the bench preset gives it to)? `3dgs` on the tuning rooms,
# seed 0, the same bench command: lane A without the switch, lane B with it:  bash drive3dgs.sh A  /  B
set -u
cd "$(dirname "$0")/../../.."
PY=${PY:-.venv/bin/python}; DATA73=${DATA73:-/work/data73}; RUNS=${RUNS:-/work/runs73}
B="--preset bench --methods 3dgs --set threads=1 --set eval_every=1000"
for room in 7301 7302 7303; do
  while [ ! -d "$DATA73/r$room/scene_$room" ]; do sleep 30; done
  case ${1:?A or B} in
    A) $PY -m glint_mi.benchmark $B --data "$DATA73/r$room" --out "$RUNS/c2f_base" ;;
    B) $PY -m glint_mi.benchmark $B --set coarse_to_fine=4:0.2,2:0.2 --data "$DATA73/r$room" --out "$RUNS/c2f_4_2" ;;
  esac
done
