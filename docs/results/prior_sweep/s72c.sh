#!/bin/bash
# The seventy-second session (README, "The two bench-rays misses at the converged preset"): GLINT and the priors' row
# at `--preset converged` as a user gets it (60 epochs of 96 x 54 with growth, ellipsoids), with the sweep's flags
# (downscale=2 w_sfm_depth=0, one Dr.Jit thread), on one room-level and seed. A finished run is skipped.
#   bash docs/results/prior_sweep/s72c.sh ROOM NAME SEED      (7303 own, or 7302 see_0.2; SEED 0 or 1)
# NAME own: the room's own priors (DATA/rROOM); see_0.2: the see-through level (DATA/levels_ROOM/see_0.2, made by
# levels.sh if absent). Folder RUNS/c72_NAME_ROOM (seed 1 as METHOD@seed1). WT (the code: a worktree), RUNS, DATA, PY.
# PRESET=bench: the bench preset as a user gets it at the rooms' own 192 x 108 (10 epochs: the rays of 40 epochs at
# 96 x 54), the same flags but downscale; folder RUNS/b72_NAME_ROOM.
set -u
WT=${WT:?WT: the worktree of the declared code}; RUNS=${RUNS:?RUNS: where the runs go}
DATA=${DATA:-/work/data73}; PY=${PY:-/work/main/.venv/bin/python}
room=${1:?ROOM: 7303 or 7302}; name=${2:?NAME: own or see_0.2}; seed=${3:?SEED: 0 or 1}
here=$(cd "$(dirname "$0")" && pwd)
case $name in
  own) data="$DATA/r$room" ;;
  see_*) source "$here/levels.sh"; LEVELS="$DATA/levels_$room" level $name $room --model realistic \
           --see-through ${name#see_} || exit 1; data="$DATA/levels_$room/$name" ;;
  *) echo "unknown level '$name': own or see_P" >&2; exit 2 ;;
esac
[ -d "$data" ] || { echo "no room at $data" >&2; exit 2; }
cd "$WT" && export PYTHONPATH=$WT:${WT}_path || exit 1
case ${PRESET:=converged} in
  converged) flags="--preset converged --set downscale=2"; tag=c72 ;;
  bench) flags="--preset bench"; tag=b72 ;;
  *) echo "PRESET '$PRESET': converged or bench" >&2; exit 2 ;;
esac
echo "=== $(date -u +%FT%TZ) $PRESET $name $room seed $seed"
$PY -m glint_mi.benchmark $flags --set w_sfm_depth=0 --set threads=1 \
    --set eval_every=1000 --seed-ids $seed --methods priors,glint --data "$data" --out "$RUNS/${tag}_${name}_$room"
echo "=== rc=$? $(date -u +%FT%TZ)"
