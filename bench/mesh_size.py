"""Times `icrflow validate`, `analyze` (and with --plan, `plan`) against the mesh's size:
config/ellipsoid_spatial.toml as it is (its 5,040-triangle mesh) and with generated
ellipsoids of the same shape (bench/ellipsoid_stl.py), in the same run. BENCHMARKS.md,
"Large meshes".

    python bench/mesh_size.py ICRFLOW_BINARY [TRIANGLES...] [--plan] [--repeat N]

Default sizes: 250000 500000 1000000 2000000. Each verb runs with `--progress-after 0`, so
its stderr has the time of each stage (reading, welding, checking, facets, section, wrenches,
support tree); the wall time and peak resident memory are the process's own (os.wait4). The
median of N runs (default 1) is reported. Prints a Markdown table, the times per million
triangles from the largest mesh, and the machine. The generated meshes go to a temporary
directory, removed at the end.
"""

import os
import platform
import re
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
SMALL = os.path.join(ROOT, "config", "ellipsoid_spatial.toml")
LINE = re.compile(r"^progress   (.+?): (\d+) \S.* in ([0-9.]+) s$")


def run(cmd):
    """Runs `cmd`; returns (exit status, wall seconds, max RSS in MiB, stage seconds)."""
    start = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    err = p.stderr.read()
    _, status, usage = os.wait4(p.pid, 0)
    wall = time.perf_counter() - start
    p.returncode = os.waitstatus_to_exitcode(status)
    stages = {}
    for line in err.splitlines():
        m = LINE.match(line)
        if m:
            stages[m.group(1)] = float(m.group(3))
    if p.returncode not in (0, 2):
        sys.exit(f"{' '.join(cmd)} failed ({p.returncode}):\n{err}")
    return p.returncode, wall, usage.ru_maxrss / 1024, stages


def median_run(cmd, repeat):
    runs = [run(cmd) for _ in range(repeat)]
    walls = [r[1] for r in runs]
    best = runs[walls.index(statistics.median_low(walls))]
    return best


def config_for(mesh, directory, name):
    text = open(SMALL).read().replace(
        'path = "meshes/ellipsoid_55x45x40mm.stl"', f'path = "{mesh}"'
    )
    path = os.path.join(directory, name)
    with open(path, "w") as f:
        f.write(text)
    return path


def main() -> int:
    args = sys.argv[1:]
    binary = args.pop(0)
    plan = "--plan" in args
    repeat = 1
    if "--repeat" in args:
        i = args.index("--repeat")
        repeat = int(args[i + 1])
        del args[i : i + 2]
    sizes = [int(a) for a in args if not a.startswith("--")] or [250000, 500000, 1000000, 2000000]
    verbs = ["validate", "analyze"] + (["plan"] if plan else [])
    rows = []
    with tempfile.TemporaryDirectory(prefix="icrflow-mesh-size-") as tmp:
        configs = [(5040, SMALL)]
        for n in sizes:
            mesh = os.path.join(tmp, f"ellipsoid_{n}.stl")
            out = subprocess.run(
                [sys.executable, os.path.join(HERE, "ellipsoid_stl.py"), mesh, str(n)],
                check=True, capture_output=True, text=True,
            ).stdout.split()
            configs.append((int(out[2]), config_for(mesh, tmp, f"ellipsoid_{n}.toml")))
        for triangles, config in configs:
            row = {"triangles": triangles}
            for verb in verbs:
                cmd = [binary, verb, config, "--progress-after", "0"]
                if verb == "plan":
                    cmd += ["--out", os.path.join(tmp, "plan"), "--json"]
                status, wall, rss, stages = median_run(cmd, repeat)
                row[verb] = (wall, rss, stages)
            rows.append(row)
            print(f"done: {triangles} triangles", file=sys.stderr, flush=True)
    load = ["reading the mesh", "welding vertices", "checking faces and edges",
            "facets and their neighbours", "cutting the section"]
    build = ["object and contact wrenches", "support tree over the object wrenches"]
    head = "| triangles | load (s) | problem build (s) | validate (s) | validate RSS (MiB) | analyze (s) | analyze RSS (MiB) |"
    if plan:
        head += " plan (s) |"
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    for row in rows:
        stages = row["validate"][2]
        cells = [
            f"{row['triangles']}",
            f"{sum(stages.get(s, 0.0) for s in load):.2f}",
            f"{sum(stages.get(s, 0.0) for s in build):.2f}",
            f"{row['validate'][0]:.2f}", f"{row['validate'][1]:.0f}",
            f"{row['analyze'][0]:.2f}", f"{row['analyze'][1]:.0f}",
        ]
        if plan:
            cells.append(f"{row['plan'][0]:.1f}")
        print("| " + " | ".join(cells) + " |")
    print()
    print("stages (validate, s):")
    for row in rows:
        stages = row["validate"][2]
        print(f"  {row['triangles']:>8}: " + ", ".join(f"{k} {v:.2f}" for k, v in stages.items()))
    big = rows[-1]
    m = big["triangles"] / 1e6
    stages = big["validate"][2]
    print()
    print(f"per million triangles ({big['triangles']} triangles): "
          f"load {sum(stages.get(s, 0.0) for s in load) / m:.2f} s, "
          f"problem build {sum(stages.get(s, 0.0) for s in build) / m:.2f} s, "
          f"validate {big['validate'][0] / m:.2f} s, analyze {big['analyze'][0] / m:.2f} s"
          + (f", plan {big['plan'][0] / m:.1f} s" if plan else ""))
    cpu = next((l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo") if l.startswith("model name")), "?")
    print(f"machine: {os.cpu_count()} cores (nproc), {cpu}, {platform.platform()}; "
          f"load average {os.getloadavg()[0]:.2f} at the end")
    return 0


if __name__ == "__main__":
    sys.exit(main())
