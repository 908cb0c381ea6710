#!/bin/bash
# issue 66 runs on rooms 9801-9804 with the declared code (worktree /work/wt98 at cafd86a), in the declared order,
# in two lanes of one thread each (two trainings share the 2 cores)
cd /work/wt98
export PYTHONPATH=/work/wt98:/work/wt98_path
PY=/work/main/.venv/bin/python
B="$PY -m glint_mi.benchmark --data /work/data98 --preset bench --set downscale=2 --set w_sfm_depth=0 --set eval_every=1000 --set threads=1"
GROW="--set densify_top=0.12 --set densify_grad_rel=0.05"
DEF="--set densify_top=0.05 --set densify_grad_rel=0.12"
WIDE="--set densify_top=0.25 --set densify_grad_rel=0.02"
C=/work/data98_curve   # rooms 9801 and 9802 (links)
mkdir -p $C && ln -sfn /work/data98/scene_9801 $C/scene_9801 && ln -sfn /work/data98/scene_9802 $C/scene_9802
run() { echo "=== $(date -u +%FT%TZ) $*"; "$@"; echo "=== done rc=$? $(date -u +%FT%TZ)"; }
laneA() {
  run $B --methods glint --set epochs=120 $GROW --out /work/runs98/e120_grow_a
  run $B --methods glint-paper --set epochs=120 $GROW --out /work/runs98/e120_grow_c
  run ${B/\/work\/data98 /$C } --methods glint,glint-paper --set epochs=240 $GROW --out /work/runs98/e240_grow_a
}
laneB() {
  run $B --methods 3dgs,3dgs-priors --set epochs=120 $GROW --out /work/runs98/e120_grow_b
  run $B --methods tsgs --set epochs=120 $GROW --out /work/runs98/e120_grow_d
  run ${B/\/work\/data98 /$C } --methods 3dgs,3dgs-priors,tsgs --set epochs=240 $GROW --out /work/runs98/e240_grow_b
  run ${B/\/work\/data98 /$C } --methods glint,glint-paper,3dgs,3dgs-priors,tsgs --set epochs=60 $GROW --out /work/runs98/e60_grow
}
laneA > /work/runs98/laneA.log 2>&1 &
laneB > /work/runs98/laneB.log 2>&1 &
wait
