#!/bin/bash
# The sixty-third session's diagnosis (README, "What costs GLINT against `3dgs` at 40 epochs of 96 x 54"): GLINT at
# today's bench preset with the prior sweep's flags (s56.sh's command: 96 x 54, 40 epochs, w_sfm_depth=0, one Dr.Jit
# thread, seed 0) and one switch, on one tuning room; decides nothing. A finished run is skipped.
#   bash docs/results/coarse_to_fine/s63d.sh ARM ROOM      (ARM: priors 3dgs copy noterms el iface copyel; ROOM: 7301-7303,
#                                                          or 9801-9803 for the check of `copy`)
# Code of the worktree WT (pinned at the declaring commit); rooms DATA73/rROOM or DATA98/rROOM; folder RUNS/d63_<arm>.
set -u
arm=${1:?an arm: priors 3dgs copy noterms el iface copyel}; room=${2:?a room: 7301 7302 7303}
methods=glint
case $arm in
  priors) switch=""; methods=priors ;;                              # the renders' check: no training
  3dgs) switch=""; methods=3dgs ;;                                  # the reference on the check rooms
  copy) switch="--set clone_opacity=copy" ;;                        # 3DGS's clones (the preset shares coverage)
  noterms) switch="--set w_normal=0 --set w_depth=0" ;;             # no prior term (the cue still read)
  el) switch="--set kernel=ellipsoid" ;;                            # 3DGS's kernel
  iface) switch="--set components=interface" ;;                     # GLINT's interface alone, no second set
  copyel) switch="--set clone_opacity=copy --set kernel=ellipsoid" ;; # both (declared after copy and el on 7301)
  *) echo "arm '$arm': use priors, 3dgs, copy, noterms, el, iface or copyel" >&2; exit 2 ;;
esac
case $room in
  730[123]) data=${DATA73:-/work/data73} ;;
  980[123]) data=${DATA98:-/work/data98_r} ;;
  *) echo "room '$room': 7301-7303 or 9801-9803" >&2; exit 2 ;;
esac
WT=${WT:-/work/wt63}; RUNS=${RUNS:-/work/runs63}; PY=${PY:-/work/main/.venv/bin/python}
echo "=== $(date -u +%FT%TZ) d63_$arm $room"
WT=$WT PY=$PY bash "$(dirname "$0")/run40.sh" $methods "$data/r$room" "$RUNS/d63_$arm" --set eval_every=1000 $switch
echo "=== rc=$? $(date -u +%FT%TZ)"
