#!/bin/bash
# session 48, after s48.sh: seed 1 of GLINT at its point with today's code (s48.sh's command, --seed-ids 1), one room:
#   bash docs/results/converge_98xx/s48b.sh 9801|9802|9803|9804   (9803-9804: the forty-ninth session)
set -u
source "$(dirname "$0")/flags.sh"
WT=${WT:-/work/wt48}; cd "$WT"; export PYTHONPATH=$WT:${WT}_path
room=${1:?a room: 9801 9802 9803 9804}
echo "=== $(date -u +%FT%TZ) e60_grow_sh_s1 $room"
$BENCH $GROW --set epochs=60 --set coarse_to_fine= --seed-ids 1 --methods glint --data /work/data98_$room \
  --out /work/runs98/e60_grow_sh_s1
echo "=== rc=$? $(date -u +%FT%TZ)"
