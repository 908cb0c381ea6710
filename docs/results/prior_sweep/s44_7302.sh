#!/bin/bash
# Forty-fourth session (README, "7302's glass at the converged budget"): converged60.sh's command for 7302 at
# realistic 1.25 and GLINT alone, lane A with the coarse start off (--set coarse_to_fine=), lane B seed 1 as declared
# (coarse start on). Ran from the worktree of converged60 (5a8b5d7), whose glint_mi/ and plugins/ equal this commit's.
#   bash docs/results/prior_sweep/s44_7302.sh A|B
set -u
here=$(dirname "$0")
case ${1:?A or B} in
  A) METHODS=glint TAG=_flat exec bash "$here/converged60.sh" 7302 realistic_e1.25 --set coarse_to_fine= ;;
  B) METHODS=glint TAG=_s1 exec bash "$here/converged60.sh" 7302 realistic_e1.25 --seed-ids 1 ;;
  *) echo "lane: A or B" >&2; exit 2 ;;
esac
