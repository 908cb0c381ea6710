#!/bin/bash
# bash keep62.sh RUNS: the sixty-second session's runs into groups: s62.sh's GLINT folders (RUNS/b62_*) into
# prior_sweep/groups, the `3dgs` arms (RUNS/w62_3dgs_*) into coarse_to_fine/groups; small files only.
R=${1:?the runs folder, e.g. /work/runs62}; here=$(cd "$(dirname "$0")" && pwd)
for src in "$R"/b62_* "$R"/w62_3dgs_*; do
  [ -d "$src" ] || continue
  name=$(basename "$src"); case $name in b62_*) G=$here/groups ;; *) G=$here/../coarse_to_fine/groups ;; esac
  case $name in b62_*)  # one room a folder; the 3dgs folders took one call a room, their tables the last room only
    for f in results.csv table.md; do [ -f "$src/$f" ] && mkdir -p "$G/$name" && cp "$src/$f" "$G/$name/$f"; done ;;
  esac
  for m in "$src"/runs/*/*/metrics.json; do
    [ -f "$m" ] || continue
    run=$(dirname "$m"); dst=$G/$name/${run#$src/}; mkdir -p "$dst"
    for f in metrics.json report.json convergence.csv config.json method.json; do
      [ -f "$run/$f" ] && cp "$run/$f" "$dst/$f"
    done
  done
done
