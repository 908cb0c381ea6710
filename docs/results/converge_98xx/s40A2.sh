#!/bin/bash
# lane A, session 40, after GLINT on 9802 at wide: GLINT at wide on 9804 (seed 0, 60 epochs), then tsgs at 60 wide on 9801, 9802
source "$(dirname "$0")/lanes.sh"
while pgrep -f "methods glint --data /work/data98_ab_9802" > /dev/null; do sleep 20; done
$BENCH $WIDE --set epochs=60 --methods glint --data /work/data98_9804 --out /work/runs98/e60_wide
$BENCH $WIDE --set epochs=60 --methods tsgs --data /work/data98_9801 --out /work/runs98/e60_wide
$BENCH $WIDE --set epochs=60 --methods tsgs --data /work/data98_ab_9802 --out /work/runs98/e60_wide
