#!/bin/bash
# lane B, session 46: glint at `wide` with the Gaussian cap doubled (max_gaussians 120000), 60 epochs, seed 0, 9802
source "$(dirname "$0")/lanes.sh"
$BENCH $WIDE --set max_gaussians=120000 --set epochs=60 --methods glint --data /work/data98_9802 --out /work/runs98/e60_wide120
