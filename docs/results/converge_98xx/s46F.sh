#!/bin/bash
# lane B, session 46 (after s46B.sh, coarse_to_fine/s45.sh B's 3dgs runs): glint at `wide` with the Gaussian cap
# doubled (max_gaussians 120000), 60 epochs, seed 0, on 9804: the other two rooms of the converged table
source "$(dirname "$0")/lanes.sh"
$BENCH $WIDE --set max_gaussians=120000 --set epochs=60 --methods glint --data /work/data98_9804 --out /work/runs98/e60_wide120
