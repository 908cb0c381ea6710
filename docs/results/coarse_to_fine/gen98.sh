#!/bin/bash
# The check rooms 9801-9803 of docs/results/converge_98xx, rendered again with their declared code (cafd86a, a
# worktree at /work/wt98 as that README's "Resuming on another machine") and their kept SfM points; each room then
# gets a folder of its own (/work/data98_r/r<room>/scene_<room>, a link) for the benchmark.
set -eu
cd /work/wt98
GLINT_CYCLES_PYTHON=/work/main/.venv-cycles/bin/python PYTHONPATH=/work/wt98:/work/wt98_path /work/main/.venv/bin/python -m glint_mi.dataset make /work/data98 \
    --scenes 3 --seed 9801 --preset bench --views 48 --spp 128 --renderer cycles
for room in 9801 9802 9803; do
  rm -rf /work/data98/scene_$room/sparse && cp -r /tmp/sfm98/scene_$room/sparse /work/data98/scene_$room/sparse
  mkdir -p /work/data98_r/r$room && ln -sfn /work/data98/scene_$room /work/data98_r/r$room/scene_$room
done
