#!/usr/bin/env python3
"""Markdown table of one `bench/compare.sh` run: criterion medians (Rust) beside the Python
reference's medians for the same cases, and the alpha* speed-up both by medians and by
minimums (Rust: the fastest criterion sample's time per iteration; Python: the fastest of its
repeats). The shared VM's speed changes from minute to minute (up to ~1.6x for the same
binary), and the two sides run minutes apart: the minimums are the comparison that phase
does not skew; `bench/compare.sh` alternates rounds of both and passes the minimums of every
round. Usage: table.py CRITERION_DIR PYTHON_JSON_LINES [RUST_MINIMUMS_JSON_LINES], or
table.py --minimums CRITERION_DIR (prints the current alpha* minimums as JSON lines)."""
import json
import pathlib
import sys

minimums_only = sys.argv[1] == "--minimums"
args = sys.argv[2:] if minimums_only else sys.argv[1:]
crit = pathlib.Path(args[0]) / "grasp"
# Per case: the last round's line, and the smallest alpha* minimum of every round.
py, py_min, rust_min = {}, {}, {}
if not minimums_only:
    for line in pathlib.Path(args[1]).read_text().splitlines():
        if line.strip().startswith("{"):
            d = json.loads(line)
            py[d["id"]] = d
            py_min[d["id"]] = min(py_min.get(d["id"], float("inf")), d["alpha_star_min_us"])
    if len(args) > 2:
        for line in pathlib.Path(args[2]).read_text().splitlines():
            if line.strip().startswith("{"):
                d = json.loads(line)
                rust_min[d["id"]] = min(rust_min.get(d["id"], float("inf")), d["alpha_star_min_us"])


def median_us(case: str, what: str):
    f = crit / f"{case}_{what}" / "new" / "estimates.json"
    if not f.exists():
        return None
    return json.loads(f.read_text())["median"]["point_estimate"] / 1e3


def min_us(case: str, what: str):
    f = crit / f"{case}_{what}" / "new" / "sample.json"
    if not f.exists():
        return None
    d = json.loads(f.read_text())
    return min(t / n for t, n in zip(d["times"], d["iters"])) / 1e3


def fmt(us):
    if us is None:
        return "-"
    return f"{us / 1e3:.2f} ms" if us >= 1000 else f"{us:.1f} us"


cases = sorted({p.name.split("_", 1)[0] for p in crit.iterdir() if p.is_dir() and "_" in p.name})
if minimums_only:
    for c in cases:
        m = min_us(c, "alpha_star")
        if m is not None:
            print(json.dumps({"id": c, "alpha_star_min_us": m}))
    sys.exit(0)
print("| case | alpha* (Rust) | hull, as evaluated | hull, beneath-beyond | support, tree "
      "| support, dense | ICR query (Rust) | ICRs given alpha* | alpha* (Python) "
      "| ICR query (Python) | alpha* speed-up | alpha* min (Rust / Python) | speed-up, min |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
for c in cases:
    a = median_us(c, "alpha_star")
    p = py.get(c, {})
    pa, pi = p.get("alpha_star_median_us"), p.get("icr_median_us")
    speed = f"{pa / a:.0f}x" if a and pa else "-"
    mins = [x for x in (min_us(c, "alpha_star"), rust_min.get(c)) if x is not None]
    am = min(mins) if mins else None
    pm = py_min.get(c)
    speed_min = f"{pm / am:.0f}x" if am and pm else "-"
    print(f"| {c} | {fmt(a)} | {fmt(median_us(c, 'hull_contacts'))} "
          f"| {fmt(median_us(c, 'hull_only'))} | {fmt(median_us(c, 'support_only'))} "
          f"| {fmt(median_us(c, 'support_dense'))} | {fmt(median_us(c, 'icrs_query'))} "
          f"| {fmt(median_us(c, 'icrs_only'))} | {fmt(pa)} | {fmt(pi)} | {speed} "
          f"| {fmt(am)} / {fmt(pm)} | {speed_min} |")
