#!/bin/bash
# lane A, session 40: the `wide` capacity at GLINT's and tsgs's points (60 epochs), 9801 then 9802, seed 0
source "$(dirname "$0")/lanes.sh"
$BENCH $WIDE --set epochs=60 --methods glint --data /work/data98_9801 --out /work/runs98/e60_wide
$BENCH $WIDE --set epochs=60 --methods glint --data /work/data98_ab_9802 --out /work/runs98/e60_wide
$BENCH $WIDE --set epochs=60 --methods tsgs --data /work/data98_9801 --out /work/runs98/e60_wide
$BENCH $WIDE --set epochs=60 --methods tsgs --data /work/data98_ab_9802 --out /work/runs98/e60_wide
