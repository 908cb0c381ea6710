#!/bin/bash
# Forty-eighth session (README, "A split that keeps its parent's footprint"): GLINT, the bench command of the
# checks (the preset: its coarse start and clone_opacity shared) with split_mode=axis: s49.sh's arm ax, in that
# session's worktree (e442aac) and runs folder.
#   bash docs/results/coarse_to_fine/s48b.sh tune|check [ROOMS]
WT=${WT:-/work/wt48b} RUNS=${RUNS:-/work/runs48} exec bash "$(dirname "$0")/s49.sh" ax "$@"
