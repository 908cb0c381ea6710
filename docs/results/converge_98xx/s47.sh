#!/bin/bash
# session 47: seed 1 of glint at `wide` with the Gaussian cap doubled (max_gaussians 120000), 60 epochs, one room:
#   bash docs/results/converge_98xx/s47.sh 9801|9802
source "$(dirname "$0")/lanes.sh"
room=${1:?9801 or 9802}
$BENCH $WIDE --set max_gaussians=120000 --set epochs=60 --seed-ids 1 --methods glint --data /work/data98_$room \
  --out /work/runs98/e60_wide120_s1
