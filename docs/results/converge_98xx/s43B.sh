#!/bin/bash
# lane B, session 43: 3dgs-priors at its point (30 epochs, growth) seed 1 on 9801-9803 and seed 0 on 9803; seed 1 of
# glint-paper at its point (120 epochs, growth) on 9801, then 9802; then 3dgs-priors on 9804 (seeds 0 and 1)
cd /work/wt98
export PYTHONPATH=/work/wt98:/work/wt98_path
PY=/work/main/.venv/bin/python
F="--preset bench --set downscale=2 --set w_sfm_depth=0 --set eval_every=1000 --set threads=1 --set densify_top=0.12 --set densify_grad_rel=0.05"
P="$PY -m glint_mi.benchmark $F --set epochs=30 --methods 3dgs-priors"
G="$PY -m glint_mi.benchmark $F --set epochs=120 --methods glint-paper --seed-ids 1"
for s in 9801 9802 9803; do $P --seed-ids 1 --data /work/data98_$s --out /work/runs98/e30_grow_s1; done
$P --data /work/data98_9803 --out /work/runs98/e30_grow
$G --data /work/data98_9801 --out /work/runs98/e120_grow_s1
$G --data /work/data98_9802 --out /work/runs98/e120_grow_s1
while [ ! -f /work/data98/scene_9804/meta.json ]; do sleep 30; done
$P --data /work/data98_9804 --out /work/runs98/e30_grow
$P --seed-ids 1 --data /work/data98_9804 --out /work/runs98/e30_grow_s1
