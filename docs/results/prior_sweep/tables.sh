#!/bin/bash
# regenerate the tables of docs/results/prior_sweep from groups/: see_through.md, exact_priors.md, errors_const.md
cd "$(dirname "$0")/../../.."; G=docs/results/prior_sweep/groups; PY=.venv/bin/python
A=()
for p in 1.0 0.8 0.6 0.4 0.2; do
  x="$p=$G/see_$p,$G/see_${p}_cuephoto:cue"
  case $p in 1.0|0.6) x="$x,$G/see_${p}_priorphoto:pp,$G/see_${p}_bothphoto:both,$G/see_${p}_halfprior:half,$G/see_${p}_normaldecay:nd";; esac
  [ $p = 0.6 ] && x="$x,$G/see_0.6_nonormal:nonormal"
  [ $p = 0.2 ] && x="$x,$G/see_0.2_normaldecay:nd"
  A+=("$x")
done
$PY benchmarks/sweep_table.py --by-room "${A[@]}" --out docs/results/prior_sweep/see_through.md > /dev/null
$PY benchmarks/sweep_table.py --rooms scene_7301 "exact=$G/ideal_see0:pane,$G/ideal_see1.0:through,$G/3dgs_glintphoto:photo,$G/ideal0_depthonly:depth,$G/ideal0_normalonly:normal" "0.6=$G/see_0.6" --out docs/results/prior_sweep/exact_priors.md > /dev/null
$PY benchmarks/sweep_table.py --by-room e0.5=$G/const_bench_realistic_e0.5 e0.75=$G/const_bench_realistic_e0.75 e1=$G/see_0.6 e2.0=$G/const_bench_realistic_e2.0 --out docs/results/prior_sweep/errors_const.md > /dev/null
