#!/bin/bash
# The fifty-fourth session: the converged table's GLINT runs (as s52.sh: --preset converged, the table's protocol
# flags downscale=2 w_sfm_depth=0, one Dr.Jit thread) with each view's depth prior weighed by its agreement with
# the SfM points (depth_prior_ref REF). A finished run is skipped.
#   bash docs/results/converge_98xx/s54.sh ROOM SEED REF
# Folders: RUNS/d54_r<REF> (seed 1 as glint@seed1).
set -u
WT=${WT:-/work/wt54}; RUNS=${RUNS:-/work/runs54}; DATA=${DATA98:-/work/data98_r}; PY=${PY:-/work/main/.venv/bin/python}
room=${1:?a room: 9801 9802 9803 9804}; seed=${2:?a seed: 0 or 1}; ref=${3:?REF: depth_prior_ref, e.g. 0.02}
cd "$WT"; export PYTHONPATH=$WT:${WT}_path
out=$RUNS/d54_r$ref
echo "=== $(date -u +%FT%TZ) $room seed $seed depth_prior_ref $ref -> $out"
$PY -m glint_mi.benchmark --preset converged --set downscale=2 --set w_sfm_depth=0 --set eval_every=1000 \
    --set threads=1 --set depth_prior_ref=$ref --seed-ids $seed --methods glint --data "$DATA/r$room" --out "$out"
echo "=== rc=$? $(date -u +%FT%TZ)"
