#!/bin/bash
# The sixty-seventh session's reading of ellipsoids at the bench preset's own size (README, "Ellipsoids at both of
# the bench preset's resolutions"): GLINT with today's bench preset at 192 x 108, 10 epochs, as the prior sweep's
# runs are read (w_sfm_depth=0, one Dr.Jit thread, seed 0), on one tuning room, into RUNS/b67_<arm>.
#   [SEED=K] bash docs/results/coarse_to_fine/s67.sh ARM ROOM      (ARM: priors, base, el, cpull; ROOM: 7301-7303)
# The sixty-eighth session's cpull at that size (README, "A consistency term that moves only the normals"): ARM cpull.
# SEED=K: that seed alone (--seed-ids K; run folders METHOD@seedK).
# priors: the priors row at 192 x 108 (no training; into RUNS/b67_base, beside the base runs, for the floor).
# Code of the worktree WT (pinned at the declaring commit); rooms DATA73/rROOM. A finished run is skipped.
set -u
arm=${1:?an arm: priors base el cpull}; room=${2:?a room: 7301 7302 7303}
methods=glint; folder=b67_$arm
case $arm in
  priors) switch=""; methods=priors; folder=b67_base ;;
  base) switch="" ;;
  el) switch="--set kernel=ellipsoid" ;;
  cpull) switch="--set prior_weight_ref=10 --set prior_weight_terms=consistency" ;;
  *) echo "arm '$arm': use priors, base, el or cpull" >&2; exit 2 ;;
esac
case $room in
  730[123]) ;;
  *) echo "room '$room': 7301-7303" >&2; exit 2 ;;
esac
WT=${WT:?WT: the worktree whose code runs}; RUNS=${RUNS:?RUNS: the runs folder}; PY=${PY:-/work/main/.venv/bin/python}
cd "$WT" && export PYTHONPATH=$WT:${WT}_path || exit 1
echo "=== $(date -u +%FT%TZ) $folder $arm $room"
$PY -m glint_mi.benchmark --preset bench --set w_sfm_depth=0 --set threads=1 --set eval_every=1000 $switch \
    --methods $methods --data "${DATA73:-/work/data73}/r$room" --out "$RUNS/$folder" ${SEED:+--seed-ids $SEED}
echo "=== rc=$? $(date -u +%FT%TZ)"
