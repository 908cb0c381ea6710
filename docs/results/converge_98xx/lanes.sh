# Sourced by drive.sh and the sessions' lane scripts (s40*.sh, s43*.sh, s44*.sh): the declared code's worktree
# (cafd86a) and the flags every run of this folder shares (flags.sh: BENCH, GROW, WIDE).
source "$(dirname "${BASH_SOURCE[0]}")/flags.sh"
cd /work/wt98
export PYTHONPATH=/work/wt98:/work/wt98_path
