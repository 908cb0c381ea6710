#!/bin/bash
# issue 66 runs on rooms 9801-9804 with the declared code (worktree /work/wt98 at cafd86a), in the declared order,
# in two lanes of one thread each (two trainings share the 2 cores)
source "$(dirname "$0")/lanes.sh"
B="$BENCH --data /work/data98"
C=/work/data98_curve   # rooms 9801 and 9802 (links)
mkdir -p $C && ln -sfn /work/data98/scene_9801 $C/scene_9801 && ln -sfn /work/data98/scene_9802 $C/scene_9802
BC="$BENCH --data $C"
run() { echo "=== $(date -u +%FT%TZ) $*"; "$@"; echo "=== done rc=$? $(date -u +%FT%TZ)"; }
laneA() {
  run $B --methods glint --set epochs=120 $GROW --out /work/runs98/e120_grow_a
  run $B --methods glint-paper --set epochs=120 $GROW --out /work/runs98/e120_grow_c
  run $BC --methods glint,glint-paper --set epochs=240 $GROW --out /work/runs98/e240_grow_a
}
laneB() {
  run $B --methods 3dgs,3dgs-priors --set epochs=120 $GROW --out /work/runs98/e120_grow_b
  run $B --methods tsgs --set epochs=120 $GROW --out /work/runs98/e120_grow_d
  run $BC --methods 3dgs,3dgs-priors,tsgs --set epochs=240 $GROW --out /work/runs98/e240_grow_b
  run $BC --methods glint,glint-paper,3dgs,3dgs-priors,tsgs --set epochs=60 $GROW --out /work/runs98/e60_grow
}
laneA > /work/runs98/laneA.log 2>&1 &
laneB > /work/runs98/laneB.log 2>&1 &
wait
