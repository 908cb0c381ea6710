#!/bin/bash
# lane A, session 40, after tsgs at wide: seed 1 of tsgs at its point (60 epochs, growth) on 9803, then 9804
source "$(dirname "$0")/lanes.sh"
G="$BENCH $GROW --set epochs=60 --seed-ids 1"
while pgrep -f "s40A2.sh" > /dev/null; do sleep 20; done
$G --methods tsgs --data /work/data98_9803 --out /work/runs98/e60_grow_s1
$G --methods tsgs --data /work/data98_9804 --out /work/runs98/e60_grow_s1
