#!/bin/bash
# The fifty-first session's arm (README, "Ellipsoids at the converged point"): GLINT at its converged point
# (converge_98xx's flags: BENCH, GROW, 60 epochs of 96 x 54; coarse start off, as converge_98xx/s48.sh) on the tuning
# rooms 7301-7303, seed 0.
#   bash docs/results/coarse_to_fine/s51.sh base|el|decay2|3dgs|priors [ROOMS]
# base: the preset; el: --set kernel=ellipsoid; decay2: both prior terms fall to 0 over the second half; 3dgs: the 3dgs method with the same command (a reference, decides
# nothing); priors: the priors' rows for the floor (no training), into base's folder. ROOMS: a subset of 7301 7302
# 7303, in order. One Dr.Jit thread a run; code of the worktree WT (pinned at the declaring commit). A finished run
# is skipped.
set -u
source "$(dirname "$0")/../converge_98xx/flags.sh"  # BENCH, GROW
arm=${1:?base, el, decay2, 3dgs or priors}
method=glint; out=$arm; switch=""
case $arm in
  base) ;;
  el) switch="--set kernel=ellipsoid" ;;
  decay2) switch="--set prior_decay_terms=depth,normal --set prior_decay_ref=0" ;;
  3dgs) method=3dgs ;;
  priors) method=priors; out=base ;;
  *) echo "arm '$arm': use base, el, decay2, 3dgs or priors" >&2; exit 2 ;;
esac
rooms=${2:-7301 7302 7303}
data=${DATA73:-/work/data73}
WT=${WT:-/work/wt51}; RUNS=${RUNS:-/work/runs51}
cd "$WT"; export PYTHONPATH=$WT:${WT}_path
for room in $rooms; do
  echo "=== $(date -u +%FT%TZ) c60_$arm $room"
  $BENCH $GROW --set epochs=60 --set coarse_to_fine= --methods $method $switch --data "$data/r$room" \
      --out "$RUNS/c60_$out"
  echo "=== rc=$? $(date -u +%FT%TZ)"
done
