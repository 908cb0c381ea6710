#!/bin/bash
# The sixty-second session (README, "Whom the coarse floor goes to"): `3dgs` at the bench preset with the prior
# sweep's flags (96 x 54, 40 epochs, w_sfm_depth=0, one Dr.Jit thread; s56.sh's command), with today's floor
# (arm p27, the preset's coarse_min_side=27) or without it (arm p0), on one tuning room, seed 0. Finished runs skip.
#   bash docs/results/coarse_to_fine/s62_3dgs.sh p27|p0 ROOM      (7301-7303)
# Code of the worktree WT; rooms DATA73/rROOM; folder RUNS/w62_3dgs_<arm>.
set -u
arm=${1:?p27 or p0}; room=${2:?a room: 7301 7302 7303}
case $arm in
  p27) sets="" ;;
  p0) sets="--set coarse_min_side=0" ;;
  *) echo "arm '$arm': use p27 or p0" >&2; exit 2 ;;
esac
case $room in 730[123]) ;; *) echo "room '$room': 7301-7303" >&2; exit 2 ;; esac
WT=${WT:-/work/wt62}; RUNS=${RUNS:-/work/runs62}; PY=${PY:-/work/main/.venv/bin/python}; DATA73=${DATA73:-/work/data73}
echo "=== $(date -u +%FT%TZ) w62_3dgs_$arm $room"
WT=$WT PY=$PY bash "$(dirname "$0")/run40.sh" 3dgs "$DATA73/r$room" "$RUNS/w62_3dgs_$arm" --set eval_every=1000 $sets
echo "=== rc=$? $(date -u +%FT%TZ)"
