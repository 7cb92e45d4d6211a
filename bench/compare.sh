#!/usr/bin/env bash
# Times the Rust grasp analysis (criterion) and the Python/Qhull reference on identical cases,
# in the same run on the same machine. Usage: bench/compare.sh [criterion filter]
# Prints the Python reference's JSON lines, then a markdown table of both (medians).
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
export ICRFLOW_CACHE="${ICRFLOW_CACHE:-$HOME/.cache/icrflow}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$ICRFLOW_CACHE/target}"
scripts/setup.sh
py="$(scripts/setup-python.sh | tail -n 1)"
cases="$CARGO_TARGET_DIR/bench-cases.json"
echo "== Rust (criterion, single thread)" >&2
ICRFLOW_BENCH_CASES="$cases" cargo bench -p icrflow-grasp --bench quality -- "$@" 2>&1 \
    | grep -E '^grasp/|time:|OWS points' >&2
echo "== Python reference (numpy + scipy Qhull), same cases" >&2
# Single thread on both sides: numpy's BLAS would otherwise use both cores.
OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 \
    "$py" bench/reference_qhull.py bench "$cases" --repeat 50 | tee "$CARGO_TARGET_DIR/bench-python.jsonl"
echo "== Table (medians)" >&2
python3 bench/table.py "$CARGO_TARGET_DIR/criterion" "$CARGO_TARGET_DIR/bench-python.jsonl"
