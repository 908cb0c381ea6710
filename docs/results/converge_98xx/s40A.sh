#!/bin/bash
# lane A, session 40: the `wide` capacity at GLINT's and tsgs's points (60 epochs), 9801 then 9802, seed 0
cd /work/wt98
export PYTHONPATH=/work/wt98:/work/wt98_path
PY=/work/main/.venv/bin/python
W="--preset bench --set downscale=2 --set w_sfm_depth=0 --set eval_every=1000 --set threads=1 --set densify_top=0.25 --set densify_grad_rel=0.02"
$PY -m glint_mi.benchmark $W --set epochs=60 --methods glint --data /work/data98_9801 --out /work/runs98/e60_wide
$PY -m glint_mi.benchmark $W --set epochs=60 --methods glint --data /work/data98_ab_9802 --out /work/runs98/e60_wide
$PY -m glint_mi.benchmark $W --set epochs=60 --methods tsgs --data /work/data98_9801 --out /work/runs98/e60_wide
$PY -m glint_mi.benchmark $W --set epochs=60 --methods tsgs --data /work/data98_ab_9802 --out /work/runs98/e60_wide
