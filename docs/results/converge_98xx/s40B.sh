#!/bin/bash
# lane B, session 40: the `wide` capacity at 3dgs's point (60), 3dgs-priors's (30), then glint-paper's (120), seed 0
source "$(dirname "$0")/lanes.sh"
$BENCH $WIDE --set epochs=60 --methods 3dgs --data /work/data98_curve --out /work/runs98/e60_wide
$BENCH $WIDE --set epochs=30 --methods 3dgs-priors --data /work/data98_curve --out /work/runs98/e30_wide
$BENCH $WIDE --set epochs=120 --methods glint-paper --data /work/data98_9801 --out /work/runs98/e120_wide
$BENCH $WIDE --set epochs=120 --methods glint-paper --data /work/data98_ab_9802 --out /work/runs98/e120_wide
