# Sourced by drive.sh and the sessions' lane scripts (s40*.sh, s43*.sh): the declared code's worktree (cafd86a), and
# the flags every run of this folder shares. BENCH: the benchmark with them; GROW / WIDE: the capacities (the defaults: no flag).
cd /work/wt98
export PYTHONPATH=/work/wt98:/work/wt98_path
PY=${PY:-/work/main/.venv/bin/python}
BENCH="$PY -m glint_mi.benchmark --preset bench --set downscale=2 --set w_sfm_depth=0 --set eval_every=1000 --set threads=1"
GROW="--set densify_top=0.12 --set densify_grad_rel=0.05"
WIDE="--set densify_top=0.25 --set densify_grad_rel=0.02"
