#!/bin/bash
# Keep the small files of every finished run (metrics.json and what describes it) under groups/ here (groups/<benchmark folder>/runs/<room>/<method>), so that a session
# on another machine can copy them back into the benchmark folders (the benchmark skips a run whose metrics.json is
# there) and the tables can be rebuilt: bash docs/results/converge_98xx/keep.sh /work/runs98 [DEST] (DEST: another
# results folder whose groups/ takes them, e.g. docs/results/prior_sweep; default this one) [PATTERN] (which benchmark
# folders, a glob; default all)
set -euo pipefail
src=${1:?runs root, e.g. /work/runs98}; here=$(cd "${2:-$(dirname "$0")}" && pwd)
for m in "$src"/${3:-*}/runs/*/*/metrics.json; do
  [ -f "$m" ] || continue
  run=$(dirname "$m"); dst="$here/groups/${run#"$src"/}"
  mkdir -p "$dst"
  for f in metrics.json report.json convergence.csv config.json method.json; do
    [ -f "$run/$f" ] && cp "$run/$f" "$dst/$f"
  done
done
du -sh "$here/groups"
