#!/bin/bash
# Item 3 at the converged budget (README, "Status (2026-11-29, forty-second session)"): GLINT and the priors' row at
# each level of prior error, 60 epochs of 96 x 54 with growth (GLINT's point in docs/results/converge_98xx), today's
# defaults otherwise (the bench preset, so its coarse start) with the sweep's flags (w_sfm_depth=0, one thread).
#   bash docs/results/prior_sweep/converged60.sh ROOM [NAMES [BENCHMARK ARGS...]]
# ROOM: 7301 or 7302 (one lane each); NAMES: model_eF names in the declared order. DATA (the tuning rooms r7301,
# r7302; levels/ is made beside them) and RUNS (where runs go) from the environment. A finished run is skipped (the
# benchmark reads its metrics.json), so a lane restarts where it stopped. Later runs of the same command with a change
# (s44_7302.sh): METHODS (default priors,glint), TAG (the runs folder's suffix) and the arguments after NAMES.
set -u
cd "$(dirname "$0")/../../.."
PY=${PY:-.venv/bin/python}; DATA=${DATA:-/work/data73}; RUNS=${RUNS:-/work/runs73p}
room=${1:?ROOM: 7301 or 7302}
case $room in 7301|7302) ;; *) echo "unknown room '$room': use 7301 or 7302" >&2; exit 2 ;; esac
NAMES=${2:-realistic_e0.5 realistic-v1_e2.0 realistic_e2.0 realistic-v1_e0.5 realistic_e1 realistic_e0.75 realistic_e1.25}
METHODS=${METHODS:-priors,glint}; TAG=${TAG:-}; EXTRA=("${@:3}")
src="$DATA/r$room/scene_$room"
source docs/results/prior_sweep/levels.sh
[ -f "$src/meta.json" ] || { echo "no room at $src: generate it as docs/results/tuning_73xx says" >&2; exit 2; }
for name in $NAMES; do
  model=${name%_e*}; f=${name##*_e}
  case $model in realistic|realistic-v1) ;; *) echo "unknown level '$name': use realistic_eF or realistic-v1_eF" >&2; exit 2 ;; esac
  LEVELS="$DATA/levels_$room" level $name $room --model $model --error-scale $f || exit 1  # a folder per room: lanes never share one
  echo "=== $(date -u +%FT%TZ) glint $name $room"
  $PY -m glint_mi.benchmark --preset bench --set downscale=2 --set w_sfm_depth=0 --set threads=1 --set epochs=60 --set eval_every=1000 \
      --set densify_top=0.12 --set densify_grad_rel=0.05 --methods "$METHODS" "${EXTRA[@]}" \
      --data "$DATA/levels_$room/$name" --out "$RUNS/conv60_${name}_$room$TAG"
  echo "=== rc=$? $(date -u +%FT%TZ)"
done
