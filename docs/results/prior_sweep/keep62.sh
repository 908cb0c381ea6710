#!/bin/bash
# bash keep62.sh RUNS: the sixty-second session's runs into groups (converge_98xx/keep.sh, small files only): s62.sh's
# GLINT folders (RUNS/b62_*) into prior_sweep/groups with their tables (one room a folder), the `3dgs` arms
# (RUNS/w62_3dgs_*) into coarse_to_fine/groups (one call a room: their tables hold the last room only, not kept).
R=${1:?the runs folder, e.g. /work/runs62}; here=$(cd "$(dirname "$0")" && pwd); keep=$here/../converge_98xx/keep.sh
bash "$keep" "$R" "$here" 'b62_*' && bash "$keep" "$R" "$here/../coarse_to_fine" 'w62_3dgs_*' || exit 1
for src in "$R"/b62_*; do
  for f in results.csv table.md; do [ -f "$src/$f" ] && cp "$src/$f" "$here/groups/$(basename "$src")/$f"; done
done
exit 0
