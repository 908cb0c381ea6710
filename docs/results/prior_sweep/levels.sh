# Sourced by drive.sh and converged60.sh: level NAME SEED ARGS... makes LEVELS/NAME/scene_SEED (LEVELS: default
# DATA/levels), every file of DATA/rSEED/scene_SEED linked but priors/, which `dataset priors --seed SEED ARGS`
# derives there; a level whose PRIORS.json exists is kept. Needs DATA and PY.
level() {
  local name=$1 s=$2 f; shift 2   # f local: the callers' loops over scales are also f
  local dst="${LEVELS:-$DATA/levels}/$name/scene_$s" src="$DATA/r$s/scene_$s"
  [ -f "$dst/priors/PRIORS.json" ] && return 0
  mkdir -p "$dst"
  for f in "$src"/*; do [ "$(basename "$f")" = priors ] || ln -sfn "$f" "$dst/$(basename "$f")"; done
  echo "=== $(date -u +%FT%TZ) priors $name $s $*"
  $PY -m glint_mi.dataset priors "$dst" --seed $s "$@"
}
