#!/usr/bin/env bash
# Create (once) a Python venv for bench/reference_qhull.py (numpy, scipy) and the Zenoh client
# test (tests/zenoh_client.py: eclipse-zenoh, pinned to the Rust crate's version) and the Rerun
# recording checks (rerun-sdk, with its `rerun` viewer/CLI in the venv's bin) and the Python
# package's tests (pytest, trimesh; maturin to build the package), and print its interpreter
# path. The package itself is installed by scripts/setup.sh.
#
#   PY=$(scripts/setup-python.sh | tail -1)
#   "$PY" bench/reference_qhull.py check cases.json out.json
#
# The venv lives outside the repo, at "${ICRFLOW_CACHE:-$HOME/.cache/icrflow}/venv".
# Idempotent: the install is skipped when the venv's stamp file holds the sha256 of the
# current bench/requirements.txt. Only the python path goes to stdout (last line); all other
# output goes to stderr. Runnable from any working directory.
set -euo pipefail

script_dir=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")" && pwd)
repo_root=$(cd -- "$script_dir/.." && pwd)
req="$repo_root/bench/requirements.txt"
cache="${ICRFLOW_CACHE:-$HOME/.cache/icrflow}"
venv="$cache/venv"
stamp="$venv/.requirements.sha256"
py="$venv/bin/python"

log() { printf '%s\n' "setup-python: $*" >&2; }

[[ -f "$req" ]] || { log "missing $req"; exit 1; }
command -v python3 >/dev/null 2>&1 || { log "python3 not found on PATH"; exit 1; }

want=$(sha256sum "$req" | cut -d' ' -f1)

if [[ -x "$py" && -f "$stamp" && "$(cat "$stamp")" == "$want" ]] \
    && "$py" -c 'import numpy, scipy.spatial, zenoh, rerun, pytest, trimesh, maturin, mujoco' >/dev/null 2>&1; then
    log "venv up to date: $venv"
    printf '%s\n' "$py"
    exit 0
fi

if [[ ! -x "$py" ]] || ! "$py" -c 'import sys' >/dev/null 2>&1; then
    log "creating venv at $venv"
    rm -rf "$venv"
    mkdir -p "$cache"
    python3 -m venv "$venv" >&2
fi

log "installing $req"
rm -f "$stamp"
"$py" -m pip install --disable-pip-version-check --quiet -r "$req" >&2
"$py" -c 'import numpy, scipy.spatial, zenoh, rerun, pytest, trimesh, maturin, mujoco' >&2
printf '%s\n' "$want" > "$stamp"
log "done: numpy $("$py" -c 'import numpy; print(numpy.__version__)'), scipy $("$py" -c 'import scipy; print(scipy.__version__)'), eclipse-zenoh $("$py" -c 'import importlib.metadata as m; print(m.version("eclipse-zenoh"))'), rerun-sdk $("$py" -c 'import importlib.metadata as m; print(m.version("rerun-sdk"))')"
printf '%s\n' "$py"
