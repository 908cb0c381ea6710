#!/bin/bash
# Forty-ninth session (README, "Seeds 1 and 2 of the coarse start"): s48.sh c2f's command (GLINT, the bench preset
# with its coarse start; on the fox it trains as the 3dgs method) at another seed; one Dr.Jit thread; code of WT.
#   bash docs/results/real_fox/s49.sh SEED
set -u
seed=${1:?SEED: 1 or 2}
WT=${WT:-/work/wt49}; RUNS=${RUNS:-/work/runs49}
cd "$WT"; export PYTHONPATH=$WT:${WT}_path
PY=${PY:-/work/main/.venv/bin/python}
echo "=== $(date -u +%FT%TZ) fox_c2f seed $seed"
$PY -m glint_mi.benchmark --data /work/shared/data/real_fox --skip-missing --preset bench --methods glint \
    --set downscale=4 --set eval_every=2500 --set max_gaussians=40000 --set threads=1 --seed-ids "$seed" \
    --out "$RUNS/fox_c2f"
echo "=== rc=$? $(date -u +%FT%TZ)"
