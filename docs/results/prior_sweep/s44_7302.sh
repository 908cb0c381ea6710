#!/bin/bash
# Forty-fourth session (README, "7302's glass at the converged budget"): converged60.sh's command for 7302 at
# realistic 1.25, lane A with the coarse start off (--set coarse_to_fine=), lane B seed 1 as declared (coarse start on).
# The same worktree as converged60 (the code of 5a8b5d7).   bash docs/results/prior_sweep/s44_7302.sh A|B
set -u
case ${1:?A or B} in A) X=(--set coarse_to_fine=); OUT=conv60_realistic_e1.25_7302_flat ;;
                     B) X=(--seed-ids 1); OUT=conv60_realistic_e1.25_7302_s1 ;; *) echo "lane: A or B" >&2; exit 2 ;; esac
cd /work/wt42; export PYTHONPATH=/work/wt42:/work/wt42_path
/work/main/.venv/bin/python -m glint_mi.benchmark --preset bench --set downscale=2 --set w_sfm_depth=0 --set threads=1 \
    --set epochs=60 --set eval_every=1000 --set densify_top=0.12 --set densify_grad_rel=0.05 --methods glint "${X[@]}" \
    --data /work/data73/levels_7302/realistic_e1.25 --out /work/runs73p/$OUT
