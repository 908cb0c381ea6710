#!/bin/bash
# The sixty-second session: item 3's fourteen room-levels at 40 epochs of 96 x 54 again, with today's bench preset
# (coarse start with its 27-pixel floor, shared clones, the per-view depth weight), errors55.sh's flags (w_sfm_depth=0,
# one thread, seed 0); then `3dgs` on the room, the same command (it reads no prior: one run a room).
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
cd "$WT" && export PYTHONPATH=$WT:${WT}_path
echo "=== $(date -u +%FT%TZ) 3dgs $room (40 epochs)"
$PY -m glint_mi.benchmark --preset bench --set downscale=2 --set w_sfm_depth=0 --set threads=1 --set epochs=40 \
    --methods 3dgs --data "$DATA/levels_$room/realistic_e1" --out "$RUNS/${TAG}_3dgs_$room"
echo "=== rc=$? $(date -u +%FT%TZ)"
