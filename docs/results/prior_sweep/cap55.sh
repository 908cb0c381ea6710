#!/bin/bash
# The fifty-fifth session: the converged preset with a Gaussian cap that rises over the growth window
# (cap_schedule CAP) on the sweep's room-levels: preset53.sh (the sweep's protocol flags, downscale=2
# w_sfm_depth=0, one thread; depth_prior_ref at its default 0.02) with that setting added. A finished run is skipped.
#   bash docs/results/prior_sweep/cap55.sh CAP ROOM NAME...   (CAP: linear; ROOM 7301 or 7302; NAME as preset53.sh)
# DATA, RUNS and WT (the code: a worktree) from the environment. Folders RUNS/conv60_NAME_ROOM_c55<CAP>.
set -u
cap=${1:?CAP: cap_schedule, e.g. linear}; shift
WT=${WT:-/work/wt55} RUNS=${RUNS:-/work/runs55} TAG=c55$cap SETS="--set cap_schedule=$cap" \
    exec bash "$(dirname "$0")/preset53.sh" "$@"
