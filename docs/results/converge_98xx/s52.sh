#!/bin/bash
# The fifty-second session: the converged table's GLINT rows with `--preset converged` (ellipsoids), through the
# product's preset rather than flags.sh's spelled-out flags; the table's protocol flags (downscale=2 w_sfm_depth=0,
# as flags.sh's BENCH) and one Dr.Jit thread a run. A finished run is skipped.
#   bash docs/results/converge_98xx/s52.sh ROOM SEED [EPOCHS [wide]]   (EPOCHS: 60 unless given; 120 for the stopping
#   check in epochs; `wide`: flags.sh's WIDE capacity, the check in capacity)
# Folders: RUNS/el60_s<SEED> (seed 0 of 9801-9803 are the fifty-first session's s51_c98xx_el), RUNS/el120 (seed 0),
# RUNS/el60_wide (seed 0).
set -u
WT=${WT:-/work/wt52}; RUNS=${RUNS:-/work/runs52}; DATA=${DATA98:-/work/data98_r}; PY=${PY:-/work/main/.venv/bin/python}
room=${1:?a room: 9801 9802 9803 9804}; seed=${2:?a seed: 0 or 1}; epochs=${3:-60}; cap=${4:-grow}
cd "$WT"; export PYTHONPATH=$WT:${WT}_path
case $cap in
  grow) capflags=""; if [ "$epochs" = 60 ]; then out=$RUNS/el60_s$seed; else out=$RUNS/el$epochs; fi ;;
  wide) capflags="--set densify_top=0.25 --set densify_grad_rel=0.02"; out=$RUNS/el${epochs}_wide ;;  # flags.sh's WIDE
  *) echo "capacity '$cap': use grow or wide" >&2; exit 2 ;;
esac
echo "=== $(date -u +%FT%TZ) $room seed $seed epochs $epochs $cap -> $out"
$PY -m glint_mi.benchmark --preset converged --set downscale=2 --set w_sfm_depth=0 --set eval_every=1000 \
    --set threads=1 --set epochs=$epochs $capflags --seed-ids $seed --methods glint --data "$DATA/r$room" --out "$out"
echo "=== rc=$? $(date -u +%FT%TZ)"
