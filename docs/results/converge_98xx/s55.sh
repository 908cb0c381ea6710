#!/bin/bash
# The fifty-fifth session: the converged table's GLINT runs (as s54.sh: --preset converged, the table's protocol
# flags downscale=2 w_sfm_depth=0, one Dr.Jit thread, the default depth_prior_ref 0.02) with a Gaussian cap that
# rises over the growth window (cap_schedule CAP). A finished run is skipped.
#   bash docs/results/converge_98xx/s55.sh ROOM SEED CAP      (CAP: linear)
# Folders: RUNS/c55_<CAP> (seed 1 as glint@seed1).
set -u
WT=${WT:-/work/wt55}; RUNS=${RUNS:-/work/runs55}; DATA=${DATA98:-/work/data98_r}; PY=${PY:-/work/main/.venv/bin/python}
room=${1:?a room: 9801 9802 9803 9804}; seed=${2:?a seed: 0 or 1}; cap=${3:?CAP: cap_schedule, e.g. linear}
cd "$WT"; export PYTHONPATH=$WT:${WT}_path
out=$RUNS/c55_$cap
echo "=== $(date -u +%FT%TZ) $room seed $seed cap_schedule $cap -> $out"
$PY -m glint_mi.benchmark --preset converged --set downscale=2 --set w_sfm_depth=0 --set eval_every=1000 \
    --set threads=1 --set cap_schedule=$cap --seed-ids $seed --methods glint --data "$DATA/r$room" --out "$out"
echo "=== rc=$? $(date -u +%FT%TZ)"
