#!/usr/bin/env bash
# Idempotent machine setup for building and testing icrflow.
# - Debian's libclang-dev: the qhull crate generates its bindings with bindgen at build time.
# - Debian's mesa-vulkan-drivers: a software Vulkan driver, so that the Rerun viewer renders
#   headless (the screenshot of a recording in the tests).
# - A Python venv with numpy + scipy for the Qhull cross-check (bench/reference_qhull.py) and
#   eclipse-zenoh for the external Zenoh client of the tests (tests/zenoh_client.py), and
#   rerun-sdk (with the `rerun` viewer) to read back and render the visualizer's recordings.
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
