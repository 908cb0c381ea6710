#!/bin/bash
# The fifty-fifth session: GLINT at the converged preset (as s54.sh's runs, today's defaults) for EPOCHS epochs
# instead of 60, whether GLINT has stopped gaining at the preset: preset_glint.sh with that setting. A finished run
# is skipped.
#   bash docs/results/converge_98xx/s55e.sh ROOM SEED EPOCHS
# Folders: RUNS/e<EPOCHS>_p55.
set -u
ep=${3:?EPOCHS, e.g. 120}
WT=${WT:-/work/wt55} RUNS=${RUNS:-/work/runs55} TAG=e${ep}_p55 SETS="--set epochs=$ep" \
    exec bash "$(dirname "$0")/preset_glint.sh" "${1:?a room: 9801 9802 9803 9804}" "${2:?a seed: 0 or 1}"
