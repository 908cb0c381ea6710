#!/bin/bash
# lane B, session 40, after glint-paper at 120 wide on 9801: the same on 9802 (the original s40B.sh's last step)
source "$(dirname "$0")/lanes.sh"
while pgrep -f "s40B2.sh" > /dev/null; do sleep 20; done
$BENCH $WIDE --set epochs=120 --methods glint-paper --data /work/data98_ab_9802 --out /work/runs98/e120_wide
