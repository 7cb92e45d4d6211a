#!/usr/bin/env bash
# The pipeline's latency benchmark (issue #4), in one run on this machine:
#  1. one hop between two processes, every way of waking (runtime/benches/hop.rs);
#  2. the pipeline for 65 s (`run --live`, stopped by SIGINT): the paper scenario turned three
#     times (~35-50 s), then holding its last step; measurement-to-command latency end to end
#     and per stage, the plan-step stream, each node's memory; meanwhile 30 s of the Zenoh
#     monitoring stream as a Python client receives it (rates, delay from the local bus).
# Usage: bench/pipeline.sh [seconds per hop cell, default 3]
# Writes the run's summary to $CARGO_TARGET_DIR/bench-pipeline.json and prints a table.
set -euo pipefail
source "$(dirname "$0")/../scripts/env.sh"
cargo build --release --workspace
echo "== load average at start: $(cut -d' ' -f1-3 /proc/loadavg)"
echo "== one hop between two processes (512 bytes)"
cargo bench -p icrflow-runtime --bench hop -- --seconds "${1:-3}"
summary="$CARGO_TARGET_DIR/bench-pipeline.json"
echo "== the pipeline: config/paper_sphere_3turns.toml"
timeout --preserve-status -s INT 65 "$CARGO_TARGET_DIR/release/icrflow" run --live config/paper_sphere_3turns.toml \
    --summary-json "$summary" 2>&1 &
run=$!
# Meanwhile, 30 s of the monitoring stream as an external Zenoh client receives it (the bridge's
# default endpoint), from 20 s into the run.
py="$(scripts/setup-python.sh | tail -n 1)"
sleep 20
"$py" tests/zenoh_client.py --measure tcp/127.0.0.1:7447 sim 30 > "$CARGO_TARGET_DIR/bench-monitor.json"
wait "$run"
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
m = json.load(open(sys.argv[1].replace("bench-pipeline.json", "bench-monitor.json")))
print("\nMonitoring over Zenoh (loopback, one Python client, 30 s): messages received, and delay")
print("from publication on the local bus to arrival at the client (the bridge polls every 10 ms)\n")
print("| topic | messages | rate (Hz) | delay p50 (us) | p99 (us) | max (us) |\n|---|--:|--:|--:|--:|--:|")
for topic, t in m.items():
    d = t["delay_us"]
    print(f"| {topic} | {t['messages']} | {t['rate_hz']:.0f} | {d['p50']:.0f} | {d['p99']:.0f} | {d['max']:.0f} |")
print("\n| node | RSS first (KiB) | last | max | samples |\n|---|--:|--:|--:|--:|")
for node, m in s["memory_kib"].items():
    print(f"| {node} | {m['first']} | {m['last']} | {m['max']} | {m['samples']} |")
print("\n| node | steady-state allocations | messages processed | per message | seconds |\n|---|--:|--:|--:|--:|")
for node, a in s["allocations"].items():
    per = a["steady"] / a["processed"] if a["processed"] else 0.0
    print(f"| {node} | {a['steady']} | {a['processed']} | {per:.1f} | {a['seconds']:.0f} |")
PY
