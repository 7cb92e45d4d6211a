#!/usr/bin/env bash
# The pipeline's latency benchmark (issue #4), in one run on this machine:
#  1. one hop between two processes, every way of waking (nodes/benches/hop.rs);
#  2. the pipeline for 65 s (`run --live`, stopped by SIGINT): the paper scenario turned three
#     times (~35-50 s), then holding its last step; measurement-to-command latency end to end
#     and per stage, the plan-step stream, each node's memory.
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
timeout --preserve-status -s INT 65 "$CARGO_TARGET_DIR/release/icrflow" run --live config/paper_sphere_3turns.toml \
    --summary-json "$summary" 2>&1
python3 - "$summary" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
l = s["latency_us"]
rows = [("end to end: joint measurement -> hand command", l["end_to_end"])]
rows += [(f"transport {k}", v) for k, v in l["transport"].items()]
rows += [(f"compute {k}", v) for k, v in l["compute"].items()]
rows += [("plan step compute", s["plan_steps"]["compute_us"])]
print(f"\n{s['seconds']:.1f} s, {s['commands']} hand commands "
      f"({s['command_rate_hz']:.0f} Hz, {s['holds']} holds), "
      f"{s['measurements']} joint measurements ({s['measurement_rate_hz']:.0f} Hz), "
      f"{s['plan_steps']['published']} plan steps ({s['plan_steps']['rate_hz']:.0f} Hz), "
      f"rotation {s['rotation_deg']:.0f} deg of {s['goal_deg']:.0f}\n")
print("| stage | samples | p50 (us) | p99 (us) | max (us) |\n|---|--:|--:|--:|--:|")
for name, p in rows:
    print(f"| {name} | {p['samples']} | {p['p50']:.0f} | {p['p99']:.0f} | {p['max']:.0f} |")
print("\n| node | RSS first (KiB) | last | max | samples |\n|---|--:|--:|--:|--:|")
for node, m in s["memory_kib"].items():
    print(f"| {node} | {m['first']} | {m['last']} | {m['max']} | {m['samples']} |")
PY
