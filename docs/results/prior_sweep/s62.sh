#!/bin/bash
# The sixty-second session: item 3's fourteen room-levels at 40 epochs of 96 x 54 again, with today's bench preset
# (coarse start with its 27-pixel floor, shared clones, the per-view depth weight), errors55.sh's flags (w_sfm_depth=0,
# one thread, seed 0); then `3dgs` on the room at today's floor and at 0 (coarse_to_fine, sixty-second session).
#   TAG=b62 WT=/work/wt62 RUNS=/work/runs62 DATA=/work/data73 bash docs/results/prior_sweep/s62.sh ROOM   (one lane)
# A finished run is skipped (the benchmark resumes).
set -u
room=${1:?ROOM: 7301 or 7302}
here=$(cd "$(dirname "$0")" && pwd)
export TAG=${TAG:-b62} WT=${WT:-/work/wt62} RUNS=${RUNS:-/work/runs62} DATA=${DATA:-/work/data73}
PY=${PY:-/work/main/.venv/bin/python}
for name in realistic_e1 realistic-v1_e2.0 realistic_e2.0 realistic_e0.5 realistic-v1_e0.5 realistic_e0.75 \
    realistic_e1.25; do
  bash "$here/errors55.sh" $room $name
done
# then `3dgs` with the coarse floor and without (coarse_to_fine/s62_3dgs.sh): lane 7301 also takes 7303's
for room3 in $room $([ $room = 7301 ] && echo 7303); do
  for arm in p27 p0; do bash "$here/../coarse_to_fine/s62_3dgs.sh" $arm $room3; done
done
