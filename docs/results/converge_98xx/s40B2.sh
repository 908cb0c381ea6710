#!/bin/bash
# lane B, session 40, from 04:5x: GLINT at the wide capacity on 9803 (seed 0, 60 epochs), then glint-paper at 120 wide on 9801
cd /work/wt98
export PYTHONPATH=/work/wt98:/work/wt98_path
PY=/work/main/.venv/bin/python
W="--preset bench --set downscale=2 --set w_sfm_depth=0 --set eval_every=1000 --set threads=1 --set densify_top=0.25 --set densify_grad_rel=0.02"
$PY -m glint_mi.benchmark $W --set epochs=60 --methods glint --data /work/data98_9803 --out /work/runs98/e60_wide
$PY -m glint_mi.benchmark $W --set epochs=120 --methods glint-paper --data /work/data98_9801 --out /work/runs98/e120_wide
