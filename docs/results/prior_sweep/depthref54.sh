#!/bin/bash
# The fifty-fourth session: the converged preset with each view's depth prior weighed by its agreement with the SfM
# points (depth_prior_ref REF) on the sweep's room-levels, the sweep's protocol flags as preset53.sh (downscale=2
# w_sfm_depth=0, one thread). A finished run is skipped.
#   bash docs/results/prior_sweep/depthref54.sh REF ROOM NAME...   (ROOM 7301 or 7302; NAME: model_eF as preset53.sh)
# DATA, RUNS and WT (the code: a worktree) from the environment. Folders RUNS/conv60_NAME_ROOM_d54r<REF>.
set -u
WT=${WT:-/work/wt54}; PY=${PY:-/work/main/.venv/bin/python}; DATA=${DATA:-/work/data73}; RUNS=${RUNS:-/work/runs54}
ref=${1:?REF: depth_prior_ref, e.g. 0.02}; room=${2:?ROOM: 7301 or 7302}; shift 2
case $room in 7301|7302) ;; *) echo "unknown room '$room': use 7301 or 7302" >&2; exit 2 ;; esac
cd "$WT"; export PYTHONPATH=$WT:${WT}_path
source docs/results/prior_sweep/levels.sh
[ -f "$DATA/r$room/scene_$room/meta.json" ] || { echo "no room at $DATA/r$room: generate it as docs/results/tuning_73xx says" >&2; exit 2; }
for name in "$@"; do
  model=${name%_e*}; f=${name##*_e}
  case $model in realistic|realistic-v1) ;; *) echo "unknown level '$name': use realistic_eF or realistic-v1_eF" >&2; exit 2 ;; esac
  LEVELS="$DATA/levels_$room" level $name $room --model $model --error-scale $f || exit 1
  echo "=== $(date -u +%FT%TZ) glint $name $room depth_prior_ref $ref"
  $PY -m glint_mi.benchmark --preset converged --set downscale=2 --set w_sfm_depth=0 --set threads=1 --set eval_every=1000 \
      --set depth_prior_ref=$ref --methods priors,glint --data "$DATA/levels_$room/$name" \
      --out "$RUNS/conv60_${name}_${room}_d54r$ref"
  echo "=== rc=$? $(date -u +%FT%TZ)"
done
