#!/bin/bash
# The fifty-fifth session: the converged table's GLINT runs (as s54.sh: --preset converged, the table's protocol
# flags downscale=2 w_sfm_depth=0, one Dr.Jit thread, the default depth_prior_ref 0.02) with a Gaussian cap that
# rises over the growth window (cap_schedule CAP): preset_glint.sh with that setting. A finished run is skipped.
#   bash docs/results/converge_98xx/s55.sh ROOM SEED CAP      (CAP: linear)
# Folders: RUNS/c55_<CAP> (seed 1 as glint@seed1).
set -u
cap=${3:?CAP: cap_schedule, e.g. linear}
WT=${WT:-/work/wt55} RUNS=${RUNS:-/work/runs55} TAG=c55_$cap SETS="--set cap_schedule=$cap" \
    exec bash "$(dirname "$0")/preset_glint.sh" "${1:?a room: 9801 9802 9803 9804}" "${2:?a seed: 0 or 1}"
