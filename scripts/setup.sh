#!/usr/bin/env bash
# Idempotent machine setup for building and testing icrflow.
# - Debian's libclang-dev: the qhull crate generates its bindings with bindgen at build time.
# - Debian's mesa-vulkan-drivers: a software Vulkan driver, so that the Rerun viewer renders
#   headless (the screenshot of a recording in the tests).
# - A Python venv with numpy + scipy for the Qhull cross-check (bench/reference_qhull.py) and
#   eclipse-zenoh for the external Zenoh client of the tests (tests/zenoh_client.py), and
#   rerun-sdk (with the `rerun` viewer) to read back and render the visualizer's recordings,
#   and pytest, trimesh and maturin for the Python package's tests.
# - MuJoCo for the plant (icrflow-physics, mujoco-rs): links in the repository's .mujoco/lib
#   (`libmujoco.so` for the build, `libmujoco.so.3.17.0` for the loader) to the library of the
#   venv's PyPI `mujoco` wheel; .cargo/config.toml points MUJOCO_DYNAMIC_LINK_DIR there.
# - The Python package `icrflow` (python/) built and installed into that venv, skipped when
#   its sources are unchanged since the last install (see python/README.md).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
need_apt=()
for pkg in libclang-dev mesa-vulkan-drivers; do
    dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "ok installed" || need_apt+=("$pkg")
done
if [ ${#need_apt[@]} -gt 0 ]; then
    echo "setup: installing ${need_apt[*]} (apt)" >&2
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    $SUDO apt-get update -qq >&2
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need_apt[@]}" >&2
fi

# The Rerun viewer/CLI of the venv sends usage analytics unless told not to: the tests and this
# machine talk to no address beyond loopback.
py="$("$root/scripts/setup-python.sh" | tail -n 1)"
"$(dirname "$py")/rerun" analytics disable >/dev/null 2>&1 || true

# MuJoCo's library from the wheel, where mujoco-rs's build looks for it.
mujoco_lib="$("$py" -c 'import mujoco, os; print(os.path.join(os.path.dirname(mujoco.__file__), "libmujoco.so." + mujoco.__version__))')"
[[ -f "$mujoco_lib" ]] || { echo "setup: the mujoco wheel has no $mujoco_lib" >&2; exit 1; }
mkdir -p "$root/.mujoco/lib"
for name in libmujoco.so "$(basename "$mujoco_lib")"; do
    [[ "$(readlink "$root/.mujoco/lib/$name" 2>/dev/null)" == "$mujoco_lib" ]] || ln -sfn "$mujoco_lib" "$root/.mujoco/lib/$name"
done

# The Python package: `pip install ./python` with the venv's maturin (no build isolation, so
# nothing is downloaded), into CARGO_TARGET_DIR like every other build. Skipped when the stamp
# holds the hash of every file the module is built from and the module imports.
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-${ICRFLOW_CACHE:-$HOME/.cache/icrflow}/target}"
stamp="$(dirname "$(dirname "$py")")/.icrflow-package.sha256"
want="$(cd "$root" && find python grasp planner scenario -type f \( -name '*.rs' -o -name '*.toml' -o -name '*.pyi' -o -name '*.md' \) \
    -not -path 'python/tests/*' | LC_ALL=C sort | xargs sha256sum | cat - Cargo.toml Cargo.lock | sha256sum | cut -d' ' -f1)"
if [[ -f "$stamp" && "$(cat "$stamp")" == "$want" ]] && "$py" -c 'import icrflow' >/dev/null 2>&1; then
    echo "setup: the icrflow Python package is up to date" >&2
else
    echo "setup: building and installing the icrflow Python package (maturin, release)" >&2
    rm -f "$stamp"
    # The build backend runs the `maturin` binary of the venv from PATH.
    PATH="$(dirname "$py"):$PATH" "$py" -m pip install --disable-pip-version-check --quiet --no-build-isolation --no-deps \
        --force-reinstall "$root/python" >&2
    "$py" -c 'import icrflow' >&2
    printf '%s\n' "$want" > "$stamp"
fi
