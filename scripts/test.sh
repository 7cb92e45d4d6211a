#!/usr/bin/env bash
# Every test: sets up what the tests need (idempotent), then runs the whole suite in release
# (one profile for tests and binaries), then the Python package's pytest suite.
set -euo pipefail
source "$(dirname "$0")/env.sh"
export ICRFLOW_PYTHON="${ICRFLOW_PYTHON:-$(scripts/setup-python.sh | tail -n 1)}"
# The pipeline tests start every node binary (the bridge's and the visualizer's too), which
# `cargo test` builds only for the packages whose own integration tests use them: build all.
cargo build --release --workspace --bins
cargo test --release --workspace "$@"
# The tests that need root and network namespaces (tests/two_hosts.rs) are #[ignore]d above;
# run them where a namespace can be made here, and say why not where it cannot.
probe="icrflow-probe-$$"
if [ $# -gt 0 ]; then
    echo "test: not run: tests/two_hosts.rs (the ignored tests), with arguments given" >&2
elif why="$(ip netns add "$probe" 2>&1)"; then
    ip netns del "$probe"
    cargo test --release --test two_hosts -- --ignored
else
    echo "test: NOT RUN: tests/two_hosts.rs (the ignored tests): no network namespace can be made here: ${why:-ip netns add failed}" >&2
fi
# The Python package's tests (python/tests), with the venv where scripts/setup.sh installed the
# package; they compare with the CLI built above ($CARGO_TARGET_DIR/release/icrflow).
"$ICRFLOW_PYTHON" -m pytest -q -p no:cacheprovider python/tests
