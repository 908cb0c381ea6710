#!/bin/bash
# Forty-eighth session (README, "A split that keeps its parent's footprint"): GLINT, the bench command of the
# checks (the preset: its coarse start and clone_opacity shared) with split_mode=axis.
#   bash docs/results/coarse_to_fine/s48b.sh tune|check [ROOMS]
# ROOMS: a subset of the study's rooms, in order (to split it over the two lanes). One Dr.Jit thread a run; code of
# the worktree WT (pinned at the declaring commit). A finished run is skipped.
set -u
PY=${PY:-/work/main/.venv/bin/python}
case ${1:?tune or check} in
  tune) rooms="7301 7302 7303"; data=${DATA73:-/work/data73} ;;
  check) rooms="9801 9802 9803"; data=${DATA98:-/work/data98_r} ;;
  *) echo "study '$1': use tune or check" >&2; exit 2 ;;
esac
rooms=${2:-$rooms}
WT=${WT:-/work/wt48b}; RUNS=${RUNS:-/work/runs48}
cd "$WT"; export PYTHONPATH=$WT:${WT}_path
for room in $rooms; do
  echo "=== $(date -u +%FT%TZ) $1_ax $room"
  $PY -m glint_mi.benchmark --preset bench --methods glint --set threads=1 --set eval_every=1000 \
      --set split_mode=axis --data "$data/r$room" --out "$RUNS/$1_ax"
  echo "=== rc=$? $(date -u +%FT%TZ)"
done
