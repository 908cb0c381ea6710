#!/bin/bash
# Forty-ninth session (README, "Where the 1.3x minutes come from"): the first 240 s of GLINT's converged-point run
# on 9801 (flags.sh's BENCH and GROW, 60 epochs, seed 0), stopped by timeout; log.csv's rays_per_s is read after.
#   bash docs/results/converge_98xx/s49ab.sh copy|shared|declared
# copy / shared: today's code (worktree WT, default /work/wt49) with clone_opacity copy or shared, coarse start off;
# declared: the declared code's worktree (/work/wt98, cafd86a: copy, constant prior weights, no coarse start).
set -u
source "$(dirname "$0")/flags.sh"
arm=${1:?copy, shared or declared}
case $arm in
  copy|shared) WT=${WT:-/work/wt49}; extra="--set coarse_to_fine= --set clone_opacity=$arm" ;;
  declared) WT=/work/wt98; extra="" ;;
  *) echo "arm '$arm': use copy, shared or declared" >&2; exit 2 ;;
esac
cd "$WT"; export PYTHONPATH=$WT:${WT}_path
echo "=== $(date -u +%FT%TZ) ab_$arm"
timeout 240 $BENCH $GROW --set epochs=60 $extra --methods glint --data /work/data98_9801 --out /work/runs49/ab_$arm${TAG:-}
echo "=== rc=$? $(date -u +%FT%TZ)"
