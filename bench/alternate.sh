#!/usr/bin/env bash
# Two builds of the pipeline compared in one sitting, alternating (A, B, A, B, ...), so that
# what the machine does meanwhile falls on both: each run is bench/pipeline.sh's pipeline run
# (`run --live config/paper_sphere_3turns.toml`, 65 s, stopped by SIGINT), without the hop
# benchmark and the Zenoh client.
# Usage: bench/alternate.sh DIR_A DIR_B [rounds, default 3] [seconds per run, default 65]
#   DIR_A, DIR_B: folders each holding an `icrflow` binary and its node binaries beside it
#   (e.g. a copy of target/release of another commit; the same folder twice to compare configs).
#   CONFIG_A, CONFIG_B: the config each side runs (default config/paper_sphere_3turns.toml for
#   both), e.g. CONFIG_B=config/paper_sphere_mujoco.toml against CONFIG_A=config/paper_sphere.toml
#   to compare the plants.
# Writes each run's summary to $CARGO_TARGET_DIR/alternate/{a,b}-N.json and prints a table.
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
cd "$root"
if [ $# -lt 2 ]; then
    echo "usage: bench/alternate.sh DIR_A DIR_B [rounds] [seconds]" >&2
    exit 1
fi
a="$1" b="$2" rounds="${3:-3}" seconds="${4:-65}"
config_a="${CONFIG_A:-config/paper_sphere_3turns.toml}" config_b="${CONFIG_B:-config/paper_sphere_3turns.toml}"
for d in "$a" "$b"; do
    for bin in icrflow icrflow-plant icrflow-estimator icrflow-wrench icrflow-planner icrflow-command icrflow-bridge icrflow-visualizer; do
        [ -x "$d/$bin" ] || { echo "alternate: $d/$bin is missing or not executable" >&2; exit 1; }
    done
done
export ICRFLOW_CACHE="${ICRFLOW_CACHE:-$HOME/.cache/icrflow}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$ICRFLOW_CACHE/target}"
out="$CARGO_TARGET_DIR/alternate"
mkdir -p "$out"
rm -f "$out"/*.json
for i in $(seq 1 "$rounds"); do
    for side in a b; do
        dir="$a" config="$config_a"
        [ "$side" = b ] && dir="$b" config="$config_b"
        echo "== round $i, $side ($dir, $config), load $(cut -d' ' -f1-3 /proc/loadavg)" >&2
        timeout --preserve-status -s INT "$seconds" "$dir/icrflow" run --live \
            "$config" \
            --summary-json "$out/$side-$i.json" >/dev/null 2>"$out/$side-$i.log" || true
        [ -s "$out/$side-$i.json" ] || { echo "alternate: run $side-$i wrote no summary:" >&2; tail -5 "$out/$side-$i.log" >&2; exit 1; }
    done
done
python3 - "$out" "$rounds" <<'PY'
import json, sys
out, rounds = sys.argv[1], int(sys.argv[2])
print("| run | meas. Hz | cmd Hz | holds | e2e p50 (us) | e2e p99 (us) | alloc/msg plant, estimator, wrench, command |")
print("|---|--:|--:|--:|--:|--:|---|")
for i in range(1, rounds + 1):
    for side in "ab":
        s = json.load(open(f"{out}/{side}-{i}.json"))
        e = s["latency_us"]["end_to_end"]
        al = s.get("allocations", {})
        per = []
        for node in ("plant", "estimator", "wrench", "command"):
            x = next((v for k, v in al.items() if node in k), None)
            per.append(f"{x['steady'] / x['processed']:.1f}" if x and x["processed"] else "-")
        print(f"| {side.upper()}{i} | {s['measurement_rate_hz']:.0f} | {s['command_rate_hz']:.0f} | "
              f"{s['holds']} | {e['p50']:.0f} | {e['p99']:.0f} | {', '.join(per)} |")
PY
