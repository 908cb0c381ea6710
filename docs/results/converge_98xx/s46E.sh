#!/bin/bash
# lane A, session 46 (after s46A.sh, coarse_to_fine/s45.sh A's 3dgs runs): glint at `wide` with the Gaussian cap
# doubled (max_gaussians 120000), 60 epochs, seed 0, on 9803: the other two rooms of the converged table
source "$(dirname "$0")/lanes.sh"
$BENCH $WIDE --set max_gaussians=120000 --set epochs=60 --methods glint --data /work/data98_9803 --out /work/runs98/e60_wide120
