#!/bin/bash
# The check rooms 9801-9803 of docs/results/converge_98xx, rendered again with their declared code (cafd86a, a
# worktree at /work/wt98 as that README's "Resuming on another machine") and their kept SfM points; each room then
# gets a folder of its own (/work/data98_r/r<room>/scene_<room>, a link) for the benchmark.
#   bash docs/results/coarse_to_fine/gen98.sh            the three rooms in one command
#   bash docs/results/coarse_to_fine/gen98.sh ROOM       one room (--scenes 1 --seed ROOM) without SfM of its own
#                                                        (--sfm none; the kept points replace it either way), so
#                                                        that three commands render side by side (sixty-first and
#                                                        sixty-third sessions)
set -eu
if [ $# -gt 0 ]; then
  case $1 in 980[123]) ;; *) echo "room '$1': 9801, 9802 or 9803" >&2; exit 2 ;; esac
  rooms=$1; make_args="--scenes 1 --seed $1 --sfm none"
else
  rooms="9801 9802 9803"; make_args="--scenes 3 --seed 9801"
fi
cd /work/wt98
GLINT_CYCLES_PYTHON=/work/main/.venv-cycles/bin/python PYTHONPATH=/work/wt98:/work/wt98_path /work/main/.venv/bin/python -m glint_mi.dataset make /work/data98 \
    $make_args --preset bench --views 48 --spp 128 --renderer cycles
for room in $rooms; do
  rm -rf /work/data98/scene_$room/sparse && cp -r /tmp/sfm98/scene_$room/sparse /work/data98/scene_$room/sparse
  mkdir -p /work/data98_r/r$room && ln -sfn /work/data98/scene_$room /work/data98_r/r$room/scene_$room
done
