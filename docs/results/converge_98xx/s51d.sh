#!/bin/bash
# The fifty-first session's diagnosis on 9803 at GLINT's converged point (README, "What costs GLINT off the glass on
# 9803 at the converged point"): flags.sh's BENCH and GROW, 60 epochs, coarse start off (as s48.sh, whose
# e60_grow_sh run is the base), seed 0, one change an arm; decides nothing.
#   [ROOM=9801] bash docs/results/converge_98xx/s51d.sh ARM ... (ARM: see the case below; ROOM: 9803 unless given,
#   another room for coarse_to_fine's check of `el` at the converged point)
# One Dr.Jit thread a run; code of the worktree WT (pinned at the declaring commit). A finished run is skipped.
set -u
source "$(dirname "$0")/flags.sh"
WT=${WT:-/work/wt51}; RUNS=${RUNS:-/work/runs51}; DATA=${DATA98:-/work/data98_r}; ROOM=${ROOM:-9803}
cd "$WT"; export PYTHONPATH=$WT:${WT}_path
CTRL="--set components=interface --set w_l1=0.8 --set w_dssim=0.2 --set w_consistency=0 --set w_normal=0"
CTRL="$CTRL --set w_depth=0 --set clone_opacity=copy --set blend=alpha"
for arm in "$@"; do
  case $arm in
    base) switch="" ;;
    noterms) switch="--set w_normal=0 --set w_depth=0" ;;              # no prior term (the cue still read)
    decay2) switch="--set prior_decay_terms=depth,normal --set prior_decay_ref=0" ;;  # both prior terms fall to 0
    el) switch="--set kernel=ellipsoid" ;;                              # 3DGS's kernel
    noterms_el) switch="--set w_normal=0 --set w_depth=0 --set kernel=ellipsoid" ;;
    iface3dgs) switch="$CTRL --set kernel=ellipsoid" ;;                 # the control: should land on 3dgs's run
    iface3dgs_s) switch="$CTRL" ;;                                      # the same with GLINT's surfels
    *) echo "arm '$arm': use base, noterms, decay2, el, noterms_el, iface3dgs or iface3dgs_s" >&2; exit 2 ;;
  esac
  echo "=== $(date -u +%FT%TZ) c${ROOM}_$arm"
  $BENCH $GROW --set epochs=60 --set coarse_to_fine= $switch --methods glint --data "$DATA/r$ROOM" \
      --out "$RUNS/c${ROOM}_$arm"
  echo "=== rc=$? $(date -u +%FT%TZ)"
done
