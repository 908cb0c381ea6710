#!/bin/bash
# lane B, session 43: 3dgs-priors at its point (30 epochs, growth) seed 1 on 9801-9803 and seed 0 on 9803; seed 1 of
# glint-paper at its point (120 epochs, growth) on 9801, then 9802; then 3dgs-priors on 9804 (seeds 0 and 1)
source "$(dirname "$0")/lanes.sh"
P="$BENCH $GROW --set epochs=30 --methods 3dgs-priors"
G="$BENCH $GROW --set epochs=120 --methods glint-paper --seed-ids 1"
for s in 9801 9802 9803; do $P --seed-ids 1 --data /work/data98_$s --out /work/runs98/e30_grow_s1; done
$P --data /work/data98_9803 --out /work/runs98/e30_grow
$G --data /work/data98_9801 --out /work/runs98/e120_grow_s1
$G --data /work/data98_9802 --out /work/runs98/e120_grow_s1
while [ ! -f /work/data98/scene_9804/meta.json ]; do sleep 30; done
$P --data /work/data98_9804 --out /work/runs98/e30_grow
$P --seed-ids 1 --data /work/data98_9804 --out /work/runs98/e30_grow_s1
