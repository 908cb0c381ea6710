#!/bin/bash
# Forty-fifth session (README, "At 96 x 54 and the converged budget"): rooms 9801-9804, seed 0, GLINT's converged
# point (60 epochs of 96 x 54 with growth, converge_98xx's flags), today's bench preset otherwise.
#   bash docs/results/coarse_to_fine/s45.sh A|B
# Lane A: GLINT without the coarse start (4 rooms), GLINT with stages of 2 epochs each on 9801-9802, then 3dgs without.
# Lane B: GLINT with the preset's coarse start (4 rooms), the 2-epoch stages on 9803-9804, then 3dgs with it.
# One Dr.Jit thread a lane; code of the worktree WT (pinned to the declaring commit). A finished run is skipped (the
# benchmark reads its metrics.json), so a lane restarts where it stopped.
set -u
lane=${1:?A or B}
WT=${WT:-/work/wt45}; RUNS=${RUNS:-/work/runs45}; D=${DATA:-/work/data98}
case $lane in
  A) mine=(--set coarse_to_fine=); tag=none; pair=${D}_12 ;;
  B) mine=(); tag=preset; pair=${D}_34 ;;
  *) echo "lane '$lane': use A or B" >&2; exit 2 ;;
esac
source "$(dirname "$0")/../converge_98xx/flags.sh"  # BENCH, GROW: converge_98xx's converged runs
cd "$WT"; export PYTHONPATH=$WT:${WT}_path
B=($BENCH --set epochs=60 $GROW --seed-ids 0)
run() { echo "=== $(date -u +%FT%TZ) $*"; "$@"; echo "=== rc=$? $(date -u +%FT%TZ)"; }
run "${B[@]}" --methods glint "${mine[@]}" --data "$D" --out "$RUNS/glint_$tag"
run "${B[@]}" --methods glint --set coarse_to_fine=4:0.0333,2:0.0333 --data "$pair" --out "$RUNS/glint_epochs2"
run "${B[@]}" --methods 3dgs "${mine[@]}" --data "$D" --out "$RUNS/3dgs_$tag"
