#!/bin/bash
# The sixty-ninth session's readings of `cpull` (README, "`cpull`'s last readings: the prior sweep and a second seed on
# the check rooms"): one lane of one Dr.Jit thread, each job in turn until the cut-off (UTC); a run not finished by it
# is stopped and said. A finished run is skipped (the benchmark resumes).
#   bash docs/results/coarse_to_fine/s69.sh CUTOFF JOB...
# JOB is c:ARM:ROOM:SEED (s63d.sh ARM ROOM at that seed: cpull, or base, today's preset) or s:ROOM:LEVEL (the prior
# sweep's room-level by prior_sweep/errors55.sh with cpull's switch, folder RUNS/p69_LEVEL_ROOM).
# Code of the worktree WT (pinned at the declaring commit), RUNS, DATA73 (with levels_ROOM beside the rooms), DATA98.
# The seventieth session's gpull: ARM=gpull runs s-jobs with its switch (folders RUNS/p70_LEVEL_ROOM), and
# s:ROOM:LEVEL:SEED a seed alone (--seed-ids SEED; folders RUNS/<tag>s<SEED>_LEVEL_ROOM, so that seeds keep their tables).
# The seventy-first session's dpull (gpull from half the run): ARM=dpull, folders RUNS/p71_LEVEL_ROOM.
# The seventy-second session's hpull, qpull (gpull, g whole from t 0.5, 0.25): folders RUNS/p72_ / p72q_LEVEL_ROOM;
# epull (gpull from 10/60 of the run): RUNS/p72e_LEVEL_ROOM.
set -u
cut=${1:?a cut-off, e.g. 22:10, or "2026-12-08 00:45" past midnight}; shift
end=$(date -ud "$cut" +%s) || exit 2
if [ "$end" -le "$(date -u +%s)" ]; then  # a bare time past midnight reads as today's, already gone
  echo "cut-off '$cut' is $(date -ud "@$end" '+%F %T') UTC, already past: give the date too, e.g. '$(date -ud tomorrow +%F) 00:45'" >&2
  exit 2
fi
here=$(cd "$(dirname "$0")" && pwd)
export WT=${WT:-/work/wt69} RUNS=${RUNS:-/work/runs69} PY=${PY:-/work/main/.venv/bin/python}
export DATA73=${DATA73:-/work/data73} DATA98=${DATA98:-/work/data98_r}
for job in "$@"; do
  left=$(( end - $(date -u +%s) ))
  if [ $left -le 60 ]; then echo "=== $job not run: past the cut-off $cut"; continue; fi
  IFS=: read kind a b c <<< "$job"
  case $kind in
    c) SEED=$c timeout $left bash "$here/s63d.sh" $a $b ;;
    s) case ${ARM:=cpull} in  # the arm's switch from s63d.sh, the one place it is written
         cpull) tag=p69 ;; gpull) tag=p70 ;; dpull) tag=p71 ;; hpull) tag=p72 ;; qpull) tag=p72q ;;
         epull) tag=p72e ;;
         *) echo "ARM '$ARM': cpull, gpull, dpull, hpull, qpull or epull for the prior sweep's jobs" >&2; exit 2 ;;
       esac
       sets=$(PRINT_SWITCH=1 bash "$here/s63d.sh" $ARM -)
       [ -n "$c" ] && tag=${tag}s$c && sets="$sets --seed-ids $c"
       TAG=$tag DATA=$DATA73 SETS="$sets" timeout $left bash "$here/../prior_sweep/errors55.sh" $a $b ;;
    *) echo "job '$job': c:ARM:ROOM:SEED or s:ROOM:LEVEL[:SEED]" >&2; continue ;;
  esac
  [ $? -eq 124 ] && echo "=== $job stopped at the cut-off $cut"
done
