#!/bin/bash
# The fifty-fourth session: the converged preset with each view's depth prior weighed by its agreement with the SfM
# points (depth_prior_ref REF) on the sweep's room-levels: preset53.sh (the sweep's protocol flags, downscale=2
# w_sfm_depth=0, one thread) with that setting added. A finished run is skipped.
#   bash docs/results/prior_sweep/depthref54.sh REF ROOM NAME...   (ROOM 7301 or 7302; NAME: model_eF as preset53.sh)
# DATA, RUNS and WT (the code: a worktree) from the environment. Folders RUNS/conv60_NAME_ROOM_d54r<REF>.
set -u
ref=${1:?REF: depth_prior_ref, e.g. 0.02}; shift
WT=${WT:-/work/wt54} RUNS=${RUNS:-/work/runs54} TAG=d54r$ref SETS="--set depth_prior_ref=$ref" \
    exec bash "$(dirname "$0")/preset53.sh" "$@"
