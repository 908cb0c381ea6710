#!/bin/bash
# The fifty-fifth session: the two room-levels where GLINT's AbsRel ended over the priors' at 40 epochs (errors.md:
# 7301 realistic-v1 x2, 7302 see-through P = 0.2), again with today's defaults (the bench preset's coarse start and
# shared clones, the per-view depth weight depth_prior_ref 0.02), drive.sh's flags otherwise (40 epochs of 96 x 54,
# w_sfm_depth=0, one thread). A finished run is skipped.
#   bash docs/results/prior_sweep/errors55.sh ROOM NAME       (7301 realistic-v1_e2.0, or 7302 see_0.2)
# DATA (the tuning rooms; levels_ROOM/ beside them), RUNS and WT (the code: a worktree) from the environment.
# Folders RUNS/TAG_NAME_ROOM (TAG: b55). SETS (e.g. "--set clone_opacity=copy") is added to the command: the
# fifty-sixth session's runs that take today's changes back one at a time.
set -u
TAG=${TAG:-b55}; SETS=${SETS:-}
WT=${WT:-/work/wt55}; PY=${PY:-/work/main/.venv/bin/python}; DATA=${DATA:-/work/data73}; RUNS=${RUNS:-/work/runs55}
room=${1:?ROOM: 7301 or 7302}; name=${2:?NAME: realistic-v1_e2.0 or see_0.2}
here=$(cd "$(dirname "$0")" && pwd)
source "$here/levels.sh"
cd "$WT"; export PYTHONPATH=$WT:${WT}_path
case $name in
  see_*) LEVELS="$DATA/levels_$room" level $name $room --model realistic --see-through ${name#see_} || exit 1 ;;
  *_e*) LEVELS="$DATA/levels_$room" level $name $room --model ${name%_e*} --error-scale ${name##*_e} || exit 1 ;;
  *) echo "unknown level '$name'" >&2; exit 2 ;;
esac
echo "=== $(date -u +%FT%TZ) glint $name $room (40 epochs) $SETS"
WT=$WT PY=$PY bash "$here/../coarse_to_fine/run40.sh" priors,glint "$DATA/levels_$room/$name" \
    "$RUNS/${TAG}_${name}_$room" $SETS
echo "=== rc=$? $(date -u +%FT%TZ)"
