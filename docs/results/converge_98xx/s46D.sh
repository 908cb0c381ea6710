#!/bin/bash
# lane B, session 46 (after s46B.sh and coarse_to_fine/s45.sh B's 3dgs runs): glint at its point (60 epochs, growth)
# with the product's SfM depth term (w_sfm_depth 0.1, the default; flags.sh's BENCH sets 0, and in the declared code the later --set wins; today's refuses a field set twice),
# seed 0, 9802 then 9804
source "$(dirname "$0")/lanes.sh"
for room in 9802 9804; do
  $BENCH $GROW --set w_sfm_depth=0.1 --set epochs=60 --methods glint --data /work/data98_$room --out /work/runs98/e60_grow_sfm
done
