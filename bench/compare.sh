#!/usr/bin/env bash
# Times the Rust grasp analysis (criterion) and the Python/Qhull reference on identical cases,
# in the same run on the same machine. Usage: bench/compare.sh [criterion options and filter]
# Prints the Python reference's JSON lines, then a markdown table of both (medians, and the
# alpha* minimums over all rounds).
# Rounds (ROUNDS, default 3): the first times everything, each further one only alpha* on
# both sides, alternating Rust and Python, so that a slow phase of the shared machine (its
# speed changes from minute to minute) does not fall on one side only; the table's minimums
# are over all rounds.
set -euo pipefail
source "$(dirname "$0")/../scripts/env.sh"
py="$(scripts/setup-python.sh | tail -n 1)"
cases="$CARGO_TARGET_DIR/bench-cases.json"
python_out="$CARGO_TARGET_DIR/bench-python.jsonl"
rust_min="$CARGO_TARGET_DIR/bench-rust-min.jsonl"
rounds="${ROUNDS:-3}"
: > "$python_out"
: > "$rust_min"
for round in $(seq 1 "$rounds"); do
    echo "== round $round of $rounds, load average $(cut -d' ' -f1-3 /proc/loadavg)" >&2
    echo "== Rust (criterion, single thread)" >&2
    if [ "$round" = 1 ]; then
        ICRFLOW_BENCH_CASES="$cases" cargo bench -p icrflow-grasp --bench quality -- "$@" 2>&1 \
            | grep -E '^grasp/|time:|OWS points' >&2
    else
        cargo bench -p icrflow-grasp --bench quality -- --warm-up-time 1 --measurement-time 3 \
            '/alpha_star$' 2>&1 | grep -E '^grasp/|time:' >&2
    fi
    python3 bench/table.py --minimums "$CARGO_TARGET_DIR/criterion" >> "$rust_min"
    echo "== Python reference (numpy + scipy Qhull), same cases" >&2
    # Single thread on both sides: numpy's BLAS would otherwise use both cores.
    OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 \
        "$py" bench/reference_qhull.py bench "$cases" --repeat 50 | tee -a "$python_out"
done
echo "== Table (medians: Python's of the last round; minimums over the $rounds rounds)" >&2
python3 bench/table.py "$CARGO_TARGET_DIR/criterion" "$python_out" "$rust_min"
