#!/bin/bash
# The fifty-sixth session (README, "A floor on the coarse start's image size"): GLINT at the bench preset with
# the prior sweep's flags (96 x 54, 40 epochs, w_sfm_depth=0, one Dr.Jit thread), today's defaults (arm base, with
# the priors row) or with coarse_min_side=27 (arm min27), on one room, seed 0. A finished run is skipped.
#   bash docs/results/coarse_to_fine/s56.sh base|min27 ROOM        (7301-7303: tuning; 9801-9803: check)
# Code of the worktree WT; rooms DATA73/rROOM or DATA98/rROOM; folder RUNS/t56_<arm>.
set -u
arm=${1:?base or min27}; room=${2:?a room: 7301 7302 7303 9801 9802 9803}
case $arm in
  base) sets=""; methods=priors,glint ;;
  min27) sets="--set coarse_min_side=27"; methods=glint ;;
  *) echo "arm '$arm': use base or min27" >&2; exit 2 ;;
esac
case $room in
  73*) data=${DATA73:-/work/data73} ;;
  98*) data=${DATA98:-/work/data98_r} ;;
  *) echo "room '$room': 7301-7303 or 9801-9803" >&2; exit 2 ;;
esac
WT=${WT:-/work/wt56}; RUNS=${RUNS:-/work/runs56}; PY=${PY:-/work/main/.venv/bin/python}
echo "=== $(date -u +%FT%TZ) t56_$arm $room"
WT=$WT PY=$PY bash "$(dirname "$0")/run40.sh" $methods "$data/r$room" "$RUNS/t56_$arm" --set eval_every=1000 $sets
echo "=== rc=$? $(date -u +%FT%TZ)"
