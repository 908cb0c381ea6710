#!/bin/bash
# Forty-eighth session (README, "The coarse start on this capture"): GLINT (components: auto; on the fox, no glass
# cue: it trains as the 3dgs method) at the bench preset with its coarse start (arm c2f) and with it off (arm none,
# coarse_to_fine=), seed 0, the command of this folder otherwise; one Dr.Jit thread; code of the worktree WT.
#   bash docs/results/real_fox/s48.sh c2f|none
set -u
case ${1:?c2f or none} in c2f) C2F=() ;; none) C2F=(--set coarse_to_fine=) ;; *) echo "arm '$1': use c2f or none" >&2; exit 2 ;; esac
WT=${WT:-/work/wt48b}; RUNS=${RUNS:-/work/runs48}
cd "$WT"; export PYTHONPATH=$WT:${WT}_path
PY=${PY:-/work/main/.venv/bin/python}
echo "=== $(date -u +%FT%TZ) fox_$1"
$PY -m glint_mi.benchmark --data /work/shared/data/real_fox --skip-missing --preset bench --methods glint \
    --set downscale=4 --set eval_every=2500 --set max_gaussians=40000 --set threads=1 "${C2F[@]}" --out "$RUNS/fox_$1"
echo "=== rc=$? $(date -u +%FT%TZ)"
