#!/bin/bash
# The 40-epoch command of the prior sweep and the coarse start's checks (96 x 54, w_sfm_depth=0, one Dr.Jit thread,
# seed 0; the bench preset otherwise), one place for every script that runs it (s56.sh, s62_3dgs.sh, s63d.sh,
# prior_sweep/errors55.sh): the benchmark in the worktree WT with PY, METHODS on DATA into OUT, ARGS added as given.
#   bash docs/results/coarse_to_fine/run40.sh METHODS DATA OUT [ARGS...]      (e.g. --set eval_every=1000)
set -u
methods=${1:?METHODS, e.g. glint}; data=${2:?DATA: a benchmark scene folder}; out=${3:?OUT: the benchmark folder}
shift 3
WT=${WT:?WT: the worktree whose code runs}; PY=${PY:-/work/main/.venv/bin/python}
cd "$WT" && export PYTHONPATH=$WT:${WT}_path || exit 1
$PY -m glint_mi.benchmark --preset bench --set downscale=2 --set w_sfm_depth=0 --set threads=1 --set epochs=40 \
    "$@" --methods "$methods" --data "$data" --out "$out"
