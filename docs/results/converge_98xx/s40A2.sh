#!/bin/bash
# lane A, session 40, after GLINT on 9802 at wide: GLINT at wide on 9804 (seed 0, 60 epochs), then tsgs at 60 wide on 9801, 9802
cd /work/wt98
export PYTHONPATH=/work/wt98:/work/wt98_path
PY=/work/main/.venv/bin/python
W="--preset bench --set downscale=2 --set w_sfm_depth=0 --set eval_every=1000 --set threads=1 --set densify_top=0.25 --set densify_grad_rel=0.02"
while pgrep -f "methods glint --data /work/data98_ab_9802" > /dev/null; do sleep 20; done
$PY -m glint_mi.benchmark $W --set epochs=60 --methods glint --data /work/data98_9804 --out /work/runs98/e60_wide
$PY -m glint_mi.benchmark $W --set epochs=60 --methods tsgs --data /work/data98_9801 --out /work/runs98/e60_wide
$PY -m glint_mi.benchmark $W --set epochs=60 --methods tsgs --data /work/data98_ab_9802 --out /work/runs98/e60_wide
