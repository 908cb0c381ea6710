#!/bin/bash
# Forty-sixth session (README, "Densification past the coarse stages"): the bench command of lanes.sh (glint or
# 3dgs, seed 0, the preset's coarse start) with densification lasting to a later share of the run.
#   bash docs/results/coarse_to_fine/s46.sh ARM STUDY [ROOMS]
#   ARM:   d50 (densify_until=0.5) or d60 (densify_until=0.6); the preset's is 0.35 (21/60)
#   STUDY: tune (glint, tuning rooms 7301-7303), check (glint, declared rooms 9801-9803), tune3dgs (3dgs, 7301-7303)
#   ROOMS: a subset of the study's rooms, in order (to split a study over the two lanes)
# One Dr.Jit thread a run; code of the worktree WT (pinned to the declaring commit). A finished run is skipped (the
# benchmark reads its metrics.json), so a lane restarts where it stopped.
set -u
arm=${1:?d50 or d60}; study=${2:?tune, check or tune3dgs}
case $arm in d50) until=0.5 ;; d60) until=0.6 ;; *) echo "arm '$arm': use d50 or d60" >&2; exit 2 ;; esac
case $study in
  tune) method=glint; rooms="7301 7302 7303"; data=${DATA73:-/work/data73} ;;
  tune3dgs) method=3dgs; rooms="7301 7302 7303"; data=${DATA73:-/work/data73} ;;
  check) method=glint; rooms="9801 9802 9803"; data=${DATA98:-/work/data98_r} ;;
  *) echo "study '$study': use tune, check or tune3dgs" >&2; exit 2 ;;
esac
rooms=${3:-$rooms}
WT=${WT:-/work/wt46}; RUNS=${RUNS:-/work/runs46}; PY=${PY:-/work/main/.venv/bin/python}
cd "$WT"; export PYTHONPATH=$WT:${WT}_path
for room in $rooms; do
  echo "=== $(date -u +%FT%TZ) $method $arm $room"
  $PY -m glint_mi.benchmark --preset bench --methods $method --set threads=1 --set eval_every=1000 \
      --set densify_until=$until --data "$data/r$room" --out "$RUNS/${study%3dgs}_$arm"
  echo "=== rc=$? $(date -u +%FT%TZ)"
done
