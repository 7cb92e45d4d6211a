#!/usr/bin/env bash
# Every test: sets up what the tests need (idempotent), then runs the whole suite in release
# (one profile for tests and binaries), then the Python package's pytest suite.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
export ICRFLOW_CACHE="${ICRFLOW_CACHE:-$HOME/.cache/icrflow}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$ICRFLOW_CACHE/target}"
scripts/setup.sh
export ICRFLOW_PYTHON="${ICRFLOW_PYTHON:-$(scripts/setup-python.sh | tail -n 1)}"
# The pipeline tests start every node binary (the bridge's and the visualizer's too), which
# `cargo test` builds only for the packages whose own integration tests use them: build all.
cargo build --release --workspace --bins
cargo test --release --workspace "$@"
# The Python package's tests (python/tests), with the venv where scripts/setup.sh installed the
# package; they compare with the CLI built above ($CARGO_TARGET_DIR/release/icrflow).
"$ICRFLOW_PYTHON" -m pytest -q -p no:cacheprovider python/tests
