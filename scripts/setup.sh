#!/usr/bin/env bash
# Idempotent machine setup for building and testing icrflow.
# - Debian's libclang-dev: the qhull crate generates its bindings with bindgen at build time.
# - A Python venv with numpy + scipy for the Qhull cross-check (bench/reference_qhull.py) and
#   eclipse-zenoh for the external Zenoh client of the tests (tests/zenoh_client.py).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
need_apt=()
for pkg in libclang-dev; do
    dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "ok installed" || need_apt+=("$pkg")
done
if [ ${#need_apt[@]} -gt 0 ]; then
    echo "setup: installing ${need_apt[*]} (apt)" >&2
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    $SUDO apt-get update -qq >&2
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${need_apt[@]}" >&2
fi
"$root/scripts/setup-python.sh" >/dev/null
