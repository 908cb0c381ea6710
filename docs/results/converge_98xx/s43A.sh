#!/bin/bash
# lane A, session 43: seed 1 of glint-paper at its point (120 epochs, growth) on 9803, then 9804
source "$(dirname "$0")/lanes.sh"
G="$BENCH $GROW --set epochs=120 --seed-ids 1"
$G --methods glint-paper --data /work/data98_9803 --out /work/runs98/e120_grow_s1
while [ ! -f /work/data98/scene_9804/meta.json ]; do sleep 30; done   # moved in once its summary lines are checked
$G --methods glint-paper --data /work/data98_9804 --out /work/runs98/e120_grow_s1
