#!/bin/bash
# lane B, session 40, from 04:5x: GLINT at the wide capacity on 9803 (seed 0, 60 epochs), then glint-paper at 120 wide on 9801
source "$(dirname "$0")/lanes.sh"
$BENCH $WIDE --set epochs=60 --methods glint --data /work/data98_9803 --out /work/runs98/e60_wide
$BENCH $WIDE --set epochs=120 --methods glint-paper --data /work/data98_9801 --out /work/runs98/e120_wide
