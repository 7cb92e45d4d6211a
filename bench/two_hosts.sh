#!/usr/bin/env bash
# The pipeline split over two hosts (issue #5), measured: two network namespaces joined by a
# veth pair, each run in a mount namespace with a private /dev/shm, the example configs
# config/split_robot.toml and config/split_workstation.toml turned three times (rotation_deg =
# 1080) and run live for 65 s (stopped by SIGINT). The robot's run summary gives, in the same
# run, the local iceoryx2 hop (plant -> estimator) next to the two hops that cross over Zenoh
# (estimator -> wrench-space node, wrench-space node -> hand command node: each through both
# bridges); meanwhile a Python client on the workstation's host reads the robot's monitoring
# topics for 30 s over the link.
# Needs root (ip netns, mount). Usage: sudo bench/two_hosts.sh
# Writes the summaries to $CARGO_TARGET_DIR/bench-two-hosts-{robot,workstation}.json.
set -euo pipefail
source "$(dirname "$0")/../scripts/env.sh"
cargo build --release --workspace
py="$(scripts/setup-python.sh | tail -n 1)"
icrflow="$CARGO_TARGET_DIR/release/icrflow"

robot_ns="icr-bench-r$$" ws_ns="icr-bench-w$$" robot_ip=10.213.78.1 ws_ip=10.213.78.2
work="$(mktemp -d /tmp/icrflow-bench-two-hosts.XXXXXX)"
cleanup() {
    ip netns del "$robot_ns" 2>/dev/null || true
    ip netns del "$ws_ns" 2>/dev/null || true
    rm -rf "$work"
}
trap cleanup EXIT
ip netns add "$robot_ns"
ip netns add "$ws_ns"
ip link add "icrb$$r" netns "$robot_ns" type veth peer name "icrb$$w" netns "$ws_ns"
ip -n "$robot_ns" addr add "$robot_ip/24" dev "icrb$$r"
ip -n "$ws_ns" addr add "$ws_ip/24" dev "icrb$$w"
for ns in "$robot_ns" "$ws_ns"; do
    ip -n "$ns" link set lo up
done
ip -n "$robot_ns" link set "icrb$$r" up
ip -n "$ws_ns" link set "icrb$$w" up

cp config/zenoh_users.example "$work/"
for host in robot workstation; do
    sed -e "s/192\.0\.2\.10/$robot_ip/" -e 's/^rotation_deg = 360.0.*/rotation_deg = 1080.0/' \
        "config/split_$host.toml" > "$work/$host.toml"
done
# `icrflow run` in namespace $1 with a private /dev/shm; the rest are its arguments.
in_host() {
    local ns="$1"
    shift
    ip netns exec "$ns" unshare -m sh -c 'mount -t tmpfs icrflow-shm /dev/shm && exec "$0" "$@"' "$@"
}
echo "== load average at start: $(cut -d' ' -f1-3 /proc/loadavg)"
robot_json="$CARGO_TARGET_DIR/bench-two-hosts-robot.json"
ws_json="$CARGO_TARGET_DIR/bench-two-hosts-workstation.json"
in_host "$robot_ns" timeout --preserve-status -s INT 65 "$icrflow" run --live "$work/robot.toml" \
    --summary-json "$robot_json" > "$work/robot.out" 2>&1 &
robot=$!
sleep 1
ICRFLOW_ZENOH_PASSWORD=change-me-too in_host "$ws_ns" timeout --preserve-status -s INT 64 "$icrflow" \
    run --live "$work/workstation.toml" --summary-json "$ws_json" > "$work/workstation.out" 2>&1 &
ws=$!
sleep 20
ZENOH_USER=monitor ZENOH_PASSWORD=change-me ip netns exec "$ws_ns" "$py" tests/zenoh_client.py \
    --measure "tcp/$robot_ip:7447" paper 30 > "$work/monitor.json"
wait "$robot" "$ws" || true
tail -n 12 "$work/robot.out"
python3 - "$robot_json" "$ws_json" "$work/monitor.json" <<'PY'
import json, sys
r, w, m = (json.load(open(p)) for p in sys.argv[1:4])
t = r["latency_us"]["transport"]
local = t["joint_state"]
print(f"\nrobot: {r['seconds']:.1f} s, {r['commands']} hand commands ({r['command_rate_hz']:.0f} Hz, "
      f"{r['holds']} holds), rotation {r['rotation_deg']:.0f} deg; workstation: "
      f"{w['plan_steps']['published']} plan steps ({w['plan_steps']['rate_hz']:.0f} Hz)\n")
print("| hop (same run) | samples | p50 (us) | p99 (us) | max (us) | added p50 (us) | added p99 (us) |")
print("|---|--:|--:|--:|--:|--:|--:|")
rows = [("plant -> estimator, local iceoryx2", local, False),
        ("estimator -> wrench space, over Zenoh", t["grasp_state"], True),
        ("wrench space -> hand command, over Zenoh", t["wrench_space"], True)]
for name, p, zenoh in rows:
    added = (f"{p['p50'] - local['p50']:.0f} | {p['p99'] - local['p99']:.0f}" if zenoh else "- | -")
    print(f"| {name} | {p['samples']} | {p['p50']:.0f} | {p['p99']:.0f} | {p['max']:.0f} | {added} |")
e = r["latency_us"]["end_to_end"]
print(f"| end to end: joint measurement -> hand command | {e['samples']} | {e['p50']:.0f} | "
      f"{e['p99']:.0f} | {e['max']:.0f} | | |")
print("\nMonitoring the robot over the link (Python client on the workstation's host, 30 s):\n")
print("| topic | messages | rate (Hz) | delay p50 (us) | p99 (us) | max (us) |\n|---|--:|--:|--:|--:|--:|")
for topic, s in m.items():
    d = s["delay_us"]
    print(f"| {topic} | {s['messages']} | {s['rate_hz']:.0f} | {d['p50']:.0f} | {d['p99']:.0f} | {d['max']:.0f} |")
PY
