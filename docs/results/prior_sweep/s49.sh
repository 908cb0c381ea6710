#!/bin/bash
# Forty-ninth session (README, "The see-through share at the converged budget"): GLINT and the priors' row at
# see-through P (the simulated estimator sees through the glass in that share of the views; `realistic` errors at
# scale 1), converged60.sh's command (60 epochs of 96 x 54 with growth, the bench preset with its coarse start,
# w_sfm_depth=0, one thread), then `3dgs` once per room (it reads no prior: one run stands for every P).
#   bash docs/results/prior_sweep/s49.sh ROOM "P [P...]"
# ROOM: 7301 or 7302 (one lane each). Code: the worktree WT (pinned at the declaring commit). DATA (the tuning rooms)
# and RUNS from the environment; a finished run is skipped.
set -u
PY=${PY:-/work/main/.venv/bin/python}; DATA=${DATA:-/work/data73}; RUNS=${RUNS:-/work/runs49}
room=${1:?ROOM: 7301 or 7302}
case $room in 7301|7302) ;; *) echo "unknown room '$room': use 7301 or 7302" >&2; exit 2 ;; esac
source "$(dirname "$0")/levels.sh"
WT=${WT:-/work/wt49}; cd "$WT"; export PYTHONPATH=$WT:${WT}_path
C="--preset bench --set downscale=2 --set w_sfm_depth=0 --set threads=1 --set epochs=60 --set eval_every=1000 \
   --set densify_top=0.12 --set densify_grad_rel=0.05"
for p in ${2:?P values, e.g. "1.0 0.4"}; do
  LEVELS="$DATA/levels_$room" level see_$p $room --model realistic --see-through $p || exit 1
  echo "=== $(date -u +%FT%TZ) glint see_$p $room"
  $PY -m glint_mi.benchmark $C --methods priors,glint --data "$DATA/levels_$room/see_$p" --out "$RUNS/conv60_see_${p}_$room"
  echo "=== rc=$? $(date -u +%FT%TZ)"
  if [ ! -f "$RUNS/conv60_3dgs_$room/runs/scene_$room/3dgs/metrics.json" ]; then
    echo "=== $(date -u +%FT%TZ) 3dgs $room"
    $PY -m glint_mi.benchmark $C --methods 3dgs --data "$DATA/r$room" --out "$RUNS/conv60_3dgs_$room"
    echo "=== rc=$? $(date -u +%FT%TZ)"
  fi
done
