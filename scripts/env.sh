# Sourced (not run) by the project's scripts, first thing: the repository's root as the working
# directory, the cache and the build directory outside the clone (so that repeated runs are
# incremental; CARGO_TARGET_DIR as set, else $ICRFLOW_CACHE/target), and the machine set up
# for building and testing (scripts/setup.sh, idempotent). Leaves `root` set.
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
export ICRFLOW_CACHE="${ICRFLOW_CACHE:-$HOME/.cache/icrflow}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$ICRFLOW_CACHE/target}"
scripts/setup.sh
