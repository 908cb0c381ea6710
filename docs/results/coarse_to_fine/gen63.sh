#!/bin/bash
# The check rooms 9801-9803 rendered again for the sixty-third session's check of `copy` (README, "What costs GLINT
# against `3dgs` at 40 epochs of 96 x 54"): gen98.sh's command at the declared code (cafd86a, worktree /work/wt98)
# with `--sfm none`, one room a command (`--scenes 1 --seed ROOM`), the kept SfM points (/tmp/sfm98, from
# converge_98xx/rooms_sfm.tgz) copied over; then the room's folder /work/data98_r/rROOM/scene_ROOM (a link).
#   bash docs/results/coarse_to_fine/gen63.sh ROOM       (9801, 9802 or 9803)
set -eu
room=${1:?9801, 9802 or 9803}
cd /work/wt98
GLINT_CYCLES_PYTHON=/work/main/.venv-cycles/bin/python PYTHONPATH=/work/wt98:/work/wt98_path /work/main/.venv/bin/python \
    -m glint_mi.dataset make /work/data98 --scenes 1 --seed $room --preset bench --views 48 --spp 128 --renderer cycles \
    --sfm none
rm -rf /work/data98/scene_$room/sparse && cp -r /tmp/sfm98/scene_$room/sparse /work/data98/scene_$room/sparse
mkdir -p /work/data98_r/r$room && ln -sfn /work/data98/scene_$room /work/data98_r/r$room/scene_$room
