#!/bin/bash
# The arms of the forty-eighth and forty-ninth sessions (README, "A split that keeps its parent's footprint", "Two
# arms aimed at the priors' cost off the glass"): GLINT, the bench command of the checks (the preset: its coarse
# start and clone_opacity shared) with one arm's switch.
#   bash docs/results/coarse_to_fine/s49.sh ax|tn5|el tune|check [ROOMS]
# ax: --set split_mode=axis (s48b.sh calls this with its worktree and runs folder); tn5: --set tau_n=0.5 (the
# release's normal-prior mask); el: --set kernel=ellipsoid (3DGS's kernel for every set).
# ROOMS: a subset of the study's rooms, in order (to split it over the two lanes). One Dr.Jit thread a run; code of
# the worktree WT (pinned at the declaring commit). A finished run is skipped.
set -u
PY=${PY:-/work/main/.venv/bin/python}
arm=${1:?ax, tn5 or el}
case $arm in
  ax) switch="--set split_mode=axis" ;;
  tn5) switch="--set tau_n=0.5" ;;
  el) switch="--set kernel=ellipsoid" ;;
  *) echo "arm '$arm': use ax, tn5 or el" >&2; exit 2 ;;
esac
case ${2:?tune or check} in
  tune) rooms="7301 7302 7303"; data=${DATA73:-/work/data73} ;;
  check) rooms="9801 9802 9803"; data=${DATA98:-/work/data98_r} ;;
  *) echo "study '$2': use tune or check" >&2; exit 2 ;;
esac
rooms=${3:-$rooms}
WT=${WT:-/work/wt49}; RUNS=${RUNS:-/work/runs49}
cd "$WT"; export PYTHONPATH=$WT:${WT}_path
for room in $rooms; do
  echo "=== $(date -u +%FT%TZ) $2_$arm $room"
  $PY -m glint_mi.benchmark --preset bench --methods glint --set threads=1 --set eval_every=1000 \
      $switch --data "$data/r$room" --out "$RUNS/$2_$arm"
  echo "=== rc=$? $(date -u +%FT%TZ)"
done
