#!/bin/bash
# The fiftieth session's arm (README, "A normal of its own"): GLINT, the bench command of the tuning runs (the
# preset: its coarse start and clone_opacity shared), on the tuning rooms regenerated on this session's machine.
#   bash docs/results/coarse_to_fine/s50.sh base|na|3dgs|priors [ROOMS]
# base: the preset (normal_source axis); na: --set normal_source=attribute; 3dgs: the 3dgs method with the same
# command (a reference, decides nothing); priors: the priors' rows for the floor (no training), into base's folder.
# ROOMS: a subset of 7301 7302 7303, in order (to split the work over two lanes). One Dr.Jit thread a run; code of
# the worktree WT (pinned at the declaring commit). A finished run is skipped.
set -u
PY=${PY:-/work/main/.venv/bin/python}
arm=${1:?base, na, 3dgs or priors}
method=glint; out=$arm; switch=""
case $arm in
  base) ;;
  na) switch="--set normal_source=attribute" ;;
  3dgs) method=3dgs ;;
  priors) method=priors; out=base ;;
  *) echo "arm '$arm': use base, na, 3dgs or priors" >&2; exit 2 ;;
esac
rooms=${2:-7301 7302 7303}
data=${DATA73:-/work/data73}
WT=${WT:-/work/wt50}; RUNS=${RUNS:-/work/runs50}
cd "$WT"; export PYTHONPATH=$WT:${WT}_path
for room in $rooms; do
  echo "=== $(date -u +%FT%TZ) tune_$arm $room"
  $PY -m glint_mi.benchmark --preset bench --methods $method --set threads=1 --set eval_every=1000 \
      $switch --data "$data/r$room" --out "$RUNS/tune_$out"
  echo "=== rc=$? $(date -u +%FT%TZ)"
done
