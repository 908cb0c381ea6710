#!/bin/bash
# GLINT at the converged preset with the converged table's protocol flags (downscale=2 w_sfm_depth=0, one Dr.Jit
# thread), one room and seed, with SETS (e.g. "--set cap_schedule=linear") added: the runs of s54.sh, s55.sh and
# s55e.sh, which set TAG and SETS. A finished run is skipped.
#   TAG=NAME SETS="--set FIELD=VALUE" bash docs/results/converge_98xx/preset_glint.sh ROOM SEED
# Folder: RUNS/TAG (seed 1 as glint@seed1). WT (the code: a worktree), RUNS, DATA98 and PY from the environment.
set -u
WT=${WT:?WT: the worktree of the declared code}; RUNS=${RUNS:?RUNS: where the runs go}
DATA=${DATA98:-/work/data98_r}; PY=${PY:-/work/main/.venv/bin/python}
TAG=${TAG:?TAG: the run folder}; SETS=${SETS:-}
room=${1:?a room: 9801 9802 9803 9804}; seed=${2:?a seed: 0 or 1}
cd "$WT"; export PYTHONPATH=$WT:${WT}_path
out=$RUNS/$TAG
echo "=== $(date -u +%FT%TZ) $room seed $seed $SETS -> $out"
$PY -m glint_mi.benchmark --preset converged --set downscale=2 --set w_sfm_depth=0 --set eval_every=1000 \
    --set threads=1 $SETS --seed-ids $seed --methods glint --data "$DATA/r$room" --out "$out"
echo "=== rc=$? $(date -u +%FT%TZ)"
