#!/bin/bash
# The fifty-third session: the converged preset as it stands after the `wide` check (ellipsoids, GLINT's capacity
# `wide`, 60 epochs, no coarse start) over the sweep's room-levels, with the sweep's protocol flags (downscale=2
# w_sfm_depth=0, one thread) and nothing else: `--preset converged` alone sets the rest. A finished run is skipped.
#   bash docs/results/prior_sweep/preset53.sh ROOM NAME...    (ROOM 7301 or 7302; NAME: model_eF as converged60.sh)
# DATA (the tuning rooms r7301, r7302; levels_ROOM/ is made beside them), RUNS and WT (the code: a worktree) from the
# environment. Folders RUNS/conv60_NAME_ROOM_TAG (TAG from the environment, p53 unless given), SETS (from the
# environment, e.g. "--set depth_prior_ref=0.02") added to the command: depthref54.sh runs it so.
set -u
WT=${WT:-/work/wt53}; PY=${PY:-/work/main/.venv/bin/python}; DATA=${DATA:-/work/data73}; RUNS=${RUNS:-/work/runs53}
TAG=${TAG:-p53}; SETS=${SETS:-}
room=${1:?ROOM: 7301 or 7302}; shift
case $room in 7301|7302) ;; *) echo "unknown room '$room': use 7301 or 7302" >&2; exit 2 ;; esac
cd "$WT"; export PYTHONPATH=$WT:${WT}_path
source docs/results/prior_sweep/levels.sh
[ -f "$DATA/r$room/scene_$room/meta.json" ] || { echo "no room at $DATA/r$room: generate it as docs/results/tuning_73xx says" >&2; exit 2; }
for name in "$@"; do
  model=${name%_e*}; f=${name##*_e}
  case $model in realistic|realistic-v1) ;; *) echo "unknown level '$name': use realistic_eF or realistic-v1_eF" >&2; exit 2 ;; esac
  LEVELS="$DATA/levels_$room" level $name $room --model $model --error-scale $f || exit 1
  echo "=== $(date -u +%FT%TZ) glint $name $room $SETS"
  $PY -m glint_mi.benchmark --preset converged --set downscale=2 --set w_sfm_depth=0 --set threads=1 --set eval_every=1000 \
      $SETS --methods priors,glint --data "$DATA/levels_$room/$name" --out "$RUNS/conv60_${name}_${room}_$TAG"
  echo "=== rc=$? $(date -u +%FT%TZ)"
done
