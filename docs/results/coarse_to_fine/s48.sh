#!/bin/bash
# session 48: `3dgs` at the bench budget on the check rooms (9801-9803), the command of the checks (s47.sh ARM check)
# with --methods 3dgs: how GLINT with clone_opacity shared (check47.md) stands against it there. Seed 0.
#   bash docs/results/coarse_to_fine/s48.sh ROOM [ROOM...]
set -u
PY=${PY:-/work/main/.venv/bin/python}
WT=${WT:-/work/wt48}; RUNS=${RUNS:-/work/runs48}; data=${DATA98:-/work/data98_r}
cd "$WT"; export PYTHONPATH=$WT:${WT}_path
for room in "${@:?rooms: 9801 9802 9803}"; do
  echo "=== $(date -u +%FT%TZ) check_3dgs $room"
  $PY -m glint_mi.benchmark --preset bench --methods 3dgs --set threads=1 --set eval_every=1000 \
      --data "$data/r$room" --out "$RUNS/check_3dgs"
  echo "=== rc=$? $(date -u +%FT%TZ)"
done
