#!/bin/bash
# session 48: GLINT at its point (60 epochs of 96 x 54, growth) with today's code, whose bench preset gives it
# clone_opacity: shared; the bench preset's coarse start is turned off (coarse_to_fine=), as in `e60_grow_head`,
# whose config differs from these runs' in clone_opacity alone (and grow_until -1, which changes nothing). Seed 0.
#   bash docs/results/converge_98xx/s48.sh ROOM [ROOM...]
# Code: the worktree WT (default /work/wt48, pinned at the commit that declares these runs).
set -u
source "$(dirname "$0")/flags.sh"
WT=${WT:-/work/wt48}; cd "$WT"; export PYTHONPATH=$WT:${WT}_path
for room in "${@:?rooms: 9801 9802 9803 9804}"; do
  echo "=== $(date -u +%FT%TZ) e60_grow_sh $room"
  $BENCH $GROW --set epochs=60 --set coarse_to_fine= --methods glint --data /work/data98_$room --out /work/runs98/e60_grow_sh
  echo "=== rc=$? $(date -u +%FT%TZ)"
done
