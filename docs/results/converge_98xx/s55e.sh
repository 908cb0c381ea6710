#!/bin/bash
# The fifty-fifth session: GLINT at the converged preset (as s54.sh's runs: the table's protocol flags downscale=2
# w_sfm_depth=0, one Dr.Jit thread, today's defaults) for EPOCHS epochs instead of 60: whether GLINT has stopped
# gaining at the preset. A finished run is skipped.
#   bash docs/results/converge_98xx/s55e.sh ROOM SEED EPOCHS
# Folders: RUNS/e<EPOCHS>_p55.
set -u
WT=${WT:-/work/wt55}; RUNS=${RUNS:-/work/runs55}; DATA=${DATA98:-/work/data98_r}; PY=${PY:-/work/main/.venv/bin/python}
room=${1:?a room: 9801 9802 9803 9804}; seed=${2:?a seed: 0 or 1}; ep=${3:?EPOCHS, e.g. 120}
cd "$WT"; export PYTHONPATH=$WT:${WT}_path
out=$RUNS/e${ep}_p55
echo "=== $(date -u +%FT%TZ) $room seed $seed epochs $ep -> $out"
$PY -m glint_mi.benchmark --preset converged --set downscale=2 --set w_sfm_depth=0 --set eval_every=1000 \
    --set threads=1 --set epochs=$ep --seed-ids $seed --methods glint --data "$DATA/r$room" --out "$out"
echo "=== rc=$? $(date -u +%FT%TZ)"
