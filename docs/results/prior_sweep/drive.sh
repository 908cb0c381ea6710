#!/bin/bash
# The sweeps declared in README.md (issue 66, items 3 and 4), resumable: every step skips what is complete.
#   bash docs/results/prior_sweep/drive.sh DATA OUT [PY]
# DATA: where the tuning rooms 7301 and 7302 are (generated here if missing) and the level folders go; OUT: the
# benchmark folders. A level folder links every file of its room except priors/, which it derives itself.
set -uo pipefail
DATA=${1:?DATA}; OUT=${2:?OUT}; PY=${3:-.venv/bin/python}
ROOMS="7301 7302"
run() { echo "=== $(date -u +%FT%TZ) $*"; "$@"; echo "=== rc=$? $(date -u +%FT%TZ)"; }
for s in $ROOMS; do
  [ -f "$DATA/r$s/scene_$s/meta.json" ] || run $PY -m glint_mi.dataset make "$DATA/r$s" --scenes 1 --seed $s \
      --preset bench --views 48 --spp 256 --renderer cycles
done
level() {  # level NAME SEED ARGS...: DATA/levels/NAME/scene_SEED with its own priors
  local name=$1 s=$2; shift 2
  local dst="$DATA/levels/$name/scene_$s" src="$DATA/r$s/scene_$s"
  [ -f "$dst/priors/PRIORS.json" ] && return
  mkdir -p "$dst"
  for f in "$src"/*; do [ "$(basename "$f")" = priors ] || ln -sfn "$f" "$dst/$(basename "$f")"; done
  run $PY -m glint_mi.dataset priors "$dst" --seed $s "$@"
}
B="$PY -m glint_mi.benchmark --preset bench --set downscale=2 --set w_sfm_depth=0 --set threads=1"
for model in realistic realistic-v1; do
  for f in 0.5 0.75 1 1.25 2.0; do
    for s in $ROOMS; do level "${model}_e$f" $s --model $model --error-scale $f; done
    run $B --data "$DATA/levels/${model}_e$f" --methods priors,glint --set epochs=40 --out "$OUT/bench_${model}_e$f"
  done
done
for p in 0.2 0.4 0.6 0.8 1.0; do
  for s in $ROOMS; do level "see_$p" $s --model realistic --see-through $p; done
  run $B --data "$DATA/levels/see_$p" --methods glint --set epochs=40 --out "$OUT/see_$p"
done
for model in realistic realistic-v1; do  # the converged budget (120 epochs with growth until converge_98xx decides)
  for f in 0.5 0.75 1 1.25 2.0; do
    run $B --data "$DATA/levels/${model}_e$f" --methods glint --set epochs=120 --set densify_top=0.12 \
        --set densify_grad_rel=0.05 --out "$OUT/grow120_${model}_e$f"
  done
done
