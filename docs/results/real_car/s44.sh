#!/bin/bash
# Forty-fourth session (README, "The coarse start on this capture"): lane A the bench preset as it is (coarse start
# "4:0.2,2:0.2"), lane B the same with it off (coarse_to_fine=), seeds 0-2, GLINT's default (components: auto), then
# components=all. One Dr.Jit thread a lane; code of the worktree WT (pinned to the declaring commit).
#   bash docs/results/real_car/s44.sh A|B
set -u
lane=${1:?A or B}
case $lane in A) C2F=() ;; B) C2F=(--set coarse_to_fine=) ;; *) echo "lane '$lane': use A or B" >&2; exit 2 ;; esac
WT=${WT:-/work/wt44}; RUNS=${RUNS:-/work/runs_car44}
cd "$WT"; export PYTHONPATH=$WT:${WT}_path
PY=${PY:-/work/main/.venv/bin/python}
B=($PY -m glint_mi.benchmark --data /work/shared/data/real_car --preset bench --set downscale=4 --set max_gaussians=40000
   --set threads=1 "${C2F[@]}")
for s in 0 1 2; do "${B[@]}" --methods glint --seed-ids $s --out "$RUNS/auto_$lane"; done
for s in 0 1 2; do "${B[@]}" --methods glint --set components=all --seed-ids $s --out "$RUNS/all_$lane"; done
