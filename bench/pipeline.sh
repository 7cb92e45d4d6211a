#!/usr/bin/env bash
# The pipeline's latency benchmark (issue #4), in one run on this machine:
#  1. one hop between two processes, every way of waking (nodes/benches/hop.rs);
#  2. the pipeline on the paper scenario turned three times (~70 s): measurement-to-command
#     latency end to end and per stage, the plan-step stream, each node's memory.
# Usage: bench/pipeline.sh [seconds per hop cell, default 3]
# Writes the run's summary to $CARGO_TARGET_DIR/bench-pipeline.json and prints a table.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
export ICRFLOW_CACHE="${ICRFLOW_CACHE:-$HOME/.cache/icrflow}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$ICRFLOW_CACHE/target}"
scripts/setup.sh
cargo build --release --workspace
echo "== load average at start: $(cut -d' ' -f1-3 /proc/loadavg)"
echo "== one hop between two processes (512 bytes)"
cargo bench -p icrflow-nodes --bench hop -- --seconds "${1:-3}"
summary="$CARGO_TARGET_DIR/bench-pipeline.json"
echo "== the pipeline: config/paper_sphere_3turns.toml"
"$CARGO_TARGET_DIR/release/icrflow" run config/paper_sphere_3turns.toml --summary-json "$summary" \
    2> >(grep -v "hand holds" >&2)
python3 - "$summary" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
l = s["latency_us"]
rows = [("end to end: joint measurement -> hand command", l["end_to_end"])]
rows += [(f"transport {k}", v) for k, v in l["transport"].items()]
rows += [(f"compute {k}", v) for k, v in l["compute"].items()]
rows += [("plan step compute", s["plan_steps"]["compute_us"])]
print(f"\n{s['seconds']:.1f} s, {s['commands']} hand commands "
      f"({s['commands'] / s['seconds']:.0f} Hz, {s['holds']} holds), "
      f"{s['plan_steps']['published']} plan steps ({s['plan_steps']['rate_hz']:.0f} Hz), "
      f"completed: {s['completed']}\n")
print("| stage | samples | p50 (us) | p99 (us) | max (us) |\n|---|--:|--:|--:|--:|")
for name, p in rows:
    print(f"| {name} | {p['samples']} | {p['p50']:.0f} | {p['p99']:.0f} | {p['max']:.0f} |")
print("\n| node | RSS first (KiB) | last | max | samples |\n|---|--:|--:|--:|--:|")
for node, m in s["memory_kib"].items():
    print(f"| {node} | {m['first']} | {m['last']} | {m['max']} | {m['samples']} |")
PY
