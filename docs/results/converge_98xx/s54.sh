#!/bin/bash
# The fifty-fourth session: the converged table's GLINT runs (as s52.sh: --preset converged, the table's protocol
# flags downscale=2 w_sfm_depth=0, one Dr.Jit thread) with each view's depth prior weighed by its agreement with
# the SfM points (depth_prior_ref REF): preset_glint.sh with that setting. A finished run is skipped.
#   bash docs/results/converge_98xx/s54.sh ROOM SEED REF
# Folders: RUNS/d54_r<REF> (seed 1 as glint@seed1).
set -u
ref=${3:?REF: depth_prior_ref, e.g. 0.02}
WT=${WT:-/work/wt54} RUNS=${RUNS:-/work/runs54} TAG=d54_r$ref SETS="--set depth_prior_ref=$ref" \
    exec bash "$(dirname "$0")/preset_glint.sh" "${1:?a room: 9801 9802 9803 9804}" "${2:?a seed: 0 or 1}"
