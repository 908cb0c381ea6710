# The flags every converged run shares (this folder's lanes through lanes.sh, and coarse_to_fine/s45.sh): BENCH the
# benchmark with them (PY: the interpreter), GROW / WIDE the capacities (the defaults: no flag). Sourced; changes
# no directory.
PY=${PY:-/work/main/.venv/bin/python}
BENCH="$PY -m glint_mi.benchmark --preset bench --set downscale=2 --set w_sfm_depth=0 --set eval_every=1000 --set threads=1"
GROW="--set densify_top=0.12 --set densify_grad_rel=0.05"
WIDE="--set densify_top=0.25 --set densify_grad_rel=0.02"
