#!/bin/bash
# lane B, session 40, after glint-paper at 120 wide on 9801: the same on 9802 (the original s40B.sh's last step)
cd /work/wt98
export PYTHONPATH=/work/wt98:/work/wt98_path
PY=/work/main/.venv/bin/python
W="--preset bench --set downscale=2 --set w_sfm_depth=0 --set eval_every=1000 --set threads=1 --set densify_top=0.25 --set densify_grad_rel=0.02"
while pgrep -f "s40B2.sh" > /dev/null; do sleep 20; done
$PY -m glint_mi.benchmark $W --set epochs=120 --methods glint-paper --data /work/data98_ab_9802 --out /work/runs98/e120_wide
