#!/bin/bash
# The fiftieth session's diagnosis on 9803 (README, "What costs GLINT on 9803 at the bench budget"): GLINT, the bench
# command of the checks (the preset), seed 0, with one term off or the normal attribute; decides nothing.
#   bash docs/results/converge_98xx/s50d.sh ARM ... (ARM: see the case below)
# One Dr.Jit thread a run; code of the worktree WT (pinned at the declaring commit). A finished run is skipped.
set -u
PY=${PY:-/work/main/.venv/bin/python}
WT=${WT:-/work/wt50}; RUNS=${RUNS:-/work/runs50}; DATA=${DATA98:-/work/data98_r}
cd "$WT"; export PYTHONPATH=$WT:${WT}_path
for arm in "$@"; do
  case $arm in
    base) switch="" ;;
    nonormal) switch="--set w_normal=0" ;;
    nodepth) switch="--set w_depth=0" ;;
    nocons) switch="--set w_consistency=0" ;;
    na) switch="--set normal_source=attribute" ;;
    noterms) switch="--set w_normal=0 --set w_depth=0" ;;  # second round: both prior terms off (the cue still read)
    nosfm) switch="--set w_sfm_depth=0" ;;
    iface) switch="--set components=interface" ;;
    el) switch="--set kernel=ellipsoid" ;;
    # third round: 3DGS's photometric weights; 3DGS's clones; the interface alone with every 3dgs field (a control
    # that should land on the 3dgs run), and the same with surfels
    w3dgs) switch="--set w_l1=0.8 --set w_dssim=0.2" ;;
    copy) switch="--set clone_opacity=copy" ;;
    iface3dgs|iface3dgs_s)
      switch="--set components=interface --set w_l1=0.8 --set w_dssim=0.2 --set w_consistency=0 --set w_normal=0"
      switch="$switch --set w_depth=0 --set w_sfm_depth=0 --set clone_opacity=copy --set blend=alpha"
      [ $arm = iface3dgs ] && switch="$switch --set kernel=ellipsoid" ;;
    *) echo "arm '$arm': use base, nonormal, nodepth, nocons, na, noterms, nosfm, iface, el, w3dgs, copy," \
            "iface3dgs or iface3dgs_s" >&2; exit 2 ;;
  esac
  echo "=== $(date -u +%FT%TZ) d9803_$arm"
  $PY -m glint_mi.benchmark --preset bench --methods glint --set threads=1 --set eval_every=1000 \
      $switch --data "$DATA/r9803" --out "$RUNS/d9803_$arm"
  echo "=== rc=$? $(date -u +%FT%TZ)"
done
