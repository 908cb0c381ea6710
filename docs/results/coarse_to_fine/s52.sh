#!/bin/bash
# The fifty-second session (README, "7303 at the converged point, seed 1"): GLINT (`el`, the converged preset) or
# `3dgs` at the converged point on one tuning room at one seed; `elwide`: GLINT at the preset with converge_98xx's
# flags.sh WIDE capacity ("GLINT's capacity at the converged point").
#   bash docs/results/coarse_to_fine/s52.sh el|3dgs|elwide ROOM SEED
# One Dr.Jit thread; code of the worktree WT. A finished run is skipped. Folder RUNS/c60_<arm>_s<SEED>.
set -u
arm=${1:?el or 3dgs}; room=${2:?a room: 7301 7302 7303}; seed=${3:?a seed}
cap=""
case $arm in
  el) method=glint ;;
  3dgs) method=3dgs ;;
  elwide) method=glint; cap="--set densify_top=0.25 --set densify_grad_rel=0.02" ;;  # flags.sh's WIDE
  *) echo "arm '$arm': use el, 3dgs or elwide" >&2; exit 2 ;;
esac
WT=${WT:-/work/wt52}; RUNS=${RUNS:-/work/runs52}; DATA=${DATA73:-/work/data73}; PY=${PY:-/work/main/.venv/bin/python}
cd "$WT"; export PYTHONPATH=$WT:${WT}_path
echo "=== $(date -u +%FT%TZ) c60_$arm $room seed $seed"
$PY -m glint_mi.benchmark --preset converged --set downscale=2 --set w_sfm_depth=0 --set eval_every=1000 \
    --set threads=1 $cap --seed-ids $seed --methods $method --data "$DATA/r$room" --out "$RUNS/c60_${arm}_s$seed"
echo "=== rc=$? $(date -u +%FT%TZ)"
