#!/bin/bash
# lane A, session 43: seed 1 of glint-paper at its point (120 epochs, growth) on 9803, then 9804
cd /work/wt98
export PYTHONPATH=/work/wt98:/work/wt98_path
PY=/work/main/.venv/bin/python
G="--preset bench --set downscale=2 --set w_sfm_depth=0 --set eval_every=1000 --set threads=1 --set epochs=120 --set densify_top=0.12 --set densify_grad_rel=0.05 --seed-ids 1"
$PY -m glint_mi.benchmark $G --methods glint-paper --data /work/data98_9803 --out /work/runs98/e120_grow_s1
while [ ! -f /work/data98/scene_9804/meta.json ]; do sleep 30; done   # moved in once its summary lines are checked
$PY -m glint_mi.benchmark $G --methods glint-paper --data /work/data98_9804 --out /work/runs98/e120_grow_s1
