#!/usr/bin/env bash
# The Python package's benchmarks (issue #23), in one run on one machine: criterion's 6D alpha*
# of the paper sphere (Rust), then bench/python_bench.py: the same evaluation called from Python
# (the binding's overhead), and batch throughput on 1 and 2 threads against
# bench/reference_qhull.py (numpy + scipy Qhull, one thread). Usage: bench/python.sh [args of
# python_bench.py]. Figures: BENCHMARKS.md.
set -euo pipefail
source "$(dirname "$0")/../scripts/env.sh"
py="$(scripts/setup-python.sh | tail -n 1)"
echo "== load average $(cut -d' ' -f1-3 /proc/loadavg); Rust (criterion, single thread)" >&2
cargo bench -p icrflow-grasp --bench quality -- --warm-up-time 1 --measurement-time 3 \
    'alpha6d-sphere72x72/alpha_star$' 2>&1 | grep -E '^grasp/|time:' >&2
echo "== Python (the package; the reference with one BLAS thread)" >&2
OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 \
    "$py" bench/python_bench.py --criterion "$CARGO_TARGET_DIR/criterion" "$@"
