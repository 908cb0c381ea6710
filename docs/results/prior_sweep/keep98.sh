#!/bin/bash
# bash keep98.sh RUNS: the 98xx check runs (drive.sh ... check98) into groups/check98_*, the two halves (ab, cd) merged
G=$(cd "$(dirname "$0")" && pwd)/groups; R=${1:?the runs folder, e.g. /work/runs98}
for c in const nd sfmfloor; do
  for h in ab cd; do
    for m in $R/b40_${c}_$h/runs/*/*/metrics.json; do
      [ -f "$m" ] || continue
      run=$(dirname "$m"); rel=${run#$R/b40_${c}_$h/}; dst=$G/check98_$c/$rel
      mkdir -p "$dst"
      for f in metrics.json report.json convergence.csv config.json method.json; do [ -f "$run/$f" ] && cp "$run/$f" "$dst/$f"; done
    done
  done
done
for s in 9801 9802 9803 9804; do  # the priors row, for the floor: one copy, linked from the other two
  for c in const sfmfloor; do
    [ -d $G/check98_nd/runs/scene_$s/priors ] && [ -d $G/check98_$c/runs/scene_$s ] && \
      ln -sfn ../../../check98_nd/runs/scene_$s/priors $G/check98_$c/runs/scene_$s/priors
  done
done
