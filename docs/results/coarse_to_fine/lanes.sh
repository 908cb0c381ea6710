#!/bin/bash
# The runs of this folder (README here), one lane at a time: bash lanes.sh STUDY LANE
#   STUDY: tune (glint on the tuning rooms 7301-7303), tune3dgs (3dgs on them), check (glint on rooms 9801-9803)
#   LANE:  A without the switch, B with it; the same room side by side, seed 0, the bench command.
# (These were drive.sh, drive3dgs.sh and check.sh when declared: the same commands; lane A now says
# coarse_to_fine= because the bench preset sets the switch since it was adopted.) A finished run is skipped (the
# benchmark reads its metrics.json), so a lane restarts where it stopped; each room is waited for (its generator
# renames scene_*.partial when done; gen98.sh links the check rooms).
set -u
cd "$(dirname "$0")/../../.."
PY=${PY:-.venv/bin/python}
case ${1:?tune, tune3dgs or check} in
  tune) method=glint; rooms="7301 7302 7303"; data=${DATA73:-/work/data73}; runs=${RUNS:-/work/runs73} ;;
  tune3dgs) method=3dgs; rooms="7301 7302 7303"; data=${DATA73:-/work/data73}; runs=${RUNS:-/work/runs73} ;;
  check) method=glint; rooms="9801 9802 9803"; data=${DATA:-/work/data98_r}; runs=${RUNS:-/work/runs98c} ;;
  *) echo "unknown study '$1': use tune, tune3dgs or check" >&2; exit 2 ;;
esac
case ${2:?A or B} in
  A) switch="--set coarse_to_fine="; out=c2f_base ;;
  B) switch="--set coarse_to_fine=4:0.2,2:0.2"; out=c2f_4_2 ;;
  *) echo "unknown lane '$2': use A or B" >&2; exit 2 ;;
esac
for room in $rooms; do
  while [ ! -e "$data/r$room/scene_$room" ]; do sleep 30; done
  $PY -m glint_mi.benchmark --preset bench --methods $method --set threads=1 --set eval_every=1000 $switch \
      --data "$data/r$room" --out "$runs/$out"
done
