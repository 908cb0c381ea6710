#!/bin/bash
# Forty-seventh session (README, "Growth apart from the resets and the t gate; `3dgs` with stages of 2 epochs").
#   bash docs/results/coarse_to_fine/s47.sh ARM tune|check [ROOMS]   GLINT, the bench command of lanes.sh (the preset's
#                                                                   coarse start) with ARM's flags: g50 grow_until=0.5,
#                                                                   sh clone_opacity=shared, sh_g50 both
#   bash docs/results/coarse_to_fine/s47.sh 3dgs [ROOMS]             3dgs at 60 epochs of 96 x 54 with growth, stages
#                                                                   of 2 epochs each (s45.sh's epochs2 arm)
# ROOMS: a subset of the study's rooms, in order (to split it over the two lanes). One Dr.Jit thread a run; the code
# of the worktree WT (g50, sh, sh_g50: pinned to their declaring commits; 3dgs: s45.sh's, so that its runs are the
# base). A finished run is skipped (the benchmark reads its metrics.json), so a lane restarts where it stopped.
set -u
PY=${PY:-/work/main/.venv/bin/python}
run() { echo "=== $(date -u +%FT%TZ) $*"; "$@"; echo "=== rc=$? $(date -u +%FT%TZ)"; }
case ${1:?g50, sh, sh_g50 or 3dgs} in
  g50|sh|sh_g50)
    case $1 in
      g50) flags=(--set grow_until=0.5) ;;
      sh) flags=(--set clone_opacity=shared) ;;
      sh_g50) flags=(--set clone_opacity=shared --set grow_until=0.5) ;;
    esac
    case ${2:?tune or check} in
      tune) rooms="7301 7302 7303"; data=${DATA73:-/work/data73} ;;
      check) rooms="9801 9802 9803"; data=${DATA98:-/work/data98_r} ;;
      *) echo "study '$2': use tune or check" >&2; exit 2 ;;
    esac
    rooms=${3:-$rooms}; study=$2
    case $1 in g50) WT=${WT:-/work/wt47} ;; *) WT=${WT:-/work/wt47b} ;; esac; RUNS=${RUNS:-/work/runs47}
    cd "$WT"; export PYTHONPATH=$WT:${WT}_path
    for room in $rooms; do
      run $PY -m glint_mi.benchmark --preset bench --methods glint --set threads=1 --set eval_every=1000 \
          "${flags[@]}" --data "$data/r$room" --out "$RUNS/${study}_$1"
    done ;;
  3dgs)
    rooms=${2:-"9801 9802 9803 9804"}; D=${DATA:-/work/data98}
    WT=${WT:-/work/wt45}; RUNS=${RUNS:-/work/runs45}
    source "$(dirname "$0")/../converge_98xx/flags.sh"  # BENCH, GROW: converge_98xx's converged runs
    cd "$WT"; export PYTHONPATH=$WT:${WT}_path
    for room in $rooms; do
      run $BENCH --set epochs=60 $GROW --seed-ids 0 --methods 3dgs --set coarse_to_fine=4:0.0333,2:0.0333 \
          --data "${D}_$room" --out "$RUNS/3dgs_epochs2"
    done ;;
  *) echo "'$1': use g50, sh, sh_g50 or 3dgs" >&2; exit 2 ;;
esac
